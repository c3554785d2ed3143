//! End-to-end tests of the QEM mesher (`mesh --method qem`, its `compare-meshers` rows
//! and `compare-meshers --qem-memory`) on the bundled sample, and on the shared DEM
//! with voids `alps_srtm_voids` (skipped with a notice when `../shared/dem` is absent).

mod support;

use serde_json::Value;
use support::{json, s, sample, shared_dem, wavemesh};

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn mesh_method_qem_meets_a_budget_and_a_max_error() {
    let dir = support::scratch("cli-qem-tests");
    let input = sample("jacksboro_fault.tif");
    let obj = dir.path().join("m.obj");
    let budget = json(&[
        "mesh",
        s(&input),
        "-o",
        s(&obj),
        "--method",
        "qem",
        "--triangles",
        "3000",
        "--json",
    ]);
    assert_eq!(budget["method"], "qem");
    let triangles = budget["triangles"].as_u64().unwrap();
    assert!((2990..=3000).contains(&triangles), "{triangles}");
    let faces = std::fs::read_to_string(&obj).unwrap();
    assert_eq!(
        faces.lines().filter(|l| l.starts_with("f ")).count() as u64,
        triangles
    );
    let tolerance = json(&[
        "mesh",
        s(&input),
        "-o",
        s(&obj),
        "--method",
        "qem",
        "--mesh-error",
        "5",
        "--json",
    ]);
    assert!(num(&tolerance["error"]["max_error"]) <= 5.0);
    assert_eq!(tolerance["error"]["uncovered_samples"], 0);
    assert!(tolerance["triangles"].as_u64().unwrap() < 275_772 / 2);
}

#[test]
fn qem_memory_table_has_the_papers_three_rows() {
    let report = json(&[
        "compare-meshers",
        s(&sample("jacksboro_fault.tif")),
        "--qem-memory",
        "--json",
    ]);
    let rows = report["qem_memory"].as_array().unwrap();
    let samples: usize = 403 * 344;
    let all = 2 * 402 * 343;
    for (row, percent) in rows.iter().zip([100, 10, 1]) {
        let triangles = row["triangles"].as_u64().unwrap() as usize;
        let wanted = all * percent / 100;
        assert!(
            triangles <= wanted && triangles + 2 >= wanted,
            "{triangles} {wanted}"
        );
        assert_eq!(
            row["raster_and_flags_bytes"].as_u64().unwrap() as usize,
            4 * samples + samples.div_ceil(2)
        );
        let mesh = 24 * triangles + 17 * row["vertices"].as_u64().unwrap() as usize;
        assert_eq!(row["mesh_bytes"].as_u64().unwrap() as usize, mesh);
        assert!(row["peak_heap_bytes"].as_u64().unwrap() > 0);
    }
    assert_eq!(rows.len(), 3);
    let conflict = wavemesh(&[
        "compare-meshers",
        s(&sample("jacksboro_fault.tif")),
        "--qem-memory",
        "--triangles",
        "100",
    ]);
    assert_eq!(conflict.status.code(), Some(2));
}

#[test]
fn shared_voids_are_left_out_and_the_max_error_holds() {
    let test = "shared_voids_are_left_out_and_the_max_error_holds";
    let Some(dem) = shared_dem(test) else {
        return;
    };
    let input = dem.join("alps_srtm_voids/alps_srtm_voids.tif");
    let rows = |extra: &[&str]| {
        let mut args = vec!["compare-meshers", s(&input), "--methods", "qem", "--json"];
        args.extend_from_slice(extra);
        json(&args)["rows"][0].clone()
    };
    // Every valid grid triangle kept: the samples no valid triangle holds stay uncovered.
    let exact = rows(&["--triangles", "100000000"]);
    assert_eq!(num(&exact["max_error"]), 0.0);
    let within = rows(&["--mesh-errors", "20"]);
    assert!(num(&within["max_error"]) <= 20.0, "{within}");
    assert_eq!(within["uncovered"], exact["uncovered"]);
    assert!(within["triangles"].as_u64().unwrap() < exact["triangles"].as_u64().unwrap() / 4);
}

#[test]
fn shared_report_meshes_puts_qem_beside_the_peers() {
    let test = "shared_report_meshes_puts_qem_beside_the_peers";
    let Some(dem) = shared_dem(test) else {
        return;
    };
    let report = json(&[
        "report",
        s(&dem),
        "--meshes",
        "--only",
        "grandcanyon_8bit",
        "--json",
    ]);
    let rows = report["meshes"].as_array().unwrap();
    assert!(rows.len() >= 10, "{}", rows.len());
    for r in rows {
        let (qem, peer) = (
            r["qem_triangles"].as_u64().unwrap(),
            r["peer_triangles"].as_u64().unwrap(),
        );
        assert!(qem <= peer && qem + 2 >= peer.min(2 * 255 * 255), "{r}");
        assert!(num(&r["qem_rmse"]) <= num(&r["qem_max_error"]));
    }
}
