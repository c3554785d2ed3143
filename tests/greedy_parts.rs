//! The greedy mesher's parallel parts end to end: a mesh towards a tolerance is the same
//! on one thread and on several (the bundled jacksboro sample, 403 × 344, is cut in 3 × 3
//! parts), and on the shared DEM `fuji_terrainrgb` (cut in 4 × 4) it keeps every sample
//! within E with no more triangles than Delatin (skipped with a notice when
//! `../shared/dem` is absent).

mod support;

use std::io::Write;

use support::{json, s, sample, shared_dem};
use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh::lod::Surface;
use wavemesh::mesh::greedy::parts::mesh_in_parts;
use wavemesh::mesh::greedy::scan::Grid;
use wavemesh::mesh::greedy::{greedy_mesh, GreedyMesher, GreedyTarget};
use wavemesh::mesh::rasterise::{mesh_error, rasterise};

/// The OBJ `mesh --mesh-error error` writes for `dem` with `threads` rayon threads.
fn mesh_on(dem: &std::path::Path, error: &str, threads: &str) -> Vec<u8> {
    let dir = support::scratch("greedy-parts-tests");
    let out = dir.path().join("m.obj");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_wavemesh"))
        .args(["mesh", s(dem), "-o", s(&out), "--mesh-error", error])
        .env("RAYON_NUM_THREADS", threads)
        .status()
        .expect("the binary runs");
    assert!(status.success());
    std::fs::read(&out).unwrap()
}

#[test]
fn a_mesh_in_parts_is_the_same_on_one_thread_and_two() {
    let dem = sample("jacksboro_fault.tif");
    for error in ["5", "1"] {
        let one = mesh_on(&dem, error, "1");
        assert!(one.len() > 100_000, "E = {error}: {} bytes", one.len());
        assert!(one == mesh_on(&dem, error, "2"), "E = {error}");
    }
}

/// pydelatin's triangles on fuji (full, 512 × 512) at E = 20, 5 and 1
/// (`../shared/peers/results/dev_mesh.csv`).
const PYDELATIN_FUJI_FULL: [(f64, u64); 3] = [(20.0, 20352), (5.0, 123173), (1.0, 376531)];

#[test]
fn shared_fuji_in_parts_within_e_with_fewer_triangles_than_delatin() {
    let Some(dir) = shared_dem("shared_fuji_in_parts_within_e_with_fewer_triangles_than_delatin")
    else {
        return;
    };
    let dem = dir.join("fuji_terrainrgb/fuji_terrainrgb.tif");
    let report = json(&[
        "compare-meshers",
        s(&dem),
        "--methods",
        "greedy",
        "--mesh-errors",
        "20,5,1",
        "--json",
    ]);
    let rows = report["rows"].as_array().unwrap();
    for (e, delatin) in PYDELATIN_FUJI_FULL {
        let row = rows.iter().find(|r| r["budget"]["max_error"] == e).unwrap();
        let triangles = row["triangles"].as_u64().unwrap();
        assert!(row["max_error"].as_f64().unwrap() <= e, "E = {e}: {row}");
        assert_eq!(row["uncovered"], 0, "E = {e}");
        assert!(
            triangles <= delatin,
            "E = {e}: {triangles} against {delatin}"
        );
    }
}

