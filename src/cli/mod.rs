//! Subcommands, their arguments and the error type the binary maps to exit codes.

mod coding;
mod demo;
mod mesh;
mod meshers;
mod report;
mod verify;

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Parser, Subcommand, ValueEnum};
use wavemesh::dem::{self, ReadOptions};
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
}

impl From<WaveletArg> for Wavelet {
    fn from(w: WaveletArg) -> Wavelet {
        match w {
            WaveletArg::Cdf97 => Wavelet::Cdf97,
            WaveletArg::Int53 => Wavelet::Int53,
        }
    }
}

/// Options shared by commands that read DEM files.
#[derive(Debug, Clone, clap::Args)]
pub struct InputArgs {
    /// Read PNG input as Mapbox Terrain-RGB (h = -10000 + (R·65536 + G·256 + B)·0.1).
    #[arg(long)]
    terrain_rgb: bool,
    /// Refuse inputs with more samples than this.
    #[arg(long, default_value_t = 1 << 31)]
    max_samples: u64,
}

impl InputArgs {
    fn read(&self, path: &Path) -> Result<Raster, CliError> {
        let options = ReadOptions {
            terrain_rgb: self.terrain_rgb,
            max_samples: self.max_samples,
        };
        dem::read_dem(path, &options).map_err(CliError::Dem)
    }

    fn limits(&self, max_memory: u64) -> Limits {
        Limits {
            max_samples: self.max_samples,
            max_memory,
        }
    }
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
    #[error("{path}: {error}", path = .0.display(), error = .1)]
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
    /// Arguments that clap cannot check alone.
    #[error("{0}")]
    Usage(String),
}

impl CliError {
    /// Process exit code: 2 usage, 3 unreadable or invalid input, 4 output failure,
    /// 1 anything else.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Usage(_) => 2,
            CliError::Input(..)
            | CliError::Stream(..)
            | CliError::Dem(_)
            | CliError::Damaged(_) => 3,
            CliError::Output(..) | CliError::DemOutput(_) => 4,
            CliError::Encode(_) => 1,
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

/// Wall-clock seconds of `work`, and the heap peak above the heap in use before it.
fn timed<T>(work: impl FnOnce() -> T) -> (T, f64, usize) {
    let start = Instant::now();
    let (out, peak) = wavemesh::memory::measure(work);
    (out, start.elapsed().as_secs_f64(), peak)
}
