//! `encode`, `decode`, `info` and `compare`.

use std::path::{Path, PathBuf};

use serde::Serialize;
use wavemesh::byte_source::FileSource;
use wavemesh::metrics::{self, Distortion};
use wavemesh_codec::format::{physical_offset, valid_sample_count};
use wavemesh_codec::tiles::{read_header, unit_grid, TiledLayout};
use wavemesh_codec::TileGrid;
use wavemesh_codec::{
    decode as decode_stream, decode_window, encode as encode_raster, DecodeOptions, EncodeOptions,
    Header, Quality, Raster, Window,
};

use super::mesh::{mesh_decoded, print_mesh_summary, MeshOptions, MeshReport};
use super::metadata_report::MetadataReport;
use super::{
    print_json, timed, with_codec_progress, CliError, InputArgs, LimitArgs, WaveletArg, Workload,
};

/// Version of every JSON object the CLI prints.
pub const SCHEMA_VERSION: u32 = 1;

#[derive(Debug, clap::Args)]
pub struct EncodeArgs {
    /// Input DEM.
    pub(super) input: PathBuf,
    /// Output .ezw file.
    #[arg(short, long)]
    pub(super) output: PathBuf,
    /// Stop at this many bits per sample (whole file); lossy 9/7 unless --wavelet 53
    /// (the lossless file instead when it fits, unless --wavelet 97).
    #[arg(long, conflicts_with_all = ["max_error", "precision"])]
    bpp: Option<f64>,
    /// Keep every valid sample within E data units of the original (the smaller of a
    /// near-lossless 5/3 stream and a cut 9/7 stream with corrections).
    #[arg(long, value_name = "E", conflicts_with = "precision")]
    max_error: Option<f64>,
    /// Float rasters: quantise to STEP (error ≤ STEP/2) instead of coding exactly.
    #[arg(long, value_name = "STEP")]
    precision: Option<f64>,
    /// Transform: 97 (CDF 9/7, lossy) or 53 (integer 5/3). Default: 97 with --bpp, else 53.
    #[arg(long)]
    wavelet: Option<WaveletArg>,
    /// Decomposition levels (default: until the coarsest band is at most 8 samples wide).
    #[arg(long)]
    levels: Option<u32>,
    /// Largest tile side: a raster with a longer side is coded as independent tiles
    /// (as equal as the raster allows) with an index, so windows and rates read only
    /// what they need; 0 codes one stream whatever the size.
    #[arg(long, value_name = "N", default_value_t = wavemesh_codec::tiles::DEFAULT_TILE)]
    tile: u32,
    /// Code blocks of N samples a side (a multiple of 64): each tile becomes one
    /// transform whose blocks are coded and indexed on their own, so windows read only
    /// the blocks they need and tile borders do not show.
    #[arg(long, value_name = "N")]
    block: Option<u32>,
    #[command(flatten)]
    threads: ThreadArgs,
    /// Report PSNR/RMSE/max error of the encoded stream against this DEM.
    #[arg(long, value_name = "ORIGINAL")]
    reference: Option<PathBuf>,
    /// Leave out the source's free metadata items (licence, source text...): scale,
    /// offset, description, units and the CRS stay. Saves their bytes at low rates.
    #[arg(long)]
    pub(super) no_metadata_items: bool,
    /// Decode what was encoded and check it against the input before writing: bit-exact
    /// for lossless, every sample within the bound for --max-error. Nothing is written
    /// if the check fails.
    #[arg(long)]
    verify: bool,
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    pub(super) json: bool,
    #[command(flatten)]
    pub(super) input_args: InputArgs,
}

#[derive(Debug, clap::Args)]
pub struct DecodeArgs {
    /// Input .ezw file.
    input: PathBuf,
    /// Output DEM (.tif, .png or .asc).
    #[arg(short, long)]
    output: PathBuf,
    /// Decode only the first bpp·width·height/8 bytes of the file.
    #[arg(long, conflicts_with = "bytes")]
    bpp: Option<f64>,
    /// Decode only the first N bytes of the file (of a tiled file: N bytes in all, each
    /// tile's share chosen for the least error).
    #[arg(long, value_name = "N")]
    bytes: Option<u64>,
    /// Decode only this pixel window: first column, first row, width, height. A tiled
    /// file is read only where the window touches it.
    #[arg(long, value_name = "X,Y,W,H", conflicts_with = "bbox")]
    window: Option<String>,
    /// Decode only the samples inside this box, in the file's CRS units (north-up files).
    #[arg(long, value_name = "MINX,MINY,MAXX,MAXY", allow_hyphen_values = true)]
    bbox: Option<String>,
    #[command(flatten)]
    threads: ThreadArgs,
    /// Report PSNR/RMSE/max error of the decoded DEM against this one.
    #[arg(long, value_name = "ORIGINAL")]
    reference: Option<PathBuf>,
    /// Treat damage (a failed chunk checksum, trailing garbage) as an error instead of
    /// decoding the undamaged prefix with a warning.
    #[arg(long)]
    strict: bool,
    /// Also write the mesh of the decoder's zerotree (.glb, .obj or .ply).
    #[arg(long, value_name = "MESH")]
    mesh: Option<PathBuf>,
    #[command(flatten, next_help_heading = "Mesh (with --mesh)")]
    mesh_options: MeshOptions,
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten, next_help_heading = "Limits, and reading the --reference DEM")]
    input_args: InputArgs,
}

