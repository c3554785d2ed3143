//! Streaming DEM I/O: `RowBands` gives, band by band, exactly what `read_dem` gives (the
//! shared DEMs, GDAL's re-layouts of them when `gdal_translate` is installed, synthetic
//! stripped and tiled GeoTIFFs of odd sizes), and `TiledGeoTiffWriter` round-trips every
//! sample type bit-exactly, for GDAL too when it is installed. The memory bound is checked
//! in `tests/dem_streaming_memory.rs` (its own binary, for the counting allocator).

mod support;

use std::path::{Path, PathBuf};
use std::process::Command;

use wavemesh::dem::TiledGeoTiffWriter;
use wavemesh::dem::{read_dem, write_dem, DemError, DemInfo, ReadOptions, RowBands};
use wavemesh::synth::{write_geotiff, write_tiled_geotiff, FractalTerrain};
use wavemesh::tiled_encode::encode_tiled;
use wavemesh_codec::{
    EncodeOptions, Georef, Metadata, MetadataItem, Quality, Raster, Samples, TileGrid, Window,
};

/// Every sample as its bit pattern, so NaN voids compare equal to themselves.
fn bits(samples: &Samples) -> Vec<u32> {
    match samples {
        Samples::U8(v) => v.iter().map(|&s| u32::from(s)).collect(),
        Samples::U16(v) => v.iter().map(|&s| u32::from(s)).collect(),
        Samples::I16(v) => v.iter().map(|&s| u32::from(s as u16)).collect(),
        Samples::I32(v) => v.iter().map(|&s| s as u32).collect(),
        Samples::F32(v) => v.iter().map(|s| s.to_bits()).collect(),
    }
}

/// The nodata value as bits (NaN equals NaN).
fn nodata_bits(nodata: Option<f64>) -> Option<u64> {
    nodata.map(f64::to_bits)
}

/// Asserts that `info` describes `raster` exactly.
fn assert_info_matches(info: &DemInfo, raster: &Raster, what: &str) {
    assert_eq!(
        (info.width, info.height, info.sample_type),
        (raster.width, raster.height, raster.sample_type()),
        "{what}"
    );
    assert_eq!(
        nodata_bits(info.nodata),
        nodata_bits(raster.nodata),
        "{what}"
    );
    assert_eq!(info.georef, raster.georef, "{what}");
    assert_eq!(info.metadata, raster.metadata, "{what}");
}

/// Reads `path` in bands of `rows` rows from the top and returns the samples' bits, checking
/// each band's shape and nodata on the way.
fn bands_in_order(path: &Path, rows: usize) -> Vec<u32> {
    let mut bands = RowBands::open(path, &ReadOptions::default()).unwrap();
    let info = bands.info().clone();
    let mut all = Vec::with_capacity(info.width * info.height);
    for y0 in (0..info.height).step_by(rows) {
        let n = rows.min(info.height - y0);
        let band = bands.read_rows(y0, n).unwrap();
        assert_eq!((band.width, band.height), (info.width, n));
        assert_eq!(nodata_bits(band.nodata), nodata_bits(info.nodata));
        assert!(band.georef.is_none());
        all.extend(bits(&band.samples));
    }
    all
}

/// Reads `path` in bands of `rows` rows from the bottom up (the slow path: every band
/// starts a new chunk row) and returns the samples' bits in raster order.
fn bands_bottom_up(path: &Path, rows: usize) -> Vec<u32> {
    let mut bands = RowBands::open(path, &ReadOptions::default()).unwrap();
    let (width, height) = (bands.info().width, bands.info().height);
    let mut all = vec![0; width * height];
    let starts: Vec<usize> = (0..height).step_by(rows).collect();
    for &y0 in starts.iter().rev() {
        let n = rows.min(height - y0);
        let band = bands.read_rows(y0, n).unwrap();
        all[y0 * width..(y0 + n) * width].copy_from_slice(&bits(&band.samples));
    }
    all
}

