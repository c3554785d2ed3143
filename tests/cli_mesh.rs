//! End-to-end tests of the mesh commands of the `wavemesh` binary: `mesh`, `decode --mesh`
//! and `table`, on the bundled samples (403 × 344, so the whole file runs in seconds).

mod support;

use support::{json, s, sample, scratch, stdout, wavemesh};

use std::path::Path;

use serde_json::Value;

/// Samples of the bundled rasters (403 × 344).
const SAMPLES: u64 = 403 * 344;
/// Valid samples of `jacksboro_voids.tif` (4173 of them are nodata).
const VOIDS_VALID: u64 = SAMPLES - 4173;

/// Runs a command that must fail with `code` and one line on stderr; returns that line.
fn fails(args: &[&str], code: i32) -> String {
    let output = wavemesh(args);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert_eq!(
        output.status.code(),
        Some(code),
        "wavemesh {args:?}: {stderr}"
    );
    assert_eq!(stderr.trim().lines().count(), 1, "{args:?}: {stderr}");
    stderr
}

fn f64_of(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn u64_of(v: &Value) -> u64 {
    v.as_u64()
        .unwrap_or_else(|| panic!("not an unsigned integer: {v}"))
}

fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Vertex and triangle counts of a mesh file, read from the file itself.
fn counts_in_file(path: &Path) -> (u64, u64) {
    let bytes = std::fs::read(path).unwrap();
    match path.extension().and_then(|e| e.to_str()) {
        Some("ply") => {
            let end = bytes
                .windows(11)
                .position(|w| w == b"end_header\n")
                .expect("a PLY header");
            let header = std::str::from_utf8(&bytes[..end]).unwrap();
            assert!(header.starts_with("ply\n"), "{header}");
            let element = |name: &str| {
                header
                    .lines()
                    .find_map(|l| l.strip_prefix(&format!("element {name} ")))
                    .unwrap_or_else(|| panic!("no {name} element: {header}"))
                    .parse()
                    .unwrap()
            };
            (element("vertex"), element("face"))
        }
        Some("obj") => {
            let text = std::str::from_utf8(&bytes).unwrap();
            let count = |p: &str| text.lines().filter(|l| l.starts_with(p)).count() as u64;
            (count("v "), count("f "))
        }
        Some("glb") => {
            assert_eq!(&bytes[..4], b"glTF");
            let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
            assert_eq!(u32_at(4), 2, "glTF version");
            assert_eq!(u32_at(8) as usize, bytes.len(), "GLB length field");
            // Chunk 0 is the JSON: the POSITION accessor's count is the vertices, the
            // indices accessor's count is 3 × the triangles.
            let json_len = u32_at(12) as usize;
            assert_eq!(&bytes[16..20], b"JSON");
            let gltf: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
            let primitive = &gltf["meshes"][0]["primitives"][0];
            let accessor = |i: &Value| &gltf["accessors"][u64_of(i) as usize];
            let vertices = u64_of(&accessor(&primitive["attributes"]["POSITION"])["count"]);
            let indices = u64_of(&accessor(&primitive["indices"])["count"]);
            assert_eq!(indices % 3, 0);
            (vertices, indices / 3)
        }
        other => panic!("unexpected mesh extension {other:?}"),
    }
}

/// Checks the invariants every mesh report has and returns the `mesh` object.
fn check_mesh_report(report: &Value, path: &Path) -> Value {
    let mesh = report["mesh"].clone();
    let triangles = u64_of(&mesh["triangles"]);
    let vertices = u64_of(&mesh["vertices"]);
    assert!(triangles > 0 && vertices >= 3, "{mesh}");
    assert_eq!(
        u64_of(&mesh["file_bytes"]),
        std::fs::metadata(path).unwrap().len()
    );
    assert_eq!(
        counts_in_file(path),
        (vertices, triangles),
        "{}",
        path.display()
    );
    let full = 2 * 402 * 343;
    let remaining = f64_of(&mesh["remaining_percent"]);
    assert!((remaining - 100.0 * triangles as f64 / full as f64).abs() < 1e-9);
    for key in ["error_vs_decoded", "error_vs_original"] {
        let e = &mesh[key];
        if e.is_null() {
            continue;
        }
        for field in [
            "compared_samples",
            "uncovered_samples",
            "rmse",
            "psnr_db",
            "max_error",
        ] {
            assert!(
                !e[field].is_null() || field == "psnr_db",
                "{key}.{field}: {e}"
            );
        }
        assert!(f64_of(&e["rmse"]) <= f64_of(&e["max_error"]) + 1e-12, "{e}");
    }
    mesh
}

#[test]
fn mesh_error_bound_holds_in_every_format() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    for (ext, e) in [("glb", 4.0), ("obj", 12.0), ("ply", 30.0)] {
        let out = dir.path().join(format!("fault.{ext}"));
        let report = json(&[
            "mesh",
            "--method",
            "zerotree",
            s(&input),
            "-o",
            s(&out),
            "--mesh-error",
            &e.to_string(),
            "--json",
        ]);
        assert_eq!(report["command"], "mesh");
        assert_eq!(report["schema_version"], 1);
        let mesh = check_mesh_report(&report, &out);
        assert_eq!(mesh["format"], ext);
        assert_eq!(mesh["xy_units"], "local_enu");
        assert_eq!(f64_of(&mesh["tolerance"]), e);
        let decoded = &mesh["error_vs_decoded"];
        let original = &mesh["error_vs_original"];
        assert!(f64_of(&decoded["max_error"]) <= e, "{ext}: {decoded}");
        // The stream is lossless: the decoded heights are the original's.
        assert!(f64_of(&original["max_error"]) <= e, "{ext}: {original}");
        assert_eq!(decoded, original);
        assert_eq!(u64_of(&decoded["compared_samples"]), SAMPLES);
        assert_eq!(u64_of(&decoded["uncovered_samples"]), 0);
        assert!(u64_of(&mesh["triangles"]) < 2 * 402 * 343);
    }
}

