//! Hostile and unusual inputs and outputs, end to end: decompression bombs, special
//! files as outputs, lossy-compressed TIFFs, GDAL-readable `.asc`, and one exit code per
//! kind of cause (the README's table).

mod support;

use support::{s, sample, wavemesh};

use std::path::Path;
use std::process::{Command, Output, Stdio};

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Asserts a failure with `code` and exactly one line on stderr; returns that line.
fn one_line_failure(output: &Output, code: i32) -> String {
    let err = stderr(output);
    assert_eq!(output.status.code(), Some(code), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.starts_with("wavemesh: error: "), "{err}");
    err
}

/// A single-strip little-endian TIFF of `width × height` i16 samples with the given
/// `Compression` value whose strip holds `data` (made at test time, never committed).
fn tiff_claiming(width: u32, height: u32, compression: u16, data: &[u8]) -> Vec<u8> {
    const SHORT: u16 = 3;
    const LONG: u16 = 4;
    let entries: [(u16, u16, u32); 10] = [
        (256, LONG, width),
        (257, LONG, height),
        (258, SHORT, 16),
        (259, SHORT, u32::from(compression)),
        (262, SHORT, 1),
        (273, LONG, 0), // strip offset, set below
        (277, SHORT, 1),
        (278, LONG, height),
        (279, LONG, data.len() as u32),
        (339, SHORT, 2),
    ];
    let data_offset = 8 + 2 + entries.len() as u32 * 12 + 4;
    let mut out = b"II*\0".to_vec();
    out.extend_from_slice(&8u32.to_le_bytes());
    out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, kind, value) in entries {
        let value = if tag == 273 { data_offset } else { value };
        out.extend_from_slice(&tag.to_le_bytes());
        out.extend_from_slice(&kind.to_le_bytes());
        out.extend_from_slice(&1u32.to_le_bytes());
        if kind == SHORT {
            out.extend_from_slice(&(value as u16).to_le_bytes());
            out.extend_from_slice(&[0, 0]);
        } else {
            out.extend_from_slice(&value.to_le_bytes());
        }
    }
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(data);
    out
}

#[test]
fn decompression_bombs_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    // A sparse 40000² i16 TIFF (GDAL SPARSE_OK: no strip data) and a 30000² Deflate one:
    // a few hundred bytes that would need gigabytes.
    for (name, side, compression, data) in [
        ("sparse.tif", 40_000, 1, &[][..]),
        ("deflate.tif", 30_000, 8, &[0x78, 0x9c, 0x03, 0x00][..]),
    ] {
        let bomb = dir.path().join(name);
        std::fs::write(&bomb, tiff_claiming(side, side, compression, data)).unwrap();
        let out = dir.path().join("out.ezw");
        let mesh = dir.path().join("out.glb");
        for args in [
            vec!["encode", s(&bomb), "-o", s(&out)],
            vec!["mesh", s(&bomb), "-o", s(&mesh)],
            vec!["table", s(&bomb)],
            vec!["compare", s(&bomb), s(&bomb)],
        ] {
            let err = one_line_failure(&wavemesh(&args), 3);
            assert!(err.contains("--max-memory"), "{args:?}: {err}");
        }
        assert!(!out.exists() && !mesh.exists());
    }
}

#[test]
fn info_and_verify_refuse_forged_huge_headers() {
    let dir = tempfile::tempdir().unwrap();
    let ezw = dir.path().join("small.ezw");
    // The voids give the file a nodata mask, which `info` decodes to count valid samples.
    let enc = wavemesh(&["encode", s(&sample("jacksboro_voids.tif")), "-o", s(&ezw)]);
    assert!(enc.status.success(), "{}", stderr(&enc));
    let bytes = std::fs::read(&ezw).unwrap();
    let (mut header, _) = wavemesh_codec::Header::parse(&bytes).unwrap();
    for side in [65_536, u32::MAX] {
        header.width = side;
        header.height = side;
        let forged = dir.path().join(format!("forged-{side}.ezw"));
        std::fs::write(&forged, header.to_bytes()).unwrap();
        let err = one_line_failure(&wavemesh(&["info", s(&forged)]), 3);
        assert!(err.contains("--max-samples"), "{err}");
        let result = wavemesh(&["verify", s(&forged)]);
        assert!(
            matches!(result.status.code(), Some(0) | Some(3)),
            "verify {side}: {}",
            stderr(&result)
        );
        assert!(!stderr(&result).contains("panicked"), "{}", stderr(&result));
        let decoded = wavemesh(&["decode", s(&forged), "-o", s(&dir.path().join("x.tif"))]);
        let err = one_line_failure(&decoded, 3);
        assert!(err.contains("--max-memory"), "{err}");
    }
}

