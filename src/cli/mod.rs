//! Subcommands, their arguments and the error type the binary maps to exit codes.

mod allocator;
mod coding;
mod demo;
mod mesh;
mod meshers;
mod metadata_report;
mod report;
mod synth;
mod tile_meshes;
mod tiled_coding;
mod tiled_info;
mod varres;
mod verify;
mod view;

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};
use wavemesh::dem::{self, DemError, ReadOptions, WorkMemory};
use wavemesh_codec::{CodecError, Limits, Raster, Wavelet};

/// Store, stream and mesh elevation models: wavelet + EZW terrain codec.
#[derive(Debug, Parser)]
#[command(name = "wavemesh", version, about, propagate_version = true)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Encode a DEM (GeoTIFF, PNG, .hgt, .asc, Terrain-RGB) into an embedded .ezw stream.
    Encode(coding::EncodeArgs),
    /// Decode a .ezw stream (or a prefix of it) to GeoTIFF, PNG or .asc.
    Decode(coding::DecodeArgs),
    /// Show a .ezw header, its passes and the bytes each pass needs.
    Info(coding::InfoArgs),
    /// Check every checksum of a .ezw file and report the usable prefix.
    Verify(verify::VerifyArgs),
    /// Compare two DEMs: range, RMSE, PSNR, max error, valid samples.
    Compare(coding::CompareArgs),
    /// Encode, decode and mesh a DEM in one go (.glb, .obj or .ply).
    Mesh(mesh::MeshArgs),
    /// Every mesher (ours, Delatin, Martini) at the same triangle budgets.
    CompareMeshers(meshers::CompareArgs),
    /// The seed paper's Tables 1 and 2 (mesh and memory per threshold or bit rate).
    Table(mesh::TableArgs),
    /// Run the bundled sample end to end and print the results table.
    Demo(demo::DemoArgs),
    /// Measure every DEM of a manifest folder beside the peer tools' results (README tables).
    Report(report::ReportArgs),
    /// Write a fractal test DEM of any size as a GeoTIFF, strip by strip.
    Synth(synth::SynthArgs),
    /// One view-dependent mesh of a .ezw stream for a camera (geomorphed, crack-free).
    View(view::ViewArgs),
    /// A camera path over a .ezw stream: incremental split/merge, geomorphing, popping.
    Flythrough(view::FlythroughArgs),
}

/// Wavelet choice on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WaveletArg {
    /// CDF 9/7 (lossy).
    #[value(name = "97")]
    Cdf97,
    /// Integer 5/3 (lossless, max-error).
    #[value(name = "53")]
    Int53,
    /// Integer 13/11 (lossless, max-error): the default for those.
    #[value(name = "1311")]
    Int1311,
}

impl From<WaveletArg> for Wavelet {
    fn from(w: WaveletArg) -> Wavelet {
        match w {
            WaveletArg::Cdf97 => Wavelet::Cdf97,
            WaveletArg::Int53 => Wavelet::Int53,
            WaveletArg::Int1311 => Wavelet::Int1311,
        }
    }
}

/// Options shared by commands that read DEM files.
#[derive(Debug, Clone, clap::Args)]
pub struct InputArgs {
    /// Read PNG input as Mapbox Terrain-RGB (h = -10000 + (R·65536 + G·256 + B)·0.1).
    #[arg(long)]
    terrain_rgb: bool,
    #[command(flatten)]
    limit_args: LimitArgs,
    /// Read TIFFs with lossy-compressed samples (JPEG...): other readers may decode them
    /// ±1 differently, so "lossless" then holds only against this reader.
    #[arg(long)]
    accept_lossy_input: bool,
}

/// Bytes a sample the encoder allocates besides the raster (measured peaks: 15 for
/// integers, 44 for floats coded exactly, with some headroom).
const ENCODE_WORK: WorkMemory = WorkMemory {
    integer: 20,
    float: 48,
};

/// The limits every command checks sizes from a file against before allocating.
#[derive(Debug, Clone, clap::Args)]
pub struct LimitArgs {
    /// Refuse inputs with more samples than this.
    #[arg(long, default_value_t = Limits::default().max_samples)]
    max_samples: u64,
    /// Refuse work that may need more memory than this many bytes (the raster and the
    /// encoder's or decoder's working memory), before allocating anything.
    #[arg(long, default_value_t = Limits::default().max_memory)]
    max_memory: u64,
}

impl LimitArgs {
    /// The codec's view of these limits.
    fn limits(&self) -> Limits {
        Limits::new(self.max_samples, self.max_memory)
    }