/// Threads for coding tiles.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct ThreadArgs {
    /// Threads at work (0: one per core; 1: everything on one thread, reading or writing
    /// the GeoTIFF included). The output does not depend on it.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub threads: usize,
}

#[derive(Debug, clap::Args)]
pub struct InfoArgs {
    /// The .ezw file.
    input: PathBuf,
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    limit_args: LimitArgs,
}

#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// The original DEM.
    original: PathBuf,
    /// The reconstruction.
    other: PathBuf,
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    input_args: InputArgs,
}

#[derive(Serialize)]
struct EncodeReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    output: &'a Path,
    width: u32,
    height: u32,
    sample_type: &'static str,
    wavelet: &'static str,
    levels: u8,
    mode: &'static str,
    max_error_bound: Option<f64>,
    bytes: u64,
    header_bytes: u64,
    mask_bytes: u64,
    bpp: f64,
    passes: usize,
    complete: bool,
    encode_seconds: f64,
    encode_msamples_per_second: f64,
    encode_peak_heap_bytes: u64,
    /// With --verify: the decoded stream's distortion against the input (checked).
    verified: Option<Distortion>,
    distortion: Option<Distortion>,
}

pub fn encode(args: &EncodeArgs) -> Result<(), CliError> {
    refuse_overwriting_input(&args.input, &args.output)?;
    let to_stdout = writes_to_stdout(&args.output, args.json)?;
    warn_about_output_extension(&args.output);
    if args.tile > 0 && !args.verify && args.reference.is_none() {
        let mut bands = args.input_args.open_bands(&args.input)?;
        let (width, height) = (bands.info().width, bands.info().height);
        let tile = args.tile as usize;
        let grid = match args.block {
            Some(side) => {
                check_block_side(side)?;
                unit_grid(width, height, tile, side as usize)
            }
            None => TileGrid::balanced(width, height, tile),
        };
        if let Some(grid) = grid {
            super::allocator::keep_freed_tile_buffers();
            let blocks = args.block.map(|side| side as usize);
            return super::tiled_coding::encode(args, &mut bands, (&grid, blocks), to_stdout);
        }
    }
    let mut raster = args.input_args.read_to_encode(&args.input)?;
    if args.no_metadata_items {
        raster.metadata.items.clear();
    }
    let options = encode_options(args, raster.len() as u64)?;
    let (encoded, seconds, peak) = with_codec_progress("encoding", Workload::of(&raster), || {
        timed(|| encode_raster(&raster, &options))
    });
    let encoded = encoded.map_err(CliError::Encode)?;
    let verified = if args.verify {
        Some(with_codec_progress(
            "verifying",
            Workload::of(&raster),
            || verify_encoding(&raster, &encoded),
        )?)
    } else {
        None
    };
    write_output(&args.output, &encoded.bytes)?;
    let distortion = match &args.reference {
        None => None,
        Some(path) => {
            let reference = args.input_args.read(path)?;
            let decoded = decode_stream(&encoded.bytes, &DecodeOptions::default())
                .map_err(|e| CliError::Stream(args.output.clone(), e))?;
            Some(compare_rasters(&reference, &decoded.raster, path)?)
        }
    };
    let facts = EncodeFacts {
        header: &encoded.header,
        header_len: encoded.header_len,
        bytes: encoded.bytes.len() as u64,
        seconds,
        peak,
    };
    print_encode_report(args, &facts, to_stdout, verified, distortion);
    Ok(())
}

/// What an encode made, for its report.
pub(super) struct EncodeFacts<'a> {
    pub(super) header: &'a Header,
    pub(super) header_len: usize,
    pub(super) bytes: u64,
    pub(super) seconds: f64,
    pub(super) peak: usize,
}

