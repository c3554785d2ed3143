//! `mesh` (encode + decode + mesh in one go), the mesh half of `decode --mesh`, and
//! `table` (the seed paper's Tables 1 and 2).

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::ValueEnum;
use serde::Serialize;
use wavemesh::lod::{self, build_mesh, decoded_plane, plane_of_threshold, Surface, TableRows};
use wavemesh::mesh::cells::SplitRule;
use wavemesh::mesh::export::{write_mesh, MeshFormat, Placement};
use wavemesh::mesh::frame::FrameError;
use wavemesh::mesh::rasterise::{mesh_error, uncoverable_samples, MeshError};
use wavemesh::mesh::tiled::{has_valid_cell, TileTarget};
use wavemesh::mesh::MeshTarget;
use wavemesh_codec::{
    decode, encode, DecodeOptions, Decoded, EncodeOptions, Georef, Quality, Raster,
};

use super::coding::SCHEMA_VERSION;
use super::meshers::{mesh_direct, MethodArg};
use super::tile_meshes::{mesh_tiles, TilingArgs};
use super::{timed, with_codec_progress, with_progress, CliError, InputArgs, WaveletArg, Workload};
use wavemesh::meshers;

/// Which coefficients split a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RuleArg {
    /// The node or any descendant significant (no zerotree root).
    Zerotree,
    /// One of the node's own coefficients significant (the seed paper's literal rule).
    Own,
}

/// How `--triangles` searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SearchArg {
    /// Over the zerotree thresholds of the significance map.
    Threshold,
    /// Over height tolerances (error pyramid).
    Error,
}

/// Output x/y units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum XyArg {
    /// Metres: geographic (longitude/latitude) DEMs in the east-north-up frame at their
    /// centre on WGS 84; projected DEMs in their CRS's x/y; pixel units without
    /// georeferencing.
    Geo,
    /// The CRS's own x/y, untransformed: degrees for geographic DEMs.
    Degrees,
    /// x = column, y = row of the grid, z = stored value × z-scale.
    Pixel,
}

/// The mesh options shared by `mesh` and `decode --mesh`.
#[derive(Debug, Clone, clap::Args)]
pub struct MeshOptions {
    /// Zerotree threshold T: cells split where a coefficient reaches T (rounded down to a
    /// power of two, a pass of the stream). Default: the decoder's threshold. With
    /// --mesh-error, the partition the tolerance refines.
    #[arg(long, value_name = "T", conflicts_with = "triangles")]
    threshold: Option<f64>,
    /// Largest mesh with at most N triangles (searched as --search says).
    #[arg(long, value_name = "N", conflicts_with = "mesh_error")]
    triangles: Option<usize>,
    /// Keep every sample of the heights the mesh is built from within E data units of it.
    #[arg(long, value_name = "E")]
    mesh_error: Option<f64>,
    /// What --triangles searches over.
    #[arg(long, value_enum, default_value = "error")]
    search: SearchArg,
    /// Which coefficients split a cell at a threshold.
    #[arg(long, value_enum, default_value = "zerotree")]
    rule: RuleArg,
    /// x/y units of the mesh file.
    #[arg(long, value_enum, default_value = "geo")]
    xy: XyArg,
    /// Multiply heights by this (e.g. 0.1 for decimetre DEMs).
    #[arg(long, default_value_t = 1.0)]
    z_scale: f64,
}

impl MeshOptions {
    /// Whether every option has its default (none was given).
    pub fn is_default(&self) -> bool {
        self.threshold.is_none()
            && self.triangles.is_none()
            && self.mesh_error.is_none()
            && self.search == SearchArg::Error
            && self.rule == RuleArg::Zerotree
            && self.xy == XyArg::Geo
            && self.z_scale == 1.0
    }

    /// Checks the options, the output path and the memory a mesh of `samples` samples
    /// may need before any work is done, so that a bad mesh argument leaves no other
    /// output behind either.
    pub fn check(&self, path: &Path, samples: u64, max_memory: u64) -> Result<(), CliError> {
        mesh_format(path)?;
        if path.is_dir() {
            return Err(CliError::Output(
                path.to_path_buf(),
                "is a directory".into(),
            ));
        }
        let (target, _) = self.target(0)?;
        let needed = mesh_memory(samples, target);
        if needed > max_memory {
            return Err(CliError::OverLimit(format!(
                "meshing {samples} samples may need {needed} bytes, more than --max-memory {max_memory}; raise it if the machine has it"
            )));
        }
        Ok(())
    }

