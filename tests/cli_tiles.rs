//! Tiled `.ezw` files through the command line: streaming encode (same bytes as in
//! memory, whatever the threads), windows and boxes reading only their tiles, budgets,
//! info and verify naming damaged tiles, and the memory of a 4096² encode and decode.

mod support;

use std::path::Path;

use support::{json, s, scratch, stdout, wavemesh};
use wavemesh::dem::{read_dem, ReadOptions};

fn read(path: &Path) -> wavemesh_codec::Raster {
    read_dem(path, &ReadOptions::default()).unwrap()
}

/// A fractal GeoTIFF of `w × h` in `dir`.
fn synth(dir: &Path, w: u32, h: u32) -> std::path::PathBuf {
    let path = dir.join(format!("synth-{w}x{h}.tif"));
    json(&[
        "synth",
        s(&path),
        "--size",
        &format!("{w}x{h}"),
        "--seed",
        "7",
        "--json",
    ]);
    path
}

/// A copy of the tiled file `ezw` (`d.ezw` beside it) with a bit flipped in its middle:
/// `verify` says it is damaged (exit 3), `decode` to `out` warns of a tile and decodes
/// the rest. The copy's path and what `verify` printed.
fn damage_one_tile(ezw: &Path, out: &Path) -> (std::path::PathBuf, String) {
    let mut bytes = std::fs::read(ezw).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 0x20;
    let damaged = ezw.with_file_name("d.ezw");
    std::fs::write(&damaged, &bytes).unwrap();
    let verify = wavemesh(&["verify", s(&damaged)]);
    assert_eq!(verify.status.code(), Some(3));
    let said = String::from_utf8_lossy(&verify.stdout).to_string();
    assert!(said.contains("DAMAGED"), "{said}");
    let decode = wavemesh(&["decode", s(&damaged), "-o", s(out)]);
    assert!(decode.status.success());
    assert!(String::from_utf8_lossy(&decode.stderr).contains("tile "));
    (damaged, said)
}

#[test]
fn streaming_coding_is_lossless_and_independent_of_threads() {
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 1300, 700);
    let one = dir.path().join("one.ezw");
    let two = dir.path().join("two.ezw");
    let memory = dir.path().join("memory.ezw");
    let report = json(&[
        "encode",
        s(&tif),
        "-o",
        s(&one),
        "--tile",
        "512",
        "--threads",
        "1",
        "--json",
    ]);
    assert_eq!(report["mode"], "lossless");
    json(&[
        "encode",
        s(&tif),
        "-o",
        s(&two),
        "--tile",
        "512",
        "--threads",
        "2",
        "--json",
    ]);
    // --verify encodes in memory: the same bytes again.
    json(&[
        "encode",
        s(&tif),
        "-o",
        s(&memory),
        "--tile",
        "512",
        "--verify",
        "--json",
    ]);
    let bytes = std::fs::read(&one).unwrap();
    assert_eq!(
        bytes,
        std::fs::read(&two).unwrap(),
        "threads changed the bytes"
    );
    assert_eq!(
        bytes,
        std::fs::read(&memory).unwrap(),
        "streaming differs from memory"
    );
    let info = json(&["info", s(&one), "--json"]);
    // 1300 = 3 tiles of 434 (the last 432); 700 = 2 of 350.
    assert_eq!(
        (info["tiles"].as_u64(), info["tile_width"].as_u64()),
        (Some(6), Some(434))
    );
    // Decoding writes the same GeoTIFF on one thread (rows written in turn) as on two
    // (rows written while the next decodes).
    let out = dir.path().join("out.tif");
    let out_one = dir.path().join("out-one.tif");
    json(&["decode", s(&one), "-o", s(&out), "--threads", "2", "--json"]);
    json(&[
        "decode",
        s(&one),
        "-o",
        s(&out_one),
        "--threads",
        "1",
        "--json",
    ]);
    assert_eq!(read(&out).samples, read(&tif).samples);
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(&out_one).unwrap(),
        "threads changed the decoded GeoTIFF"
    );
}