#[test]
fn looser_tolerances_give_fewer_triangles() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    let mut last = u64::MAX;
    for e in ["0", "10", "40"] {
        let out = dir.path().join(format!("e{e}.ply"));
        let report = json(&[
            "mesh",
            "--method",
            "zerotree",
            s(&input),
            "-o",
            s(&out),
            "--mesh-error",
            e,
            "--json",
        ]);
        let mesh = check_mesh_report(&report, &out);
        let max = f64_of(&mesh["error_vs_original"]["max_error"]);
        assert!(max <= e.parse::<f64>().unwrap(), "--mesh-error {e}: {max}");
        let triangles = u64_of(&mesh["triangles"]);
        assert!(triangles < last, "--mesh-error {e}: {triangles} >= {last}");
        last = triangles;
    }
}

#[test]
fn triangle_budgets_hold_for_both_searches() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    for search in ["threshold", "error"] {
        let mut last = 0;
        for budget in [2000u64, 20000] {
            let out = dir.path().join(format!("{search}-{budget}.ply"));
            let report = json(&[
                "mesh",
                "--method",
                "zerotree",
                s(&input),
                "-o",
                s(&out),
                "--triangles",
                &budget.to_string(),
                "--search",
                search,
                "--json",
            ]);
            let mesh = check_mesh_report(&report, &out);
            let triangles = u64_of(&mesh["triangles"]);
            assert!(triangles <= budget, "{search} {budget}: {triangles}");
            assert!(triangles >= last, "{search} {budget}: {triangles} < {last}");
            last = triangles;
            match search {
                "threshold" => {
                    let plane = u64_of(&mesh["plane"]);
                    assert_eq!(f64_of(&mesh["threshold"]), 2f64.powi(plane as i32));
                    assert!(mesh["tolerance"].is_null(), "{mesh}");
                }
                _ => {
                    let tolerance = f64_of(&mesh["tolerance"]);
                    let max = f64_of(&mesh["error_vs_decoded"]["max_error"]);
                    assert!(max <= tolerance, "{budget}: {max} > {tolerance}");
                }
            }
        }
    }
}