    fn rule(&self) -> SplitRule {
        match self.rule {
            RuleArg::Zerotree => SplitRule::Zerotree,
            RuleArg::Own => SplitRule::OwnCoefficients,
        }
    }

    /// The target and the base plane for a stream decoded to `decoded_plane`.
    fn target(&self, decoded_plane: u32) -> Result<(MeshTarget, Option<u32>), CliError> {
        if !(self.z_scale.is_finite() && self.z_scale != 0.0) {
            return Err(CliError::Usage(format!(
                "--z-scale must be finite and non-zero, got {}",
                self.z_scale
            )));
        }
        let threshold_plane = match self.threshold {
            Some(t) if t.is_finite() && t >= 0.0 => Some(plane_of_threshold(t).max(decoded_plane)),
            Some(t) => {
                return Err(CliError::Usage(format!(
                    "--threshold must be a non-negative number, got {t}"
                )))
            }
            None => None,
        };
        if let Some(e) = self.mesh_error {
            if !(e.is_finite() && e >= 0.0) {
                return Err(CliError::Usage(format!(
                    "--mesh-error must be a non-negative number, got {e}"
                )));
            }
            return Ok((MeshTarget::Tolerance(e), threshold_plane));
        }
        if let Some(n) = self.triangles {
            return Ok(match self.search {
                SearchArg::Threshold => (MeshTarget::Triangles(n), None),
                SearchArg::Error => (MeshTarget::TrianglesByTolerance(n), None),
            });
        }
        Ok((
            MeshTarget::Plane(threshold_plane.unwrap_or(decoded_plane)),
            None,
        ))
    }

    /// The budget of a mesh built straight from the heights (`--method` other than
    /// zerotree): `--triangles`, else `--mesh-error`, else 1 % of the grid's triangles.
    fn direct_budget(&self, samples: usize) -> Result<meshers::Budget, CliError> {
        self.target(0)?;
        if self.threshold.is_some() {
            return Err(CliError::Usage(
                "--threshold applies to --method zerotree only".into(),
            ));
        }
        Ok(match (self.triangles, self.mesh_error) {
            (Some(n), _) => meshers::Budget::Triangles(n),
            (None, Some(e)) => meshers::Budget::MaxError(e),
            (None, None) => meshers::Budget::Triangles((samples / 50).max(2)),
        })
    }

    /// Where the samples of `raster` go in the mesh file.
    fn placement(&self, raster: &Raster) -> Result<Placement, FrameError> {
        self.placement_for(raster.georef.as_ref(), raster.width, raster.height)
    }

    /// Where the samples of a `width × height` DEM placed by `georef` go.
    pub(super) fn placement_for(
        &self,
        georef: Option<&Georef>,
        width: usize,
        height: usize,
    ) -> Result<Placement, FrameError> {
        Ok(match self.xy {
            XyArg::Pixel => Placement::pixel(self.z_scale),
            XyArg::Degrees => Placement::crs_units(georef, self.z_scale),
            XyArg::Geo => Placement::metric(georef, width, height, self.z_scale)?,
        })
    }

    /// What every tile of `--tile-meshes` meets, and the split rule.
    pub(super) fn tile_target(&self) -> Result<(TileTarget, SplitRule), CliError> {
        let (target, base_plane) = self.target(0)?;
        let tile_target = match target {
            MeshTarget::Plane(plane) => TileTarget::Zerotree {
                plane: self.threshold.map(|_| plane),
            },
            MeshTarget::Tolerance(error) => TileTarget::Tolerance {
                error,
                plane: base_plane,
            },
            MeshTarget::Triangles(total) => TileTarget::Triangles {
                total,
                by_threshold: true,
            },
            MeshTarget::TrianglesByTolerance(total) => TileTarget::Triangles {
                total,
                by_threshold: false,
            },
        };
        Ok((tile_target, self.rule()))
    }

    /// Checks that `raster` (read from `input`) can be meshed as asked: it has a 2 × 2
    /// block of valid samples (a 1 × N or all-nodata raster has no triangle) and its
    /// georeferencing fits the chosen x/y units. Callers run it before writing anything.
    pub fn check_raster(&self, raster: &Raster, input: &Path) -> Result<(), CliError> {
        let refuse = |message: String| CliError::Input(input.to_path_buf(), message);
        if !has_valid_cell(raster) {
            return Err(refuse(format!(
                "nothing to mesh: the {} × {} raster has no 2 × 2 block of valid samples",
                raster.width, raster.height
            )));
        }
        self.placement(raster)
            .map(|_| ())
            .map_err(|e| refuse(e.to_string()))
    }
}

