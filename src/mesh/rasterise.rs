//! Puts a mesh back onto its grid: the height of every sample a triangle covers, by
//! linear interpolation in that triangle. This is how a mesh's error is measured, ours
//! and the peers' alike.

use bitvec::prelude::*;
use serde::Serialize;

use super::GridMesh;

/// Calls `visit(sample, height)` for every grid sample inside or on the edge of triangle
/// `corners` (each `(column, row, height)`); samples on shared edges are visited once per
/// triangle, with the same height.
#[inline]
pub fn rasterise_triangle(
    width: usize,
    corners: [(usize, usize, f64); 3],
    mut visit: impl FnMut(usize, f64),
) {
    let [(ax, ay, az), (bx, by, bz), (cx, cy, cz)] = corners;
    let (ax, ay, bx, by, cx, cy) = (
        ax as i64, ay as i64, bx as i64, by as i64, cx as i64, cy as i64,
    );
    let area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    if area == 0 {
        return;
    }
    // Orient positively so the edge functions are non-negative inside.
    let sign = area.signum();
    let area = area.abs() as f64;
    let (min_x, max_x) = (ax.min(bx).min(cx), ax.max(bx).max(cx));
    let (min_y, max_y) = (ay.min(by).min(cy), ay.max(by).max(cy));
    let edge = |px: i64, py: i64, qx: i64, qy: i64, x: i64, y: i64| {
        sign * ((qx - px) * (y - py) - (qy - py) * (x - px))
    };
    for y in min_y..=max_y {
        for x in min_x..=max_x {
            // Weights of a (opposite edge bc), b (ca) and c (ab).
            let wa = edge(bx, by, cx, cy, x, y);
            let wb = edge(cx, cy, ax, ay, x, y);
            let wc = edge(ax, ay, bx, by, x, y);
            if wa >= 0 && wb >= 0 && wc >= 0 {
                let z = (wa as f64 * az + wb as f64 * bz + wc as f64 * cz) / area;
                visit(y as usize * width + x as usize, z);
            }
        }
    }
}

/// The mesh's height at every sample it covers (`covered`), from the heights of its
/// vertices' samples in `heights`.
pub fn rasterise(mesh: &GridMesh, heights: &[f64]) -> (Vec<f64>, BitVec<u64, Lsb0>) {
    let n = mesh.width * mesh.height;
    let mut surface = vec![0.0; n];
    let mut covered = bitvec![u64, Lsb0; 0; n];
    for t in &mesh.triangles {
        let corner = |v: u32| {
            let (x, y) = mesh.vertex_position(v);
            (x, y, heights[mesh.vertices[v as usize] as usize])
        };
        rasterise_triangle(
            mesh.width,
            [corner(t[0]), corner(t[1]), corner(t[2])],
            |s, z| {
                surface[s] = z;
                covered.set(s, true);
            },
        );
    }
    (surface, covered)
}

/// A mesh's error against a DEM, over the DEM's valid samples the mesh covers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeshError {
    /// Valid samples the mesh covers (those compared).
    pub compared_samples: u64,
    /// Valid samples outside every triangle (cut off by nodata around them).
    pub uncovered_samples: u64,
    /// Root mean squared error, data units.
    pub rmse: f64,
    /// 20·log10(R / RMSE) with R the range of the DEM's valid samples (`inf` when exact).
    pub psnr_db: f64,
    /// Largest absolute error, data units.
    pub max_error: f64,
}

/// Measures `mesh` (vertex heights taken from `mesh_heights`) against `reference`
/// (`valid` marks its valid samples).
pub fn mesh_error(
    mesh: &GridMesh,
    mesh_heights: &[f64],
    reference: &[f64],
    valid: &BitSlice<u64, Lsb0>,
) -> MeshError {
    let (surface, covered) = rasterise(mesh, mesh_heights);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut sum_sq, mut max_error) = (0.0f64, 0.0f64);
    let (mut compared, mut uncovered) = (0u64, 0u64);
    for (s, &h) in reference.iter().enumerate() {
        if !valid[s] {
            continue;
        }
        lo = lo.min(h);
        hi = hi.max(h);
        if !covered[s] {
            uncovered += 1;
            continue;
        }
        compared += 1;
        let e = surface[s] - h;
        sum_sq += e * e;
        max_error = max_error.max(e.abs());
    }
    let rmse = if compared > 0 {
        (sum_sq / compared as f64).sqrt()
    } else {
        0.0
    };
    MeshError {
        compared_samples: compared,
        uncovered_samples: uncovered,
        rmse,
        psnr_db: crate::metrics::psnr(hi - lo, rmse),
        max_error,
    }
}

/// Valid samples no mesh on the grid can cover: those that no grid cell with at least
/// three valid corners has as a corner (the least [`MeshError::uncovered_samples`] a mesh
/// that never uses a nodata vertex can reach; the zerotree mesh reaches it).
pub fn uncoverable_samples(width: usize, height: usize, valid: &BitSlice<u64, Lsb0>) -> u64 {
    assert_eq!(valid.len(), width * height);
    if valid.all() && width > 1 && height > 1 {
        return 0;
    }
    let mut reachable = bitvec![u64, Lsb0; 0; width * height];
    for y in 0..height.saturating_sub(1) {
        for x in 0..width - 1 {
            let (tl, tr) = (y * width + x, y * width + x + 1);
            let corners = [tl, tr, tr + width, tl + width];
            if corners.iter().filter(|&&s| valid[s]).count() >= 3 {
                for s in corners {
                    reachable.set(s, true);
                }
            }
        }
    }
    (valid.to_bitvec() & !reachable).count_ones() as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_triangle_covers_its_lattice_points_with_a_plane() {
        let mut seen = Vec::new();
        rasterise_triangle(10, [(0, 0, 0.0), (4, 0, 4.0), (0, 4, 8.0)], |s, z| {
            seen.push((s % 10, s / 10, z))
        });
        // Lattice points with x + y ≤ 4: 15 of them.
        assert_eq!(seen.len(), 15);
        for (x, y, z) in seen {
            assert!(x + y <= 4);
            assert!((z - (x as f64 + 2.0 * y as f64)).abs() < 1e-12);
        }
    }

    #[test]
    fn a_sample_is_uncoverable_when_no_cell_around_it_has_three_valid_corners() {
        // 4 × 3, nodata marked 0:
        // 1 1 0 1
        // 1 0 1 0
        // 1 1 0 1
        let valid: BitVec<u64, Lsb0> = [1, 1, 0, 1, 1, 0, 1, 0, 1, 1, 0, 1]
            .iter()
            .map(|&v| v == 1)
            .collect();
        // Cells (0,0) and (0,1) have three valid corners: they reach (0,0), (1,0), (0,1),
        // (0,2), (1,2). Samples (3,0), (2,1) and (3,2) are valid and reached by none.
        assert_eq!(uncoverable_samples(4, 3, &valid), 3);
        assert_eq!(uncoverable_samples(4, 3, &bitvec![u64, Lsb0; 1; 12]), 0);
    }
}
