//! `info` on a tiled file: the raster, the tile grid, and the estimated quality of a
//! decode at a few rates (from the index's ladders, as a decode would allocate them).

use std::path::Path;

use serde::Serialize;
use wavemesh::metrics;
use wavemesh_codec::tiles::{allocate, TiledLayout};
use wavemesh_codec::Mode;

use super::coding::{RasterReport, SCHEMA_VERSION};
use super::metadata_report::MetadataReport;
use super::print_json;

#[derive(Serialize)]
struct RateReport {
    bpp: f64,
    bytes: u64,
    estimated_rmse: f64,
    estimated_psnr_db: f64,
}

#[derive(Serialize)]
struct TiledInfoReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    file_bytes: u64,
    format_version: u16,
    #[serde(flatten)]
    raster: RasterReport,
    header_bytes: u64,
    index_bytes: u64,
    tile_width: usize,
    tile_height: usize,
    tiles: usize,
    /// Side of the code blocks the tiles are cut into (none: each tile one stream).
    code_block: Option<usize>,
    /// Code blocks in all.
    blocks: Option<usize>,
    tile_bytes_min: u64,
    tile_bytes_median: u64,
    tile_bytes_max: u64,
    truncated: bool,
    georeferenced: bool,
    geotransform: Option<[f64; 6]>,
    metadata: MetadataReport,
    /// Estimated quality of a decode at each rate (RMSE over all samples).
    rates: Vec<RateReport>,
}

/// Rates the report estimates, bits per sample.
const RATES: [f64; 7] = [0.05, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0];

/// Prints what `layout` says about the file (`file_len` bytes long).
pub fn run(input: &Path, json: bool, layout: &TiledLayout, file_len: u64) {
    let header = &layout.header;
    let starts = &layout.tile_entries;
    let mut lengths: Vec<u64> = starts
        .windows(2)
        .map(|pair| layout.entries[pair[0]..pair[1]].iter().map(|e| e.len).sum())
        .collect();
    lengths.sort_unstable();
    let code_block = layout.code_block();
    let report = TiledInfoReport {
        schema_version: SCHEMA_VERSION,
        command: "info",
        input,
        file_bytes: file_len,
        format_version: 2,
        raster: RasterReport::of(header),
        header_bytes: layout.header_len,
        index_bytes: layout.head_len() - layout.header_len,
        tile_width: layout.grid.tile_width,
        tile_height: layout.grid.tile_height,
        tiles: layout.grid.count(),
        code_block,
        blocks: code_block.map(|_| layout.entries.len() - layout.grid.count()),
        tile_bytes_min: lengths[0],
        tile_bytes_median: lengths[lengths.len() / 2],
        tile_bytes_max: lengths[lengths.len() - 1],
        truncated: file_len < layout.file_len(),
        georeferenced: header.georef.is_some(),
        geotransform: header.georef.as_ref().map(|g| g.geotransform),
        metadata: MetadataReport::new(&header.metadata),
        rates: rates(layout),
    };
    if json {
        print_json(&report);
    } else {
        print_text(&report);
    }
}

/// The estimated error of a decode at each of [`RATES`] the file can serve.
fn rates(layout: &TiledLayout) -> Vec<RateReport> {
    let header = &layout.header;
    let samples = header.sample_count() as f64;
    let range = header.valid_range.1 - header.valid_range.0;
    let lossless = header.mode == Mode::Lossless;
    RATES
        .iter()
        .filter_map(|&bpp| {
            let bytes = (bpp * samples / 8.0) as u64;
            let left = bytes.checked_sub(layout.head_len())?;
            let shares = allocate(&layout.entries, lossless, left)?;
            let error: f64 = layout
                .entries
                .iter()
                .zip(&shares)
                .map(|(entry, &share)| error_at(&entry.points(lossless), share))
                .sum();
            let rmse = (error / samples).sqrt();
            (bytes < layout.file_len()).then_some(RateReport {
                bpp,
                bytes,
                estimated_rmse: rmse,
                estimated_psnr_db: metrics::psnr(range, rmse),
            })
        })
        .collect()
}

/// The estimated error of a tile's decode of `bytes`: interpolated along a straight line
/// between the points around it.
fn error_at(points: &[(u64, f64)], bytes: u64) -> f64 {
    let k = points.partition_point(|p| p.0 <= bytes);
    match (k.checked_sub(1).map(|j| points[j]), points.get(k)) {
        (Some((from, e0)), Some(&(to, e1))) => {
            e0 + (e1 - e0) * (bytes - from) as f64 / (to - from) as f64
        }
        (Some((_, e)), None) => e,
        (None, _) => points[0].1,
    }
}

fn print_text(r: &TiledInfoReport) {
    println!(
        "{}: .ezw version {}, {} bytes, tiled",
        r.input.display(),
        r.format_version,
        r.file_bytes
    );
    r.raster.print_kind();
    println!(
        "  values {}, nodata {}{}",
        r.raster.values(),
        r.raster.nodata(),
        if r.georeferenced {
            ", georeferenced"
        } else {
            ""
        }
    );
    let blocks = match (r.code_block, r.blocks) {
        (Some(side), Some(count)) => format!(" in {count} code blocks of {side}x{side}"),
        _ => String::new(),
    };
    println!(
        "  {} tiles of {}x{}{blocks}: header {} B, index {} B, tiles {} .. {} B (median {}){}",
        r.tiles,
        r.tile_width,
        r.tile_height,
        r.header_bytes,
        r.index_bytes,
        r.tile_bytes_min,
        r.tile_bytes_max,
        r.tile_bytes_median,
        if r.truncated { ", TRUNCATED" } else { "" }
    );
    for line in r.metadata.lines() {
        println!("{line}");
    }
    println!(
        "  {:>6} {:>12} {:>12} {:>9}",
        "bpp", "bytes", "est. RMSE", "est. PSNR"
    );
    for rate in &r.rates {
        println!(
            "  {:>6} {:>12} {:>12.4} {:>9.2}",
            rate.bpp, rate.bytes, rate.estimated_rmse, rate.estimated_psnr_db
        );
    }
}
