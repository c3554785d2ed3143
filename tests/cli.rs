//! End-to-end tests of the `wavemesh` binary: every subcommand, JSON reports, errors.

mod support;

use support::{json, s, sample, wavemesh};

use std::path::{Path, PathBuf};
use std::process::Command;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli-tests");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn lossless_round_trip_of_every_sample_is_bit_exact() {
    for name in ["jacksboro_fault.tif", "jacksboro_voids.tif"] {
        let input = sample(name);
        let ezw = scratch(&format!("{name}.ezw"));
        let out = scratch(&format!("{name}.decoded.tif"));
        let enc = json(&["encode", s(&input), "-o", s(&ezw), "--json"]);
        assert_eq!(enc["schema_version"], 1);
        assert_eq!(enc["mode"], "lossless");
        assert_eq!(enc["wavelet"], "13/11", "{name}: terrain takes the 13/11");
        let dec = json(&[
            "decode",
            s(&ezw),
            "-o",
            s(&out),
            "--reference",
            s(&input),
            "--json",
        ]);
        assert_eq!(dec["complete"], true);
        assert_eq!(dec["distortion"]["identical"], true, "{name} not bit-exact");
        assert_eq!(dec["distortion"]["nodata_mismatches"], 0);
        let cmp = json(&["compare", s(&input), s(&out), "--json"]);
        assert_eq!(cmp["max_error"], 0.0);
        assert_eq!(cmp["identical"], true);
    }
}

#[test]
fn rate_budget_and_progressive_prefixes() {
    let input = sample("jacksboro_fault.tif");
    let ezw = scratch("rate.ezw");
    let enc = json(&["encode", s(&input), "-o", s(&ezw), "--bpp", "1", "--json"]);
    assert_eq!(enc["wavelet"], "9/7");
    let samples = 403.0 * 344.0;
    assert_eq!(enc["bytes"], (samples / 8.0f64).floor() as u64);
    let mut last_psnr = 0.0;
    for bpp in ["0.1", "0.25", "0.5", "1"] {
        let out = scratch(&format!("rate-{bpp}.tif"));
        let dec = json(&[
            "decode",
            s(&ezw),
            "-o",
            s(&out),
            "--bpp",
            bpp,
            "--reference",
            s(&input),
            "--json",
        ]);
        let psnr = dec["distortion"]["psnr_db"].as_f64().unwrap();
        assert!(
            psnr > last_psnr,
            "PSNR {psnr} at {bpp} bpp after {last_psnr}"
        );
        last_psnr = psnr;
    }
    assert!(last_psnr > 40.0, "1 bpp gives only {last_psnr} dB");
}

#[test]
fn max_error_is_guaranteed() {
    let input = sample("jacksboro_voids.tif");
    for e in ["1", "2", "5"] {
        let ezw = scratch(&format!("e{e}.ezw"));
        let out = scratch(&format!("e{e}.tif"));
        let enc = json(&[
            "encode",
            s(&input),
            "-o",
            s(&ezw),
            "--max-error",
            e,
            "--json",
        ]);
        assert_eq!(enc["mode"], "max-error");
        let dec = json(&[
            "decode",
            s(&ezw),
            "-o",
            s(&out),
            "--reference",
            s(&input),
            "--json",
        ]);
        let max = dec["distortion"]["max_error"].as_f64().unwrap();
        assert!(max <= e.parse::<f64>().unwrap(), "max error {max} > {e}");
        assert_eq!(dec["distortion"]["nodata_mismatches"], 0);
    }
}

#[test]
fn info_lists_the_ladder() {
    let input = sample("jacksboro_fault.tif");
    let ezw = scratch("info.ezw");
    json(&["encode", s(&input), "-o", s(&ezw), "--json"]);
    let info = json(&["info", s(&ezw), "--json"]);
    assert_eq!(info["width"], 403);
    assert_eq!(info["height"], 344);
    assert_eq!(info["sample_type"], "i16");
    assert_eq!(info["georeferenced"], true);
    let passes = info["passes"].as_array().unwrap();
    assert!(passes.len() > 5);
    let ends: Vec<u64> = passes
        .iter()
        .map(|p| p["end_byte"].as_u64().unwrap())
        .collect();
    assert!(ends.windows(2).all(|w| w[0] <= w[1]));
    // The last pass of a complete stream ends where the payload does; the ladder trails.
    let payload_end =
        info["payload_start"].as_u64().unwrap() + info["payload_bytes"].as_u64().unwrap();
    // (the payload's last chunk checksum follows the last pass's bytes).
    let last = *ends.last().unwrap();
    assert!(
        last <= payload_end && payload_end - last <= 4,
        "{last} vs {payload_end}"
    );
    assert!(payload_end < info["file_bytes"].as_u64().unwrap());
    assert_eq!(info["truncated"], false);
    let text = wavemesh(&["info", s(&ezw)]);
    assert!(text.status.success());
    assert!(String::from_utf8_lossy(&text.stdout).contains("403x344 i16"));
}