/// The mesh part of a JSON report.
#[derive(Debug, Serialize)]
pub struct MeshReport {
    output: PathBuf,
    format: &'static str,
    rule: &'static str,
    plane: Option<u32>,
    threshold: Option<f64>,
    tolerance: Option<f64>,
    triangles: usize,
    vertices: usize,
    cells: usize,
    refinement_splits: usize,
    remaining_percent: f64,
    /// `pixel`, `georeferenced` (the CRS's own x/y) or `local_enu` (metres).
    xy_units: &'static str,
    /// The frame as the file records it (name, CRS, `z_scale`, local origin).
    frame: serde_json::Value,
    /// Against the heights the mesh is built from (the decoded DEM).
    error_vs_decoded: MeshError,
    /// Against the original DEM (`--reference`, or the input of `mesh`).
    error_vs_original: Option<MeshError>,
    /// Valid samples of the decoded DEM no triangle of three valid grid neighbours can
    /// reach: the least `error_vs_decoded.uncovered_samples` can be (it is that).
    uncoverable_samples: u64,
    mesh_bytes_in_memory: usize,
    mesh_bytes_paper: f64,
    pyramid_seconds: f64,
    mesh_seconds: f64,
    mesh_triangles_per_second: f64,
    mesh_peak_heap_bytes: usize,
    measure_seconds: f64,
    write_seconds: f64,
    file_bytes: u64,
}

/// Meshes a decode (made with the significance map) and writes the mesh to `path`; the
/// caller has checked the decoded raster with [`MeshOptions::check_raster`].
pub fn mesh_decoded(
    decoded: &Decoded,
    options: &MeshOptions,
    path: &Path,
    original: Option<&Raster>,
    max_memory: u64,
) -> Result<MeshReport, CliError> {
    options.check(path, decoded.raster.len() as u64, max_memory)?;
    let format = mesh_format(path)?;
    let (target, base_plane) = options.target(decoded_plane(decoded))?;
    let map = decoded
        .significance
        .as_ref()
        .expect("decoded with the significance map");
    let surface = Surface::of(&decoded.raster);
    let timed_mesh = with_progress("meshing", || {
        build_mesh(map, &surface, target, options.rule(), base_plane)
    });
    let mesh = &timed_mesh.mesh;
    if let MeshTarget::Triangles(n) | MeshTarget::TrianglesByTolerance(n) = target {
        if mesh.triangles.len() > n {
            eprintln!(
                "wavemesh: warning: no mesh has at most {n} triangles (nodata and the coarsest cells force {}); writing the coarsest",
                mesh.triangles.len()
            );
        }
    }
    let start = Instant::now();
    let error_vs_decoded = mesh_error(mesh, &surface.heights, &surface.heights, &surface.valid);
    let uncoverable_samples = uncoverable_samples(surface.width, surface.height, &surface.valid);
    let error_vs_original = original.map(|o| {
        let reference = Surface::of(o);
        mesh_error(mesh, &surface.heights, &reference.heights, &reference.valid)
    });
    let measure_seconds = start.elapsed().as_secs_f64();
    let placement = options
        .placement(&decoded.raster)
        .map_err(|e| CliError::Input(path.to_path_buf(), e.to_string()))?;
    let start = Instant::now();
    write_mesh(path, mesh, &surface.heights, &placement, format)
        .map_err(|e| CliError::Output(path.to_path_buf(), e.to_string()))?;
    let write_seconds = start.elapsed().as_secs_f64();
    let full = 2 * surface.width.saturating_sub(1) * surface.height.saturating_sub(1);
    Ok(MeshReport {
        output: path.to_path_buf(),
        format: format.name(),
        rule: match options.rule {
            RuleArg::Zerotree => "zerotree",
            RuleArg::Own => "own",
        },
        plane: timed_mesh.plane,
        threshold: timed_mesh.plane.map(|p| 2f64.powi(p as i32)),
        tolerance: timed_mesh.tolerance,
        triangles: mesh.triangles.len(),
        vertices: mesh.vertices.len(),
        cells: timed_mesh.cells,
        refinement_splits: timed_mesh.refinement_splits,
        remaining_percent: 100.0 * mesh.triangles.len() as f64 / full.max(1) as f64,
        xy_units: placement.frame_name(),
        frame: placement.frame_record(),
        error_vs_decoded,
        error_vs_original,
        uncoverable_samples,
        mesh_bytes_in_memory: mesh.heap_bytes(),
        mesh_bytes_paper: lod::paper_mesh_bytes(mesh.triangles.len(), mesh.vertices.len()),
        pyramid_seconds: timed_mesh.pyramid_seconds,
        mesh_seconds: timed_mesh.mesh_seconds,
        mesh_triangles_per_second: mesh.triangles.len() as f64 / timed_mesh.mesh_seconds.max(1e-9),
        mesh_peak_heap_bytes: timed_mesh.peak_heap_bytes,
        measure_seconds,
        write_seconds,
        file_bytes: std::fs::metadata(path).map_or(0, |m| m.len()),
    })
}

