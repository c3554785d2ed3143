//! The simplifier end to end: targets met, and every mesh valid.

use std::collections::HashSet;

use super::*;
use crate::mesh::rasterise::mesh_error;

/// Rolling hills with a ridge oblique to the grid.
fn terrain(w: usize, h: usize) -> Vec<f64> {
    (0..w * h)
        .map(|s| {
            let (x, y) = ((s % w) as f64, (s / w) as f64);
            40.0 * (-(x - 0.6 * y - 10.0).powi(2) / 30.0).exp()
                + 5.0 * (x / 7.0).sin() * (y / 5.0).cos()
        })
        .collect()
}

/// Valid grid triangles of a grid (what the mesh must cover exactly).
fn valid_grid_triangles(w: usize, h: usize, heights: &[f64], valid: &BitVec<u64, Lsb0>) -> i64 {
    let grid = Grid {
        width: w,
        height: h,
        heights,
        valid,
    };
    initial_quadrics(&grid, &grid.flag_map()).2 as i64
}

/// Panics unless `mesh` is valid over `valid`: every triangle counter-clockwise seen
/// from above, every directed edge once (no fold, no non-manifold edge), the area of
/// the valid grid triangles covered exactly, no void sample covered, the grid's
/// corners kept when valid.
fn check_valid(mesh: &GridMesh, heights: &[f64], valid: &BitVec<u64, Lsb0>) {
    let (w, h) = (mesh.width, mesh.height);
    let mut edges = HashSet::new();
    let mut twice_area = 0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
        let twice = grid::orient(w, a, b, c);
        assert!(twice > 0, "triangle {a} {b} {c} flipped or flat");
        twice_area += twice;
        for edge in [(a, b), (b, c), (c, a)] {
            assert!(edges.insert(edge), "edge {edge:?} twice the same way");
        }
        let corner = |s: u32| ((s as usize % w), (s as usize / w), 0.0);
        rasterise_triangle(w, [corner(a), corner(b), corner(c)], |s, _| {
            assert!(valid[s], "sample {s} is nodata and covered");
        });
    }
    assert_eq!(twice_area, valid_grid_triangles(w, h, heights, valid));
    let used: HashSet<u32> = mesh.vertices.iter().copied().collect();
    for corner in [0, w - 1, w * (h - 1), w * h - 1] {
        assert!(
            !valid[corner] || used.contains(&(corner as u32)),
            "corner {corner} moved"
        );
    }
}

fn all_valid(n: usize) -> BitVec<u64, Lsb0> {
    bitvec![u64, Lsb0; 1; n]
}

#[test]
fn a_triangle_budget_is_met_and_the_mesh_is_valid() {
    let (w, h) = (61, 47);
    let heights = terrain(w, h);
    let valid = all_valid(w * h);
    for budget in [2000, 500, 100] {
        let out = qem_mesh(w, h, &heights, &valid, QemTarget::Triangles(budget)).unwrap();
        let count = out.mesh.triangles.len();
        assert!(
            count <= budget && count + 2 >= budget,
            "{count} for {budget}"
        );
        check_valid(&out.mesh, &heights, &valid);
    }
}

#[test]
fn fewer_triangles_cost_more_error() {
    let (w, h) = (61, 47);
    let heights = terrain(w, h);
    let valid = all_valid(w * h);
    let rmse = |n| {
        let out = qem_mesh(w, h, &heights, &valid, QemTarget::Triangles(n)).unwrap();
        mesh_error(&out.mesh, &heights, &heights, &valid).rmse
    };
    let (fine, coarse) = (rmse(1500), rmse(150));
    assert!(fine < coarse, "{fine} vs {coarse}");
    assert!(fine < coarse / 4.0, "{fine} vs {coarse}");
}

#[test]
fn a_max_error_holds_at_every_sample() {
    let (w, h) = (61, 47);
    let heights = terrain(w, h);
    let valid = all_valid(w * h);
    let out = qem_mesh(w, h, &heights, &valid, QemTarget::MaxError(0.5)).unwrap();
    check_valid(&out.mesh, &heights, &valid);
    let error = mesh_error(&out.mesh, &heights, &heights, &valid);
    assert!(error.max_error <= 0.5, "{}", error.max_error);
    assert_eq!(error.uncovered_samples, 0);
    assert!(out.mesh.triangles.len() < 2 * (w - 1) * (h - 1) / 4);
}