/// `RowBands` on `path` equals `read_dem` on `reference` (its info and, for every band
/// height, its samples).
fn assert_bands_equal(path: &Path, reference: &Raster, band_rows: &[usize]) {
    let what = path.display().to_string();
    let bands = RowBands::open(path, &ReadOptions::default()).unwrap();
    assert_info_matches(bands.info(), reference, &what);
    let expected = bits(&reference.samples);
    for &rows in band_rows {
        assert!(
            bands_in_order(path, rows) == expected,
            "{what}: bands of {rows}"
        );
    }
    assert!(bands_bottom_up(path, 37) == expected, "{what}: bottom up");
}

/// Every DEM file of the shared set that a reader takes: the GeoTIFFs, the PNGs, the .hgt.
fn shared_dem_files(dir: &Path) -> Vec<PathBuf> {
    let text = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
    let manifest: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut files = Vec::new();
    for dataset in manifest["datasets"].as_array().unwrap() {
        let listed = &dataset["files"];
        let originals = listed["original"].as_array().unwrap().iter();
        let names = originals.chain([&listed["tif"], &listed["png"]]);
        files.extend(names.filter_map(|f| f.as_str()).map(|f| dir.join(f)));
    }
    let readable = ["tif", "png", "hgt"];
    files.retain(|f| {
        f.extension()
            .is_some_and(|e| readable.iter().any(|r| e == *r))
    });
    files
}

#[test]
fn bands_equal_read_dem_on_every_shared_dem() {
    let Some(dir) = support::shared_dem("bands_equal_read_dem_on_every_shared_dem") else {
        return;
    };
    let files = shared_dem_files(&dir);
    assert!(files.len() >= 15, "{files:?}");
    let mut tiffs = 0;
    for path in files {
        match read_dem(&path, &ReadOptions::default()) {
            Ok(raster) => {
                tiffs += usize::from(path.extension().unwrap() == "tif");
                assert_bands_equal(&path, &raster, &[1, 5, 64, raster.height]);
            }
            // fuji.png is Terrain-RGB: refused alike without --terrain-rgb.
            Err(e) => assert_eq!(
                RowBands::open(&path, &ReadOptions::default())
                    .err()
                    .map(|b| b.to_string()),
                Some(e.to_string())
            ),
        }
    }
    assert_eq!(tiffs, 8);
}

/// `gdal_translate` options for each layout the reader must stream: strips of an odd
/// height, tiles of odd counts, COG, BigTIFF, big-endian, every compression and predictor.
const GDAL_LAYOUTS: [&[&str]; 7] = [
    &[
        "-co",
        "BLOCKYSIZE=7",
        "-co",
        "COMPRESS=LZW",
        "-co",
        "PREDICTOR=2",
    ],
    &[
        "-co",
        "TILED=YES",
        "-co",
        "BLOCKXSIZE=48",
        "-co",
        "BLOCKYSIZE=32",
        "-co",
        "COMPRESS=DEFLATE",
        "-co",
        "PREDICTOR=2",
    ],
    &[
        "-co",
        "TILED=YES",
        "-co",
        "BLOCKXSIZE=32",
        "-co",
        "BLOCKYSIZE=64",
        "-co",
        "COMPRESS=PACKBITS",
    ],
    &[
        "-co",
        "BIGTIFF=YES",
        "-co",
        "TILED=YES",
        "-co",
        "COMPRESS=DEFLATE",
    ],
    &[
        "-co",
        "ENDIANNESS=BIG",
        "-co",
        "TILED=YES",
        "-co",
        "BLOCKXSIZE=16",
        "-co",
        "BLOCKYSIZE=16",
    ],
    &[
        "-of",
        "COG",
        "-co",
        "BLOCKSIZE=128",
        "-co",
        "COMPRESS=DEFLATE",
    ],
    &[
        "-co",
        "BLOCKYSIZE=3",
        "-co",
        "COMPRESS=DEFLATE",
        "-co",
        "PREDICTOR=3",
    ],
];

/// Runs `gdal_translate` with `options` from `source` to `out`.
fn translate(gdal_translate: &Path, options: &[&str], source: &Path, out: &Path) {
    let status = Command::new(gdal_translate)
        .arg("-q")
        .args(options)
        .arg(source)
        .arg(out)
        .status()
        .unwrap();
    assert!(status.success(), "gdal_translate {options:?}");
}