/// The most bytes meshing `samples` samples for `target` may hold: heights as `f64` (8 a
/// sample), leaves (12), triangles and their file encoding (up to 2 a sample, 12 + 18 bytes
/// each), plus the error pyramid (16) for tolerances.
fn mesh_memory(samples: u64, target: MeshTarget) -> u64 {
    let tolerance = matches!(
        target,
        MeshTarget::Tolerance(_) | MeshTarget::TrianglesByTolerance(_)
    );
    samples.saturating_mul(8 + 12 + 2 * 30 + if tolerance { 16 } else { 0 })
}

/// The mesh format of `path`'s extension (binary glTF for an extensionless device or
/// FIFO).
pub(super) fn mesh_format(path: &Path) -> Result<MeshFormat, CliError> {
    if path.as_os_str() == "-" {
        return Err(CliError::Usage(
            "meshes are not written to standard output (-); name a file, a device or a FIFO".into(),
        ));
    }
    // A device or FIFO has no extension to go by: binary glTF, the one-file format.
    let is_stream = wavemesh::atomic::destination(path).is_ok_and(|d| d.is_stream());
    if path.extension().is_none() && is_stream {
        return Ok(MeshFormat::Glb);
    }
    MeshFormat::from_path(path).ok_or_else(|| {
        CliError::Usage(format!(
            "{}: unknown mesh format (use .glb, .obj or .ply)",
            path.display()
        ))
    })
}

/// One line summarising a mesh report.
pub fn print_mesh_summary(report: &MeshReport) {
    let what = match (report.plane, report.tolerance) {
        (_, Some(e)) => format!("tolerance {e}"),
        (Some(p), None) => format!("threshold 2^{p}"),
        (None, None) => String::new(),
    };
    println!(
        "mesh {} ({}, {}): {} triangles, {} vertices ({:.2} % of the grid's), {:.3} s",
        report.output.display(),
        report.format,
        what,
        report.triangles,
        report.vertices,
        report.remaining_percent,
        report.mesh_seconds + report.pyramid_seconds
    );
    print_mesh_error("vs decoded DEM: ", &report.error_vs_decoded);
    if let Some(e) = &report.error_vs_original {
        print_mesh_error("vs original DEM:", e);
    }
}

/// One line of a mesh's errors, with [`uncovered_note`].
fn print_mesh_error(label: &str, e: &MeshError) {
    println!(
        "  {label} RMSE {:.4}  PSNR {:.2} dB  max error {:.4}{}",
        e.rmse,
        e.psnr_db,
        e.max_error,
        uncovered_note(e)
    );
}

/// What follows a mesh's errors when it leaves valid samples uncovered (cut off by
/// nodata), which the errors do not include; empty when it covers them all.
pub fn uncovered_note(e: &MeshError) -> String {
    if e.uncovered_samples > 0 {
        format!(
            "  over {} covered samples; {} valid samples uncovered",
            e.compared_samples, e.uncovered_samples
        )
    } else {
        String::new()
    }
}

#[derive(Debug, clap::Args)]
pub struct MeshArgs {
    /// Input DEM.
    input: PathBuf,
    /// Output mesh (.glb, .obj or .ply).
    #[arg(short, long)]
    output: PathBuf,
    /// Encode lossy (9/7) at this many bits per sample before meshing (default lossless).
    #[arg(long)]
    bpp: Option<f64>,
    #[command(flatten)]
    mesh: MeshOptions,
    /// Which mesher: the zerotree (after an encode and decode) or one straight from the
    /// heights. Default: zerotree when a stream is asked for (`--threshold`, `--bpp`),
    /// else greedy (insertion with data-dependent flips: fewer triangles and a smaller
    /// RMSE than Delatin's).
    #[arg(long, value_enum)]
    method: Option<MethodArg>,
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    input_args: InputArgs,
    #[command(flatten)]
    tiling: TilingArgs,
}