/// Prints the report of an encode (none when the data went to standard output).
pub(super) fn print_encode_report(
    args: &EncodeArgs,
    facts: &EncodeFacts,
    to_stdout: bool,
    verified: Option<Distortion>,
    distortion: Option<Distortion>,
) {
    let header = facts.header;
    let (seconds, samples) = (facts.seconds, header.sample_count() as f64);
    let report = EncodeReport {
        schema_version: SCHEMA_VERSION,
        command: "encode",
        input: &args.input,
        output: &args.output,
        width: header.width,
        height: header.height,
        sample_type: header.sample_type.name(),
        wavelet: header.wavelet.name(),
        levels: header.levels,
        mode: header.mode.name(),
        max_error_bound: header.max_error.is_finite().then_some(header.max_error),
        bytes: facts.bytes,
        header_bytes: facts.header_len as u64,
        mask_bytes: header.mask_len as u64,
        bpp: metrics::bits_per_sample(facts.bytes, header.width as usize, header.height as usize),
        passes: header.passes.len(),
        complete: !header.payload_truncated,
        encode_seconds: seconds,
        encode_msamples_per_second: samples / seconds / 1e6,
        encode_peak_heap_bytes: facts.peak as u64,
        verified,
        distortion,
    };
    if to_stdout {
        // The data went to standard output: no report beside it.
    } else if args.json {
        print_json(&report);
    } else {
        println!(
            "{} -> {}: {}x{} {}, {} {} ({}), {} bytes = {:.4} bpp, {:.3} s ({:.1} MS/s)",
            args.input.display(),
            args.output.display(),
            report.width,
            report.height,
            report.sample_type,
            report.wavelet,
            report.mode,
            report
                .max_error_bound
                .map_or("no error bound".to_string(), |e| format!("max error {e}")),
            report.bytes,
            report.bpp,
            seconds,
            report.encode_msamples_per_second
        );
        // (--bpp excludes --max-error and --precision.)
        if args.bpp.is_some() && args.wavelet.is_none() && header.wavelet.is_reversible() {
            println!(
                "  the lossless file fits the budget: written instead of a 9/7 one (--wavelet 97 forces that)"
            );
        }
        if let Some(v) = &report.verified {
            println!(
                "  verified: decoded and checked before writing ({})",
                verified_promise(v)
            );
        }
        if let Some(d) = &report.distortion {
            print_distortion(d);
        }
    }
}

/// Refuses a code block side the format cannot have.
fn check_block_side(side: u32) -> Result<(), CliError> {
    match side > 0 && side.is_multiple_of(64) {
        true => Ok(()),
        false => Err(CliError::Usage(format!(
            "--block must be a positive multiple of 64, got {side}"
        ))),
    }
}

/// The encoder's options as `args` give them, for a raster of `samples` samples.
pub(super) fn encode_options(args: &EncodeArgs, samples: u64) -> Result<EncodeOptions, CliError> {
    let budget = match args.bpp {
        Some(bpp) if bpp.is_finite() && bpp > 0.0 => {
            Some((bpp * samples as f64 / 8.0).floor() as u64)
        }
        Some(bpp) => {
            return Err(CliError::Usage(format!(
                "--bpp must be positive, got {bpp}"
            )))
        }
        None => None,
    };
    let quality = match (args.max_error, args.precision) {
        (Some(e), _) => Quality::MaxError(e),
        (_, Some(step)) => Quality::Precision(step),
        _ => Quality::Lossless,
    };
    let mut options = EncodeOptions::new(quality, budget);
    if let Some(w) = args.wavelet {
        options = options.with_wavelet(w.into());
    }
    if options.wavelet == wavemesh_codec::Wavelet::Cdf97 && budget.is_none() {
        return Err(CliError::Usage(
            "the 9/7 wavelet is lossy: give a rate with --bpp".into(),
        ));
    }
    options.levels = args.levels;
    options.tile_size = (args.tile > 0).then_some(args.tile);
    options.threads = args.threads.threads;
    options.code_block = args.block;
    Ok(options)
}

/// What `--verify` checked, in words.
fn verified_promise(d: &Distortion) -> String {
    if d.identical {
        "bit-exact".into()
    } else {
        format!("max error {} within the bound", d.max_error)
    }
}

/// Decodes `encoded` and checks the mode's promise against `raster`.
fn verify_encoding(
    raster: &Raster,
    encoded: &wavemesh_codec::Encoded,
) -> Result<Distortion, CliError> {
    let fail = |what: String| {
        CliError::CheckFailed(format!("verification failed: {what}; nothing was written"))
    };
    let decoded = decode_stream(&encoded.bytes, &DecodeOptions::default())
        .map_err(|e| fail(e.to_string()))?;
    if !decoded.complete || decoded.damage.is_some() {
        return Err(fail("the stream does not decode completely".into()));
    }
    let d = metrics::compare(raster, &decoded.raster).map_err(|e| fail(e.to_string()))?;
    if d.nodata_mismatches > 0 {
        return Err(fail(format!(
            "{} nodata samples differ",
            d.nodata_mismatches
        )));
    }
    let header = &encoded.header;
    match header.mode {
        wavemesh_codec::Mode::Lossless if !d.identical => Err(fail(format!(
            "lossless stream differs (max error {})",
            d.max_error
        ))),
        wavemesh_codec::Mode::MaxError | wavemesh_codec::Mode::Precision
            if d.max_error > header.max_error =>
        {
            Err(fail(format!(
                "max error {} exceeds the bound {}",
                d.max_error, header.max_error
            )))
        }
        _ => Ok(d),
    }
}