#[test]
fn lossy_streams_mesh_against_the_decoded_heights() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    let out = dir.path().join("lossy.glb");
    let report = json(&[
        "mesh",
        s(&input),
        "-o",
        s(&out),
        "--bpp",
        "1",
        "--mesh-error",
        "10",
        "--json",
    ]);
    assert!(u64_of(&report["ezw_bytes"]) <= SAMPLES / 8, "{report}");
    assert!(f64_of(&report["bpp"]) <= 1.0);
    let mesh = check_mesh_report(&report, &out);
    let decoded = &mesh["error_vs_decoded"];
    let original = &mesh["error_vs_original"];
    assert!(f64_of(&decoded["max_error"]) <= 10.0, "{decoded}");
    // The tolerance is against the lossy heights: the original is farther away.
    assert!(
        f64_of(&original["rmse"]) > f64_of(&decoded["rmse"]),
        "{mesh}"
    );

    // Without a target: the zerotree partition at the decoder's threshold.
    let out = dir.path().join("lossy-plane.ply");
    let report = json(&["mesh", s(&input), "-o", s(&out), "--bpp", "1", "--json"]);
    let mesh = check_mesh_report(&report, &out);
    assert!(mesh["tolerance"].is_null(), "{mesh}");
    assert!(!mesh["plane"].is_null(), "{mesh}");
}

#[test]
fn pixel_units_and_z_scale_reach_the_file() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    let out = dir.path().join("pixel.obj");
    let report = json(&[
        "mesh",
        s(&input),
        "-o",
        s(&out),
        "--threshold",
        "256",
        "--xy",
        "pixel",
        "--z-scale",
        "2",
        "--json",
    ]);
    let mesh = check_mesh_report(&report, &out);
    assert_eq!(mesh["xy_units"], "pixel");
    assert_eq!(u64_of(&mesh["plane"]), 8);
    let text = std::fs::read_to_string(&out).unwrap();
    let mut corners = [false; 4];
    for line in text.lines().filter(|l| l.starts_with("v ")) {
        let v: Vec<f64> = line[2..]
            .split_whitespace()
            .map(|t| t.parse().unwrap())
            .collect();
        assert_eq!(v.len(), 3, "{line}");
        let (x, y, z) = (v[0], v[1], v[2]);
        // x = column, y = row, z = 2 × the sample (236..1076 m).
        assert!(x.fract() == 0.0 && (0.0..403.0).contains(&x), "{line}");
        assert!(y.fract() == 0.0 && (0.0..344.0).contains(&y), "{line}");
        assert!(z % 2.0 == 0.0 && (472.0..=2152.0).contains(&z), "{line}");
        for (k, corner) in [(0.0, 0.0), (402.0, 0.0), (0.0, 343.0), (402.0, 343.0)]
            .iter()
            .enumerate()
        {
            corners[k] |= (x, y) == *corner;
        }
    }
    assert_eq!(corners, [true; 4], "the mesh covers the grid's corners");

    // Georeferenced degrees on request, heights unscaled.
    let geo = dir.path().join("geo.obj");
    let report = json(&[
        "mesh",
        s(&input),
        "-o",
        s(&geo),
        "--threshold",
        "256",
        "--xy",
        "degrees",
        "--json",
    ]);
    assert_eq!(report["mesh"]["xy_units"], "georeferenced");
    let text = std::fs::read_to_string(&geo).unwrap();
    let first = text.lines().find(|l| l.starts_with("v ")).unwrap();
    let v: Vec<f64> = first[2..]
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    assert!(
        (-84.5..-84.0).contains(&v[0]) && (36.4..36.8).contains(&v[1]),
        "{first}"
    );
    assert!((236.0..=1076.0).contains(&v[2]), "{first}");
}

#[test]
fn decode_meshes_at_a_threshold() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    let ezw = dir.path().join("fault.ezw");
    // The 5/3, as `table` codes it (the zerotree mesher's stream).
    stdout(&["encode", s(&input), "-o", s(&ezw), "--wavelet", "53"]);
    let mut last = u64::MAX;
    for (threshold, plane) in [("64", 6), ("100", 6), ("256", 8)] {
        let tif = dir.path().join(format!("out-{threshold}.tif"));
        let ply = dir.path().join(format!("m-{threshold}.ply"));
        let report = json(&[
            "decode",
            s(&ezw),
            "-o",
            s(&tif),
            "--mesh",
            s(&ply),
            "--threshold",
            threshold,
            "--reference",
            s(&input),
            "--json",
        ]);
        assert_eq!(report["complete"], true);
        assert_eq!(report["distortion"]["identical"], true);
        assert!(tif.exists());
        let mesh = check_mesh_report(&report, &ply);
        assert_eq!(u64_of(&mesh["plane"]), plane, "--threshold {threshold}");
        assert_eq!(f64_of(&mesh["threshold"]), 2f64.powi(plane as i32));
        assert_eq!(mesh["error_vs_decoded"], mesh["error_vs_original"]);
        let triangles = u64_of(&mesh["triangles"]);
        assert!(triangles <= last, "--threshold {threshold}");
        last = triangles;
    }
    // The same rows as `table --thresholds`.
    let table = json(&["table", s(&input), "--thresholds", "64", "--format", "json"]);
    let m64 = json(&[
        "decode",
        s(&ezw),
        "-o",
        s(&dir.path().join("again.tif")),
        "--mesh",
        s(&dir.path().join("again.obj")),
        "--threshold",
        "64",
        "--json",
    ]);
    assert_eq!(table["rows"][0]["triangles"], m64["mesh"]["triangles"]);
    assert_eq!(table["rows"][0]["vertices"], m64["mesh"]["vertices"]);
}