#[derive(Serialize)]
struct MeshCommandReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    width: usize,
    height: usize,
    ezw_bytes: u64,
    bpp: f64,
    encode_seconds: f64,
    decode_seconds: f64,
    decode_peak_heap_bytes: usize,
    mesh: MeshReport,
}

pub fn mesh(args: &MeshArgs) -> Result<(), CliError> {
    if args.input == args.output {
        return Err(CliError::Usage(
            "the output would overwrite the input".into(),
        ));
    }
    if args.tiling.enabled() {
        if args.bpp.is_some() {
            return Err(CliError::Usage(
                "--tile-meshes meshes each tile's lossless stream: --bpp does not apply".into(),
            ));
        }
        let paths = (args.input.as_path(), args.output.as_path());
        return mesh_tiles(paths, &args.mesh, &args.tiling, &args.input_args, args.json);
    }
    let raster = args.input_args.read_to_encode(&args.input)?;
    args.mesh.check(
        &args.output,
        raster.len() as u64,
        args.input_args.max_memory(),
    )?;
    args.mesh.check_raster(&raster, &args.input)?;
    let asks_for_a_stream = args.bpp.is_some() || args.mesh.threshold.is_some();
    let method = args.method.unwrap_or(if asks_for_a_stream {
        MethodArg::Zerotree
    } else {
        MethodArg::Greedy
    });
    if method != MethodArg::Zerotree {
        if args.bpp.is_some() {
            return Err(CliError::Usage(
                "--bpp applies to --method zerotree only (it meshes a decoded stream)".into(),
            ));
        }
        let needed = method.method().peak_bytes_per_sample() * raster.len() as u64;
        let max_memory = args.input_args.max_memory();
        if needed > max_memory {
            return Err(CliError::OverLimit(format!(
                "meshing {} samples with {} may need {needed} bytes, more than --max-memory {max_memory}; raise it if the machine has it",
                raster.len(),
                method.method().name()
            )));
        }
        let budget = args.mesh.direct_budget(raster.len())?;
        let placement = args
            .mesh
            .placement(&raster)
            .map_err(|e| CliError::Input(args.input.clone(), e.to_string()))?;
        let paths = (args.input.as_path(), args.output.as_path());
        return mesh_direct(method, &raster, budget, &placement, paths, args.json);
    }
    let budget = match args.bpp {
        Some(bpp) if bpp.is_finite() && bpp > 0.0 => {
            Some((bpp * raster.len() as f64 / 8.0).floor() as u64)
        }
        Some(bpp) => {
            return Err(CliError::Usage(format!(
                "--bpp must be positive, got {bpp}"
            )))
        }
        None => None,
    };
    let options = match budget {
        Some(_) => EncodeOptions::new(Quality::Lossless, budget).single_stream(),
        None => EncodeOptions::zerotree_mesh(),
    };
    let (encoded, encode_seconds, _) =
        with_codec_progress("encoding", Workload::of(&raster), || {
            timed(|| encode(&raster, &options))
        });
    let encoded = encoded.map_err(CliError::Encode)?;
    let decode_options = DecodeOptions::default()
        .with_significance_map(true)
        .with_limits(args.input_args.limits());
    let (decoded, decode_seconds, decode_peak) =
        with_codec_progress("decoding", Workload::of(&raster), || {
            timed(|| decode(&encoded.bytes, &decode_options))
        });
    let decoded = decoded.map_err(|e| CliError::Stream(args.input.clone(), e))?;
    let mesh = mesh_decoded(
        &decoded,
        &args.mesh,
        &args.output,
        Some(&raster),
        args.input_args.max_memory(),
    )?;
    let report = MeshCommandReport {
        schema_version: SCHEMA_VERSION,
        command: "mesh",
        input: &args.input,
        width: raster.width,
        height: raster.height,
        ezw_bytes: encoded.bytes.len() as u64,
        bpp: wavemesh::metrics::bits_per_sample(
            encoded.bytes.len() as u64,
            raster.width,
            raster.height,
        ),
        encode_seconds,
        decode_seconds,
        decode_peak_heap_bytes: decode_peak,
        mesh,
    };
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("reports serialise")
        );
    } else {
        println!(
            "{}: {}x{}, {} bytes = {:.4} bpp (encode {:.3} s, decode {:.3} s)",
            args.input.display(),
            report.width,
            report.height,
            report.ezw_bytes,
            report.bpp,
            encode_seconds,
            decode_seconds
        );
        print_mesh_summary(&report.mesh);
    }
    Ok(())
}