#[test]
fn bands_stream_every_gdal_layout_exactly() {
    let test = "bands_stream_every_gdal_layout_exactly";
    let Some(dir) = support::shared_dem(test) else {
        return;
    };
    let Some(gdal_translate) = support::program(test, "gdal_translate", "Debian: gdal-bin") else {
        return;
    };
    let scratch = support::scratch("dem_streaming");
    let sources = [
        "alps_srtm_voids/alps_srtm_voids.tif",
        "srtm3_utm32_f32/srtm3_utm32_f32.tif",
        "alps_montblanc/alps_montblanc.tif",
    ];
    for source in sources {
        let source = dir.join(source);
        let reference = read_dem(&source, &ReadOptions::default()).unwrap();
        let float = reference.sample_type() == wavemesh_codec::SampleType::F32;
        for (i, layout) in GDAL_LAYOUTS.iter().enumerate() {
            // Predictor 3 is for floats, 2 for integers.
            if layout.contains(&"PREDICTOR=3") != float
                && layout.iter().any(|o| o.starts_with("PREDICTOR"))
            {
                continue;
            }
            let out = scratch.path().join(format!("layout{i}.tif"));
            let plain = scratch.path().join(format!("layout{i}_plain.tif"));
            translate(&gdal_translate, layout, &source, &out);
            // GDAL's own reading of the layout, as a plain stripped little-endian TIFF.
            translate(&gdal_translate, &[], &out, &plain);
            let again = read_dem(&out, &ReadOptions::default()).unwrap();
            let gdal = read_dem(&plain, &ReadOptions::default()).unwrap();
            assert!(bits(&again.samples) == bits(&gdal.samples), "{layout:?}");
            assert_eq!(nodata_bits(again.nodata), nodata_bits(reference.nodata));
            assert_eq!(again.georef, reference.georef, "{layout:?}");
            assert_bands_equal(&out, &again, &[29]);
        }
    }
}

#[test]
fn bands_equal_read_dem_on_synthetic_strips_and_tiles_of_odd_sizes() {
    let scratch = support::scratch("dem_streaming");
    let terrain = FractalTerrain::new(11);
    let (width, height) = (333, 250);
    let strips = scratch.path().join("strips.tif");
    let tiles = scratch.path().join("tiles.tif");
    write_geotiff(&strips, width, height, &terrain).unwrap();
    write_tiled_geotiff(&tiles, width, height, &terrain, 48).unwrap();
    let reference = read_dem(&strips, &ReadOptions::default()).unwrap();
    let tiled = read_dem(&tiles, &ReadOptions::default()).unwrap();
    assert_eq!(tiled, reference, "both layouts hold the same terrain");
    assert_eq!(reference.georef, Some(wavemesh::synth::utm32_georef()));
    let mut row = vec![0; width as usize];
    terrain.row_i16(123, &mut row);
    let Samples::I16(samples) = &reference.samples else {
        panic!("synth writes i16")
    };
    assert_eq!(
        &samples[123 * 333..124 * 333],
        &row[..],
        "row 123 is the terrain's"
    );
    for path in [&strips, &tiles] {
        assert_bands_equal(path, &reference, &[1, 16, 37, 48, 250]);
    }
    let chunk_rows = |path: &Path| {
        RowBands::open(path, &ReadOptions::default())
            .unwrap()
            .chunk_rows()
    };
    assert_eq!((chunk_rows(&strips), chunk_rows(&tiles)), (16, 48));
    let mut decoder = tiff::decoder::Decoder::new(std::fs::File::open(&tiles).unwrap()).unwrap();
    assert_eq!(decoder.get_chunk_type(), tiff::decoder::ChunkType::Tile);
    assert_eq!(decoder.chunk_dimensions(), (48, 48));
    decoder = tiff::decoder::Decoder::new(std::fs::File::open(&strips).unwrap()).unwrap();
    assert_eq!(decoder.get_chunk_type(), tiff::decoder::ChunkType::Strip);
}

