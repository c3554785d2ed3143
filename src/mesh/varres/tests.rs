use super::classify::{classify, Class, FeatureRule};
use super::extract::{triangles_at_error, triangles_at_step};
use super::topology::{Star, Topology};
use super::*;

/// The class of every sample of a `w × h` grid of `heights` (all valid).
fn classes(w: usize, h: usize, heights: &[f64]) -> Vec<Class> {
    let valid = bitvec![u64, Lsb0; 1; w * h];
    let grid = Grid {
        width: w,
        height: h,
        heights,
        valid: &valid,
    };
    let topology = Topology::of_grid(&grid);
    let rule = FeatureRule {
        cos_angle: 30f64.to_radians().cos(),
        z_scale: 1.0,
    };
    let mut star = Star::default();
    (0..(w * h) as u32)
        .map(|v| {
            topology.star(v, &mut star);
            classify(&topology, heights, &rule, v, &star)
        })
        .collect()
}

#[test]
fn a_cones_apex_is_a_peak_and_its_flanks_are_plain() {
    let (w, h) = (9, 9);
    let heights: Vec<f64> = (0..w * h)
        .map(|s| {
            let (x, y) = ((s % w) as f64 - 4.0, (s / w) as f64 - 4.0);
            10.0 - (x * x + y * y).sqrt()
        })
        .collect();
    let classes = classes(w, h, &heights);
    assert_eq!(classes[4 * w + 4], Class::Peak);
    // Far down a flank the surface is nearly flat across every edge.
    let flank = classes[4 * w + 1];
    assert!(matches!(flank, Class::Plain | Class::Ridge(_)), "{flank:?}");
}

#[test]
fn a_ridge_line_is_a_ridge_and_border_vertices_slide_only_along_the_border() {
    let (w, h) = (9, 7);
    let heights: Vec<f64> = (0..w * h)
        .map(|s| 10.0 - 3.0 * ((s % w) as f64 - 4.0).abs())
        .collect();
    let classes = classes(w, h, &heights);
    for y in 1..h - 1 {
        let v = (y * w + 4) as u32;
        let Class::Ridge(ends) = classes[v as usize] else {
            panic!("row {y}: {:?}", classes[v as usize]);
        };
        let mut ends = ends.to_vec();
        ends.sort();
        assert_eq!(ends, vec![v - w as u32, v + w as u32], "along the ridge");
    }
    assert_eq!(classes[2 * w + 2], Class::Plain);
    assert_eq!(classes[0], Class::Peak, "a corner of the grid");
    assert!(matches!(
        classes[2],
        Class::Boundary([1, 3]) | Class::Boundary([3, 1])
    ));
}

/// A deterministic rough surface with a void blob.
fn rough(w: usize, h: usize, seed: u64) -> (Vec<f64>, BitVec<u64, Lsb0>) {
    let mut state = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % 1000) as f64 / 1000.0
    };
    let heights: Vec<f64> = (0..w * h)
        .map(|s| {
            let (x, y) = ((s % w) as f64, (s / w) as f64);
            20.0 * (x / 5.0).sin() * (y / 7.0).cos() + 3.0 * next()
        })
        .collect();
    let mut valid = bitvec![u64, Lsb0; 1; w * h];
    for s in 0..w * h {
        let (x, y) = ((s % w) as f64, (s / w) as f64);
        if (x - w as f64 / 3.0).powi(2) + (y - h as f64 / 2.0).powi(2) < 16.0 {
            valid.set(s, false);
        }
    }
    (heights, valid)
}

fn sorted(mut triangles: Vec<[u32; 3]>) -> Vec<[u32; 3]> {
    for t in &mut triangles {
        let k = (0..3).min_by_key(|&i| t[i]).unwrap();
        t.rotate_left(k);
    }
    triangles.sort();
    triangles
}

#[test]
fn the_mesh_at_a_step_is_the_mesh_the_simplification_had_then() {
    let (w, h) = (24, 20);
    let (heights, valid) = rough(w, h, 3);
    let full = build_model(w, h, &heights, &valid, &VarresOptions::default()).unwrap();
    for floor in [600, 250, 60] {
        let options = VarresOptions {
            min_triangles: floor,
            ..VarresOptions::default()
        };
        let stopped = build_model(w, h, &heights, &valid, &options).unwrap();
        let live: Vec<[u32; 3]> = (0..stopped.corners.len())
            .filter(|&t| stopped.death[t] == history::NEVER)
            .map(|t| stopped.corners[t])
            .collect();
        assert!(live.len() <= floor);
        let mut extracted = Vec::new();
        triangles_at_step(&full, stopped.steps(), &mut extracted);
        assert_eq!(sorted(extracted), sorted(live), "floor {floor}");
    }
}

#[test]
fn the_mesh_at_an_error_is_the_mesh_after_every_step_within_it() {
    let (w, h) = (20, 20);
    let (heights, valid) = rough(w, h, 5);
    let model = build_model(w, h, &heights, &valid, &VarresOptions::default()).unwrap();
    assert!(model.step_error.windows(2).all(|e| e[0] <= e[1]));
    let epsilon = model.step_error[model.steps() / 2];
    let step = model.step_at_error(epsilon);
    assert!(model.error_of_step(step) <= epsilon);
    assert!(step == model.steps() || model.step_error[step] > epsilon);
    let (mut by_error, mut by_step) = (Vec::new(), Vec::new());
    triangles_at_error(&model, epsilon, &mut by_error);
    triangles_at_step(&model, step, &mut by_step);
    assert_eq!(by_error, by_step);
    assert_eq!(by_step.len(), model.step_triangles[step] as usize);
}

#[test]
fn bad_grids_are_errors() {
    let valid = bitvec![u64, Lsb0; 1; 4];
    let options = VarresOptions::default();
    assert!(matches!(
        build_model(4, 1, &[0.0; 4], &valid, &options),
        Err(VarresError::TooSmall { .. })
    ));
    assert_eq!(
        build_model(2, 2, &[0.0, f64::NAN, 0.0, 0.0], &valid, &options).unwrap_err(),
        VarresError::NotFinite(1)
    );
    assert!(matches!(
        build_model(2, 2, &[0.0; 3], &valid, &options),
        Err(VarresError::SizeMismatch(3, 4))
    ));
}