/// Output format of `table`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TableFormat {
    /// Markdown tables.
    Md,
    /// Comma-separated values, one line per row.
    Csv,
    /// One JSON object.
    Json,
}

#[derive(Debug, clap::Args)]
pub struct TableArgs {
    /// Input DEM.
    input: PathBuf,
    /// Comma-separated thresholds (rounded down to powers of two); default: every pass.
    #[arg(long, value_delimiter = ',', conflicts_with = "bpp")]
    thresholds: Option<Vec<f64>>,
    /// Comma-separated bit rates: rows are prefixes of one lossless stream.
    #[arg(long, value_delimiter = ',')]
    bpp: Option<Vec<f64>>,
    /// Which coefficients split a cell.
    #[arg(long, value_enum, default_value = "zerotree")]
    rule: RuleArg,
    /// Transform of the stream the rows decode: 53 (one lossless stream, the default) or
    /// 97 (a lossy stream cut at the largest --bpp; needs --bpp).
    #[arg(long, default_value = "53")]
    wavelet: WaveletArg,
    /// Output format.
    #[arg(long, value_enum, default_value = "md")]
    format: TableFormat,
    /// Time each row's search and triangulation this many times (medians are reported).
    #[arg(long, default_value_t = 5)]
    runs: usize,
    #[command(flatten)]
    input_args: InputArgs,
}

#[derive(Serialize)]
struct TableReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    width: usize,
    height: usize,
    ezw_bytes: u64,
    rows: Vec<lod::TableRow>,
}

pub fn table(args: &TableArgs) -> Result<(), CliError> {
    let raster = args.input_args.read_to_encode(&args.input)?;
    let rows = match (&args.thresholds, &args.bpp) {
        (Some(ts), _) => {
            if let Some(t) = ts.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
                return Err(CliError::Usage(format!("bad threshold {t}")));
            }
            TableRows::Thresholds(ts.clone())
        }
        (None, Some(rates)) => {
            if let Some(r) = rates.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
                return Err(CliError::Usage(format!("bad bit rate {r}")));
            }
            TableRows::BitRates(rates.clone())
        }
        (None, None) => TableRows::AllPasses,
    };
    let mut options = EncodeOptions::zerotree_mesh();
    if args.wavelet == WaveletArg::Cdf97 {
        let Some(top) = args
            .bpp
            .as_ref()
            .and_then(|r| r.iter().copied().reduce(f64::max))
        else {
            return Err(CliError::Usage(
                "--wavelet 97 is lossy: give the rows' rates with --bpp".into(),
            ));
        };
        options = options.with_wavelet(args.wavelet.into());
        options.budget_bytes = Some((top * raster.len() as f64 / 8.0).ceil() as u64);
    }
    let encoded = with_codec_progress("encoding", Workload::of(&raster), || {
        encode(&raster, &options)
    })
    .map_err(CliError::Encode)?;
    let rule = match args.rule {
        RuleArg::Zerotree => SplitRule::Zerotree,
        RuleArg::Own => SplitRule::OwnCoefficients,
    };
    let table = with_progress("measuring", || {
        lod::paper_table(&raster, &encoded, &rows, rule, args.runs)
    })
    .map_err(|e| CliError::Stream(args.input.clone(), e))?;
    match args.format {
        TableFormat::Md => print!("{}", lod::table_markdown(&table)),
        TableFormat::Csv => print!("{}", lod::table_csv(&table)),
        TableFormat::Json => {
            let report = TableReport {
                schema_version: SCHEMA_VERSION,
                command: "table",
                input: &args.input,
                width: raster.width,
                height: raster.height,
                ezw_bytes: encoded.bytes.len() as u64,
                rows: table,
            };
            println!(
                "{}",
                serde_json::to_string_pretty(&report).expect("reports serialise")
            );
        }
    }
    Ok(())
}
