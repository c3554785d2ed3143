//! `synth`: a fractal test DEM of any size, written strip by strip or tile row by tile row.

use std::path::{Path, PathBuf};

use serde::Serialize;
use wavemesh::synth::{write_geotiff, write_tiled_geotiff, FractalTerrain};

use super::coding::SCHEMA_VERSION;
use super::{print_json, timed, with_progress, CliError};

#[derive(Debug, clap::Args)]
pub struct SynthArgs {
    /// Output GeoTIFF (i16 metres, UTM 32N, 10 m pixels; BigTIFF past 4 GiB).
    output: PathBuf,
    /// Raster size, WIDTHxHEIGHT (e.g. 16384x16384).
    #[arg(long, value_parser = parse_size)]
    size: (u32, u32),
    /// Seed of the terrain: the same seed and size give the same file.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write N x N tiles (a multiple of 16) instead of 16-row strips.
    #[arg(long, value_name = "N", value_parser = parse_tile)]
    tile: Option<u32>,
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    json: bool,
}

/// `WIDTHxHEIGHT`, both positive.
fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let parse = |part: &str| part.trim().parse::<u32>().ok().filter(|&n| n > 0);
    match text.split_once(['x', 'X']) {
        Some((w, h)) => match (parse(w), parse(h)) {
            (Some(w), Some(h)) => Ok((w, h)),
            _ => Err(format!(
                "expected WIDTHxHEIGHT with positive sides, got {text}"
            )),
        },
        None => Err(format!("expected WIDTHxHEIGHT, got {text}")),
    }
}

/// A tile side TIFF allows: a positive multiple of 16.
fn parse_tile(text: &str) -> Result<u32, String> {
    match text.trim().parse::<u32>() {
        Ok(n) if n > 0 && n.is_multiple_of(16) => Ok(n),
        _ => Err(format!(
            "expected a positive multiple of 16 (TIFF's rule for tiles), got {text}"
        )),
    }
}

#[derive(Serialize)]
struct SynthReport<'a> {
    schema_version: u32,
    command: &'static str,
    output: &'a Path,
    width: u32,
    height: u32,
    seed: u64,
    bytes: u64,
    seconds: f64,
    msamples_per_second: f64,
    peak_heap_bytes: u64,
}

pub fn run(args: &SynthArgs) -> Result<(), CliError> {
    let (width, height) = args.size;
    let terrain = FractalTerrain::new(args.seed);
    let (written, seconds, peak) = with_progress("writing terrain", || {
        timed(|| match args.tile {
            Some(tile) => write_tiled_geotiff(&args.output, width, height, &terrain, tile)
                .map_err(CliError::DemOutput),
            None => {
                write_geotiff(&args.output, width, height, &terrain).map_err(CliError::DemOutput)
            }
        })
    });
    written?;
    let bytes = std::fs::metadata(&args.output).map_or(0, |m| m.len());
    let samples = f64::from(width) * f64::from(height);
    let report = SynthReport {
        schema_version: SCHEMA_VERSION,
        command: "synth",
        output: &args.output,
        width,
        height,
        seed: args.seed,
        bytes,
        seconds,
        msamples_per_second: samples / seconds / 1e6,
        peak_heap_bytes: peak as u64,
    };
    if args.json {
        print_json(&report);
    } else {
        println!(
            "{}: {width}x{height} fractal terrain (seed {}), {bytes} bytes, {seconds:.2} s ({:.1} MS/s), heap peak {} bytes",
            args.output.display(),
            args.seed,
            report.msamples_per_second,
            report.peak_heap_bytes
        );
    }
    Ok(())
}
