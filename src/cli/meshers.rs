//! `mesh --method greedy|delaunay|qem` (meshes straight from the DEM) and `compare-meshers`
//! (every mesher at the same triangle budgets, as a table, JSON and a log–log plot).

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::ValueEnum;
use serde::Serialize;
use wavemesh::lod::Surface;
use wavemesh::mesh::export::{write_mesh, Placement};
use wavemesh::mesh::rasterise::{mesh_error, MeshError};
use wavemesh::meshers::{self, Budget, MeshRow, Method};
use wavemesh_codec::Raster;

use super::coding::SCHEMA_VERSION;
use super::{with_progress, CliError, InputArgs};

/// Which mesher `mesh` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    /// Quadtree cells from the zerotree (free with a decode).
    Zerotree,
    /// Greedy insertion with Delaunay flips, then flips that lower the squared error.
    Greedy,
    /// Greedy insertion with Delaunay flips only (Delatin's algorithm).
    Delaunay,
    /// QEM edge contraction straight on the height map.
    Qem,
    /// Edge collapse without new vertices (the variable-resolution model).
    Varres,
}

impl MethodArg {
    pub(super) fn method(self) -> Method {
        match self {
            MethodArg::Zerotree => Method::Zerotree,
            MethodArg::Greedy => Method::Greedy,
            MethodArg::Delaunay => Method::Delaunay,
            MethodArg::Qem => Method::Qem,
            MethodArg::Varres => Method::Varres,
        }
    }
}

/// The report of `mesh --method greedy|delaunay`.
#[derive(Debug, Serialize)]
struct DirectMeshReport<'a> {
    schema_version: u32,
    command: &'static str,
    method: &'static str,
    input: &'a Path,
    output: &'a Path,
    width: usize,
    height: usize,
    triangles: usize,
    vertices: usize,
    error: MeshError,
    mesh_seconds: f64,
    mesh_peak_heap_bytes: usize,
    /// The mesh file's format and bytes.
    format: &'static str,
    file_bytes: u64,
    /// Units of x and y, and the frame the vertices are in (as the zerotree's report).
    xy_units: &'static str,
    frame: serde_json::Value,
}

/// Meshes `raster` with `method` straight from its heights (no stream) and writes it.
pub fn mesh_direct(
    method: MethodArg,
    raster: &Raster,
    budget: Budget,
    placement: &Placement,
    (input, output): (&Path, &Path),
    json: bool,
) -> Result<(), CliError> {
    let format = super::mesh::mesh_format(output)?;
    let surface = Surface::of(raster);
    let start = Instant::now();
    let (mesh, peak) = with_progress("meshing", || {
        wavemesh::memory::measure(|| meshers::build(method.method(), raster, &surface, budget))
    });
    let mesh_seconds = start.elapsed().as_secs_f64();
    let mesh = mesh.map_err(|e| CliError::Input(input.to_path_buf(), e.to_string()))?;
    write_mesh(output, &mesh, &surface.heights, placement, format)
        .map_err(|e| CliError::Output(output.to_path_buf(), e.to_string()))?;
    let report = DirectMeshReport {
        schema_version: SCHEMA_VERSION,
        command: "mesh",
        method: method.method().name(),
        input,
        output,
        width: raster.width,
        height: raster.height,
        triangles: mesh.triangles.len(),
        vertices: mesh.vertices.len(),
        error: mesh_error(&mesh, &surface.heights, &surface.heights, &surface.valid),
        mesh_seconds,
        mesh_peak_heap_bytes: peak,
        format: format.name(),
        file_bytes: std::fs::metadata(output).map_or(0, |m| m.len()),
        xy_units: placement.frame_name(),
        frame: placement.frame_record(),
    };
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("reports serialise")
        );
    } else {
        println!(
            "mesh {} ({}, {}): {} triangles, {} vertices, {:.3} s\n  RMSE {:.4}  max error {:.4}",
            output.display(),
            format.name(),
            report.method,
            report.triangles,
            report.vertices,
            mesh_seconds,
            report.error.rmse,
            report.error.max_error
        );
    }
    Ok(())
}