#[test]
fn windows_and_boxes_read_only_their_tiles() {
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 1024, 1024);
    let ezw = dir.path().join("w.ezw");
    json(&["encode", s(&tif), "-o", s(&ezw), "--tile", "256", "--json"]);
    let whole = read(&tif);
    let out = dir.path().join("window.tif");
    let report = json(&[
        "decode",
        s(&ezw),
        "-o",
        s(&out),
        "--window",
        "300,520,100,60",
        "--json",
    ]);
    assert_eq!(read(&out).samples, whole.crop(300, 520, 100, 60).samples);
    let (read_bytes, file) = (
        report["bytes_read"].as_u64().unwrap(),
        report["file_bytes"].as_u64().unwrap(),
    );
    assert!(
        read_bytes * 4 < file,
        "a one-tile window read {read_bytes} of {file} bytes"
    );
    // The same window as a box in the CRS (synth: UTM, 10 m pixels).
    let gt = whole.georef.as_ref().unwrap().geotransform;
    let (minx, maxy) = (gt[0] + 300.0 * gt[1], gt[3] + 520.0 * gt[5]);
    let bbox = format!(
        "{},{},{},{}",
        minx + 1.0,
        maxy + 60.0 * gt[5] + 1.0,
        minx + 1000.0 - 1.0,
        maxy - 1.0
    );
    let boxed = dir.path().join("box.tif");
    json(&[
        "decode",
        s(&ezw),
        "-o",
        s(&boxed),
        "--bbox",
        &bbox,
        "--json",
    ]);
    let boxed = read(&boxed);
    assert_eq!(boxed.samples, whole.crop(300, 520, 100, 60).samples);
    assert_eq!(boxed.georef.unwrap().geotransform[0], minx);
    // A window outside the raster is a usage error.
    let bad = wavemesh(&[
        "decode",
        s(&ezw),
        "-o",
        s(&out),
        "--window",
        "1000,0,100,10",
    ]);
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn budgets_and_damage_on_tiled_files() {
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 900, 600);
    let ezw = dir.path().join("b.ezw");
    let lossy = json(&[
        "encode",
        s(&tif),
        "-o",
        s(&ezw),
        "--tile",
        "256",
        "--bpp",
        "0.5",
        "--json",
    ]);
    assert!(lossy["bytes"].as_u64().unwrap() <= (0.5 * 900.0 * 600.0 / 8.0) as u64);
    let lossless = dir.path().join("l.ezw");
    json(&[
        "encode",
        s(&tif),
        "-o",
        s(&lossless),
        "--tile",
        "256",
        "--json",
    ]);
    let out = dir.path().join("p.tif");
    let coarse = json(&[
        "decode",
        s(&lossless),
        "-o",
        s(&out),
        "--bpp",
        "0.5",
        "--reference",
        s(&tif),
        "--json",
    ]);
    let fine = json(&[
        "decode",
        s(&lossless),
        "-o",
        s(&out),
        "--bpp",
        "2",
        "--reference",
        s(&tif),
        "--json",
    ]);
    let rmse = |r: &serde_json::Value| r["distortion"]["rmse"].as_f64().unwrap();
    assert!(rmse(&fine) < rmse(&coarse));
    assert!(coarse["bytes_read"].as_u64().unwrap() <= (0.5 * 900.0 * 600.0 / 8.0) as u64 + 65536);
    // Damage inside one tile: verify names it, decode warns and decodes the others.
    let (damaged, _) = damage_one_tile(&lossless, &out);
    // --strict refuses it, and leaves no output behind.
    let strict_out = dir.path().join("strict.tif");
    let strict = wavemesh(&["decode", s(&damaged), "-o", s(&strict_out), "--strict"]);
    assert_eq!(strict.status.code(), Some(3));
    assert!(!strict_out.exists());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(".wavemesh-tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    // An output that cannot be written: exit 4.
    let nowhere = dir.path().join("missing-folder").join("x.tif");
    assert_eq!(
        wavemesh(&["decode", s(&lossless), "-o", s(&nowhere)])
            .status
            .code(),
        Some(4)
    );
}