#[test]
fn prefix_decodes_mesh_at_the_decoders_threshold() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_voids.tif");
    let ezw = dir.path().join("voids.ezw");
    stdout(&["encode", s(&input), "-o", s(&ezw)]);
    let (mut last_plane, mut last_triangles) = (u64::MAX, 0);
    for bytes in ["1500", "5000", "20000"] {
        let tif = dir.path().join(format!("prefix-{bytes}.tif"));
        let glb = dir.path().join(format!("prefix-{bytes}.glb"));
        let report = json(&[
            "decode",
            s(&ezw),
            "-o",
            s(&tif),
            "--bytes",
            bytes,
            "--mesh",
            s(&glb),
            "--reference",
            s(&input),
            "--json",
        ]);
        assert_eq!(report["complete"], false);
        let mesh = check_mesh_report(&report, &glb);
        // The pass the decoder was in when the bytes ran out.
        let top = u64_of(&report["passes_total"]) - 1;
        let plane = top - u64_of(&report["passes_decoded"]);
        assert_eq!(u64_of(&mesh["plane"]), plane, "--bytes {bytes}: {mesh}");
        assert!(plane <= last_plane);
        let triangles = u64_of(&mesh["triangles"]);
        assert!(triangles >= last_triangles, "--bytes {bytes}");
        (last_plane, last_triangles) = (plane, triangles);
        for key in ["error_vs_decoded", "error_vs_original"] {
            let e = &mesh[key];
            assert_eq!(
                u64_of(&e["compared_samples"]) + u64_of(&e["uncovered_samples"]),
                VOIDS_VALID,
                "{key}: {e}"
            );
        }
    }
}

#[test]
fn mesh_options_without_mesh_are_a_usage_error() {
    let dir = scratch("cli-mesh-tests");
    let ezw = dir.path().join("fault.ezw");
    stdout(&["encode", s(&sample("jacksboro_fault.tif")), "-o", s(&ezw)]);
    let out = dir.path().join("never.tif");
    for option in [
        &["--mesh-error", "3"][..],
        &["--threshold", "64"],
        &["--triangles", "100"],
        &["--search", "threshold"],
        &["--rule", "own"],
        &["--xy", "pixel"],
        &["--z-scale", "2"],
    ] {
        let mut args = vec!["decode", s(&ezw), "-o", s(&out)];
        args.extend_from_slice(option);
        let error = fails(&args, 2);
        assert!(error.contains("need --mesh"), "{option:?}: {error}");
        assert!(!out.exists(), "{option:?} wrote the DEM");
    }
    assert_eq!(entries(dir.path()), ["fault.ezw"]);
}

#[test]
fn unknown_mesh_extensions_are_refused_and_write_nothing() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    for name in ["fault.stl", "fault", "fault.glb.txt"] {
        let out = dir.path().join(name);
        let error = fails(&["mesh", s(&input), "-o", s(&out), "--mesh-error", "5"], 2);
        assert!(error.contains("unknown mesh format"), "{name}: {error}");
        assert!(!out.exists(), "{name}");
    }
    assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));

    // decode --mesh: neither the mesh nor the DEM.
    let ezw = dir.path().join("fault.ezw");
    stdout(&["encode", s(&input), "-o", s(&ezw)]);
    let mesh = dir.path().join("m.stl");
    let error = fails(
        &[
            "decode",
            s(&ezw),
            "-o",
            s(&dir.path().join("out.tif")),
            "--mesh",
            s(&mesh),
        ],
        2,
    );
    assert!(error.contains("unknown mesh format"), "{error}");
    assert!(!mesh.exists());
    assert!(!dir.path().join("out.tif").exists());
    assert!(!entries(dir.path())
        .iter()
        .any(|n| n.contains("wavemesh-tmp")));
}

