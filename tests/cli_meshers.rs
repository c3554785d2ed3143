//! End-to-end tests of `compare-meshers` and `mesh --method greedy|delaunay` on the
//! bundled samples (403 × 344), and one check against the peers' pydelatin figures on
//! the shared DEM `fuji_terrainrgb` (skipped with a notice when `../shared/dem` is absent).

mod support;

use support::{json, s, sample, shared_dem, wavemesh};

use serde_json::Value;

/// Runs a command that must fail with `code` and one line on stderr.
fn fails(args: &[&str], code: i32) {
    let output = wavemesh(args);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(output.status.code(), Some(code), "{args:?}: {stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
}

fn scratch() -> tempfile::TempDir {
    support::scratch("cli-meshers-tests")
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// The row of `method` at triangle budget `n`.
fn row<'a>(rows: &'a [Value], method: &str, n: u64) -> &'a Value {
    rows.iter()
        .find(|r| r["method"] == method && r["budget"]["triangles"] == n)
        .unwrap_or_else(|| panic!("no {method} row at {n}"))
}

#[test]
fn compare_meshers_measures_every_mesher_and_draws_the_plot() {
    let dir = scratch();
    let plot = dir.path().join("errors.svg");
    let input = sample("jacksboro_fault.tif");
    let report = json(&[
        "compare-meshers",
        s(&input),
        "--window",
        "100,100,129,129",
        "--triangles",
        "400,2000",
        "--json",
        "--plot",
        s(&plot),
    ]);
    let rows = report["rows"].as_array().unwrap();
    for method in ["zerotree", "greedy", "delaunay", "delatin", "martini"] {
        for n in [400, 2000] {
            let r = row(rows, method, n);
            assert!(r["triangles"].as_u64().unwrap() <= n, "{method} {n}");
            assert!(r["triangles"].as_u64().unwrap() >= n / 2, "{method} {n}");
            assert_eq!(r["uncovered"], 0, "{method}");
            assert!(num(&r["rmse"]) > 0.0 && num(&r["rmse"]) <= num(&r["max_error"]));
            assert!(num(&r["build_seconds"]) > 0.0);
        }
    }
    for n in [400, 2000] {
        let greedy = num(&row(rows, "greedy", n)["rmse"]);
        assert!(greedy < num(&row(rows, "delatin", n)["rmse"]), "at {n}");
        assert!(greedy < num(&row(rows, "martini", n)["rmse"]), "at {n}");
    }
    let svg = std::fs::read_to_string(&plot).unwrap();
    assert!(svg.starts_with("<svg") || svg.contains("<svg"));
    for method in ["greedy", "delatin", "martini", "zerotree"] {
        assert!(svg.contains(method), "{method} missing from the legend");
    }
}

#[test]
fn greedy_meets_a_tolerance_with_fewer_triangles_than_delaunay() {
    let dir = scratch();
    let input = sample("jacksboro_fault.tif");
    let mesh_at = |method: &str| {
        let out = dir.path().join(format!("{method}.obj"));
        let report = json(&[
            "mesh",
            s(&input),
            "-o",
            s(&out),
            "--method",
            method,
            "--mesh-error",
            "3",
            "--json",
        ]);
        let (models, _) = tobj::load_obj(&out, &tobj::LoadOptions::default()).unwrap();
        let faces: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
        assert_eq!(faces as u64, report["triangles"].as_u64().unwrap());
        assert!(num(&report["error"]["max_error"]) <= 3.0, "{method}");
        assert_eq!(report["error"]["uncovered_samples"], 0);
        report["triangles"].as_u64().unwrap()
    };
    let (greedy, delaunay) = (mesh_at("greedy"), mesh_at("delaunay"));
    assert!(greedy < delaunay, "greedy {greedy}, delaunay {delaunay}");
}

#[test]
fn mesh_defaults_to_greedy_unless_a_stream_is_asked_for() {
    let dir = scratch();
    let input = sample("jacksboro_fault.tif");
    let out = dir.path().join("default.ply");
    let method_of = |extra: &[&str]| {
        let mut args = vec!["mesh", s(&input), "-o", s(&out), "--json"];
        args.extend_from_slice(extra);
        let report = json(&args);
        // The zerotree report nests its mesh; the direct one names its method.
        match report["method"].as_str() {
            Some(method) => {
                // Where the vertices are, as the zerotree's report says it.
                assert_eq!(report["xy_units"], "local_enu", "{report}");
                assert_eq!(report["frame"]["crs"], "EPSG:4326", "{report}");
                assert_eq!(report["format"], "ply", "{report}");
                method.to_string()
            }
            None => {
                assert!(report["mesh"].is_object(), "{report}");
                "zerotree".to_string()
            }
        }
    };
    assert_eq!(method_of(&[]), "greedy");
    assert_eq!(method_of(&["--mesh-error", "5"]), "greedy");
    assert_eq!(method_of(&["--threshold", "64"]), "zerotree");
    assert_eq!(method_of(&["--bpp", "1"]), "zerotree");
    assert_eq!(method_of(&["--method", "zerotree"]), "zerotree");
}