#[derive(Serialize)]
struct DecodeReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    output: &'a Path,
    width: u32,
    height: u32,
    /// The decoded window (x, y, width, height), when one was asked for.
    window: Option<[usize; 4]>,
    /// Tiles in the file (tiled files).
    tiles: Option<usize>,
    file_bytes: u64,
    /// Distinct bytes of the file read (headers and indexes probed included).
    bytes_read: u64,
    /// Bytes the decoded image needed: the prefix, or the tiles' prefixes and the head.
    bytes_used: u64,
    /// `bytes_used` in bits per sample of the whole raster.
    bpp: f64,
    passes_decoded: u32,
    /// Passes of the stream, the fewest of any tile (`null` with code blocks: each block
    /// has its own, not listed once cut).
    passes_total: Option<usize>,
    complete: bool,
    decode_seconds: f64,
    decode_msamples_per_second: f64,
    decode_peak_heap_bytes: u64,
    raster_bytes: u64,
    peak_heap_per_raster_byte: f64,
    damage: Option<DamageReport>,
    distortion: Option<Distortion>,
    mesh: Option<MeshReport>,
}

#[derive(Serialize)]
struct DamageReport {
    section: &'static str,
    offset: u64,
    tile: Option<u32>,
}

pub fn decode(args: &DecodeArgs) -> Result<(), CliError> {
    refuse_overwriting_input(&args.input, &args.output)?;
    let to_stdout = writes_to_stdout(&args.output, args.json)?;
    let stream_error = |e| CliError::Stream(args.input.clone(), e);
    let mut source = FileSource::open(&args.input)
        .map_err(|e| CliError::Input(args.input.clone(), e.to_string()))?;
    let limits = args.input_args.limits();
    let (header, header_len) = read_header(&mut source).map_err(stream_error)?;
    let layout = TiledLayout::read(&mut source, limits.max_memory / 4).map_err(stream_error)?;
    if layout.is_some() {
        super::allocator::keep_freed_tile_buffers();
    }
    let samples = header.sample_count();
    let max_bytes = match (args.bpp, args.bytes) {
        (Some(bpp), _) if bpp.is_finite() && bpp > 0.0 => {
            Some((bpp * samples as f64 / 8.0).floor() as u64)
        }
        (Some(bpp), _) => {
            return Err(CliError::Usage(format!(
                "--bpp must be positive, got {bpp}"
            )))
        }
        (None, bytes) => bytes,
    };
    let smallest = match &layout {
        Some(l) => l.head_len() + l.entries.iter().map(|e| e.head_len).sum::<u64>(),
        None => header_len as u64 + u64::from(header.mask_len),
    };
    let max_bytes = max_bytes.map(|asked| at_least_decodable(asked, smallest, samples));
    let window = requested_window(args, &header)?;
    let options = DecodeOptions::default()
        .with_max_bytes(max_bytes)
        .with_limits(limits)
        .with_strict(args.strict)
        .with_significance_map(args.mesh.is_some())
        .with_threads(args.threads.threads);
    check_mesh_args(args, &header, samples)?;
    // A whole tiled file to a GeoTIFF is decoded and written one tile row at a time.
    let streamed = layout.as_ref().filter(|_| {
        window.is_none()
            && args.mesh.is_none()
            && args.reference.is_none()
            && !to_stdout
            && wavemesh::dem::is_geotiff_path(&args.output)
    });
    let load = Workload::new(samples, header.sample_type);
    let (decoded, seconds, peak) = match streamed {
        Some(layout) => {
            let bar =
                super::tiled_coding::TileRowBar::new("decoding", &layout.grid, load, args.json);
            let out = timed(|| {
                super::tiled_coding::decode_to_geotiff(
                    (&args.input, &args.output),
                    &mut source,
                    layout,
                    &options,
                    &bar,
                )
                .map(|outcome| (outcome, None))
            });
            bar.finish();
            out
        }
        None => with_codec_progress("decoding", load, || {
            timed(|| {
                decode_window(&mut source, window, &options)
                    .map(|d| (DecodeOutcome::of(&d), Some(d)))
                    .map_err(stream_error)
            })
        }),
    };
    let (outcome, decoded) = decoded?;
    let bytes_read = match &layout {
        Some(_) => source.bytes_read(),
        None => max_bytes.map_or(source.len(), |m| m.min(source.len())),
    };
    if let Some(d) = outcome.damage {
        let what = match d.tile {
            Some(tile) => format!("tile {tile} ({})", d.section),
            None => d.section.to_string(),
        };
        eprintln!(
            "wavemesh: warning: {}: {what} damaged at byte {}; decoded what precedes it{} (--strict makes this an error)",
            args.input.display(),
            d.offset,
            if d.tile.is_some() { " and the other tiles" } else { "" },
        );
    }
    let (distortion, mesh) = match &decoded {
        Some(decoded) => write_decoded(args, decoded)?,
        None => (None, None),
    };
    let out_samples = (outcome.width * outcome.height) as u64;
    let raster_bytes = out_samples * header.sample_type.bytes() as u64;
    let report = DecodeReport {
        schema_version: SCHEMA_VERSION,
        command: "decode",
        input: &args.input,
        output: &args.output,
        width: outcome.width as u32,
        height: outcome.height as u32,
        window: window.map(|w| [w.x, w.y, w.width, w.height]),
        tiles: layout.as_ref().map(|l| l.grid.count()),
        file_bytes: source.len(),
        bytes_read,
        bytes_used: outcome.bytes_used,
        bpp: metrics::bits_per_sample(
            outcome.bytes_used,
            header.width as usize,
            header.height as usize,
        ),
        passes_decoded: outcome.passes_decoded,
        passes_total: match &layout {
            // A tiled file: the passes every tile has (passes_decoded is the least any
            // tile decoded).
            Some(l) if l.code_block().is_some() => None,
            Some(l) => Some(l.entries.iter().map(|e| e.passes.len()).min().unwrap_or(0)),
            None => Some(header.top_plane.map_or(0, |t| t as usize + 1)),
        },
        complete: outcome.complete,
        decode_seconds: seconds,
        decode_msamples_per_second: out_samples as f64 / seconds / 1e6,
        decode_peak_heap_bytes: peak as u64,
        raster_bytes,
        peak_heap_per_raster_byte: peak as f64 / raster_bytes as f64,
        damage: outcome.damage.map(|d| DamageReport {
            section: d.section,
            offset: d.offset,
            tile: d.tile,
        }),
        distortion,
        mesh,
    };
    if to_stdout {
        // The data went to standard output: no report beside it.
    } else if args.json {
        print_json(&report);
    } else {
        println!(
            "{} -> {}: {} of {} bytes ({:.4} bpp), {}/{} passes{}{}, {:.3} s ({:.1} MS/s)",
            args.input.display(),
            args.output.display(),
            report.bytes_used,
            report.file_bytes,
            report.bpp,
            report.passes_decoded,
            report
                .passes_total
                .map_or("?".to_string(), |total| total.to_string()),
            if report.tiles.is_some() {
                " (the fewest of any tile)"
            } else {
                ""
            },
            if report.complete { ", complete" } else { "" },
            seconds,
            report.decode_msamples_per_second
        );
        if let Some(d) = &report.distortion {
            print_distortion(d);
        }
        if let Some(m) = &report.mesh {
            print_mesh_summary(m);
        }
    }
    Ok(())
}

