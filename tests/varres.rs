//! The variable-resolution mesher (seed paper 001): meshes out of the model are valid
//! (no flipped triangle, manifold, conforming, the outline and voids kept) at uniform
//! and view-dependent errors, on random DEMs with voids and on a window of the shared
//! `alps_srtm_voids` (skipped with a notice when `../shared/dem` is absent), and every
//! sample is within the metric's bound, 2ε, of the mesh at ε.

mod support;

use std::collections::HashMap;

use bitvec::prelude::*;
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh::lod::Surface;
use wavemesh::mesh::rasterise::{mesh_error, rasterise};
use wavemesh::mesh::varres::extract::{grid_mesh, triangles_at_error, triangles_varying};
use wavemesh::mesh::varres::{build_model, mesh_meeting, History, VarresOptions, VarresTarget};
use wavemesh::meshers::window;

/// A rough random surface with a round void and a void square touching the border.
fn random_dem(w: usize, h: usize, seed: u64) -> (Vec<f64>, BitVec<u64, Lsb0>) {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let (cx, cy, r) = (next() * w as f64, next() * h as f64, 2.0 + 4.0 * next());
    let mut heights = Vec::with_capacity(w * h);
    let mut valid = bitvec![u64, Lsb0; 1; w * h];
    for s in 0..w * h {
        let (x, y) = ((s % w) as f64, (s / w) as f64);
        heights.push(30.0 * (x / 6.0).sin() * (y / 9.0).cos() + 10.0 * next());
        let hole = (x - cx).powi(2) + (y - cy).powi(2) < r * r;
        let notch = x < 4.0 && (5.0..9.0).contains(&y);
        if hole || notch || next() < 0.01 {
            valid.set(s, false);
        }
    }
    (heights, valid)
}