#[test]
fn decode_with_an_unknown_mesh_extension_writes_no_dem() {
    let dir = scratch("cli-mesh-tests");
    let ezw = dir.path().join("fault.ezw");
    stdout(&["encode", s(&sample("jacksboro_fault.tif")), "-o", s(&ezw)]);
    let out = dir.path().join("out.tif");
    fails(
        &[
            "decode",
            s(&ezw),
            "-o",
            s(&out),
            "--mesh",
            s(&dir.path().join("m.stl")),
        ],
        2,
    );
    assert!(!out.exists(), "a usage error left {}", out.display());
}

/// The rows of the first Markdown table after `title`.
fn markdown_rows<'a>(text: &'a str, title: &str) -> Vec<Vec<&'a str>> {
    let start = text.find(title).unwrap_or_else(|| panic!("no {title}"));
    text[start..]
        .lines()
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .skip(2) // the header and the alignment row
        .map(|l| l.trim_matches('|').split('|').map(str::trim).collect())
        .collect()
}

#[test]
fn table_prints_both_tables_with_a_row_per_pass() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_fault.tif");
    let ezw = dir.path().join("fault.ezw");
    let info = {
        // The 5/3, as `table` codes it (the zerotree mesher's stream).
        stdout(&["encode", s(&input), "-o", s(&ezw), "--wavelet", "53"]);
        json(&["info", s(&ezw), "--json"])
    };
    let passes = info["passes"].as_array().unwrap().len();
    assert!(passes > 4);
    let text = stdout(&["table", s(&input)]);
    let table1 = markdown_rows(&text, "Table 1");
    let table2 = markdown_rows(&text, "Table 2");
    assert_eq!(table1.len(), passes, "{text}");
    assert_eq!(table2.len(), passes, "{text}");
    for (k, (a, b)) in table1.iter().zip(&table2).enumerate() {
        let plane = format!("2^{}", passes - 1 - k);
        assert_eq!(a[0], plane);
        assert_eq!(b[0], plane);
        assert_eq!(a.len(), 10, "{a:?}");
        assert_eq!(b.len(), 6, "{b:?}");
        let triangles: u64 = a[1].parse().unwrap();
        assert!(triangles > 0, "{a:?}");
    }
    // Table 2's stream bytes: where each pass ends in the file, as `info` has them.
    let ladder = info["passes"].as_array().unwrap();
    for (row, pass) in table2.iter().zip(ladder) {
        let bytes: u64 = row[4].parse().unwrap();
        assert_eq!(bytes, u64_of(&pass["end_byte"]), "{row:?}");
        let bpp: f64 = row[1].parse().unwrap();
        assert!(
            (bpp - bytes as f64 * 8.0 / SAMPLES as f64).abs() < 1e-4,
            "{row:?}"
        );
    }
}

/// `table --format csv` as (header, rows of named fields).
fn csv_table(args: &[&str]) -> Vec<std::collections::HashMap<String, f64>> {
    let text = stdout(args);
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .unwrap()
        .iter()
        .map(str::to_string)
        .collect();
    assert_eq!(header.len(), 18, "{header:?}");
    for column in [
        "plane",
        "threshold",
        "triangles",
        "vertices",
        "bpp",
        "ezw_bytes",
    ] {
        assert!(
            header.iter().any(|h| h == column),
            "no {column}: {header:?}"
        );
    }
    reader
        .records()
        .map(|r| {
            let r = r.unwrap();
            assert_eq!(r.len(), header.len());
            header
                .iter()
                .zip(r.iter())
                .map(|(h, v)| {
                    let v = if v == "inf" {
                        f64::INFINITY
                    } else {
                        v.parse().unwrap()
                    };
                    (h.clone(), v)
                })
                .collect()
        })
        .collect()
}