#[test]
fn lossy_compressed_tiffs_are_refused_unless_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let jpeg = dir.path().join("jpeg.tif");
    std::fs::write(&jpeg, tiff_claiming(4, 4, 7, &[0xff, 0xd8, 0xff, 0xd9])).unwrap();
    let out = dir.path().join("out.ezw");
    let err = one_line_failure(&wavemesh(&["encode", s(&jpeg), "-o", s(&out)]), 3);
    assert!(
        err.contains("JPEG") && err.contains("--accept-lossy-input"),
        "{err}"
    );
    // Accepted, the reader goes on (and finds this strip is no image).
    let accepted = wavemesh(&["encode", s(&jpeg), "-o", s(&out), "--accept-lossy-input"]);
    assert!(!stderr(&accepted).contains("--accept-lossy-input"));
}

#[test]
fn a_real_jpeg_tiff_encodes_only_when_accepted() {
    let test = "cli_hardening::a_real_jpeg_tiff_encodes_only_when_accepted";
    let Some(gdal_translate) = support::program(test, "gdal_translate", "Debian: gdal-bin") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let jpeg = dir.path().join("jpeg.tif");
    let made = Command::new(gdal_translate)
        .args(["-q", "-ot", "Byte", "-scale", "-co", "COMPRESS=JPEG"])
        .args([s(&sample("jacksboro_fault.tif")), s(&jpeg)])
        .status()
        .unwrap();
    assert!(made.success());
    let out = dir.path().join("out.ezw");
    one_line_failure(&wavemesh(&["encode", s(&jpeg), "-o", s(&out)]), 3);
    let accepted = wavemesh(&["encode", s(&jpeg), "-o", s(&out), "--accept-lossy-input"]);
    assert!(accepted.status.success(), "{}", stderr(&accepted));
}

#[cfg(unix)]
#[test]
fn outputs_never_replace_devices_fifos_or_symlinks() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let input = sample("jacksboro_fault.tif");
    let ezw = dir.path().join("dem.ezw");
    assert!(wavemesh(&["encode", s(&input), "-o", s(&ezw)])
        .status
        .success());
    let expected = std::fs::read(&ezw).unwrap();

    // /dev/null stays a character device whatever writes to it.
    for args in [
        vec!["encode", s(&input), "-o", "/dev/null"],
        vec!["decode", s(&ezw), "-o", "/dev/null"],
        vec!["mesh", s(&input), "-o", "/dev/null"],
    ] {
        let result = wavemesh(&args);
        assert!(result.status.success(), "{args:?}: {}", stderr(&result));
        let meta = std::fs::metadata("/dev/null").unwrap();
        assert!(
            meta.file_type().is_char_device(),
            "{args:?} replaced /dev/null"
        );
    }

    // `-o -` pipes the stream; a decode to `-` pipes a GeoTIFF.
    let piped = wavemesh(&["encode", s(&input), "-o", "-"]);
    assert!(piped.status.success());
    assert_eq!(piped.stdout, expected);
    let tif = wavemesh(&["decode", s(&ezw), "-o", "-"]);
    assert!(tif.stdout.starts_with(b"II*\0"), "a GeoTIFF on stdout");
    one_line_failure(&wavemesh(&["encode", s(&input), "-o", "-", "--json"]), 2);

    // A FIFO is written through, not replaced.
    let fifo = dir.path().join("pipe");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let result = wavemesh(&["encode", s(&input), "-o", s(&fifo)]);
    assert!(result.status.success(), "{}", stderr(&result));
    assert_eq!(reader.join().unwrap(), expected);
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());

    // A symlink is followed: its target is replaced, the link stays.
    let target = dir.path().join("target.ezw");
    std::fs::write(&target, b"old").unwrap();
    let link = dir.path().join("link.ezw");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    assert!(wavemesh(&["encode", s(&input), "-o", s(&link)])
        .status
        .success());
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&target).unwrap(), expected);
}

/// A float raster with NaN voids, written as GeoTIFF.
fn float_dem_with_nan_voids(path: &Path) {
    use wavemesh_codec::{Raster, Samples};
    let (width, height) = (37, 23);
    let values = (0..width * height)
        .map(|i| {
            if i % 7 == 0 || i < width {
                f32::NAN
            } else {
                (i as f32 * 0.37).sin() * 100.0 + 0.123
            }
        })
        .collect();
    let mut raster = Raster::new(width, height, Samples::F32(values)).unwrap();
    raster.nodata = Some(f64::NAN);
    wavemesh::dem::write_dem(path, &raster).unwrap();
}