/// One voided grid meshed towards `e` in parts: the parts ran (no fallback to one
/// piece), `greedy_mesh` gives that mesh, the same on one thread and two; every triangle
/// counter-clockwise, no vertex and no covered sample at nodata, every valid sample
/// within `e`, and every valid sample left uncovered next to nodata. Returns the valid
/// samples left uncovered by the parts and by one piece.
fn check_voided_parts(label: &str, surface: &Surface, e: f64) -> (u64, u64) {
    let (w, h) = (surface.width, surface.height);
    let words = surface.valid.as_raw_slice();
    let grid = Grid::new(w, h, &surface.heights, words);
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| mesh_in_parts(&grid, e, 2))
    };
    let mesh = on(1).unwrap_or_else(|| panic!("{label} E = {e}: not meshed in parts"));
    assert!(on(2).as_ref() == Some(&mesh), "{label} E = {e}: threads");
    let target = GreedyTarget::MaxError(e);
    let public = greedy_mesh(w, h, &surface.heights, &surface.valid, target, Some(2)).unwrap();
    assert!(
        public == mesh,
        "{label} E = {e}: greedy_mesh is not the parts' mesh"
    );
    for t in &mesh.triangles {
        let p = t.map(|v| {
            let (x, y) = mesh.vertex_position(v);
            (x as i64, y as i64)
        });
        let twice = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0);
        assert!(twice > 0, "{label} E = {e}: triangle {p:?} flipped");
    }
    assert!(mesh.vertices.iter().all(|&s| surface.valid[s as usize]));
    let (_, covered) = rasterise(&mesh, &surface.heights);
    assert!(
        covered.iter_ones().all(|s| surface.valid[s]),
        "{label}: nodata meshed"
    );
    let error = mesh_error(&mesh, &surface.heights, &surface.heights, &surface.valid);
    assert!(error.max_error <= e, "{label} E = {e}: {}", error.max_error);
    let near_nodata = |s: usize| {
        let (x, y) = (s % w, s / w);
        (y.saturating_sub(1)..=(y + 1).min(h - 1))
            .flat_map(|y| (x.saturating_sub(1)..=(x + 1).min(w - 1)).map(move |x| y * w + x))
            .any(|n| !surface.valid[n])
    };
    let uncovered = surface.valid.clone() & !covered;
    assert!(
        uncovered.iter_ones().all(near_nodata),
        "{label} E = {e}: a valid sample away from nodata is uncovered"
    );
    let mut one_piece = GreedyMesher::new(grid).unwrap().with_resolving_flips();
    one_piece.run(target);
    let one_piece = one_piece.optimise_flips(Some(e), 2).0;
    let one_piece_error = mesh_error(
        &one_piece,
        &surface.heights,
        &surface.heights,
        &surface.valid,
    );
    (error.uncovered_samples, one_piece_error.uncovered_samples)
}

/// The shared DEMs with nodata (alps_srtm_voids' voids, srtm3_utm32_f32's NaN collar)
/// and two masked ones (srtm3_utm32_f32's sea at 0 m and fuji below 400 m cut out)
/// meshed in parts: see [`check_voided_parts`]. Prints the uncovered valid samples in
/// parts and in one piece.
#[test]
fn shared_voided_dems_in_parts_needs_shared_dems() {
    let Some(dir) = shared_dem("shared_voided_dems_in_parts_needs_shared_dems") else {
        return;
    };
    let read = |name: &str| {
        let path = dir.join(name).join(format!("{name}.tif"));
        Surface::of(&read_dem(&path, &ReadOptions::default()).unwrap())
    };
    let cut_below = |mut surface: Surface, level: f64| {
        for s in 0..surface.heights.len() {
            let keep = surface.valid[s] && surface.heights[s] > level;
            surface.valid.set(s, keep);
        }
        surface
    };
    let utm = read("srtm3_utm32_f32");
    let cases = [
        ("alps_srtm_voids", read("alps_srtm_voids"), [20.0, 2.0]),
        ("srtm3_utm32_f32", utm.clone(), [20.0, 1.0]),
        ("srtm3_utm32_f32 sea cut", cut_below(utm, 0.5), [5.0, 1.0]),
        (
            "fuji_terrainrgb below 400 m cut",
            cut_below(read("fuji_terrainrgb"), 400.0),
            [20.0, 2.0],
        ),
    ];
    for (label, surface, errors) in &cases {
        for &e in errors {
            let (parts, one_piece) = check_voided_parts(label, surface, e);
            let _ = writeln!(
                std::io::stderr(),
                "{label} E = {e}: uncovered valid samples {parts} in parts, {one_piece} in one piece"
            );
        }
    }
}