#[test]
fn greedy_leaves_nodata_out() {
    let dir = scratch();
    let out = dir.path().join("voids.obj");
    let input = sample("jacksboro_voids.tif");
    let report = json(&[
        "mesh",
        s(&input),
        "-o",
        s(&out),
        "--method",
        "greedy",
        "--triangles",
        "20000",
        "--xy",
        "pixel",
        "--json",
    ]);
    assert!(report["triangles"].as_u64().unwrap() <= 20000);
    let (models, _) = tobj::load_obj(&out, &tobj::LoadOptions::default()).unwrap();
    // The sample's valid heights are 236..1076 m: a nodata vertex would be far outside.
    for z in models[0].mesh.positions.chunks_exact(3).map(|p| p[2]) {
        assert!((200.0..1100.0).contains(&z), "vertex at height {z}");
    }
}

#[test]
fn bad_arguments_and_inputs_are_one_line_errors() {
    let input = sample("jacksboro_fault.tif");
    let input = s(&input);
    fails(&["compare-meshers", input, "--triangles", "0"], 2);
    fails(
        &[
            "compare-meshers",
            input,
            "--triangles",
            "10",
            "--window",
            "400,0,10,10",
        ],
        2,
    );
    fails(
        &[
            "compare-meshers",
            input,
            "--triangles",
            "10",
            "--window",
            "1,2",
        ],
        2,
    );
    fails(&["compare-meshers", input, "--mesh-errors=-1"], 2);
    fails(
        &[
            "compare-meshers",
            "/nonexistent/dem.tif",
            "--triangles",
            "10",
        ],
        3,
    );
    let dir = scratch();
    let out = dir.path().join("m.obj");
    fails(
        &[
            "mesh",
            input,
            "-o",
            s(&out),
            "--method",
            "greedy",
            "--mesh-error",
            "nan",
        ],
        2,
    );
    fails(
        &[
            "mesh",
            input,
            "-o",
            s(&out),
            "--method",
            "greedy",
            "--threshold",
            "4",
        ],
        2,
    );
    // --bpp codes a stream: only the zerotree mesher meshes one.
    fails(
        &[
            "mesh",
            input,
            "-o",
            s(&out),
            "--method",
            "greedy",
            "--bpp",
            "1",
        ],
        2,
    );
    // varres takes ~511 bytes a sample of this 138632-sample DEM at its finest.
    fails(
        &[
            "mesh",
            input,
            "-o",
            s(&out),
            "--method",
            "varres",
            "--max-memory",
            "40000000",
        ],
        3,
    );
    assert!(!out.exists());
    let report = json(&[
        "compare-meshers",
        input,
        "--methods",
        "greedy,varres",
        "--triangles",
        "1000",
        "--max-memory",
        "40000000",
        "--json",
    ]);
    let rows = report["rows"].as_array().unwrap();
    assert!(rows.iter().all(|r| r["method"] == "greedy"), "{rows:?}");
    assert_eq!(report["skipped"][0]["method"], "varres");
    assert!(report["skipped"][0]["reason"]
        .as_str()
        .unwrap()
        .contains("memory limit"));
}

/// Delatin (pydelatin, `../shared/peers/results/dev_mesh.csv`) on fuji's crop257
/// r0=127 c0=127: (triangles, RMSE) at E = 20 and 5, and its triangles at E = 5.
const PYDELATIN_FUJI_CROP: [(u64, f64); 2] = [(2484, 6.64891), (23832, 1.91331)];

#[test]
fn shared_fuji_greedy_beats_pydelatin_figures() {
    let Some(dir) = shared_dem("shared_fuji_greedy_beats_pydelatin_figures") else {
        return;
    };
    let dem = dir.join("fuji_terrainrgb/fuji_terrainrgb.tif");
    let report = json(&[
        "compare-meshers",
        s(&dem),
        "--window",
        "127,127,257,257",
        "--methods",
        "greedy",
        "--triangles",
        "2484,23832",
        "--mesh-errors",
        "5",
        "--json",
    ]);
    let rows = report["rows"].as_array().unwrap();
    for (n, rmse) in PYDELATIN_FUJI_CROP {
        let ours = num(&row(rows, "greedy", n)["rmse"]);
        assert!(
            ours <= rmse,
            "at {n} triangles: RMSE {ours} against Delatin's {rmse}"
        );
    }
    let within = rows
        .iter()
        .find(|r| r["budget"]["max_error"] == 5.0)
        .unwrap();
    assert!(num(&within["max_error"]) <= 5.0);
    assert!(within["triangles"].as_u64().unwrap() <= 23832);
}