    /// Refuses `what` needing `samples` samples and `bytes` bytes beyond the limits.
    fn check(&self, what: &str, samples: u64, bytes: u64) -> Result<(), CliError> {
        if samples > self.max_samples {
            return Err(CliError::OverLimit(format!(
                "{what} covers {samples} samples, more than --max-samples {}; raise it if the file is trusted",
                self.max_samples
            )));
        }
        if bytes > self.max_memory {
            return Err(CliError::OverLimit(format!(
                "{what} needs {bytes} bytes, more than --max-memory {}; raise it if the machine has it",
                self.max_memory
            )));
        }
        Ok(())
    }
}

/// Bytes a sample of the other raster held beside one being compared (at most an f32).
const COMPARE_WORK: WorkMemory = WorkMemory {
    integer: 4,
    float: 4,
};

impl InputArgs {
    /// Reads a DEM that will be compared with another of its size (held beside it).
    fn read(&self, path: &Path) -> Result<Raster, CliError> {
        self.read_for(path, COMPARE_WORK)
    }

    /// Reads a DEM that will be encoded: the encoder's memory counts against the limit.
    fn read_to_encode(&self, path: &Path) -> Result<Raster, CliError> {
        self.read_for(path, ENCODE_WORK)
    }

    /// Opens a DEM to be encoded band by band: the limits bound a band, and the
    /// encoder's memory counts per band sample.
    fn open_bands(&self, path: &Path) -> Result<dem::RowBands, CliError> {
        dem::RowBands::open(path, &self.read_options(ENCODE_WORK))
            .map_err(|e| read_failure(path, e))
    }

    fn read_options(&self, work: WorkMemory) -> ReadOptions {
        ReadOptions {
            terrain_rgb: self.terrain_rgb,
            max_samples: self.limit_args.max_samples,
            max_memory: self.limit_args.max_memory,
            work,
            accept_lossy: self.accept_lossy_input,
        }
    }

    fn read_for(&self, path: &Path, work: WorkMemory) -> Result<Raster, CliError> {
        let options = self.read_options(work);
        let raster = dem::read_dem(path, &options).map_err(|e| read_failure(path, e))?;
        warn_if_hgt_lost_its_place(path, &raster);
        Ok(raster)
    }

    fn limits(&self) -> Limits {
        self.limit_args.limits()
    }

    fn max_memory(&self) -> u64 {
        self.limit_args.max_memory
    }
}

/// An SRTM `.hgt` tile is placed by its name (`N57E011.hgt`): warn when the name did not
/// give it a place, since everything made from it has no georeferencing.
fn warn_if_hgt_lost_its_place(path: &Path, raster: &Raster) {
    let is_hgt = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("hgt"));
    if is_hgt && raster.georef.is_none() {
        eprintln!(
            "wavemesh: warning: {}: not named like an SRTM tile (e.g. N57E011.hgt), so it has no georeferencing",
            path.display()
        );
    }
}

/// A reader's error, with the option that lifts a limit named.
fn read_failure(path: &Path, error: DemError) -> CliError {
    let hint = match error {
        DemError::TooLarge { .. } => "raise --max-samples if the file is trusted",
        DemError::OverMemory { .. } => "raise --max-memory if the machine has it",
        DemError::BandOverLimit { unit: "bytes", .. } => "raise --max-memory if the machine has it",
        DemError::BandOverLimit { .. } => "raise --max-samples if the file is trusted",
        DemError::LossyInput(_) => "--accept-lossy-input reads them anyway",
        other => return CliError::Dem(other),
    };
    CliError::Input(path.to_path_buf(), format!("{error}; {hint}"))
}

/// A command failure, by cause.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// A DEM could not be read.
    #[error("{path}: {message}", path = .0.display(), message = .1)]
    Input(PathBuf, String),
    /// A DEM reader or writer failed (its message names the file).
    #[error("{0}")]
    Dem(dem::DemError),
    /// A DEM writer failed (its message names the file).
    #[error("{0}")]
    DemOutput(dem::DemError),
    /// A `.ezw` file could not be decoded.
    #[error("{path}: {error}{hint}", path = .0.display(), error = .1, hint = limit_hint(.1))]
    Stream(PathBuf, CodecError),
    /// Encoding failed.
    #[error("{0}")]
    Encode(CodecError),
    /// An output could not be written.
    #[error("{path}: {message}", path = .0.display(), message = .1)]
    Output(PathBuf, String),
    /// `verify` found damage (the report is already printed).
    #[error("{}: damaged (see the report above)", .0.display())]
    Damaged(PathBuf),
    /// The work would exceed `--max-memory` or `--max-samples` (the message names which).
    #[error("{0}")]
    OverLimit(String),
    /// A check failed: `encode --verify`, or `compare` found the rasters' voids differ.
    #[error("{0}")]
    CheckFailed(String),
    /// Arguments that clap cannot check alone.
    #[error("{0}")]
    Usage(String),
}

/// The options that lift a decoder limit, for messages about one.
fn limit_hint(error: &CodecError) -> &'static str {
    match error {
        CodecError::LimitExceeded { .. } => {
            "; raise --max-samples or --max-memory if the file is trusted"
        }
        _ => "",
    }
}