#[test]
fn table_csv_grows_as_the_plane_falls() {
    for name in ["jacksboro_fault.tif", "jacksboro_voids.tif"] {
        let input = sample(name);
        let rows = csv_table(&["table", s(&input), "--format", "csv"]);
        assert!(rows.len() > 4, "{name}");
        assert_eq!(rows.last().unwrap()["plane"], 0.0, "{name}");
        for pair in rows.windows(2) {
            let (a, b) = (&pair[0], &pair[1]);
            assert_eq!(b["plane"], a["plane"] - 1.0, "{name}");
            assert!(b["triangles"] >= a["triangles"], "{name}: {a:?} then {b:?}");
            assert!(b["ezw_bytes"] >= a["ezw_bytes"], "{name}");
            assert!(b["image_psnr_db"] >= a["image_psnr_db"], "{name}");
        }
        for r in &rows {
            assert_eq!(r["threshold"], 2f64.powf(r["plane"]));
            assert!(
                r["triangles"] > 0.0 && r["vertices"] >= 3.0,
                "{name}: {r:?}"
            );
            assert!(r["mesh_rmse"] <= r["mesh_max_error"], "{name}: {r:?}");
        }
    }
}

#[test]
fn table_json_parses() {
    let input = sample("jacksboro_voids.tif");
    let report = json(&["table", s(&input), "--format", "json"]);
    assert_eq!(report["command"], "table");
    assert_eq!(report["schema_version"], 1);
    assert_eq!(
        (report["width"].as_u64(), report["height"].as_u64()),
        (Some(403), Some(344))
    );
    let rows = report["rows"].as_array().expect("a rows array");
    assert!(rows.len() > 4);
    for row in rows {
        assert!(u64_of(&row["triangles"]) > 0, "{row}");
        let mesh = &row["mesh"];
        assert_eq!(
            u64_of(&mesh["compared_samples"]) + u64_of(&mesh["uncovered_samples"]),
            VOIDS_VALID,
            "{row}"
        );
        assert!(u64_of(&row["ezw_bytes"]) <= u64_of(&report["ezw_bytes"]));
        assert!(f64_of(&row["saving_ratio"]) > 0.0);
    }
}

#[test]
fn table_rows_by_threshold_and_by_bit_rate() {
    let input = sample("jacksboro_fault.tif");
    let report = json(&[
        "table",
        s(&input),
        "--thresholds",
        "16,256",
        "--format",
        "json",
    ]);
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        (u64_of(&rows[0]["plane"]), u64_of(&rows[1]["plane"])),
        (4, 8)
    );
    assert_eq!(f64_of(&rows[0]["threshold"]), 16.0);
    assert_eq!(f64_of(&rows[1]["threshold"]), 256.0);
    assert!(u64_of(&rows[0]["triangles"]) > u64_of(&rows[1]["triangles"]));

    let rows = csv_table(&["table", s(&input), "--bpp", "0.5,1,2", "--format", "csv"]);
    assert_eq!(rows.len(), 3);
    for (r, rate) in rows.iter().zip([0.5, 1.0, 2.0]) {
        assert_eq!(
            r["ezw_bytes"],
            (rate * SAMPLES as f64 / 8.0).floor(),
            "{rate}"
        );
        assert!((r["bpp"] - rate).abs() < 1e-3, "{rate}: {r:?}");
    }
    for pair in rows.windows(2) {
        assert!(pair[1]["triangles"] >= pair[0]["triangles"]);
        assert!(pair[1]["plane"] <= pair[0]["plane"]);
        assert!(pair[1]["image_psnr_db"] > pair[0]["image_psnr_db"]);
    }

    // Thresholds and bit rates exclude each other (clap's usage error).
    let both = wavemesh(&["table", s(&input), "--thresholds", "16", "--bpp", "1"]);
    assert_eq!(both.status.code(), Some(2));
}

#[test]
fn own_rule_splits_no_more_than_the_zerotree() {
    let input = sample("jacksboro_fault.tif");
    let zerotree = csv_table(&["table", s(&input), "--format", "csv"]);
    let own = csv_table(&["table", s(&input), "--format", "csv", "--rule", "own"]);
    assert_eq!(own.len(), zerotree.len());
    let mut fewer = false;
    for (o, z) in own.iter().zip(&zerotree) {
        assert_eq!(o["plane"], z["plane"]);
        assert!(o["triangles"] > 0.0);
        assert!(o["triangles"] <= z["triangles"], "{o:?} vs {z:?}");
        fewer |= o["triangles"] < z["triangles"];
        // The decoded image does not depend on the rule.
        assert_eq!(o["image_rmse"], z["image_rmse"]);
    }
    assert!(fewer, "the own-coefficient rule never differed");
}

