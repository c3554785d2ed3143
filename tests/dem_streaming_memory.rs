//! Streaming GeoTIFF I/O in bounded memory, measured with the counting allocator (in its
//! own test binary, the tests serialised, so nothing else allocates meanwhile): reading a
//! synthetic DEM by 256-row bands holds a band and one row of chunks, and writing it holds
//! one row of tiles, far below the raster's size.
//!
//! The 16384² figures (throughput and heap peak) come from the ignored test:
//! `cargo test --release --test dem_streaming_memory -- --ignored --nocapture`.

mod support;

use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use wavemesh::dem::{ReadOptions, RowBands, TiledGeoTiffWriter};
use wavemesh::memory::{measure, CountingAllocator};
use wavemesh::synth::{write_tiled_geotiff, FractalTerrain};
use wavemesh_codec::Samples;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// One measurement at a time: the allocator's counters are global.
static SERIAL: Mutex<()> = Mutex::new(());

/// Rows a band holds.
const BAND_ROWS: usize = 256;

/// The sum of every sample of `path`, read by bands, with the rows per second.
fn sum_by_bands(path: &Path) -> (i64, f64) {
    let start = Instant::now();
    let mut bands = RowBands::open(path, &ReadOptions::default()).unwrap();
    let height = bands.info().height;
    let mut sum = 0i64;
    for y0 in (0..height).step_by(BAND_ROWS) {
        let band = bands.read_rows(y0, BAND_ROWS.min(height - y0)).unwrap();
        let Samples::I16(v) = &band.samples else {
            panic!("synth writes i16")
        };
        sum += v.iter().map(|&s| i64::from(s)).sum::<i64>();
    }
    (sum, start.elapsed().as_secs_f64())
}

/// Copies `from` into a GeoTIFF of 16-row strips at `to`, by bands.
fn restripe(from: &Path, to: &Path) {
    let mut bands = RowBands::open(from, &ReadOptions::default()).unwrap();
    let info = bands.info().clone();
    let mut writer = TiledGeoTiffWriter::create_striped(to, &info, 16).unwrap();
    for y0 in (0..info.height).step_by(BAND_ROWS) {
        let band = bands
            .read_rows(y0, BAND_ROWS.min(info.height - y0))
            .unwrap();
        writer.write_rows(y0, &band).unwrap();
    }
    writer.finish().unwrap();
}

/// Writes a `side²` terrain tiled and stripped, reads both by bands; returns the heap
/// peaks (tiled write, restripe, tiled read, stripped read) and the two reads' seconds.
fn stream_both_layouts(dir: &Path, side: u32, tile: u32) -> ([usize; 4], [f64; 2]) {
    let tiled = dir.join("tiled.tif");
    let stripped = dir.join("stripped.tif");
    let terrain = FractalTerrain::new(4);
    let (written, write_peak) = measure(|| write_tiled_geotiff(&tiled, side, side, &terrain, tile));
    written.unwrap();
    let ((), restripe_peak) = measure(|| restripe(&tiled, &stripped));
    let ((tiled_sum, tiled_seconds), tiled_peak) = measure(|| sum_by_bands(&tiled));
    let ((strip_sum, strip_seconds), strip_peak) = measure(|| sum_by_bands(&stripped));
    assert_eq!(tiled_sum, strip_sum, "both layouts hold the same samples");
    (
        [write_peak, restripe_peak, tiled_peak, strip_peak],
        [tiled_seconds, strip_seconds],
    )
}

#[test]
fn a_4096_square_geotiff_streams_in_a_band_and_a_row_of_chunks() {
    let _serial = SERIAL.lock().unwrap();
    let scratch = support::scratch("dem_streaming_memory");
    let (side, tile) = (4096usize, 256usize);
    let ([write, restripe, tiled, stripped], [tiled_s, strip_s]) =
        stream_both_layouts(scratch.path(), side as u32, tile as u32);
    let msamples = (side * side) as f64 / 1e6;
    println!(
        "4096² heap peaks (bytes): tiled write {write}, restripe {restripe}, \
         tiled read {tiled} ({:.1} Msamples/s), stripped read {stripped} ({:.1} Msamples/s)",
        msamples / tiled_s,
        msamples / strip_s
    );
    let raster = side * side * 2;
    let band = side * BAND_ROWS * 2;
    let tile_row = side * tile * 2;
    let slack = 1 << 20;
    // Reading: the band plus one row of chunks (tiles: 256 rows; strips: 16 rows).
    assert!(tiled < band + tile_row + slack, "tiled read peak {tiled}");
    assert!(
        stripped < band + side * 16 * 2 + slack,
        "stripped read peak {stripped}"
    );
    // Writing: the caller's band, the row of tiles gathered and its compressed tiles.
    assert!(
        write < band + 2 * tile_row + slack,
        "tiled write peak {write}"
    );
    assert!(
        restripe < 2 * band + tile_row + slack,
        "restripe peak {restripe}"
    );
    for peak in [write, restripe, tiled, stripped] {
        assert!(peak < raster / 4, "peak {peak} of a {raster}-byte raster");
    }
}

#[test]
#[ignore = "16384² (512 MiB of samples): minutes; run with --ignored --nocapture"]
fn a_16384_square_geotiff_by_bands_throughput_and_peak() {
    let _serial = SERIAL.lock().unwrap();
    let scratch = support::scratch("dem_streaming_memory");
    let side = 16384u32;
    let start = Instant::now();
    let ([write, restripe, tiled, stripped], [tiled_s, strip_s]) =
        stream_both_layouts(scratch.path(), side, 512);
    let msamples = f64::from(side).powi(2) / 1e6;
    let mib = |bytes: usize| bytes as f64 / f64::from(1 << 20);
    println!(
        "16384² i16 (512 MiB of samples), 256-row bands: tiled (512²) read {:.1} Msamples/s, \
         peak {:.1} MiB; stripped (16 rows) read {:.1} Msamples/s, peak {:.1} MiB; \
         tiled write (synth) peak {:.1} MiB; restripe peak {:.1} MiB; all in {:.0} s",
        msamples / tiled_s,
        mib(tiled),
        msamples / strip_s,
        mib(stripped),
        mib(write),
        mib(restripe),
        start.elapsed().as_secs_f64()
    );
    assert!(tiled.max(stripped).max(write).max(restripe) < 64 << 20);
}