/// A mesher of the comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodName {
    /// The zerotree mesher.
    Zerotree,
    /// Greedy insertion with data-dependent flips.
    Greedy,
    /// Greedy insertion with Delaunay flips only.
    Delaunay,
    /// QEM edge contraction on the height map.
    Qem,
    /// Edge collapse without new vertices (the variable-resolution model).
    Varres,
    /// The delatin crate.
    Delatin,
    /// The martini crate.
    Martini,
}

impl From<MethodName> for Method {
    fn from(m: MethodName) -> Method {
        match m {
            MethodName::Zerotree => Method::Zerotree,
            MethodName::Greedy => Method::Greedy,
            MethodName::Delaunay => Method::Delaunay,
            MethodName::Qem => Method::Qem,
            MethodName::Varres => Method::Varres,
            MethodName::Delatin => Method::Delatin,
            MethodName::Martini => Method::Martini,
        }
    }
}

#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// Input DEM.
    input: PathBuf,
    /// Comma-separated triangle budgets.
    #[arg(
        long,
        value_delimiter = ',',
        required_unless_present_any = ["mesh_errors", "qem_memory", "varres_metrics"]
    )]
    triangles: Vec<usize>,
    /// Comma-separated height tolerances (data units): also the mesh of each method
    /// within each (Martini and Delatin at their max-error parameter).
    #[arg(long, value_delimiter = ',', value_name = "E")]
    mesh_errors: Vec<f64>,
    /// Comma-separated methods (default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<MethodName>,
    /// Only this window of the DEM: column, row, width, height.
    #[arg(long, value_delimiter = ',', value_name = "X0,Y0,W,H")]
    window: Option<Vec<usize>>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
    /// Write a log–log SVG of RMSE against triangles here.
    #[arg(long, value_name = "SVG")]
    plot: Option<PathBuf>,
    /// Print the seed paper's memory table instead (QEM meshes at 100 %, 10 % and 1 % of
    /// the grid's triangles: triangle-mesh bytes against raster + flag map, heap peak).
    #[arg(long, conflicts_with_all = ["triangles", "mesh_errors", "methods", "plot"])]
    qem_memory: bool,
    /// Print seed paper 001's Table 1 instead (its average-plane metric against the
    /// distance-to-plane metric: mean distance at 62, 70 and 81 % of vertices removed).
    #[arg(long, conflicts_with_all = ["triangles", "mesh_errors", "methods", "plot", "qem_memory"])]
    varres_metrics: bool,
    #[command(flatten)]
    input_args: InputArgs,
}

#[derive(Serialize)]
struct CompareReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    width: usize,
    height: usize,
    rows: &'a [MeshRow],
    skipped: Vec<Skipped>,
}

#[derive(Serialize)]
struct Skipped {
    method: Method,
    reason: String,
}