#[test]
fn windows_equal_crops_of_read_dem_on_strips_and_tiles() {
    let scratch = support::scratch("dem_streaming");
    let terrain = FractalTerrain::new(12);
    let (width, height) = (333u32, 250u32);
    let strips = scratch.path().join("strips.tif");
    let tiles = scratch.path().join("tiles.tif");
    write_geotiff(&strips, width, height, &terrain).unwrap();
    write_tiled_geotiff(&tiles, width, height, &terrain, 48).unwrap();
    let reference = read_dem(&strips, &ReadOptions::default()).unwrap();
    // Inside one tile, across tile edges, on the raster's edges, one sample, whole rows.
    let windows = [
        (5, 7, 20, 30),
        (40, 40, 60, 17),
        (300, 200, 33, 50),
        (0, 0, 333, 250),
        (332, 249, 1, 1),
        (0, 100, 333, 3),
        (47, 95, 2, 2),
    ];
    for path in [&strips, &tiles] {
        let mut bands = RowBands::open(path, &ReadOptions::default()).unwrap();
        assert_eq!(bands.reads_columns(), path == &tiles, "{}", path.display());
        for (x, y, w, h) in windows {
            let window = Window {
                x,
                y,
                width: w,
                height: h,
            };
            let read = bands.read_window(window).unwrap();
            let expected = reference.crop(x, y, w, h);
            assert_eq!(
                read.samples,
                expected.samples,
                "{window:?} of {}",
                path.display()
            );
            // A band below kept rows gives the rows of both.
            if h > 1 {
                let above = reference.crop(x, y, w, 1);
                let below = Window {
                    y: y + 1,
                    height: h - 1,
                    ..window
                };
                let joined = bands.read_window_below(&above, below).unwrap();
                assert_eq!(joined.samples, expected.samples, "{window:?} joined");
            }
        }
        for (x, y, w, h) in [
            (0, 0, 0, 5),
            (330, 0, 4, 1),
            (0, 250, 1, 1),
            (usize::MAX, 0, 2, 2),
        ] {
            let window = Window {
                x,
                y,
                width: w,
                height: h,
            };
            let err = bands.read_window(window).unwrap_err();
            assert!(matches!(err, DemError::WindowOutOfRange { .. }), "{err}");
        }
    }
}

/// Encodes `path` as the command line does (`RowBands`, tiles of at most `tile`),
/// with blocks of `block_width` samples, into `out`; returns the file's bytes.
fn stream_encode(
    path: &Path,
    tile: usize,
    options: &EncodeOptions,
    block_width: usize,
    out: &Path,
) -> Vec<u8> {
    let mut bands = RowBands::open(path, &ReadOptions::default()).unwrap();
    let info = bands.info().clone();
    let grid = TileGrid::balanced(info.width, info.height, tile).unwrap();
    let mut rows = Vec::new();
    encode_tiled(
        &mut bands,
        &info,
        &grid,
        options,
        block_width,
        out,
        &mut |k| rows.push(k),
    )
    .unwrap();
    assert_eq!(
        rows,
        (1..=grid.rows()).collect::<Vec<_>>(),
        "every tile row reported once, in order"
    );
    std::fs::read(out).unwrap()
}

#[test]
fn streaming_encode_by_blocks_gives_the_in_memory_bytes() {
    let scratch = support::scratch("dem_streaming");
    let terrain = FractalTerrain::new(13);
    let tiles = scratch.path().join("tiles.tif");
    let strips = scratch.path().join("strips.tif");
    write_tiled_geotiff(&tiles, 700, 333, &terrain, 64).unwrap();
    write_geotiff(&strips, 700, 333, &terrain).unwrap();
    let raster = read_dem(&tiles, &ReadOptions::default()).unwrap();
    let out = scratch.path().join("out.ezw");
    for (quality, budget) in [(Quality::Lossless, None), (Quality::Lossless, Some(9000))] {
        for threads in [1, 2] {
            let options = EncodeOptions::new(quality, budget)
                .with_tile_size(Some(128))
                .with_threads(threads);
            let memory = wavemesh_codec::encode(&raster, &options).unwrap().bytes;
            // Tiles of 117 x 111 (6 across): blocks of 1, 2 and 4 tiles, and whole rows.
            for (path, block_width) in [
                (&tiles, 100),
                (&tiles, 256),
                (&tiles, 500),
                (&tiles, usize::MAX),
                (&strips, 256),
            ] {
                let streamed = stream_encode(path, 128, &options, block_width, &out);
                assert!(
                    streamed == memory,
                    "{budget:?} bytes, {threads} threads, blocks of {block_width} from {}: \
                     {} bytes streamed, {} in memory",
                    path.display(),
                    streamed.len(),
                    memory.len()
                );
            }
        }
    }
}