/// Process exit codes, one per kind of cause (the README's table).
pub mod exit {
    /// A check failed: `encode --verify`, `compare` with mismatched voids, an encoder fault.
    pub const CHECK_FAILED: u8 = 1;
    /// Bad arguments.
    pub const USAGE: u8 = 2;
    /// Input unreadable, invalid, damaged (`verify`, `--strict`), or over a limit.
    pub const BAD_INPUT: u8 = 3;
    /// An output could not be written.
    pub const OUTPUT: u8 = 4;
}

impl CliError {
    /// Process exit code (see [`exit`]).
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Usage(_) => exit::USAGE,
            CliError::Input(..)
            | CliError::Stream(..)
            | CliError::Dem(_)
            | CliError::Damaged(_)
            | CliError::OverLimit(_) => exit::BAD_INPUT,
            CliError::Output(..) | CliError::DemOutput(_) => exit::OUTPUT,
            CliError::Encode(CodecError::InvalidParameters(_)) => exit::USAGE,
            CliError::Encode(CodecError::UnsupportedValues(_)) => exit::BAD_INPUT,
            CliError::Encode(_) | CliError::CheckFailed(_) => exit::CHECK_FAILED,
        }
    }
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Encode(args) => coding::encode(&args),
        Command::Decode(args) => coding::decode(&args),
        Command::Info(args) => coding::info(&args),
        Command::Verify(args) => verify::run(&args),
        Command::Compare(args) => coding::compare(&args),
        Command::Mesh(args) => mesh::mesh(&args),
        Command::Table(args) => mesh::table(&args),
        Command::CompareMeshers(args) => meshers::compare(&args),
        Command::Demo(args) => demo::run(&args),
        Command::Report(args) => report::run(&args),
        Command::Synth(args) => synth::run(&args),
        Command::View(args) => view::view(&args),
        Command::Flythrough(args) => view::flythrough(&args),
    }
}

/// A spinner on stderr while `work` runs, shown only on a terminal.
fn with_progress<T>(message: &str, work: impl FnOnce() -> T) -> T {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return work();
    }
    let bar = indicatif::ProgressBar::new_spinner().with_message(message.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(100));
    let out = work();
    bar.finish_and_clear();
    out
}

/// The raster an encode or decode works through, for its progress bar.
#[derive(Debug, Clone, Copy)]
struct Workload {
    samples: u64,
    bytes: u64,
}

impl Workload {
    fn of(raster: &Raster) -> Workload {
        Workload::new(raster.len() as u64, raster.sample_type())
    }

    fn new(samples: u64, sample_type: wavemesh_codec::SampleType) -> Workload {
        Workload {
            samples,
            bytes: samples * sample_type.bytes() as u64,
        }
    }
}

/// A progress bar on stderr while an encode or decode runs (on a terminal only): the
/// codec's stage, percent, samples swept, MB/s of raster and the time left.
fn with_codec_progress<T>(message: &str, load: Workload, work: impl FnOnce() -> T) -> T {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return work();
    }
    let style = indicatif::ProgressStyle::with_template(
        "{spinner} {prefix} [{wide_bar}] {percent:>3}% {msg} ETA {eta}",
    )
    .expect("a valid template")
    .progress_chars("=> ");
    let bar = indicatif::ProgressBar::new(1)
        .with_style(style)
        .with_prefix(message.to_string());
    bar.enable_steady_tick(std::time::Duration::from_millis(100));
    let start = Instant::now();
    let shown = bar.clone();
    let out = wavemesh_codec::progress::observe(
        move |p| {
            let fraction = p.done as f64 / p.total.max(1) as f64;
            let seconds = start.elapsed().as_secs_f64().max(1e-3);
            shown.set_length(p.total.max(1));
            shown.set_position(p.done);
            shown.set_message(format!(
                "{}: {:.1} of {:.1} Msamples, {:.1} MB/s",
                p.stage.name(),
                fraction * load.samples as f64 / 1e6,
                load.samples as f64 / 1e6,
                fraction * load.bytes as f64 / 1e6 / seconds
            ));
        },
        work,
    );
    bar.finish_and_clear();
    out
}

/// Prints a report as one line of JSON on stdout. serde_json writes non-finite floats
/// as null: an infinite PSNR (identical rasters) is null.
fn print_json<T: serde::Serialize>(value: &T) {
    println!(
        "{}",
        serde_json::to_string(value).expect("reports serialise")
    );
}

/// Wall-clock seconds of `work`, and the heap peak above the heap in use before it.
fn timed<T>(work: impl FnOnce() -> T) -> (T, f64, usize) {
    let start = Instant::now();
    let (out, peak) = wavemesh::memory::measure(work);
    (out, start.elapsed().as_secs_f64(), peak)
}