#[test]
fn georeferencing_and_nodata_survive_to_the_output() {
    let input = sample("jacksboro_voids.tif");
    let ezw = scratch("geo.ezw");
    let out = scratch("geo.tif");
    json(&["encode", s(&input), "-o", s(&ezw), "--json"]);
    json(&["decode", s(&ezw), "-o", s(&out), "--json"]);
    let options = wavemesh::dem::ReadOptions::default();
    let original = wavemesh::dem::read_dem(&input, &options).unwrap();
    let decoded = wavemesh::dem::read_dem(&out, &options).unwrap();
    assert_eq!(decoded.georef, original.georef);
    assert_eq!(decoded.nodata, original.nodata);
    assert_eq!(decoded.samples, original.samples);
}

#[test]
fn bad_input_gives_one_line_errors_and_no_output() {
    let garbage = scratch("garbage.ezw");
    std::fs::write(&garbage, b"this is not an ezw file at all").unwrap();
    let out = scratch("never-written.tif");
    let _ = std::fs::remove_file(&out);
    let result = wavemesh(&["decode", s(&garbage), "-o", s(&out)]);
    assert_eq!(result.status.code(), Some(3));
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    assert!(stderr.contains("not an .ezw file"), "{stderr}");
    assert!(!out.exists());

    let missing = wavemesh(&["encode", "no/such/file.tif", "-o", s(&scratch("x.ezw"))]);
    assert_eq!(missing.status.code(), Some(3));

    let input = sample("jacksboro_fault.tif");
    let same = wavemesh(&["encode", s(&input), "-o", s(&input)]);
    assert_eq!(same.status.code(), Some(2));

    let lossy_without_rate = wavemesh(&[
        "encode",
        s(&input),
        "-o",
        s(&scratch("y.ezw")),
        "--wavelet",
        "97",
    ]);
    assert_eq!(lossy_without_rate.status.code(), Some(2));
}

#[test]
fn truncated_file_decodes_to_a_coarser_image() {
    let input = sample("jacksboro_fault.tif");
    let ezw = scratch("trunc.ezw");
    json(&["encode", s(&input), "-o", s(&ezw), "--json"]);
    let bytes = std::fs::read(&ezw).unwrap();
    let cut = scratch("trunc-cut.ezw");
    std::fs::write(&cut, &bytes[..bytes.len() / 3]).unwrap();
    let out = scratch("trunc.tif");
    let dec = json(&[
        "decode",
        s(&cut),
        "-o",
        s(&out),
        "--reference",
        s(&input),
        "--json",
    ]);
    assert_eq!(dec["complete"], false);
    let psnr = dec["distortion"]["psnr_db"].as_f64().unwrap();
    assert!(psnr > 30.0 && psnr.is_finite(), "{psnr}");
}

#[test]
fn demo_runs_on_the_bundled_sample() {
    let dir = scratch("demo");
    let report = json(&["demo", "--out-dir", s(&dir), "--json"]);
    let rows = report["rows"].as_array().unwrap();
    assert!(rows.iter().any(|r| r["exact"] == true));
    assert!(dir.join("lossless.ezw").exists());
}