/// What a decode produced, for its report.
pub(super) struct DecodeOutcome {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) passes_decoded: u32,
    pub(super) complete: bool,
    pub(super) bytes_used: u64,
    pub(super) damage: Option<wavemesh_codec::Damage>,
}

impl DecodeOutcome {
    fn of(decoded: &wavemesh_codec::Decoded) -> DecodeOutcome {
        DecodeOutcome {
            width: decoded.raster.width,
            height: decoded.raster.height,
            passes_decoded: decoded.passes_decoded,
            complete: decoded.complete,
            bytes_used: decoded.bytes_used,
            damage: decoded.damage,
        }
    }
}

/// Writes a decode held in memory, then measures it against `--reference` and meshes
/// it with `--mesh` when asked.
fn write_decoded(
    args: &DecodeArgs,
    decoded: &wavemesh_codec::Decoded,
) -> Result<(Option<Distortion>, Option<MeshReport>), CliError> {
    if args.mesh.is_some() {
        args.mesh_options
            .check_raster(&decoded.raster, &args.input)?;
    }
    wavemesh::dem::write_dem(&args.output, &decoded.raster).map_err(CliError::DemOutput)?;
    let reference = match &args.reference {
        None => None,
        Some(path) => Some(args.input_args.read(path)?),
    };
    let distortion = match (&args.reference, &reference) {
        (Some(path), Some(reference)) => Some(compare_rasters(reference, &decoded.raster, path)?),
        _ => None,
    };
    let mesh = match &args.mesh {
        Some(path) => Some(mesh_decoded(
            decoded,
            &args.mesh_options,
            path,
            reference.as_ref(),
            args.input_args.max_memory(),
        )?),
        None => None,
    };
    Ok((distortion, mesh))
}

/// The window `--window` or `--bbox` asks for, if any.
fn requested_window(args: &DecodeArgs, header: &Header) -> Result<Option<Window>, CliError> {
    let numbers = |text: &str, flag: &str| -> Result<Vec<f64>, CliError> {
        let values: Vec<f64> = text
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| {
                CliError::Usage(format!(
                    "{flag} wants four numbers separated by commas, got {text:?}"
                ))
            })?;
        if values.len() != 4 || values.iter().any(|v| !v.is_finite()) {
            return Err(CliError::Usage(format!(
                "{flag} wants four finite numbers separated by commas, got {text:?}"
            )));
        }
        Ok(values)
    };
    let (width, height) = (header.width as f64, header.height as f64);
    let pixels = match (&args.window, &args.bbox) {
        (Some(text), _) => {
            let v = numbers(text, "--window")?;
            if v.iter().any(|x| x.fract() != 0.0 || *x < 0.0) || v[2] < 1.0 || v[3] < 1.0 {
                return Err(CliError::Usage(format!(
                    "--window wants whole pixels X,Y,W,H with W and H at least 1, got {text:?}"
                )));
            }
            if v[0] + v[2] > width || v[1] + v[3] > height {
                return Err(CliError::Usage(format!(
                    "--window {text} does not fit the {width}x{height} raster"
                )));
            }
            [v[0], v[1], v[0] + v[2], v[1] + v[3]]
        }
        (None, Some(text)) => bbox_pixels(&numbers(text, "--bbox")?, header, text)?,
        (None, None) => return Ok(None),
    };
    Ok(Some(Window {
        x: pixels[0] as usize,
        y: pixels[1] as usize,
        width: (pixels[2] - pixels[0]) as usize,
        height: (pixels[3] - pixels[1]) as usize,
    }))
}