pub fn compare(args: &CompareArgs) -> Result<(), CliError> {
    if args.triangles.contains(&0) {
        return Err(CliError::Usage("--triangles must be positive".into()));
    }
    if let Some(e) = args
        .mesh_errors
        .iter()
        .find(|e| !(e.is_finite() && **e >= 0.0))
    {
        return Err(CliError::Usage(format!(
            "--mesh-errors must be non-negative numbers, got {e}"
        )));
    }
    let budgets: Vec<Budget> = args
        .triangles
        .iter()
        .map(|&n| Budget::Triangles(n))
        .chain(args.mesh_errors.iter().map(|&e| Budget::MaxError(e)))
        .collect();
    let methods: Vec<Method> = if args.methods.is_empty() {
        Method::ALL.to_vec()
    } else {
        args.methods.iter().map(|&m| m.into()).collect()
    };
    let mut raster = args.input_args.read(&args.input)?;
    if let Some(w) = &args.window {
        if w.len() != 4 {
            return Err(CliError::Usage("--window takes X0,Y0,W,H".into()));
        }
        raster = meshers::window(&raster, w[0], w[1], w[2], w[3]).ok_or_else(|| {
            CliError::Usage(format!(
                "--window {},{},{},{} is not inside the {}x{} DEM",
                w[0], w[1], w[2], w[3], raster.width, raster.height
            ))
        })?;
    }
    if args.qem_memory {
        return qem_memory(args, &raster);
    }
    if args.varres_metrics {
        return super::varres::varres_metrics(&args.input, &raster, args.json);
    }
    let (rows, skipped) = with_progress("meshing", || {
        meshers::compare(&raster, &methods, &budgets, args.input_args.max_memory())
    });
    if let Some(path) = &args.plot {
        let name = args.input.file_name().unwrap_or_default().to_string_lossy();
        let title = format!("{name} ({}x{})", raster.width, raster.height);
        let svg = meshers::error_plot_svg(&rows, &title)
            .map_err(|e| CliError::Output(path.clone(), e.to_string()))?;
        wavemesh::atomic::write_atomic(path, |w| w.write_all(svg.as_bytes()))
            .map_err(|e| CliError::Output(path.clone(), e.to_string()))?;
    }
    let skipped: Vec<Skipped> = skipped
        .into_iter()
        .map(|(method, reason)| Skipped { method, reason })
        .collect();
    if args.json {
        let report = CompareReport {
            schema_version: SCHEMA_VERSION,
            command: "compare-meshers",
            input: &args.input,
            width: raster.width,
            height: raster.height,
            rows: &rows,
            skipped,
        };
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("reports serialise")
        );
    } else {
        print!("{}", markdown(&rows));
        for s in &skipped {
            println!("{}: skipped ({})", s.method.name(), s.reason);
        }
    }
    Ok(())
}

/// `compare-meshers --qem-memory`: the seed paper's Table 1 for one DEM.
fn qem_memory(args: &CompareArgs, raster: &Raster) -> Result<(), CliError> {
    let rows = with_progress("simplifying", || meshers::qem_memory_table(raster))
        .map_err(|e| CliError::Input(args.input.clone(), e.to_string()))?;
    if args.json {
        let report = serde_json::json!({
            "schema_version": SCHEMA_VERSION,
            "command": "compare-meshers",
            "input": args.input,
            "width": raster.width,
            "height": raster.height,
            "qem_memory": rows,
        });
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("reports serialise")
        );
        return Ok(());
    }
    let name = args.input.file_name().unwrap_or_default().to_string_lossy();
    println!("| DEM | kept | triangles | vertices | triangle mesh KB | raster + flag map KB | measured peak KB | build s |\n|---|---:|---:|---:|---:|---:|---:|---:|");
    for r in &rows {
        println!(
            "| {name} | {} % | {} | {} | {} | {} | {} | {:.2} |",
            r.percent,
            r.triangles,
            r.vertices,
            r.mesh_bytes / 1024,
            r.raster_and_flags_bytes / 1024,
            r.peak_heap_bytes / 1024,
            r.build_seconds
        );
    }
    Ok(())
}

/// The rows as a Markdown table.
fn markdown(rows: &[MeshRow]) -> String {
    let mut s = String::from(
        "| mesher | budget | triangles | vertices | RMSE | max error | uncovered | build s | build CPU s | peak heap MB |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {:.4} | {:.3} | {} | {:.3} | {} | {:.1} |\n",
            r.method.name(),
            match r.budget {
                Budget::Triangles(n) => format!("{n} triangles"),
                Budget::MaxError(e) => format!("error {e}"),
            },
            r.triangles,
            r.vertices,
            r.rmse,
            r.max_error,
            r.uncovered,
            r.build_seconds,
            r.build_cpu_seconds
                .map_or_else(|| "n/a".into(), |s| format!("{s:.3}")),
            r.peak_heap_bytes as f64 / 1e6
        ));
    }
    s
}