#[test]
fn read_rows_refuses_rows_outside_and_bands_over_the_limits() {
    let scratch = support::scratch("dem_streaming");
    let path = scratch.path().join("small.tif");
    write_tiled_geotiff(&path, 100, 90, &FractalTerrain::new(2), 32).unwrap();
    let mut bands = RowBands::open(&path, &ReadOptions::default()).unwrap();
    for (y0, rows) in [(0, 0), (80, 11), (90, 1), (usize::MAX, 2)] {
        let err = bands.read_rows(y0, rows).unwrap_err();
        assert!(matches!(err, DemError::WindowOutOfRange { .. }), "{err}");
    }
    // The raster (9000 samples) is over max_samples; a row of 4 tiles and 10 rows are not.
    let small = ReadOptions {
        max_samples: 4 * 32 * 32 + 100 * 10,
        ..ReadOptions::default()
    };
    let mut bands = RowBands::open(&path, &small).unwrap();
    assert_eq!(bands.read_rows(85, 5).unwrap().samples.len(), 500);
    assert!(bands.read_rows(10, 10).is_ok());
    let err = bands.read_rows(0, 11).unwrap_err();
    assert!(
        matches!(
            err,
            DemError::BandOverLimit {
                unit: "samples",
                ..
            }
        ),
        "{err}"
    );
    let limit = 2 * (4 * 32 * 32 + 100 * 4);
    let tight = ReadOptions {
        max_memory: limit,
        ..ReadOptions::default()
    };
    let mut bands = RowBands::open(&path, &tight).unwrap();
    assert!(bands.read_rows(0, 4).is_ok());
    let err = bands.read_rows(0, 5).unwrap_err().to_string();
    assert!(
        err.contains(&format!("more than the limit of {limit} bytes")),
        "{err}"
    );
}

/// A `width × height` raster of `samples`'s type with a nodata value, a georef and metadata.
fn raster_with_everything(samples: Samples, nodata: f64) -> Raster {
    let mut raster = Raster::new(101, 77, samples).unwrap();
    raster.nodata = Some(nodata);
    raster.georef = Some(Georef {
        geotransform: [600_000.0, 2.0, 0.0, 5_100_000.0, 0.0, -2.0],
        ..wavemesh::synth::utm32_georef()
    });
    raster.metadata = Metadata {
        scale: Some(0.5),
        offset: Some(-10.0),
        description: Some("Höhe".into()),
        unit_type: Some("m".into()),
        crs_wkt: None,
        items: vec![MetadataItem {
            name: "SOURCE".into(),
            value: "synthetic".into(),
            ..Default::default()
        }],
    };
    raster
}

/// One raster of each sample type, voids at every 13th sample.
fn every_type() -> Vec<Raster> {
    let n = 101 * 77;
    let void = |i: usize| i % 13 == 5;
    vec![
        raster_with_everything(
            Samples::U8(
                (0..n)
                    .map(|i| if void(i) { 255 } else { (i * 7 % 250) as u8 })
                    .collect(),
            ),
            255.0,
        ),
        raster_with_everything(
            Samples::U16(
                (0..n)
                    .map(|i| {
                        if void(i) {
                            0
                        } else {
                            (i * 1871 % 65000 + 1) as u16
                        }
                    })
                    .collect(),
            ),
            0.0,
        ),
        raster_with_everything(
            Samples::I16(
                (0..n)
                    .map(|i| {
                        if void(i) {
                            i16::MIN
                        } else {
                            (i as i16).wrapping_mul(37)
                        }
                    })
                    .collect(),
            ),
            -32768.0,
        ),
        raster_with_everything(
            Samples::I32(
                (0..n)
                    .map(|i| {
                        if void(i) {
                            -9999
                        } else {
                            (i as i32 - 3000) * 123_457
                        }
                    })
                    .collect(),
            ),
            -9999.0,
        ),
        raster_with_everything(
            Samples::F32(
                (0..n)
                    .map(|i| {
                        if void(i) {
                            f32::NAN
                        } else {
                            i as f32 * 0.37 - 800.25
                        }
                    })
                    .collect(),
            ),
            f64::NAN,
        ),
    ]
}