#[test]
fn a_4096_square_encode_holds_a_row_of_tiles_not_the_raster() {
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 4096, 4096);
    let ezw = dir.path().join("big.ezw");
    let report = json(&[
        "encode",
        s(&tif),
        "-o",
        s(&ezw),
        "--tile",
        "512",
        "--threads",
        "1",
        "--json",
    ]);
    let peak = report["encode_peak_heap_bytes"].as_u64().unwrap();
    let raster = 4096u64 * 4096 * 2;
    // One band of 512 rows (4 MiB) and one tile's coder (about 20 bytes a sample).
    assert!(
        peak < raster / 2,
        "peak heap {peak} for a {raster}-byte raster"
    );
}

#[test]
fn memory_does_not_grow_with_the_raster_width() {
    let dir = scratch("cli-tiles");
    let peaks = |width: u32| {
        let tif = dir.path().join(format!("tiled-{width}.tif"));
        let size = format!("{width}x512");
        json(&["synth", s(&tif), "--size", &size, "--tile", "512", "--json"]);
        let ezw = dir.path().join("wide.ezw");
        let out = dir.path().join("wide.tif");
        let encoded = json(&["encode", s(&tif), "-o", s(&ezw), "--json"]);
        let decoded = json(&["decode", s(&ezw), "-o", s(&out), "--json"]);
        assert_eq!(
            read(&out),
            read(&tif),
            "lossless round trip at {width} across"
        );
        std::fs::remove_file(&tif).unwrap();
        let peak = |report: &serde_json::Value, key: &str| report[key].as_u64().unwrap();
        (
            peak(&encoded, "encode_peak_heap_bytes"),
            peak(&decoded, "decode_peak_heap_bytes"),
        )
    };
    // A tiled GeoTIFF, one tile row of 1024 x 512 tiles coded and written in blocks of
    // 16 tiles, 16 MiB of i16 (the next read or decoded while the current one is coded
    // or written): the wider raster has four blocks a row where the narrower has two.
    // Its peak may hold one block more (a decoded block can wait for the writer while
    // the next is decoded, which two blocks a row leave no room for), never a row more.
    let (narrow, wide) = (peaks(32768), peaks(65536));
    let block = 16384 * 512 * 2;
    for (what, narrow, wide) in [("encode", narrow.0, wide.0), ("decode", narrow.1, wide.1)] {
        println!("{what} heap peak: {narrow} bytes at 32768 x 512, {wide} at 65536 x 512");
        assert!(
            wide < narrow + block + block / 8,
            "{what} peak heap {wide} at 65536 samples across against {narrow} at 32768"
        );
        // Full-width bands (the tile row and its overlap, this one and the next) alone
        // would take more.
        let two_rows = 2 * 65536 * 512 * 2;
        assert!(
            wide < two_rows,
            "{what} peak heap {wide}, two full-width bands {two_rows}"
        );
    }
}

#[test]
fn views_of_a_tiled_file_say_they_need_one_stream() {
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 300, 200);
    let ezw = dir.path().join("v.ezw");
    json(&["encode", s(&tif), "-o", s(&ezw), "--tile", "128", "--json"]);
    let view = [
        "view",
        s(&ezw),
        "--camera",
        "150,-200,3000",
        "--look",
        "150,100,0",
    ];
    let glb = dir.path().join("v.glb");
    for args in [
        [&view[..], &["-o", s(&glb)]].concat(),
        vec!["flythrough", s(&ezw), "--orbit", "--frames", "2"],
    ] {
        let out = wavemesh(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{args:?}: {stderr}");
        assert!(
            stderr.trim().ends_with(
                "views need a single-stream file: this one is tiled (encode with --tile 0)"
            ) && stderr.lines().count() == 1,
            "{args:?}: {stderr}"
        );
    }
    assert!(!glb.exists());
}