/// The pixel columns and rows `[x0, y0, x1, y1)` covering a box in CRS units, clipped
/// to the raster.
fn bbox_pixels(b: &[f64], header: &Header, text: &str) -> Result<[f64; 4], CliError> {
    let Some(gt) = header.georef.as_ref().map(|g| g.geotransform) else {
        return Err(CliError::Usage(
            "--bbox needs a georeferenced file; use --window in pixels".into(),
        ));
    };
    if gt[2] != 0.0 || gt[4] != 0.0 || gt[1] == 0.0 || gt[5] == 0.0 {
        return Err(CliError::Usage(
            "--bbox needs a north-up file (no rotation); use --window in pixels".into(),
        ));
    }
    if b[0] >= b[2] || b[1] >= b[3] {
        return Err(CliError::Usage(format!(
            "--bbox wants MINX,MINY,MAXX,MAXY with min < max, got {text}"
        )));
    }
    let columns = [(b[0] - gt[0]) / gt[1], (b[2] - gt[0]) / gt[1]];
    let rows = [(b[1] - gt[3]) / gt[5], (b[3] - gt[3]) / gt[5]];
    let (w, h) = (header.width as f64, header.height as f64);
    let x0 = columns[0].min(columns[1]).floor().clamp(0.0, w);
    let x1 = columns[0].max(columns[1]).ceil().clamp(0.0, w);
    let y0 = rows[0].min(rows[1]).floor().clamp(0.0, h);
    let y1 = rows[0].max(rows[1]).ceil().clamp(0.0, h);
    if x1 <= x0 || y1 <= y0 {
        return Err(CliError::Usage(format!(
            "--bbox {text} does not overlap the raster"
        )));
    }
    Ok([x0, y0, x1, y1])
}

/// Refuses mesh options without `--mesh`, and `--mesh` where it cannot be made.
fn check_mesh_args(args: &DecodeArgs, header: &Header, samples: u64) -> Result<(), CliError> {
    if args.mesh.is_none() && !args.mesh_options.is_default() {
        return Err(CliError::Usage(
            "mesh options (--threshold, --triangles, --mesh-error, ...) need --mesh".into(),
        ));
    }
    let Some(mesh) = &args.mesh else {
        return Ok(());
    };
    if header.tiling.is_some() {
        return Err(CliError::Usage(
            "--mesh needs a single-stream file: this one is tiled (encode with --tile 0, or mesh the decoded DEM with wavemesh mesh)".into(),
        ));
    }
    if args.window.is_some() || args.bbox.is_some() {
        return Err(CliError::Usage(
            "--mesh meshes the whole file: drop --window/--bbox".into(),
        ));
    }
    refuse_overwriting_input(&args.input, mesh)?;
    if mesh == &args.output {
        return Err(CliError::Usage("--mesh and -o name the same file".into()));
    }
    args.mesh_options
        .check(mesh, samples, args.input_args.max_memory())
}

#[derive(Serialize)]
struct PassReport {
    plane: u32,
    end_byte: u64,
    bpp: f64,
    estimated_rmse: f64,
    estimated_psnr_db: f64,
}

/// What `info` says of the raster a header describes, single stream or tiled.
#[derive(Serialize)]
pub(super) struct RasterReport {
    width: u32,
    height: u32,
    sample_type: &'static str,
    wavelet: &'static str,
    levels: u8,
    mode: &'static str,
    max_error_bound: Option<f64>,
    nodata: Option<String>,
    valid_min: f64,
    valid_max: f64,
}

impl RasterReport {
    /// The raster `header` describes.
    pub(super) fn of(header: &Header) -> RasterReport {
        RasterReport {
            width: header.width,
            height: header.height,
            sample_type: header.sample_type.name(),
            wavelet: header.wavelet.name(),
            levels: header.levels,
            mode: header.mode.name(),
            max_error_bound: header.max_error.is_finite().then_some(header.max_error),
            nodata: header.nodata.map(|v| v.to_string()),
            valid_min: header.valid_range.0,
            valid_max: header.valid_range.1,
        }
    }

