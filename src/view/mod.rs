//! View-dependent terrain from one decode: per-region thresholds from a camera, one
//! crack-free mesh with mixed cell sizes, geomorphing, and frame-to-frame split/merge.
//!
//! Pipeline, one module per stage: [`camera`] (glam: frame, frustum, projections) →
//! [`selection`] (which quadtree nodes split under the view: screen-space error from the
//! error pyramid, or the seed paper's projected-area threshold on the significance map)
//! → the existing triangulation ([`crate::mesh::triangulate`], hanging vertices, so no
//! T-junction) → [`morph`] (every vertex between its coarse and true height). Between
//! frames, [`incremental`] updates the previous selection in place; [`checks`] counts
//! cracks and popping; [`render`] draws frames as PNG.

pub mod camera;
pub mod checks;
pub mod compare;
pub mod incremental;
pub mod morph;
pub mod render;
pub mod selection;

/// Why a view could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The camera is unusable (the message says why).
    #[error("bad camera: {0}")]
    Camera(String),
    /// The threshold rule's constants are out of range.
    #[error("bad rule: {0}")]
    Rule(String),
    /// The significance map, heights and validity describe different grids.
    #[error("the significance map, heights and validity differ in size")]
    SizeMismatch,
    /// A frame image could not be encoded or written.
    #[error("cannot write the frame image: {0}")]
    Render(String),
}

/// Uniform numbers in [0, 1) from a fixed-seed linear congruential generator, for tests
/// that walk random cameras.
#[cfg(test)]
fn unit_random(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}