/// Checks `triangles` form a valid mesh of the grid triangles of `model` (step 0):
/// corners valid, none flipped or flat, every edge in at most two triangles in
/// opposite directions, the same area, and every border edge along the grid mesh's
/// outline (no crack, no T-junction).
fn assert_valid(model: &History, valid: &BitSlice<u64, Lsb0>, triangles: &[[u32; 3]]) {
    let w = model.width as i64;
    let xy = |v: u32| (v as i64 % w, v as i64 / w);
    let orient = |[a, b, c]: [u32; 3]| {
        let (a, b, c) = (xy(a), xy(b), xy(c));
        (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
    };
    let grid: Vec<[u32; 3]> = (0..model.corners.len())
        .filter(|&t| model.birth[t] == 0)
        .map(|t| model.corners[t])
        .collect();
    let outline = border_half_edges(&grid);
    let mut area = 0;
    let mut half_edges: HashMap<(u32, u32), usize> = HashMap::new();
    for &t in triangles {
        assert!(t.iter().all(|&v| valid[v as usize]), "{t:?} touches nodata");
        let doubled = orient(t);
        assert!(doubled > 0, "{t:?} flipped or flat");
        area += doubled;
        for i in 0..3 {
            *half_edges.entry((t[i], t[(i + 1) % 3])).or_default() += 1;
        }
    }
    assert_eq!(area, grid.len() as i64, "the area of the grid's triangles");
    for (&(p, q), &n) in &half_edges {
        assert_eq!(n, 1, "half-edge {p}->{q} in {n} triangles: not manifold");
        if half_edges.contains_key(&(q, p)) {
            continue;
        }
        // A border edge: every unit step along it is a border edge of the grid mesh.
        let ((px, py), (qx, qy)) = (xy(p), xy(q));
        let steps = gcd((qx - px).abs(), (qy - py).abs());
        let (dx, dy) = ((qx - px) / steps, (qy - py) / steps);
        for k in 0..steps {
            let a = ((py + k * dy) * w + px + k * dx) as u32;
            let b = ((py + (k + 1) * dy) * w + px + (k + 1) * dx) as u32;
            assert!(
                outline.contains_key(&(a, b)),
                "border edge {p}->{q} leaves the outline"
            );
        }
    }
}

fn border_half_edges(triangles: &[[u32; 3]]) -> HashMap<(u32, u32), ()> {
    let all: HashMap<(u32, u32), ()> = triangles
        .iter()
        .flat_map(|t| (0..3).map(move |i| ((t[i], t[(i + 1) % 3]), ())))
        .collect();
    all.keys()
        .filter(|&&(p, q)| !all.contains_key(&(q, p)))
        .map(|&e| (e, ()))
        .collect()
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Every valid sample a grid triangle covers is covered by `triangles` and within
/// `bound` of them.
fn assert_within(
    model: &History,
    heights: &[f64],
    valid: &BitSlice<u64, Lsb0>,
    triangles: &[[u32; 3]],
    bound: f64,
) {
    let mesh = grid_mesh(model.width, model.height, triangles);
    let error = mesh_error(&mesh, heights, heights, valid);
    let grid: Vec<[u32; 3]> = (0..model.corners.len())
        .filter(|&t| model.birth[t] == 0)
        .map(|t| model.corners[t])
        .collect();
    let (_, covered_by_grid) = rasterise(&grid_mesh(model.width, model.height, &grid), heights);
    let (_, covered) = rasterise(&mesh, heights);
    assert_eq!(covered, covered_by_grid, "the same samples covered");
    assert!(
        error.max_error <= bound + 1e-9,
        "max error {} over the bound {bound}",
        error.max_error
    );
}

/// The errors of a few steps spread over the model.
fn sample_errors(model: &History) -> Vec<f64> {
    [0.2, 0.5, 0.8, 0.95, 1.0]
        .iter()
        .map(|f| model.error_of_step((model.steps() as f64 * f) as usize))
        .collect()
}

#[test]
fn meshes_at_any_error_are_valid_and_within_twice_the_error() {
    for seed in 1..=4 {
        let (w, h) = (36 + seed as usize, 30);
        let (heights, valid) = random_dem(w, h, seed);
        let model = build_model(w, h, &heights, &valid, &VarresOptions::default()).unwrap();
        assert!(
            model.steps() > w * h / 2,
            "seed {seed}: {} steps",
            model.steps()
        );
        let mut triangles = Vec::new();
        for epsilon in sample_errors(&model) {
            triangles_at_error(&model, epsilon, &mut triangles);
            assert_valid(&model, &valid, &triangles);
            assert_within(&model, &heights, &valid, &triangles, 2.0 * epsilon);
        }
    }
}

#[test]
fn view_dependent_meshes_are_valid_and_finer_near_the_viewer() {
    let (w, h) = (48, 40);
    let (heights, valid) = random_dem(w, h, 9);
    let model = build_model(w, h, &heights, &valid, &VarresOptions::default()).unwrap();
    let near = model.error_of_step(model.steps() / 3);
    let far = model.error_of_step(model.steps());
    // Fine at the top-left corner, coarse from 40 samples away.
    let epsilon_at =
        |x: f64, y: f64| near + (far - near) * ((x * x + y * y).sqrt() / 40.0).min(1.0);
    let varying = triangles_varying(&model, epsilon_at);
    assert_valid(&model, &valid, &varying);
    assert_within(&model, &heights, &valid, &varying, 2.0 * far);
    let (mut fine, mut coarse) = (Vec::new(), Vec::new());
    triangles_at_error(&model, near, &mut fine);
    triangles_at_error(&model, far, &mut coarse);
    assert!(coarse.len() < varying.len() && varying.len() < fine.len());
    let in_corner = |ts: &[[u32; 3]]| {
        ts.iter()
            .filter(|t| {
                t.iter()
                    .all(|&v| (v as usize % w) < 12 && (v as usize / w) < 12)
            })
            .count()
    };
    assert!(
        in_corner(&varying) > in_corner(&coarse),
        "finer near the viewer"
    );
    // A uniform error function gives the uniform mesh.
    let mut uniform = triangles_varying(&model, |_, _| near);
    let mut at_near = fine.clone();
    uniform.sort();
    at_near.sort();
    assert_eq!(uniform, at_near);
}

#[test]
fn a_max_error_budget_is_checked_at_every_sample() {
    let (w, h) = (40, 32);
    let (heights, valid) = random_dem(w, h, 21);
    let model = build_model(w, h, &heights, &valid, &VarresOptions::default()).unwrap();
    for limit in [2.0, 8.0, 25.0] {
        let mesh = mesh_meeting(&model, &heights, &valid, VarresTarget::MaxError(limit));
        assert!(mesh_error(&mesh, &heights, &heights, &valid).max_error <= limit);
        let mut at_half = Vec::new();
        triangles_at_error(&model, limit / 2.0, &mut at_half);
        assert!(
            mesh.triangles.len() <= at_half.len(),
            "no finer than the bound's mesh"
        );
    }
    let budget = mesh_meeting(&model, &heights, &valid, VarresTarget::Triangles(300));
    let least = *model.step_triangles.last().unwrap() as usize;
    assert!(
        budget.triangles.len() <= 300.max(least),
        "{} {least}",
        budget.triangles.len()
    );
    assert!(
        budget.triangles.len() >= 290.min(least),
        "{} {least}",
        budget.triangles.len()
    );
}

#[test]
fn a_window_of_alps_srtm_voids_is_meshed_validly() {
    let Some(dir) = support::shared_dem("a_window_of_alps_srtm_voids_is_meshed_validly") else {
        return;
    };
    let raster = read_dem(
        &dir.join("alps_srtm_voids/alps_srtm_voids.tif"),
        &ReadOptions::default(),
    )
    .unwrap();
    let raster = window(&raster, 200, 200, 160, 160).unwrap();
    let surface = Surface::of(&raster);
    assert!(surface.valid.count_zeros() > 100, "the window holds voids");
    let model = build_model(
        160,
        160,
        &surface.heights,
        &surface.valid,
        &VarresOptions::default(),
    )
    .unwrap();
    let mut triangles = Vec::new();
    for epsilon in sample_errors(&model) {
        triangles_at_error(&model, epsilon, &mut triangles);
        assert_valid(&model, &surface.valid, &triangles);
        assert_within(
            &model,
            &surface.heights,
            &surface.valid,
            &triangles,
            2.0 * epsilon,
        );
    }
}

#[test]
fn mesh_method_varres_meets_a_budget_and_a_max_error() {
    let dir = support::scratch("cli-varres-tests");
    let input = support::sample("jacksboro_fault.tif");
    let obj = dir.path().join("m.obj");
    let path = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let run = |budget: &[&str]| {
        let mut args = vec!["mesh".to_string(), path(&input), "-o".into(), path(&obj)];
        args.extend(["--method", "varres", "--json"].map(String::from));
        args.extend(budget.iter().map(|s| s.to_string()));
        support::json(&args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let budget = run(&["--triangles", "3000"]);
    assert_eq!(budget["method"], "varres");
    let triangles = budget["triangles"].as_u64().unwrap();
    assert!((2990..=3000).contains(&triangles), "{triangles}");
    let faces = std::fs::read_to_string(&obj).unwrap();
    assert_eq!(
        faces.lines().filter(|l| l.starts_with("f ")).count() as u64,
        triangles
    );
    let tolerance = run(&["--mesh-error", "20"]);
    assert!(tolerance["error"]["max_error"].as_f64().unwrap() <= 20.0);
    assert_eq!(tolerance["error"]["uncovered_samples"], 0);
    assert!(tolerance["triangles"].as_u64().unwrap() < 275_772 / 2);
}

#[test]
fn the_metric_table_has_both_metrics_at_the_papers_ratios() {
    let input = support::sample("jacksboro_fault.tif");
    let report = support::json(&[
        "compare-meshers",
        input.to_str().unwrap(),
        "--varres-metrics",
        "--window",
        "100,100,120,120",
        "--json",
    ]);
    let rows = report["varres_metrics"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for (k, row) in rows.iter().enumerate() {
        let metric = if k < 3 {
            "average_plane"
        } else {
            "vertex_plane"
        };
        assert_eq!(row["metric"], metric);
        let ratio = row["ratio_percent"].as_f64().unwrap();
        assert!((ratio - [62.0, 70.0, 81.0][k % 3]).abs() < 0.5, "{ratio}");
        assert!(row["mean_error"].as_f64().unwrap() > 0.0);
    }
    let mean = |k: usize| rows[k]["mean_error"].as_f64().unwrap();
    assert!(
        mean(0) < mean(1) && mean(1) < mean(2),
        "coarser meshes are further off"
    );
}
