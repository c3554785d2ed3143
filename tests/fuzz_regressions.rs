//! Replays the fuzzing inputs of the DEM reader targets on stable: every file under
//! `fuzz/regressions/<target>/` (inputs that once crashed or hung) and the seed corpora
//! `fuzz/corpus/<target>/`, through the same harness the `cargo fuzz` targets call
//! ([`wavemesh::fuzzing::read_arbitrary`]). The codec targets are replayed by
//! `codec/tests/fuzz_regressions.rs`.
//!
//! The ignored test `make_seeds` (re)writes the seed corpora of every target from crops of
//! `samples/`:
//! `cargo test --release --test fuzz_regressions -- --ignored make_seeds`.

mod support;

use std::fs;
use std::path::{Path, PathBuf};

use wavemesh::dem::{read_dem, write_dem, DemFormat, ReadOptions};
use wavemesh::fuzzing::read_arbitrary;
use wavemesh_codec::fuzzing::PARAMS;
use wavemesh_codec::{encode, EncodeOptions, Quality, Raster, Samples, Wavelet};

/// The reader targets and the format each one reads.
const READERS: [(&str, DemFormat); 5] = [
    ("read_tiff", DemFormat::GeoTiff),
    ("read_png", DemFormat::Png),
    ("read_hgt", DemFormat::Hgt),
    ("read_asc", DemFormat::Asc),
    ("read_terrain_rgb", DemFormat::TerrainRgb),
];

/// Regression inputs whose bug is not fixed yet: skipped by `replay_reader_inputs`, each
/// replayed by its own ignored test below. (Path under `fuzz/`, the bug.)
const OPEN: &[(&str, &str)] = &[];

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// The files directly inside `dir` (none if it does not exist), sorted.
fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

/// Replays the regressions and seeds of one target; returns (regressions, seeds).
fn replay(target: &str, run: impl Fn(&[u8])) -> (usize, usize) {
    let fuzz = fuzz_dir();
    let mut counts = [0, 0];
    for (k, kind) in ["regressions", "corpus"].into_iter().enumerate() {
        for path in files_in(&fuzz.join(kind).join(target)) {
            let relative = path
                .strip_prefix(&fuzz)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            if OPEN.iter().any(|(p, _)| *p == relative) {
                support::skipped(
                    &format!("fuzz_regressions {relative}"),
                    "open bug (see OPEN)",
                );
                continue;
            }
            let data = fs::read(&path).unwrap();
            eprintln!("replaying {relative}");
            run(&data);
            counts[k] += 1;
        }
    }
    (counts[0], counts[1])
}

#[test]
fn replay_reader_inputs() {
    let mut total = 0;
    for (target, format) in READERS {
        let (regressions, seeds) = replay(target, |data| read_arbitrary(data, format));
        println!("{target}: replayed {regressions} regression inputs and {seeds} seeds");
        total += regressions + seeds;
    }
    println!("replayed {total} files through the DEM readers");
    assert!(total > 0, "no fuzzing inputs found under fuzz/");
}

/// A `width × height` window of `raster` starting at (`x0`, `y0`), with its nodata.
fn crop(raster: &Raster, x0: usize, y0: usize, width: usize, height: usize) -> Raster {
    let values: Vec<f64> = (0..width * height)
        .map(|i| {
            raster
                .samples
                .get_f64((y0 + i / width) * raster.width + x0 + i % width)
        })
        .collect();
    let mut out = Raster::new(
        width,
        height,
        Samples::from_f64(raster.sample_type(), &values),
    )
    .unwrap();
    out.nodata = raster.nodata;
    out
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    assert!(
        bytes.len() <= 20_000,
        "seed {name} is {} bytes: keep seeds small",
        bytes.len()
    );
    fs::create_dir_all(dir).unwrap();
    fs::write(dir.join(name), bytes).unwrap();
}