/// Writes `raster` with the tiled writer in bands of uneven heights.
fn write_tiled_by_bands(path: &Path, raster: &Raster, tile: u32) {
    write_tiled_by_bands_on(path, raster, tile, 1);
}

/// [`write_tiled_by_bands`], compressing on `threads` threads.
fn write_tiled_by_bands_on(path: &Path, raster: &Raster, tile: u32, threads: usize) {
    let mut writer = TiledGeoTiffWriter::create(path, &DemInfo::of(raster), tile)
        .unwrap()
        .with_threads(threads)
        .unwrap();
    let (width, height) = (raster.width, raster.height);
    let mut y0 = 0;
    for rows in [10, 32, 1, 17].iter().cycle() {
        let rows = (*rows).min(height - y0);
        let band = slice_rows(raster, y0, rows);
        writer.write_rows(y0, &band).unwrap();
        y0 += rows;
        if y0 == height {
            break;
        }
    }
    assert_eq!(y0 * width, raster.samples.len());
    writer.finish().unwrap();
}

/// Rows `y0..y0 + rows` of `raster` as a band.
fn slice_rows(raster: &Raster, y0: usize, rows: usize) -> Raster {
    let range = y0 * raster.width..(y0 + rows) * raster.width;
    let samples = match &raster.samples {
        Samples::U8(v) => Samples::U8(v[range].to_vec()),
        Samples::U16(v) => Samples::U16(v[range].to_vec()),
        Samples::I16(v) => Samples::I16(v[range].to_vec()),
        Samples::I32(v) => Samples::I32(v[range].to_vec()),
        Samples::F32(v) => Samples::F32(v[range].to_vec()),
    };
    Raster::new(raster.width, rows, samples).unwrap()
}

#[test]
fn tiled_writer_round_trips_every_sample_type_bit_exactly() {
    let scratch = support::scratch("dem_streaming");
    for raster in every_type() {
        let what = raster.sample_type().name();
        let path = scratch.path().join(format!("tiled_{what}.tif"));
        write_tiled_by_bands(&path, &raster, 32);
        let back = read_dem(&path, &ReadOptions::default()).unwrap();
        assert!(bits(&back.samples) == bits(&raster.samples), "{what}");
        assert_info_matches(&DemInfo::of(&back), &raster, what);
        let file = std::fs::File::open(&path).unwrap();
        let decoder = tiff::decoder::Decoder::new(file).unwrap();
        assert_eq!(decoder.chunk_dimensions(), (32, 32), "{what}");
    }
}

/// What `gdalinfo -json` says of `path` that both writers must agree on.
fn gdal_view(gdalinfo: &Path, path: &Path) -> serde_json::Value {
    let out = Command::new(gdalinfo)
        .args(["-json", "-checksum"])
        .arg(path)
        .output()
        .unwrap();
    assert!(out.status.success(), "gdalinfo {}", path.display());
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let band = &info["bands"][0];
    serde_json::json!({
        "size": info["size"],
        "geoTransform": info["geoTransform"],
        "crs": info["coordinateSystem"]["wkt"],
        "metadata": info["metadata"][""],
        "type": band["type"],
        "noDataValue": band["noDataValue"],
        "checksum": band["checksum"],
        "scale": band["scale"],
        "offset": band["offset"],
        "unit": band["unit"],
        "description": band["description"],
    })
}