#[test]
fn a_plane_collapses_to_a_few_triangles() {
    let (w, h) = (33, 17);
    let heights: Vec<f64> = (0..w * h)
        .map(|s| 3.0 * (s % w) as f64 - 2.0 * (s / w) as f64)
        .collect();
    let valid = all_valid(w * h);
    let out = qem_mesh(w, h, &heights, &valid, QemTarget::MaxError(1e-9)).unwrap();
    check_valid(&out.mesh, &heights, &valid);
    assert!(
        out.mesh.triangles.len() <= 8,
        "{}",
        out.mesh.triangles.len()
    );
}

/// The hills with a round void and a void strip along the left side.
fn voided(w: usize, h: usize) -> (Vec<f64>, BitVec<u64, Lsb0>) {
    let mut heights = terrain(w, h);
    let mut valid = all_valid(w * h);
    for (s, height) in heights.iter_mut().enumerate() {
        let (x, y) = ((s % w) as f64, (s / w) as f64);
        if (x - 30.0).powi(2) + (y - 20.0).powi(2) < 40.0 || (x < 3.0 && y > 30.0) {
            *height = f64::NAN;
            valid.set(s, false);
        }
    }
    (heights, valid)
}

#[test]
fn voids_are_never_meshed_and_their_outline_is_kept() {
    let (w, h) = (61, 47);
    let (heights, valid) = voided(w, h);
    for target in [QemTarget::Triangles(200), QemTarget::MaxError(1.0)] {
        let out = qem_mesh(w, h, &heights, &valid, target).unwrap();
        check_valid(&out.mesh, &heights, &valid);
        let error = mesh_error(&out.mesh, &heights, &heights, &valid);
        assert_eq!(error.uncovered_samples, 0, "{target:?}");
    }
}

#[test]
fn the_flag_map_alone_gives_the_mesh_the_contractions_left() {
    let (w, h) = (61, 47);
    let (heights, valid) = voided(w, h);
    let grid = Grid {
        width: w,
        height: h,
        heights: &heights,
        valid: &valid,
    };
    let mut simplifier = Simplifier::new(grid, QemTarget::Triangles(300));
    simplifier.run(QemTarget::Triangles(300));
    let counted = simplifier.triangles;
    let roots: Vec<u32> = (0..w * h)
        .map(|s| simplifier.clusters.find_merger(s as u32))
        .collect();
    let sizes = simplifier.fan_sizes.clone();
    let out = simplifier.snapshot();
    assert_eq!(out.mesh.triangles.len(), counted);
    // The fan sizes kept along the way are the extracted mesh's, each within the cap.
    let mut around = vec![0u8; w * h];
    for t in &out.mesh.triangles {
        for v in t {
            around[out.mesh.vertices[*v as usize] as usize] += 1;
        }
    }
    assert_eq!(around, sizes);
    assert!(sizes.iter().all(|&k| usize::from(k) <= MAX_FAN));
    assert_eq!(out.flags.mergers(), roots);
    assert_eq!(out.flags.bytes(), (w * h).div_ceil(2));
}

#[test]
fn bad_grids_are_refused() {
    let valid = all_valid(4);
    let too_small = qem_mesh(4, 1, &[0.0; 4], &valid, QemTarget::Triangles(1));
    assert!(matches!(too_small, Err(QemError::TooSmall { .. })));
    let infinite = qem_mesh(
        2,
        2,
        &[0.0, f64::INFINITY, 0.0, 0.0],
        &valid,
        QemTarget::Triangles(1),
    );
    assert_eq!(infinite.unwrap_err(), QemError::NotFinite(1));
    let short = qem_mesh(2, 2, &[0.0; 3], &valid, QemTarget::Triangles(1));
    assert!(matches!(short, Err(QemError::SizeMismatch(3, 4))));
}

#[test]
fn one_run_gives_the_meshes_of_separate_runs() {
    let (w, h) = (61, 47);
    let (heights, valid) = voided(w, h);
    let budgets = [300, 2000, 800];
    let meshes = qem_meshes_within(w, h, &heights, &valid, &budgets).unwrap();
    for (mesh, &budget) in meshes.iter().zip(&budgets) {
        let alone = qem_mesh(w, h, &heights, &valid, QemTarget::Triangles(budget)).unwrap();
        assert_eq!(*mesh, alone.mesh, "{budget}");
    }
}
