//! The two threshold rules side by side: the screen-space error a view mesh leaves, in
//! pixels, over every sample the camera sees, and the area rule tuned to the triangle
//! count of a screen-space mesh.

use serde::Serialize;

use super::camera::View;
use super::selection::{Rule, ViewTerrain};
use crate::mesh::cells::CellTree;
use crate::mesh::rasterise::rasterise_triangle;
use crate::mesh::GridMesh;

/// How far a mesh is from the true surface, seen from a camera.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ScreenError {
    /// Largest height error projected to pixels.
    pub max_pixels: f64,
    /// Mean of the same over the samples seen.
    pub mean_pixels: f64,
    /// Samples inside the view frustum that the mesh covers.
    pub samples: usize,
}

/// The screen-space error of `mesh` with per-vertex heights `vertex_heights` (data units)
/// under `view`: for every valid sample in the frustum, the distance in pixels between
/// the images of the true surface point and of the mesh point above or below it (a mesh
/// point behind the eye is skipped).
pub fn screen_error(
    terrain: &ViewTerrain<'_>,
    view: &View,
    mesh: &GridMesh,
    vertex_heights: &[f64],
) -> ScreenError {
    let heights = terrain.heights();
    let w = heights.width;
    let mut surface = vec![f64::NAN; heights.values.len()];
    for t in &mesh.triangles {
        let corner = |v: u32| {
            let s = mesh.vertices[v as usize] as usize;
            (s % w, s / w, vertex_heights[v as usize])
        };
        rasterise_triangle(w, t.map(corner), |s, z| surface[s] = z);
    }
    let (mut worst, mut sum, mut count) = (0.0f64, 0.0f64, 0usize);
    for (s, &z) in surface.iter().enumerate() {
        if z.is_nan() {
            continue;
        }
        let truth = heights.values[s];
        let p = terrain.world(s % w, s / w, truth);
        if view.outside_distance(p, p) > 0.0 {
            continue;
        }
        let (Some((seen, _)), Some((drawn, _))) = (
            view.project(p),
            view.project(terrain.world(s % w, s / w, z)),
        ) else {
            continue;
        };
        let pixels = seen.distance(drawn);
        worst = worst.max(pixels);
        sum += pixels;
        count += 1;
    }
    ScreenError {
        max_pixels: worst,
        mean_pixels: if count > 0 { sum / count as f64 } else { 0.0 },
        samples: count,
    }
}

/// The area rule (`b = 0`) whose mesh under `view` has the triangle count closest to
/// `triangles`, searched over `a` (fewer triangles as `a` grows); with its selection and
/// mesh.
pub fn area_rule_matching(
    terrain: &ViewTerrain<'_>,
    view: &View,
    triangles: usize,
) -> (Rule, CellTree, GridMesh) {
    let build = |a: f64| {
        let rule = Rule::Area { a, b: 0.0 };
        let tree = terrain.select(view, rule);
        let mesh = terrain.triangulate(&tree);
        (rule, tree, mesh)
    };
    let (mut lo, mut hi) = (-12.0f64, 12.0f64); // log10 a
    let mut best = build(10f64.powf(hi));
    let gap = |m: &GridMesh| m.triangles.len().abs_diff(triangles);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        let candidate = build(10f64.powf(mid));
        let count = candidate.2.triangles.len();
        let closer = gap(&candidate.2) < gap(&best.2);
        if count > triangles {
            lo = mid;
        } else {
            hi = mid;
        }
        if closer {
            best = candidate;
        }
        if count == triangles {
            break;
        }
    }
    best
}

/// The screen-space rule whose mesh under `view` has the triangle count closest to
/// `triangles`, searched over τ (fewer triangles as τ grows); with its selection and mesh.
pub fn sse_rule_matching(
    terrain: &ViewTerrain<'_>,
    view: &View,
    triangles: usize,
) -> (Rule, CellTree, GridMesh) {
    let build = |log_tau: f64| {
        let rule = Rule::ScreenSpace {
            tau: 10f64.powf(log_tau),
        };
        let tree = terrain.select(view, rule);
        let mesh = terrain.triangulate(&tree);
        (rule, tree, mesh)
    };
    let (mut lo, mut hi) = (-3.0f64, 6.0f64);
    let mut best = build(hi);
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        let candidate = build(mid);
        let count = candidate.2.triangles.len();
        if count > triangles {
            lo = mid;
        } else {
            hi = mid;
        }
        if count.abs_diff(triangles) < best.2.triangles.len().abs_diff(triangles) {
            best = candidate;
        }
    }
    best
}