#[test]
fn verify_reports_intact_damaged_and_truncated_files() {
    let input = sample("jacksboro_voids.tif");
    let ezw = scratch("verify.ezw");
    json(&["encode", s(&input), "-o", s(&ezw), "--verify", "--json"]);
    let intact = json(&["verify", s(&ezw), "--json"]);
    assert_eq!(intact["damaged"], false);
    assert_eq!(intact["truncated"], false);
    assert_eq!(intact["usable_bytes"], intact["file_bytes"]);

    let mut bytes = std::fs::read(&ezw).unwrap();
    let flip = bytes.len() / 2;
    bytes[flip] ^= 0x20;
    let damaged = scratch("verify-damaged.ezw");
    std::fs::write(&damaged, &bytes).unwrap();
    let result = wavemesh(&["verify", s(&damaged), "--json"]);
    assert_eq!(result.status.code(), Some(3));
    let report: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
    assert_eq!(report["damaged"], true);
    assert!(report["usable_bytes"].as_u64().unwrap() <= flip as u64);

    // decode: a warning and the undamaged prefix; --strict: an error and no file.
    let out = scratch("verify-damaged.tif");
    let _ = std::fs::remove_file(&out);
    let lenient = wavemesh(&["decode", s(&damaged), "-o", s(&out), "--json"]);
    assert!(lenient.status.success());
    assert!(String::from_utf8_lossy(&lenient.stderr).contains("warning"));
    let report: serde_json::Value = serde_json::from_slice(&lenient.stdout).unwrap();
    assert_eq!(report["damage"]["section"], "payload");
    assert!(out.exists());
    std::fs::remove_file(&out).unwrap();
    let strict = wavemesh(&["decode", s(&damaged), "-o", s(&out), "--strict"]);
    assert_eq!(strict.status.code(), Some(3));
    assert!(!out.exists());

    let truncated = scratch("verify-truncated.ezw");
    let clean = std::fs::read(&ezw).unwrap();
    std::fs::write(&truncated, &clean[..clean.len() * 2 / 3]).unwrap();
    let report = json(&["verify", s(&truncated), "--json"]);
    assert_eq!(report["damaged"], false);
    assert_eq!(report["truncated"], true);
}

#[test]
fn output_into_a_directory_is_refused() {
    let input = sample("jacksboro_fault.tif");
    let dir = scratch("a-directory");
    std::fs::create_dir_all(&dir).unwrap();
    let before = std::fs::read_dir(&dir).unwrap().count();
    let result = wavemesh(&["encode", s(&input), "-o", s(&dir)]);
    assert_eq!(result.status.code(), Some(4));
    assert!(String::from_utf8_lossy(&result.stderr).contains("directory"));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), before);
}

#[test]
fn killing_an_encode_never_leaves_a_partial_output() {
    // A raster large enough that encoding takes a while.
    let big = scratch("kill-input.tif");
    if !big.exists() {
        let (w, h) = (2400, 2000);
        let values: Vec<i16> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (1000.0
                    + 700.0 * (x / 97.0).sin() * (y / 73.0).cos()
                    + 30.0 * (x * y / 5000.0).sin()) as i16
            })
            .collect();
        let raster =
            wavemesh_codec::Raster::new(w, h, wavemesh_codec::Samples::I16(values)).unwrap();
        wavemesh::dem::write_dem(&big, &raster).unwrap();
    }
    let out = scratch("kill-output.ezw");
    for delay_ms in [20u64, 80, 200, 400, 700, 1200] {
        std::fs::write(&out, b"the previous version").unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_wavemesh"))
            .args(["encode", s(&big), "-o", s(&out)])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill();
        let _ = child.wait();
        let now = std::fs::read(&out).unwrap();
        if now != b"the previous version" {
            // The rename happened: the file must be the whole, valid stream.
            let decoded =
                wavemesh_codec::decode(&now, &wavemesh_codec::DecodeOptions::default()).unwrap();
            assert!(
                decoded.complete && decoded.damage.is_none(),
                "partial output after {delay_ms} ms"
            );
        }
    }
}

#[test]
fn a_header_claiming_a_huge_raster_is_refused_at_once() {
    let input = sample("jacksboro_fault.tif");
    let ezw = scratch("huge-source.ezw");
    json(&["encode", s(&input), "-o", s(&ezw), "--json"]);
    let bytes = std::fs::read(&ezw).unwrap();
    let (mut header, _) = wavemesh_codec::Header::parse(&bytes).unwrap();
    header.width = 30_000;
    header.height = 30_000;
    let forged = scratch("huge.ezw");
    std::fs::write(&forged, header.to_bytes()).unwrap();
    let start = std::time::Instant::now();
    let result = wavemesh(&["decode", s(&forged), "-o", s(&scratch("huge.tif"))]);
    assert_eq!(result.status.code(), Some(3));
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert!(stderr.contains("exceeds the limit"), "{stderr}");
    assert!(start.elapsed() < std::time::Duration::from_secs(5));
}