    /// The text line of size, type, wavelet, levels and mode.
    pub(super) fn print_kind(&self) {
        println!(
            "  {}x{} {}, {} wavelet, {} levels, {} mode{}",
            self.width,
            self.height,
            self.sample_type,
            self.wavelet,
            self.levels,
            self.mode,
            self.max_error_bound
                .map_or(String::new(), |e| format!(" (max error {e})"))
        );
    }

    /// The valid range, as the text reports show it (a stream keeps it in its ladder,
    /// which a cut file may lack).
    pub(super) fn values(&self) -> String {
        if self.valid_min.is_nan() {
            return "range unknown (not in this prefix)".into();
        }
        format!("{} .. {}", self.valid_min, self.valid_max)
    }

    /// The nodata value, or "none".
    pub(super) fn nodata(&self) -> &str {
        self.nodata.as_deref().unwrap_or("none")
    }
}

#[derive(Serialize)]
struct InfoReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    file_bytes: u64,
    format_version: u16,
    #[serde(flatten)]
    raster: RasterReport,
    value_offset: f64,
    value_step: f64,
    header_bytes: u64,
    mask_bytes: u32,
    payload_start: u64,
    payload_bytes: u64,
    payload_cut_by_encoder: bool,
    residual_bytes: u32,
    correction_step: Option<f64>,
    truncated: bool,
    georeferenced: bool,
    geotransform: Option<[f64; 6]>,
    metadata: MetadataReport,
    passes: Vec<PassReport>,
}

pub fn info(args: &InfoArgs) -> Result<(), CliError> {
    let mut source = FileSource::open(&args.input)
        .map_err(|e| CliError::Input(args.input.clone(), e.to_string()))?;
    let max_index = args.limit_args.limits().max_memory / 4;
    if let Some(layout) = TiledLayout::read(&mut source, max_index)
        .map_err(|e| CliError::Stream(args.input.clone(), e))?
    {
        super::tiled_info::run(&args.input, args.json, &layout, source.len());
        return Ok(());
    }
    let data = std::fs::read(&args.input)
        .map_err(|e| CliError::Input(args.input.clone(), e.to_string()))?;
    let (header, header_len) =
        Header::parse(&data).map_err(|e| CliError::Stream(args.input.clone(), e))?;
    let (w, h) = (header.width as usize, header.height as usize);
    let payload_start = (header_len + header.mask_len as usize) as u64;
    let samples = header.sample_count();
    // Counting the valid samples decodes the nodata mask: one bit a sample.
    let mask_bytes = if header.mask_len > 0 { samples / 8 } else { 0 };
    args.limit_args
        .check("the header's raster", samples, mask_bytes)
        .map_err(|e| CliError::Input(args.input.clone(), e.to_string()))?;
    let valid = valid_sample_count(&data, &header, header_len, &args.limit_args.limits())
        .map_err(|e| CliError::Stream(args.input.clone(), e))? as f64;
    let range = header.valid_range.1 - header.valid_range.0;
    let passes = header
        .passes
        .iter()
        .map(|p| {
            let rmse = (p.squared_error / valid.max(1.0)).sqrt();
            PassReport {
                plane: p.plane,
                end_byte: payload_start + physical_offset(p.end_byte),
                bpp: metrics::bits_per_sample(payload_start + physical_offset(p.end_byte), w, h),
                estimated_rmse: rmse,
                estimated_psnr_db: metrics::psnr(range, rmse),
            }
        })
        .collect::<Vec<_>>();
    let expected = payload_start + header.payload_len + header.residual_len as u64;
    let report = InfoReport {
        schema_version: SCHEMA_VERSION,
        command: "info",
        input: &args.input,
        file_bytes: data.len() as u64,
        format_version: u16::from_le_bytes([data[8], data[9]]),
        raster: RasterReport::of(&header),
        value_offset: header.mapping.offset,
        value_step: header.mapping.step,
        header_bytes: header_len as u64,
        mask_bytes: header.mask_len,
        payload_bytes: header.payload_len,
        payload_cut_by_encoder: header.payload_truncated,
        residual_bytes: header.residual_len,
        correction_step: (header.correction_step > 0.0).then_some(header.correction_step),
        truncated: (data.len() as u64) < expected
            || (header.passes.is_empty() && header.top_plane.is_some()),
        payload_start,
        georeferenced: header.georef.is_some(),
        geotransform: header.georef.as_ref().map(|g| g.geotransform),
        metadata: MetadataReport::new(&header.metadata),
        passes,
    };
    if args.json {
        print_json(&report);
        return Ok(());
    }
    println!(
        "{}: .ezw version {}, {} bytes",
        args.input.display(),
        report.format_version,
        report.file_bytes
    );
    report.raster.print_kind();
    println!(
        "  values {}, sample = {} + {} * q, nodata {}",
        report.raster.values(),
        report.value_offset,
        report.value_step,
        report.raster.nodata()
    );
    println!(
        "  header {} B, mask {} B, payload {} B{}, {} {} B{}{}",
        report.header_bytes,
        report.mask_bytes,
        report.payload_bytes,
        if report.payload_cut_by_encoder {
            " (a cut stream)"
        } else {
            ""
        },
        if report.correction_step.is_some() {
            "corrections"
        } else {
            "residuals"
        },
        report.residual_bytes,
        if report.truncated { ", TRUNCATED" } else { "" },
        if report.georeferenced {
            ", georeferenced"
        } else {
            ""
        }
    );
    for line in report.metadata.lines() {
        println!("{line}");
    }
    println!(
        "  {:>5} {:>12} {:>9} {:>12} {:>9}",
        "plane", "end byte", "bpp", "est. RMSE", "est. PSNR"
    );
    for p in &report.passes {
        println!(
            "  {:>5} {:>12} {:>9.4} {:>12.4} {:>9.2}",
            p.plane, p.end_byte, p.bpp, p.estimated_rmse, p.estimated_psnr_db
        );
    }
    Ok(())
}