#[test]
fn tiled_writer_takes_blocks_of_whole_tiles_in_any_order() {
    let scratch = support::scratch("dem_streaming");
    for raster in every_type() {
        let info = DemInfo::of(&raster);
        let (w, h) = (raster.width, raster.height);
        let path = scratch.path().join("blocks.tif");
        let mut writer = TiledGeoTiffWriter::create(&path, &info, 32).unwrap();
        // Blocks of 2 x 1 tiles (the last of a row and column cut by the raster's
        // edges), bottom row first, right to left.
        let mut blocks = Vec::new();
        for y in (0..h).step_by(32) {
            for x in (0..w).step_by(64) {
                blocks.push((x, y));
            }
        }
        for &(x, y) in blocks.iter().rev() {
            let part = raster.crop(x, y, 64.min(w - x), 32.min(h - y));
            writer.write_block((x, y), &part).unwrap();
        }
        writer.finish().unwrap();
        let back = read_dem(&path, &ReadOptions::default()).unwrap();
        assert_eq!(
            bits(&back.samples),
            bits(&raster.samples),
            "{}",
            raster.sample_type().name()
        );
        assert_info_matches(&DemInfo::of(&back), &raster, "blocks");
    }
}

#[test]
fn tiled_writer_files_do_not_depend_on_its_threads() {
    let scratch = support::scratch("dem_streaming");
    for raster in every_type() {
        let one = scratch.path().join("one.tif");
        let three = scratch.path().join("three.tif");
        write_tiled_by_bands_on(&one, &raster, 16, 1);
        write_tiled_by_bands_on(&three, &raster, 16, 3);
        let name = raster.sample_type().name();
        assert_eq!(
            std::fs::read(&one).unwrap(),
            std::fs::read(&three).unwrap(),
            "{name}"
        );
        let back = read_dem(&three, &ReadOptions::default()).unwrap();
        assert_eq!(bits(&back.samples), bits(&raster.samples), "{name}");
    }
}

#[test]
fn tiled_writer_refuses_blocks_that_are_not_whole_tiles_once() {
    let scratch = support::scratch("dem_streaming");
    let raster = every_type().remove(2);
    let info = DemInfo::of(&raster);
    let path = scratch.path().join("refused.tif");
    let mut writer = TiledGeoTiffWriter::create(&path, &info, 32).unwrap();
    // Off the tile grid, a side neither whole tiles nor reaching the edge, past the edge.
    for (x, y, w, h) in [
        (16, 0, 32, 32),
        (0, 0, 40, 32),
        (96, 0, 3, 32),
        (0, 64, 32, 32),
    ] {
        let part = Raster::new(w, h, Samples::I16(vec![0; w * h])).unwrap();
        let err = writer.write_block((x, y), &part).unwrap_err();
        assert!(
            err.to_string().contains("not whole tiles"),
            "({x}, {y}): {err}"
        );
    }
    writer
        .write_block((0, 0), &raster.crop(0, 0, 32, 32))
        .unwrap();
    let err = writer
        .write_block((0, 0), &raster.crop(0, 0, 32, 32))
        .unwrap_err();
    assert!(err.to_string().contains("given twice"), "{err}");
    let err = writer
        .write_rows(0, &slice_rows(&raster, 0, 8))
        .unwrap_err();
    assert!(err.to_string().contains("written by blocks"), "{err}");
    let err = writer.finish().unwrap_err();
    assert!(err.to_string().contains("with 1 of"), "{err}");
    let left: Vec<_> = std::fs::read_dir(scratch.path()).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn gdal_reads_the_tiled_writer_as_it_reads_the_whole_raster_writer() {
    let test = "gdal_reads_the_tiled_writer_as_it_reads_the_whole_raster_writer";
    let Some(gdalinfo) = support::program(test, "gdalinfo", "Debian: gdal-bin") else {
        return;
    };
    let scratch = support::scratch("dem_streaming");
    for raster in every_type() {
        let what = raster.sample_type().name();
        let whole = scratch.path().join(format!("whole_{what}.tif"));
        let tiled = scratch.path().join(format!("tiled_{what}.tif"));
        write_dem(&whole, &raster).unwrap();
        write_tiled_by_bands(&tiled, &raster, 48);
        let (expected, seen) = (gdal_view(&gdalinfo, &whole), gdal_view(&gdalinfo, &tiled));
        assert_eq!(seen, expected, "{what}");
        assert!(seen["checksum"].is_number(), "{what}: {seen}");
        let out = Command::new(&gdalinfo).arg(&tiled).output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("Block=48x48"), "{what}: {text}");
        assert!(text.contains("COMPRESSION=DEFLATE"), "{what}: {text}");
    }
}