#[test]
fn asc_output_with_nan_voids_opens_in_gdal() {
    let dir = tempfile::tempdir().unwrap();
    let tif = dir.path().join("voids.tif");
    float_dem_with_nan_voids(&tif);
    let ezw = dir.path().join("voids.ezw");
    let asc = dir.path().join("voids.asc");
    assert!(wavemesh(&["encode", s(&tif), "-o", s(&ezw)])
        .status
        .success());
    let dec = wavemesh(&["decode", s(&ezw), "-o", s(&asc), "--reference", s(&tif)]);
    assert!(dec.status.success(), "{}", stderr(&dec));
    let text = std::fs::read_to_string(&asc).unwrap();
    assert!(!text.to_ascii_lowercase().contains("nan"), "no NaN token");
    // Same voids and values back through our own reader.
    let cmp = wavemesh(&["compare", s(&tif), s(&asc), "--json"]);
    assert!(cmp.status.success(), "{}", stderr(&cmp));

    let test = "cli_hardening::asc_output_with_nan_voids_opens_in_gdal";
    let Some(gdalinfo) = support::program(test, "gdalinfo", "Debian: gdal-bin") else {
        return;
    };
    let info = Command::new(gdalinfo)
        .args(["-json", "-stats", s(&asc)])
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert!(info.status.success(), "{}", stderr(&info));
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    let band = &json["bands"][0];
    assert!(band["noDataValue"].is_number(), "{band}");
    let valid = band["metadata"][""]["STATISTICS_VALID_PERCENT"]
        .as_str()
        .unwrap()
        .parse::<f64>()
        .unwrap();
    assert!(valid > 50.0 && valid < 100.0, "{valid}");
}

#[test]
fn exit_codes_follow_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("jacksboro_fault.tif");
    let voids = sample("jacksboro_voids.tif");
    let out = dir.path().join("out.ezw");
    let ezw = dir.path().join("dem.ezw");
    assert!(wavemesh(&["encode", s(&input), "-o", s(&ezw)])
        .status
        .success());
    let tif_out = dir.path().join("out.tif");
    let glb = dir.path().join("out.glb");
    let nowhere = dir.path().join("no/such/dir/out.ezw");
    let cases: [(Vec<&str>, i32); 10] = [
        (vec!["encode", s(&input), "-o", s(&out), "--bpp", "0"], 2),
        (
            vec!["encode", s(&input), "-o", s(&out), "--max-error", "0"],
            2,
        ),
        (
            vec!["encode", s(&input), "-o", s(&out), "--precision", "1"],
            2,
        ),
        (vec!["encode", "no/such/file.tif", "-o", s(&out)], 3),
        (
            vec!["encode", s(&input), "-o", s(&out), "--max-memory", "1000"],
            3,
        ),
        (
            vec!["decode", s(&ezw), "-o", s(&tif_out), "--max-memory", "1000"],
            3,
        ),
        (
            vec!["mesh", s(&input), "-o", s(&glb), "--max-memory", "3000000"],
            3,
        ),
        (
            vec![
                "decode",
                s(&ezw),
                "-o",
                s(&tif_out),
                "--mesh",
                s(&glb),
                "--max-memory",
                "3000000",
            ],
            3,
        ),
        (vec!["encode", s(&input), "-o", s(&nowhere)], 4),
        (vec!["compare", s(&input), s(&voids)], 1),
    ];
    for (args, code) in cases {
        let err = one_line_failure(&wavemesh(&args), code);
        assert!(!err.contains("max_samples"), "CLI words only: {err}");
    }
}

#[test]
fn small_things_a_user_hit() {
    let dir = tempfile::tempdir().unwrap();
    let input = sample("jacksboro_fault.tif");
    // An .ezw under a DEM extension warns; --verify says what it checked.
    let png = dir.path().join("x.png");
    let result = wavemesh(&["encode", s(&input), "-o", s(&png), "--verify"]);
    assert!(result.status.success());
    assert!(stderr(&result).contains("warning"), "{}", stderr(&result));
    let stdout = String::from_utf8_lossy(&result.stdout);
    assert!(
        stdout.contains("verified") && stdout.contains("bit-exact"),
        "{stdout}"
    );
    // A .hgt not named like a tile says it has no georeferencing.
    let hgt = dir.path().join("dem.hgt");
    std::fs::write(&hgt, [0u8; 18]).unwrap();
    let result = wavemesh(&["encode", s(&hgt), "-o", s(&dir.path().join("h.ezw"))]);
    assert!(result.status.success());
    assert!(stderr(&result).contains("no georeferencing"));
    // Infinite floats name the sample; i32 extremes name the max error that fits.
    let inf = dir.path().join("inf.asc");
    let header = "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
    std::fs::write(&inf, format!("{header}1.5 inf\n")).unwrap();
    let out = dir.path().join("inf.ezw");
    let err = one_line_failure(&wavemesh(&["encode", s(&inf), "-o", s(&out)]), 3);
    assert!(err.contains("row 0, column 1 is inf"), "{err}");
    let wide = dir.path().join("wide.asc");
    std::fs::write(&wide, format!("{header}-2147483648 2147483647\n")).unwrap();
    let out = dir.path().join("wide.ezw");
    let err = one_line_failure(&wavemesh(&["encode", s(&wide), "-o", s(&out)]), 3);
    assert!(err.contains("at least 32"), "{err}");
    let fits = wavemesh(&["encode", s(&wide), "-o", s(&out), "--max-error", "32"]);
    assert!(fits.status.success(), "{}", stderr(&fits));
    // compare headlines void mismatches.
    let cmp = wavemesh(&["compare", s(&input), s(&sample("jacksboro_voids.tif"))]);
    assert!(String::from_utf8_lossy(&cmp.stdout).starts_with("VOIDS DIFFER"));
}