/// A [`PARAMS`]-byte parameter block for `decode_prefix` / `roundtrip` (layout in
/// `wavemesh_codec::fuzzing::roundtrip`), followed by `samples`.
#[allow(clippy::too_many_arguments)]
fn harness_input(
    type_code: u8,
    width: usize,
    height: usize,
    style: u8,
    nodata: u8,
    mode: u8,
    bound: u8,
    budget: u16,
    samples: &[u8],
) -> Vec<u8> {
    let mut out = vec![0u8; PARAMS];
    out[0] = type_code;
    out[1] = (width - 1) as u8;
    out[2] = (height - 1) as u8;
    out[3] = style;
    out[4] = nodata;
    out[13] = mode;
    out[14] = bound;
    out[19..21].copy_from_slice(&budget.to_le_bytes());
    // Prefix lengths and the flipped bit (decode_prefix).
    for (k, v) in [40u16, 90, 150, 300, 700, 1200, 2500, 9000, 777]
        .into_iter()
        .enumerate()
    {
        out[22 + 2 * k..24 + 2 * k].copy_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(samples);
    out
}

/// Writes the seed corpora of every target into `fuzz/corpus/<target>/`.
#[test]
#[ignore = "writes fuzz/corpus; run by hand: -- --ignored make_seeds"]
fn make_seeds() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let corpus = fuzz_dir().join("corpus");
    let options = ReadOptions::default();
    let fault = read_dem(&root.join("samples/jacksboro_fault.tif"), &options).unwrap();
    let voids = read_dem(&root.join("samples/jacksboro_voids.tif"), &options).unwrap();
    // A window of the voids sample that holds a few voids.
    let (vx, vy) = (0..voids.height - 24)
        .step_by(4)
        .flat_map(|y| (0..voids.width - 32).step_by(4).map(move |x| (x, y)))
        .find(|&(x, y)| {
            let c = crop(&voids, x, y, 16, 12);
            let n = c.valid_mask().iter().filter(|&&m| !m).count();
            (8..40).contains(&n)
        })
        .expect("a window with a few voids");

    // decode_ezw: small valid streams of every kind (small rasters keep the fuzzer fast).
    let small = crop(&fault, 120, 100, 16, 12);
    let mut georef_small = crop(&fault, 200, 150, 16, 12);
    georef_small.georef = fault.georef.clone();
    let with_voids = crop(&voids, vx, vy, 16, 12);
    let floats = {
        let values: Vec<f32> = small
            .samples
            .to_f64()
            .iter()
            .map(|v| (v / 7.0) as f32)
            .collect();
        Raster::new(small.width, small.height, Samples::F32(values)).unwrap()
    };
    let on_grid = {
        let values: Vec<f32> = small
            .samples
            .to_f64()
            .iter()
            .map(|v| (v * 0.1) as f32)
            .collect();
        let mut r = Raster::new(small.width, small.height, Samples::F32(values)).unwrap();
        if let Samples::F32(v) = &mut r.samples {
            v[5] = f32::NAN;
            v[100] = f32::NAN;
            v[101] = f32::NAN;
        }
        r
    };
    let wide = {
        // Smooth, wide-range u16: a cut 9/7 stream plus corrections wins here.
        let values: Vec<f64> = (0..64 * 48)
            .map(|i| {
                let (x, y) = ((i % 64) as f64, (i / 64) as f64);
                30000.0 + 20000.0 * (x * 0.21).sin() * (y * 0.13).cos()
            })
            .collect();
        Raster::new(
            64,
            48,
            Samples::from_f64(wavemesh_codec::SampleType::U16, &values),
        )
        .unwrap()
    };
    let tiny = Raster::new(5, 3, Samples::U8((0..15).map(|i| i * 17).collect())).unwrap();
    // Version 2's metadata block: GDAL band roles, an item, a CRS as WKT.
    let mut with_metadata = georef_small.clone();
    with_metadata.metadata = wavemesh_codec::Metadata {
        scale: Some(0.1),
        offset: Some(100.0),
        description: Some("elevation".into()),
        unit_type: Some("m".into()),
        crs_wkt: Some("GEOGCS[\"WGS 84\"]".into()),
        items: vec![wavemesh_codec::MetadataItem {
            name: "DTED_VerticalDatum".into(),
            value: "E08".into(),
            ..Default::default()
        }],
    };
    let lossless = EncodeOptions::new(Quality::Lossless, None);
    let streams: Vec<(&str, &Raster, EncodeOptions)> = vec![
        ("i16_lossless.ezw", &small, lossless.clone()),
        ("i16_georef_lossless.ezw", &georef_small, lossless.clone()),
        (
            "i16_max_error_2.ezw",
            &small,
            EncodeOptions::new(Quality::MaxError(2.0), None),
        ),
        (
            "i16_97_250_bytes.ezw",
            &small,
            EncodeOptions::new(Quality::Lossless, Some(250)),
        ),
        (
            "i16_53_200_bytes.ezw",
            &small,
            EncodeOptions::new(Quality::Lossless, Some(200)).with_wavelet(Wavelet::Int53),
        ),
        ("i16_voids_lossless.ezw", &with_voids, lossless.clone()),
        (
            "i16_voids_max_error_3.ezw",
            &with_voids,
            EncodeOptions::new(Quality::MaxError(3.0), None),
        ),
        ("f32_residuals_lossless.ezw", &floats, lossless.clone()),
        ("f32_grid_nan_lossless.ezw", &on_grid, lossless.clone()),
        (
            "f32_precision_0.05.ezw",
            &floats,
            EncodeOptions::new(Quality::Precision(0.05), None),
        ),
        (
            "u16_max_error_40.ezw",
            &wide,
            EncodeOptions::new(Quality::MaxError(40.0), None),
        ),
        ("u8_tiny_lossless.ezw", &tiny, lossless.clone()),
        (
            "i16_metadata_lossless.ezw",
            &with_metadata,
            lossless.clone(),
        ),
    ];
    for (name, raster, options) in &streams {
        let encoded = encode(raster, options).unwrap();
        println!(
            "{name}: {} bytes, {:?} {:?}",
            encoded.bytes.len(),
            encoded.header.wavelet,
            encoded.header.mode
        );
        // The version-1 seeds (made before version 2) stay as they are.
        for target in ["decode_ezw", "inspect_ezw"] {
            write(&corpus.join(target), &format!("v2_{name}"), &encoded.bytes);
        }
    }
    // Tiled files: small tiles (with their overlap), lossless, at a budget, with voids.
    let tiled = |quality, budget| EncodeOptions::new(quality, budget).with_tile_size(Some(8));
    let tiled_streams: Vec<(&str, &Raster, EncodeOptions)> = vec![
        (
            "tiled_i16_lossless.ezw",
            &small,
            tiled(Quality::Lossless, None),
        ),
        (
            "tiled_i16_97_300_bytes.ezw",
            &small,
            tiled(Quality::Lossless, Some(300)),
        ),
        (
            "tiled_i16_voids_max_error_3.ezw",
            &with_voids,
            tiled(Quality::MaxError(3.0), None),
        ),
        (
            "tiled_f32_lossless.ezw",
            &floats,
            tiled(Quality::Lossless, None),
        ),
    ];
    for (name, raster, options) in &tiled_streams {
        let encoded = encode(raster, options).unwrap();
        assert!(encoded.header.tiling.is_some(), "{name} is tiled");
        println!("{name}: {} bytes", encoded.bytes.len());
        for target in ["decode_ezw", "inspect_ezw"] {
            write(&corpus.join(target), &format!("v2_{name}"), &encoded.bytes);
        }
    }

    // decode_prefix and roundtrip: parameter block + sample bytes.
    let le_i16 = |r: &Raster| -> Vec<u8> {
        r.samples
            .to_f64()
            .iter()
            .flat_map(|&v| (v as i16).to_le_bytes())
            .collect()
    };
    let le_f32 = |r: &Raster| -> Vec<u8> {
        r.samples
            .to_f64()
            .iter()
            .flat_map(|&v| (v as f32).to_le_bytes())
            .collect()
    };
    for (target, side) in [("decode_prefix", 24usize), ("roundtrip", 32)] {
        let c = crop(&fault, 100, 90, side, side * 3 / 4);
        let cv = crop(&voids, vx, vy, side, side * 3 / 4);
        let (w, h) = (c.width, c.height);
        let fc: Vec<u8> = le_f32(&c)
            .chunks(4)
            .flat_map(|b| (f32::from_le_bytes(b.try_into().unwrap()) / 7.0).to_le_bytes())
            .collect();
        let seeds: Vec<(&str, Vec<u8>)> = vec![
            // type 2 = i16, style 0 = raw, nodata 0 = none, mode 0 = lossless.
            ("i16_lossless", harness_input(2, w, h, 0, 0, 0, 0, 0, &le_i16(&c))),
            // mode 1 = max-error, bound 3 = 2.0.
            ("i16_max_error_2", harness_input(2, w, h, 0, 0, 1, 3, 0, &le_i16(&c))),
            // mode 3 = 9/7 at a budget of 500 + 100 bytes.
            ("i16_97_budget", harness_input(2, w, h, 0, 0, 3, 0, 500, &le_i16(&c))),
            // mode 4 = 5/3 at a budget.
            ("i16_53_budget", harness_input(2, w, h, 0, 0, 4, 0, 300, &le_i16(&c))),
            // nodata 3 = the type's minimum (-32768, the voids' value).
            ("i16_voids_lossless", harness_input(2, w, h, 0, 3, 0, 0, 0, &le_i16(&cv))),
            ("i16_voids_max_error", harness_input(2, w, h, 0, 3, 1, 4, 0, &le_i16(&cv))),
            // type 4 = f32: lossless (residuals), precision 0.1 (bound 9).
            ("f32_lossless", harness_input(4, w, h, 0, 0, 0, 0, 0, &fc)),
            ("f32_precision", harness_input(4, w, h, 0, 0, 2, 9, 0, &fc)),
            ("f32_max_error", harness_input(4, w, h, 0, 1, 1, 1, 0, &fc)),
            // style 1 = smooth walk (scale 1000), u16 (type 1), max-error 10 (bound 6).
            (
                "u16_walk_max_error",
                harness_input(1, w, h, 1 | (3 << 2), 0, 1, 6, 0, &le_i16(&c)),
            ),
            // style 3 = special values, f32, nodata 1 = NaN.
            ("f32_special", harness_input(4, 9, 7, 3, 1, 0, 0, 0, b"\x00\x01\x02\x03\x04\x05\x06\x07\x08\x09\x0a\x0b\x0c\x0d\x0e\x0f")),
            // style 2 = four values, i32 (type 3), nodata 2 = the first sample.
            ("i32_palette", harness_input(3, 13, 11, 2, 2, 0, 0, 0, b"\x10\x00\x00\x00\xff\xff\x00\x00\x00\x00\x01\x80\x07\x00\x00\x00\xe4\x1b\x39\x93")),
            // u8, mode 5 = any combination.
            ("u8_combination", harness_input(0, 10, 6, 0, 0, 5 | 8 | 0x40, 2, 50, b"abcdefghijklmnopqrstuvwxyz")),
        ];
        for (name, bytes) in seeds {
            write(&corpus.join(target), name, &bytes);
        }
    }

    // Reader seeds: tiny files of each format.
    let dir = tempfile::tempdir().unwrap();
    let mut tif = crop(&fault, 60, 40, 12, 9);
    tif.georef = fault.georef.clone();
    let mut tif_voids = crop(&voids, vx, vy, 16, 12);
    tif_voids.georef = voids.georef.clone();
    let f32_tif = {
        let mut r = Raster::new(
            7,
            5,
            Samples::F32((0..35).map(|i| i as f32 * 0.37 - 3.0).collect()),
        )
        .unwrap();
        r.nodata = Some(-9999.0);
        r
    };
    let u8_raster = Raster::new(6, 4, Samples::U8((0..24).map(|i| i * 10).collect())).unwrap();
    let asc_raster = {
        let mut r = crop(&voids, vx, vy, 8, 6);
        r.georef = voids.georef.clone();
        r
    };
    let files: Vec<(&str, &str, &Raster)> = vec![
        ("read_tiff", "i16_georef.tif", &tif),
        ("read_tiff", "i16_voids.tif", &tif_voids),
        ("read_tiff", "f32_nodata.tif", &f32_tif),
        ("read_tiff", "u8.tif", &u8_raster),
        ("read_png", "u16.png", &tif),
        ("read_png", "u8.png", &u8_raster),
        ("read_asc", "i16_voids.asc", &asc_raster),
        ("read_asc", "f32_nodata.asc", &f32_tif),
    ];
    for (target, name, raster) in files {
        let path = dir.path().join(name);
        write_dem(&path, raster).unwrap();
        write(&corpus.join(target), name, &fs::read(&path).unwrap());
    }
    // .hgt: 3 x 3 and 4 x 4 big-endian i16, the second with a void.
    let hgt3: Vec<u8> = [100i16, 200, 300, -5, 0, 5, 1000, 2000, 3000]
        .iter()
        .flat_map(|v| v.to_be_bytes())
        .collect();
    write(&corpus.join("read_hgt"), "3x3.hgt", &hgt3);
    let hgt4: Vec<u8> = (0..16i16)
        .map(|i| if i == 6 { -32768 } else { i * 37 - 100 })
        .flat_map(|v| v.to_be_bytes())
        .collect();
    write(&corpus.join("read_hgt"), "4x4_void.hgt", &hgt4);
    // Terrain-RGB: 8-bit RGB and RGBA PNGs.
    for (name, color, channels) in [
        ("rgb.png", png::ColorType::Rgb, 3usize),
        ("rgba.png", png::ColorType::Rgba, 4),
    ] {
        let (w, h) = (6u32, 5u32);
        let mut data = Vec::new();
        for i in 0..(w * h) {
            // h = -10000 + code · 0.1 with heights 236..1076 m.
            let code = ((fault.samples.get_f64(i as usize * 50) + 10000.0) * 10.0) as u32;
            data.extend_from_slice(&[(code >> 16) as u8, (code >> 8) as u8, code as u8]);
            if channels == 4 {
                data.push(255);
            }
        }
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, w, h);
        encoder.set_color(color);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().unwrap();
        writer.write_image_data(&data).unwrap();
        writer.finish().unwrap();
        write(&corpus.join("read_terrain_rgb"), name, &out);
    }
}