#[test]
fn voids_meshes_keep_the_bound_and_count_cut_off_samples() {
    let dir = scratch("cli-mesh-tests");
    let input = sample("jacksboro_voids.tif");
    for (args, bound) in [
        (&["--mesh-error", "6"][..], Some(6.0)),
        (&["--mesh-error", "20", "--threshold", "1024"], Some(20.0)),
        (&["--triangles", "20000", "--search", "threshold"], None),
        (&["--threshold", "64", "--rule", "own"], None),
    ] {
        let out = dir.path().join("voids.ply");
        let mut full = vec![
            "mesh",
            "--method",
            "zerotree",
            s(&input),
            "-o",
            s(&out),
            "--json",
        ];
        full.extend_from_slice(args);
        let report = json(&full);
        let mesh = check_mesh_report(&report, &out);
        for key in ["error_vs_decoded", "error_vs_original"] {
            let e = &mesh[key];
            assert_eq!(
                u64_of(&e["compared_samples"]) + u64_of(&e["uncovered_samples"]),
                VOIDS_VALID,
                "{args:?} {key}: {e}"
            );
            if let Some(bound) = bound {
                assert!(f64_of(&e["max_error"]) <= bound, "{args:?} {key}: {e}");
            }
        }
        if args[0] == "--triangles" {
            assert!(u64_of(&mesh["triangles"]) <= 20000, "{mesh}");
        }
    }
}

#[test]
fn demo_writes_a_mesh_and_prints_the_tables() {
    let dir = scratch("cli-mesh-tests");
    let report = json(&["demo", "--out-dir", s(dir.path()), "--json"]);
    let mesh = &report["mesh"];
    let path = dir.path().join("jacksboro_fault.glb");
    assert_eq!(mesh["output"], s(&path));
    assert_eq!(mesh["format"], "glb");
    let tolerance = f64_of(&mesh["tolerance"]);
    let triangles = u64_of(&mesh["triangles"]);
    assert!(triangles > 0);
    assert!(f64_of(&mesh["error"]["max_error"]) <= tolerance, "{mesh}");
    assert_eq!(u64_of(&mesh["error"]["compared_samples"]), SAMPLES);
    assert_eq!(
        u64_of(&mesh["file_bytes"]),
        std::fs::metadata(&path).unwrap().len()
    );
    assert_eq!(
        counts_in_file(&path),
        (u64_of(&mesh["vertices"]), triangles)
    );
    // One row per pass of the lossless stream, the plane falling to 0.
    let tables = report["tables"].as_array().expect("a tables array");
    assert!(tables.len() > 4);
    for (k, row) in tables.iter().enumerate() {
        assert_eq!(u64_of(&row["plane"]), (tables.len() - 1 - k) as u64);
        assert!(u64_of(&row["triangles"]) > 0);
    }

    // The text report prints both tables after the rate table.
    let text = stdout(&["demo", "--out-dir", s(dir.path())]);
    let table1 = markdown_rows(&text, "Table 1");
    assert_eq!(table1.len(), tables.len(), "{text}");
    assert_eq!(markdown_rows(&text, "Table 2").len(), tables.len());
    assert!(text.contains("jacksboro_fault.glb"), "{text}");
}

#[test]
fn meshes_larger_than_the_memory_limit_are_refused_before_any_work() {
    let dir = scratch("cli-mesh-tests");
    let out = dir.path().join("big.glb");
    let input = sample("jacksboro_fault.tif");
    // 403 × 344 samples need far more than 100 kB for a mesh.
    let message = fails(
        &["mesh", s(&input), "-o", s(&out), "--max-memory", "100000"],
        3,
    );
    assert!(message.contains("--max-memory"), "{message}");
    assert!(!out.exists());
    let ezw = dir.path().join("fault.ezw");
    let dem = dir.path().join("fault.tif");
    let encode = wavemesh(&["encode", s(&input), "-o", s(&ezw)]);
    assert!(encode.status.success());
    let message = fails(
        &[
            "decode",
            s(&ezw),
            "-o",
            s(&dem),
            "--mesh",
            s(&out),
            "--max-memory",
            "1000000",
        ],
        3,
    );
    assert!(message.contains("--max-memory"), "{message}");
    assert!(!out.exists() && !dem.exists());
}