#[test]
fn demo_runs_anywhere_from_its_bundled_sample() {
    let dir = tempfile::tempdir().unwrap();
    let result = Command::new(env!("CARGO_BIN_EXE_wavemesh"))
        .args(["demo", "--json"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(result.status.success(), "{}", stderr(&result));
    let out = dir.path().join("wavemesh-demo");
    assert_eq!(
        std::fs::read(out.join("jacksboro_fault.tif")).unwrap(),
        std::fs::read(sample("jacksboro_fault.tif")).unwrap()
    );
    assert!(out.join("lossless.ezw").exists() && out.join("jacksboro_fault.glb").exists());
    assert!(!dir.path().join("target").exists());
}

#[test]
fn the_readme_lists_every_exit_code() {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let start = readme
        .find("| code | cause |")
        .expect("the exit-code table");
    let rows: Vec<&str> = readme[start..]
        .lines()
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .collect();
    let codes: Vec<u32> = rows
        .iter()
        .map(|r| r.split('|').nth(1).unwrap().trim().parse().unwrap())
        .collect();
    assert_eq!(codes, [0, 1, 2, 3, 4], "{rows:?}");
}

#[test]
fn a_rate_below_the_smallest_prefix_decodes_the_smallest_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let ezw = dir.path().join("voids.ezw");
    let input = sample("jacksboro_voids.tif");
    assert!(wavemesh(&["encode", s(&input), "-o", s(&ezw)])
        .status
        .success());
    let out = dir.path().join("tiny.tif");
    for rate in [["--bytes", "10"], ["--bpp", "0.0001"]] {
        let result = wavemesh(&["decode", s(&ezw), "-o", s(&out), rate[0], rate[1], "--json"]);
        assert!(result.status.success(), "{}", stderr(&result));
        assert!(stderr(&result).contains("smallest decodable prefix"));
        let report: serde_json::Value = serde_json::from_slice(&result.stdout).unwrap();
        let used = report["bytes_read"].as_u64().unwrap();
        assert!(used > 10 && used < 2000, "{used}");
    }
}

#[test]
fn views_of_a_raster_with_nothing_to_mesh_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let thin = dir.path().join("thin.asc");
    let header = "ncols 1\nnrows 5\nxllcorner 0\nyllcorner 0\ncellsize 1\n";
    std::fs::write(&thin, format!("{header}1\n2\n3\n4\n5\n")).unwrap();
    let ezw = dir.path().join("thin.ezw");
    assert!(wavemesh(&["encode", s(&thin), "-o", s(&ezw)])
        .status
        .success());
    let glb = dir.path().join("v.glb");
    let view = [
        "view",
        s(&ezw),
        "--camera",
        "0,0,100",
        "--look",
        "0,2,0",
        "-o",
        s(&glb),
    ];
    let err = one_line_failure(&wavemesh(&view), 3);
    assert!(err.contains("nothing to mesh"), "{err}");
    let err = one_line_failure(&wavemesh(&["flythrough", s(&ezw), "--json"]), 3);
    assert!(!err.contains("panicked"), "{err}");
    assert!(!glb.exists());
}

#[cfg(unix)]
#[test]
fn a_closed_stdout_ends_the_run_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let ezw = dir.path().join("dem.ezw");
    assert!(
        wavemesh(&["encode", s(&sample("jacksboro_fault.tif")), "-o", s(&ezw)])
            .status
            .success()
    );
    // The reader is gone before the first line is printed.
    let mut child = Command::new(env!("CARGO_BIN_EXE_wavemesh"))
        .args(["info", s(&ezw)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let output = child.wait_with_output().unwrap();
    let err = stderr(&output);
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        output.status.success() || output.status.signal() == Some(13),
        "{:?}: {err}",
        output.status
    );
}
