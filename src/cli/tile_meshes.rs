//! `mesh DEM -o FOLDER --tile-meshes`: one glb per tile, crack-free across tiles, the DEM
//! read a tile row at a time (`wavemesh::mesh::tiled`).

use std::path::{Path, PathBuf};

use serde::Serialize;
use wavemesh::mesh::tiled::{
    write_tile_meshes, TileMeshError, TileMeshOptions, TiledMeshes, INDEX_FILE,
};

use super::coding::SCHEMA_VERSION;
use super::mesh::MeshOptions;
use super::tiled_coding::TileRowBar;
use super::{read_failure, timed, CliError, InputArgs, Workload};

/// Bytes a tile sample may need while it is coded, decoded and meshed at once (the
/// encoder's 20, the mesher's 96 for tolerance meshes; see `mesh`'s memory check).
const TILE_WORK_PER_SAMPLE: u64 = 20 + 96;

/// The options of `mesh --tile-meshes`.
#[derive(Debug, Clone, clap::Args)]
pub struct TilingArgs {
    /// Write one glb per tile into the folder -o names (made if missing), with an index
    /// `tiles.json`; neighbouring tiles share their border vertices exactly. The DEM is
    /// read a tile row at a time. Lossless zerotree meshes only (no --bpp, no --method).
    #[arg(long, conflicts_with = "method")]
    tile_meshes: bool,
    /// Largest tile side of --tile-meshes, in samples (tiles as equal as the DEM allows).
    #[arg(
        long,
        value_name = "N",
        default_value_t = 1024,
        requires = "tile_meshes"
    )]
    tile: usize,
    /// Threads meshing tiles at once with --tile-meshes (0: one per core). The output
    /// does not depend on it.
    #[arg(long, value_name = "N", default_value_t = 0, requires = "tile_meshes")]
    threads: usize,
}

impl TilingArgs {
    /// Whether `--tile-meshes` was given.
    pub fn enabled(&self) -> bool {
        self.tile_meshes
    }
}

/// The `--json` report of a tiled mesh run.
#[derive(Serialize)]
struct TileMeshReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    output: &'a Path,
    index: PathBuf,
    threads: usize,
    tile_count: usize,
    tiles_written: usize,
    triangles: usize,
    vertices: usize,
    max_error: f64,
    seconds: f64,
    msamples_per_second: f64,
    peak_heap_bytes: usize,
    #[serde(flatten)]
    meshes: &'a TiledMeshes,
}

/// Meshes `input` tile by tile into the folder `output`.
pub fn mesh_tiles(
    (input, output): (&Path, &Path),
    mesh: &MeshOptions,
    tiling: &TilingArgs,
    input_args: &InputArgs,
    json: bool,
) -> Result<(), CliError> {
    if output.as_os_str() == "-" {
        return Err(CliError::Usage(
            "--tile-meshes writes a folder, not standard output (-)".into(),
        ));
    }
    if tiling.tile == 0 {
        return Err(CliError::Usage(
            "--tile must be at least 1 with --tile-meshes".into(),
        ));
    }
    let (target, rule) = mesh.tile_target()?;
    let mut bands = input_args.open_bands(input)?;
    let info = bands.info().clone();
    let placement = mesh
        .placement_for(info.georef.as_ref(), info.width, info.height)
        .map_err(|e| CliError::Input(input.to_path_buf(), e.to_string()))?;
    let threads = match tiling.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    };
    check_memory(&info, tiling.tile, threads, input_args.max_memory())?;
    let mut options = TileMeshOptions::new(&info, placement, target);
    options.tile = tiling.tile;
    options.rule = rule;
    options.threads = threads;
    let samples = (info.width * info.height) as u64;
    let grid = wavemesh::mesh::tiled::mesh_grid(info.width, info.height, tiling.tile);
    let bar = TileRowBar::new(
        "meshing",
        &grid,
        Workload::new(samples, info.sample_type),
        json,
    );
    let (meshes, seconds, peak) =
        timed(|| write_tile_meshes(&mut bands, output, &options, &mut |k| bar.show(k)));
    bar.finish();
    let meshes = meshes.map_err(|e| cli_error(e, input, output))?;
    let report = TileMeshReport {
        schema_version: SCHEMA_VERSION,
        command: "mesh",
        input,
        output,
        index: output.join(INDEX_FILE),
        threads,
        tile_count: meshes.tiles.len(),
        tiles_written: meshes.tiles.iter().filter(|t| t.file.is_some()).count(),
        triangles: meshes.triangles(),
        vertices: meshes.vertices(),
        max_error: meshes.max_error(),
        seconds,
        msamples_per_second: samples as f64 / 1e6 / seconds.max(1e-9),
        peak_heap_bytes: peak,
        meshes: &meshes,
    };
    print_report(&report, json);
    Ok(())
}

/// Refuses a run whose tiles, `threads` at a time, may need more than `max_memory`.
fn check_memory(
    info: &wavemesh::dem::DemInfo,
    tile: usize,
    threads: usize,
    max_memory: u64,
) -> Result<(), CliError> {
    let side = |len: usize| (tile.min(len) + 1) as u64;
    let per_tile = side(info.width) * side(info.height) * TILE_WORK_PER_SAMPLE;
    let needed = per_tile.saturating_mul(threads as u64);
    if needed > max_memory {
        return Err(CliError::OverLimit(format!(
            "meshing {threads} tiles of {tile} samples a side at once may need {needed} bytes, more than --max-memory {max_memory}; raise it, or lower --tile or --threads"
        )));
    }
    Ok(())
}

/// The command line's error for a library one.
fn cli_error(error: TileMeshError, input: &Path, output: &Path) -> CliError {
    match error {
        TileMeshError::Read(e) => read_failure(input, e),
        TileMeshError::NothingToMesh { .. } => {
            CliError::Input(input.to_path_buf(), error.to_string())
        }
        TileMeshError::BadTile(_) => CliError::Usage(error.to_string()),
        TileMeshError::Encode(e) => CliError::Encode(e),
        TileMeshError::Decode(e) => CliError::Stream(input.to_path_buf(), e),
        TileMeshError::BoundMissed { .. } | TileMeshError::Threads(_) => {
            CliError::CheckFailed(error.to_string())
        }
        TileMeshError::NotAFolder(_) => CliError::Output(
            output.to_path_buf(),
            "exists and is not a folder (--tile-meshes writes a folder)".into(),
        ),
        other => CliError::Output(output.to_path_buf(), other.to_string()),
    }
}

/// Prints the report: one JSON object, or a few lines of text.
fn print_report(report: &TileMeshReport, json: bool) {
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(report).expect("reports serialise")
        );
        return;
    }
    let m = report.meshes;
    println!(
        "{}: {}x{} in {} x {} tiles of {}x{}: {} glb files and {} in {}",
        report.input.display(),
        m.width,
        m.height,
        m.columns,
        m.rows,
        m.tile_width,
        m.tile_height,
        report.tiles_written,
        INDEX_FILE,
        report.output.display()
    );
    println!(
        "  {} triangles, {} vertices, max error {:.4}; {:.2} s on {} threads, heap peak {:.1} MiB",
        report.triangles,
        report.vertices,
        report.max_error,
        report.seconds,
        report.threads,
        report.peak_heap_bytes as f64 / (1 << 20) as f64
    );
}