#[test]
fn code_blocks_stream_like_memory_and_name_their_damage() {
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 1100, 600);
    let encode = |name: &str, extra: &[&str]| {
        let path = dir.path().join(name);
        let mut args = vec![
            "encode",
            s(&tif),
            "-o",
            s(&path),
            "--block",
            "256",
            "--json",
        ];
        args.extend_from_slice(extra);
        json(&args);
        std::fs::read(&path).unwrap()
    };
    // Lossless, 9/7 at a rate, and 5/3 cut a little below its lossless size: no block
    // reaches its cap there, only the budget's cut makes the tiles lossy.
    let lossless_bpp = encode("one.ezw", &[]).len() as f64 * 8.0 / (1100.0 * 600.0);
    let near = format!("{:.3}", 0.95 * lossless_bpp);
    for rate in [
        &[][..],
        &["--bpp", "0.5"],
        &["--bpp", &near, "--wavelet", "53"],
    ] {
        let streamed = encode("one.ezw", &[&["--threads", "1"], rate].concat());
        assert_eq!(
            streamed,
            encode("two.ezw", &[&["--threads", "2"], rate].concat())
        );
        // --verify encodes in memory: the same bytes again.
        assert_eq!(
            streamed,
            encode("memory.ezw", &[&["--verify"], rate].concat())
        );
    }
    let cut = json(&["info", s(&dir.path().join("one.ezw")), "--json"]);
    assert_eq!(cut["mode"], "lossy", "a 5/3 file cut below its size");
    let lossless = dir.path().join("one.ezw");
    encode("one.ezw", &[]);
    let info = json(&["info", s(&lossless), "--json"]);
    // 1100 = 2 tiles of 768 (whole blocks of 256; the last 332), 600 = one.
    assert_eq!(
        (info["tiles"].as_u64(), info["tile_width"].as_u64()),
        (Some(2), Some(768))
    );
    assert_eq!(
        (info["code_block"].as_u64(), info["blocks"].as_u64()),
        (Some(256), Some(15))
    );
    let out = dir.path().join("out.tif");
    json(&["decode", s(&lossless), "-o", s(&out), "--json"]);
    assert_eq!(read(&out).samples, read(&tif).samples);
    // A window reads the blocks around it, not the file.
    let window = json(&[
        "decode",
        s(&lossless),
        "-o",
        s(&out),
        "--window",
        "300,300,50,50",
        "--json",
    ]);
    let file_bytes = window["file_bytes"].as_u64().unwrap();
    assert!(window["bytes_read"].as_u64().unwrap() < file_bytes / 2 + 65536);
    let (_, said) = damage_one_tile(&lossless, &out);
    assert!(said.contains("code block"), "{said}");
    // Sides that are not multiples of 64: a usage error.
    let bad = wavemesh(&["encode", s(&tif), "-o", s(&out), "--block", "100"]);
    assert_eq!(bad.status.code(), Some(2));
}

#[test]
fn a_small_tiled_file_decoded_at_a_rate_reports_that_rate_and_reads_each_byte_once() {
    // The readers probe 64 KiB for the header and index, more than this whole file: the
    // probes are read again for each tile row, but a byte read twice counts once, and the
    // rate is that of the bytes the image needed, not of the file.
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 256, 256);
    let ezw = dir.path().join("small.ezw");
    let out = dir.path().join("out.tif");
    json(&[
        "encode",
        s(&tif),
        "-o",
        s(&ezw),
        "--tile",
        "128",
        "--bpp",
        "1",
        "--json",
    ]);
    let file_bytes = std::fs::metadata(&ezw).unwrap().len();
    let report = json(&["decode", s(&ezw), "-o", s(&out), "--bpp", "0.25", "--json"]);
    assert_eq!(report["tiles"], 4);
    assert_eq!(report["bytes_read"].as_u64().unwrap(), file_bytes);
    let used = report["bytes_used"].as_u64().unwrap();
    assert!(used <= 256 * 256 / 32, "{used} bytes used for 0.25 bpp");
    let bpp = report["bpp"].as_f64().unwrap();
    assert_eq!(bpp, used as f64 * 8.0 / (256.0 * 256.0));
}