#[derive(Serialize)]
struct CompareReport<'a> {
    schema_version: u32,
    command: &'static str,
    original: &'a Path,
    other: &'a Path,
    #[serde(flatten)]
    distortion: Distortion,
}

pub fn compare(args: &CompareArgs) -> Result<(), CliError> {
    let original = args.input_args.read(&args.original)?;
    let other = args.input_args.read(&args.other)?;
    let distortion = compare_rasters(&original, &other, &args.other)?;
    let mismatches = distortion.nodata_mismatches;
    if args.json {
        print_json(&CompareReport {
            schema_version: SCHEMA_VERSION,
            command: "compare",
            original: &args.original,
            other: &args.other,
            distortion,
        });
    } else {
        if mismatches > 0 {
            println!("VOIDS DIFFER: {mismatches} samples are nodata in one raster and valid in the other; the errors below cover only the samples valid in both");
        }
        print_distortion(&distortion);
    }
    if mismatches > 0 {
        return Err(CliError::CheckFailed(format!(
            "{} and {} differ in {mismatches} voids (nodata in one, valid in the other)",
            args.original.display(),
            args.other.display()
        )));
    }
    Ok(())
}

pub(super) fn compare_rasters(
    original: &Raster,
    other: &Raster,
    path: &Path,
) -> Result<Distortion, CliError> {
    metrics::compare(original, other)
        .map_err(|e| CliError::Input(path.to_path_buf(), e.to_string()))
}

fn print_distortion(d: &Distortion) {
    println!(
        "  R {} | RMSE {:.6} | PSNR {:.3} dB | max error {} | valid samples {}{}{}",
        d.range,
        d.rmse,
        d.psnr_db,
        d.max_error,
        d.valid_samples,
        if d.nodata_mismatches > 0 {
            format!(" | nodata mismatches {}", d.nodata_mismatches)
        } else {
            String::new()
        },
        if d.identical { " | bit-identical" } else { "" }
    );
}

/// A prefix of `asked` bytes, raised to `smallest` (the header and nodata mask, the
/// shortest prefix that decodes) with a note on stderr saying the rate used.
fn at_least_decodable(asked: u64, smallest: u64, samples: u64) -> u64 {
    if asked >= smallest {
        return asked;
    }
    eprintln!(
        "wavemesh: note: {asked} bytes is less than the smallest decodable prefix; decoding {smallest} bytes ({:.4} bpp): the header and nodata mask",
        smallest as f64 * 8.0 / samples as f64
    );
    smallest
}

/// Whether the output is `-` (standard output, where no report is printed then);
/// `--json` would share standard output with the data and is refused.
fn writes_to_stdout(output: &Path, json: bool) -> Result<bool, CliError> {
    let to_stdout = output.as_os_str() == "-";
    if to_stdout && json {
        return Err(CliError::Usage(
            "-o - writes the data to standard output; --json cannot share it".into(),
        ));
    }
    Ok(to_stdout)
}

/// Warns when an `.ezw` stream is about to be written under a DEM file's extension.
fn warn_about_output_extension(output: &Path) {
    let ext = output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if let Some(ext) = ext.filter(|e| e != "ezw") {
        eprintln!(
            "wavemesh: warning: {}: writing a .ezw stream under a .{ext} name (decode makes DEM files)",
            output.display()
        );
    }
}

/// Refuses to write over the input file.
fn refuse_overwriting_input(input: &Path, output: &Path) -> Result<(), CliError> {
    if let (Ok(a), Ok(b)) = (input.canonicalize(), output.canonicalize()) {
        if a == b {
            return Err(CliError::Usage(format!(
                "refusing to overwrite the input file {}",
                input.display()
            )));
        }
    }
    Ok(())
}

/// Writes bytes atomically (temp file + rename).
pub(super) fn write_output(path: &Path, bytes: &[u8]) -> Result<(), CliError> {
    wavemesh::atomic::write_atomic(path, |w| w.write_all(bytes))
        .map_err(|e| CliError::Output(path.to_path_buf(), e.to_string()))
}