#[test]
fn tiled_writer_refuses_misuse_and_leaves_nothing_behind() {
    let scratch = support::scratch("dem_streaming");
    let raster = every_type().remove(2);
    let info = DemInfo::of(&raster);
    let path = scratch.path().join("refused.tif");
    let err = TiledGeoTiffWriter::create(&path, &info, 40).err().unwrap();
    assert!(err.to_string().contains("multiple of 16"), "{err}");
    let err = TiledGeoTiffWriter::create(Path::new("-"), &info, 32)
        .err()
        .unwrap();
    assert!(err.to_string().contains("regular file"), "{err}");

    let mut writer = TiledGeoTiffWriter::create(&path, &info, 32).unwrap();
    let narrow = Raster::new(100, 1, Samples::I16(vec![0; 100])).unwrap();
    assert!(matches!(
        writer.write_rows(0, &narrow),
        Err(DemError::InvalidRaster(_))
    ));
    let other_type = Raster::new(101, 1, Samples::U16(vec![0; 101])).unwrap();
    assert!(writer.write_rows(0, &other_type).is_err());
    writer.write_rows(0, &slice_rows(&raster, 0, 40)).unwrap();
    let err = writer
        .write_rows(41, &slice_rows(&raster, 41, 3))
        .unwrap_err();
    assert!(err.to_string().contains("row 40 comes next"), "{err}");
    let err = writer
        .write_rows(40, &slice_rows(&raster, 0, 40))
        .unwrap_err();
    assert!(err.to_string().contains("for a raster of 77 rows"), "{err}");
    let err = writer.finish().unwrap_err();
    assert!(err.to_string().contains("after 40 of 77 rows"), "{err}");

    let dropped = TiledGeoTiffWriter::create(&path, &info, 32).unwrap();
    drop(dropped);
    let left: Vec<_> = std::fs::read_dir(scratch.path()).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn synth_writes_tiles_with_tile_and_refuses_sides_tiff_forbids() {
    let scratch = support::scratch("dem_streaming");
    let path = scratch.path().join("synth.tif");
    let path_arg = support::s(&path);
    let report = support::json(&[
        "synth", path_arg, "--size", "100x50", "--tile", "32", "--json",
    ]);
    assert_eq!(report["width"], 100);
    let file = std::fs::File::open(&path).unwrap();
    let decoder = tiff::decoder::Decoder::new(file).unwrap();
    assert_eq!(decoder.get_chunk_type(), tiff::decoder::ChunkType::Tile);
    assert_eq!(decoder.chunk_dimensions(), (32, 32));
    let refused = support::wavemesh(&["synth", path_arg, "--size", "100x50", "--tile", "20"]);
    assert_eq!(refused.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(stderr.contains("multiple of 16"), "{stderr}");
}

#[test]
fn damaged_geotiffs_give_errors_by_bands_not_panics() {
    let scratch = support::scratch("dem_streaming");
    let whole = scratch.path().join("whole.tif");
    write_tiled_geotiff(&whole, 200, 150, &FractalTerrain::new(5), 64).unwrap();
    let bytes = std::fs::read(&whole).unwrap();
    let cut = scratch.path().join("cut.tif");
    // The tiles come first and the directory last: every cut loses the directory or data.
    for len in [8, 100, bytes.len() / 3, bytes.len() - 40, bytes.len() - 1] {
        std::fs::write(&cut, &bytes[..len]).unwrap();
        let read_all = || -> Result<(), DemError> {
            let mut bands = RowBands::open(&cut, &ReadOptions::default())?;
            for y0 in (0..150).step_by(40) {
                bands.read_rows(y0, 40.min(150 - y0))?;
            }
            Ok(())
        };
        assert!(read_all().is_err(), "cut at {len}");
    }
    // A tile's bytes scrambled: Deflate notices.
    let mut scrambled = bytes.clone();
    scrambled[200..400].fill(0xA5);
    std::fs::write(&cut, &scrambled).unwrap();
    let mut bands = RowBands::open(&cut, &ReadOptions::default()).unwrap();
    let err = bands.read_rows(0, 10).unwrap_err().to_string();
    assert!(err.contains("cut.tif"), "{err}");
}