#[test]
fn streaming_and_in_memory_encodes_settle_on_the_same_wavelet() {
    // A noisy raster takes the 5/3 and a fractal one the 13/11; both are read by tile
    // rows when streamed, and the wavelet is settled on the raster's centre either way.
    let dir = scratch("cli-tiles");
    let (width, height) = (700usize, 600usize);
    let mut state = 0x0005_DEEC_E66Du64;
    let noisy: Vec<i16> = (0..width * height)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((i % width) / 4) as i16 + (state % 400) as i16
        })
        .collect();
    let noisy_tif = dir.path().join("noisy.tif");
    let raster = wavemesh_codec::Raster::new(width, height, wavemesh_codec::Samples::I16(noisy));
    wavemesh::dem::write_dem(&noisy_tif, &raster.unwrap()).unwrap();
    let fractal_tif = synth(dir.path(), 700, 600);
    for (tif, wavelet) in [(&noisy_tif, "5/3"), (&fractal_tif, "13/11")] {
        let (streamed, memory) = (dir.path().join("s.ezw"), dir.path().join("m.ezw"));
        let report = json(&[
            "encode",
            s(tif),
            "-o",
            s(&streamed),
            "--tile",
            "256",
            "--json",
        ]);
        assert_eq!(report["wavelet"], wavelet, "{}", tif.display());
        let args = [
            "encode",
            s(tif),
            "-o",
            s(&memory),
            "--tile",
            "256",
            "--verify",
        ];
        json(&[&args[..], &["--json"]].concat());
        assert_eq!(
            std::fs::read(&streamed).unwrap(),
            std::fs::read(&memory).unwrap(),
            "{}: streaming differs from memory",
            tif.display()
        );
    }
}

#[test]
fn a_budget_the_lossless_file_fits_writes_it_streamed_or_not() {
    let dir = scratch("cli-tiles");
    let tif = synth(dir.path(), 700, 600);
    // The same heights in feet, as floats off any grid, with a NaN void.
    let feet = dir.path().join("feet.tif");
    let metres = read_dem(&tif, &ReadOptions::default()).unwrap();
    let heights: Vec<f32> = (0..metres.len())
        .map(|i| match (i % 700, i / 700) {
            (100..300, 50..200) => f32::NAN,
            _ => metres.samples.get_f64(i) as f32 * 3.28084,
        })
        .collect();
    let mut floats =
        wavemesh_codec::Raster::new(700, 600, wavemesh_codec::Samples::F32(heights)).unwrap();
    floats.nodata = Some(f64::NAN);
    wavemesh::dem::write_dem(&feet, &floats).unwrap();
    for tif in [&tif, &feet] {
        let lossless = dir.path().join("l.ezw");
        let tiled = ["encode", s(tif), "--tile", "256"];
        let exact = json(&[&tiled[..], &["-o", s(&lossless), "--json"]].concat());
        let bytes = std::fs::read(&lossless).unwrap();
        let bpp = format!("{:.3}", 1.02 * bytes.len() as f64 * 8.0 / (700.0 * 600.0));
        let (streamed, memory) = (dir.path().join("s.ezw"), dir.path().join("m.ezw"));
        let args = [&tiled[..], &["--bpp", &bpp]].concat();
        let report = json(&[&args[..], &["-o", s(&streamed), "--json"]].concat());
        assert_eq!(report["wavelet"], exact["wavelet"], "{}", tif.display());
        assert_eq!(std::fs::read(&streamed).unwrap(), bytes);
        json(&[&args[..], &["-o", s(&memory), "--verify", "--json"]].concat());
        assert_eq!(std::fs::read(&memory).unwrap(), bytes);
        let text = stdout(&[&args[..], &["-o", s(&streamed)]].concat());
        assert!(text.contains("the lossless file fits the budget"), "{text}");
        // Asked for, the 9/7 it is.
        let forced = json(
            &[
                &args[..],
                &["-o", s(&streamed), "--wavelet", "97", "--json"],
            ]
            .concat(),
        );
        assert_eq!(forced["wavelet"], "9/7");
    }
}
