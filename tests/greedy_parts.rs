//! The greedy mesher's parallel parts end to end: a mesh towards a tolerance is the same
//! on one thread and on several (the bundled jacksboro sample, 403 × 344, is cut in 3 × 3
//! parts), and on the shared DEM `fuji_terrainrgb` (cut in 4 × 4) it keeps every sample
//! within E with no more triangles than Delatin (skipped with a notice when
//! `../shared/dem` is absent).

mod support;

use support::{json, s, sample, shared_dem};

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
