//! Every mesher on one DEM: ours (the zerotree mesher, greedy insertion with Delaunay
//! flips as Delatin does, and greedy insertion refined by error-lowering flips) and two
//! peers from crates.io (`delatin`, `martini`), at the same triangle budgets, each
//! measured the same way (rasterised back onto every sample), timed and with its heap
//! peak.

use std::time::Instant;

use serde::Serialize;
use wavemesh_codec::{decode, encode, CodecError, DecodeOptions, EncodeOptions, Raster, Samples};

use crate::lod::Surface;
use crate::memory;
use crate::mesh::cells::SplitRule;
use crate::mesh::greedy::{greedy_mesh, GreedyError, GreedyTarget};
use crate::mesh::qem::grid::GridError;
use crate::mesh::qem::{qem_mesh, QemTarget};
use crate::mesh::rasterise::mesh_error;
use crate::mesh::varres::{varres_mesh, VarresTarget};
use crate::mesh::{GridMesh, MeshTarget, Mesher};

/// Passes of error-lowering flips after greedy insertion (more change little: measured
/// on fuji 512², 4 and 20 passes give RMSE within 0.01 %).
pub const OPTIMISE_PASSES: usize = 2;

/// A mesher.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// The zerotree mesher (quadtree cells; budgets searched over height tolerances).
    Zerotree,
    /// Greedy insertion with Delaunay flips, then flips that lower the squared error.
    Greedy,
    /// Greedy insertion with Delaunay flips only (Delatin's algorithm, ours).
    Delaunay,
    /// QEM edge contraction straight on the height map (seed paper 000).
    Qem,
    /// Edge collapse without new vertices, out of the variable-resolution model (seed
    /// paper 001).
    Varres,
    /// The `delatin` crate (budgets searched over its max error).
    Delatin,
    /// The `martini` crate (2^k + 1 grids; budgets searched over its max error).
    Martini,
}

impl Method {
    /// Every method, ours first.
    pub const ALL: [Method; 7] = [
        Method::Zerotree,
        Method::Greedy,
        Method::Delaunay,
        Method::Qem,
        Method::Varres,
        Method::Delatin,
        Method::Martini,
    ];

    /// Heap a build may take per sample of the raster, at most: the peaks of near-full
    /// meshes (the bundled jacksboro sample at E = 0.5, `compare-meshers --json`:
    /// zerotree 52, greedy 198, delaunay 144, qem 147, varres 511, delatin 440 bytes a
    /// sample) with a quarter more.
    pub fn peak_bytes_per_sample(self) -> u64 {
        match self {
            Method::Zerotree => 65,
            Method::Greedy | Method::Martini => 250,
            Method::Delaunay | Method::Qem => 185,
            Method::Varres => 640,
            Method::Delatin => 550,
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Zerotree => "zerotree",
            Method::Greedy => "greedy",
            Method::Delaunay => "delaunay",
            Method::Qem => "qem",
            Method::Varres => "varres",
            Method::Delatin => "delatin",
            Method::Martini => "martini",
        }
    }
}

/// What a mesh is asked to meet.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Budget {
    /// At most this many triangles.
    Triangles(usize),
    /// Every valid sample within this many data units.
    MaxError(f64),
}

/// Why a comparison failed.
#[derive(Debug, thiserror::Error)]
pub enum MeshersError {
    /// The greedy mesher refused the grid.
    #[error("{0}")]
    Greedy(#[from] GreedyError),
    /// The QEM or variable-resolution mesher refused the grid.
    #[error("{0}")]
    Grid(#[from] GridError),
    /// The zerotree mesher's encode or decode failed.
    #[error("{0}")]
    Codec(#[from] CodecError),
    /// A peer mesher failed.
    #[error("{0}: {1}")]
    Peer(&'static str, String),
    /// The method cannot mesh this grid.
    #[error("{0} cannot mesh this grid: {1}")]
    Unsupported(&'static str, &'static str),
}

/// One mesh of the comparison.
#[derive(Debug, Clone, Serialize)]
pub struct MeshRow {
    /// The mesher.
    pub method: Method,
    /// What was asked for.
    pub budget: Budget,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Vertices of the mesh.
    pub vertices: usize,
    /// RMSE over the valid samples the mesh covers, data units.
    pub rmse: f64,
    /// Largest error at any such sample, data units.
    pub max_error: f64,
    /// Valid samples no triangle covers.
    pub uncovered: u64,
    /// Seconds to build the mesh (for a budget search, the whole search).
    pub build_seconds: f64,
    /// CPU seconds of the process's threads while building (Linux; `None` elsewhere):
    /// unlike wall-clock seconds, not inflated by other processes on a busy machine.
    pub build_cpu_seconds: Option<f64>,
    /// Heap peak while building, bytes.
    pub peak_heap_bytes: usize,
}

/// The mesh of `raster` (whose heights are `surface`) by `method` meeting `budget`.
pub fn build(
    method: Method,
    raster: &Raster,
    surface: &Surface,
    budget: Budget,
) -> Result<GridMesh, MeshersError> {
    let (w, h) = (surface.width, surface.height);
    let greedy_target = match budget {
        Budget::Triangles(n) => GreedyTarget::Triangles(n),
        Budget::MaxError(e) => GreedyTarget::MaxError(e),
    };
    match method {
        Method::Greedy => Ok(greedy_mesh(
            w,
            h,
            &surface.heights,
            &surface.valid,
            greedy_target,
            Some(OPTIMISE_PASSES),
        )?),
        Method::Delaunay => Ok(greedy_mesh(
            w,
            h,
            &surface.heights,
            &surface.valid,
            greedy_target,
            None,
        )?),
        Method::Qem => {
            let target = match budget {
                Budget::Triangles(n) => QemTarget::Triangles(n),
                Budget::MaxError(e) => QemTarget::MaxError(e),
            };
            Ok(qem_mesh(w, h, &surface.heights, &surface.valid, target)?.mesh)
        }
        Method::Varres => {
            let target = match budget {
                Budget::Triangles(n) => VarresTarget::Triangles(n),
                Budget::MaxError(e) => VarresTarget::MaxError(e),
            };
            Ok(varres_mesh(w, h, &surface.heights, &surface.valid, target)?)
        }
        Method::Zerotree => zerotree(raster, surface, budget),
        Method::Delatin | Method::Martini => {
            if surface.valid.not_any() || !surface.valid.all() {
                return Err(MeshersError::Unsupported(method.name(), "it has nodata"));
            }
            match budget {
                Budget::MaxError(e) => peer(method, surface, e),
                Budget::Triangles(n) => peer_within(method, surface, n),
            }
        }
    }
}

/// The zerotree mesh: lossless stream, decode with the significance map, tolerance or
/// tolerance-searched budget.
fn zerotree(raster: &Raster, surface: &Surface, budget: Budget) -> Result<GridMesh, MeshersError> {
    let encoded = encode(raster, &EncodeOptions::zerotree_mesh())?;
    let options = DecodeOptions::default().with_significance_map(true);
    let decoded = decode(&encoded.bytes, &options)?;
    let map = decoded.significance.as_ref().expect("asked for");
    let mut mesher = Mesher::new(map, surface.heights(), &surface.valid);
    let target = match budget {
        Budget::Triangles(n) => MeshTarget::TrianglesByTolerance(n),
        Budget::MaxError(e) => MeshTarget::Tolerance(e),
    };
    Ok(mesher.build(target, SplitRule::Zerotree, None).mesh)
}

/// A peer's mesh at max error `e`.
fn peer(method: Method, surface: &Surface, e: f64) -> Result<GridMesh, MeshersError> {
    let (w, h) = (surface.width, surface.height);
    let (vertices, triangles) = match method {
        Method::Delatin => {
            let (points, triangles) =
                delatin::triangulate(&surface.heights, (w, h), delatin::Error(e))
                    .map_err(|err| MeshersError::Peer("delatin", err.to_string()))?;
            let vertices = points.iter().map(|&(x, y)| (y * w + x) as u32).collect();
            let triangles = triangles
                .iter()
                .map(|&(a, b, c)| [a as u32, b as u32, c as u32])
                .collect();
            (vertices, triangles)
        }
        _ => martini_mesh(surface, e)?,
    };
    Ok(GridMesh {
        width: w,
        height: h,
        vertices,
        triangles,
    })
}

/// Martini's mesh at max error `e` (square `2^k + 1` grids only).
fn martini_mesh(surface: &Surface, e: f64) -> Result<(Vec<u32>, Vec<[u32; 3]>), MeshersError> {
    let side = surface.width;
    if surface.height != side || side < 3 || !(side - 1).is_power_of_two() {
        return Err(MeshersError::Unsupported(
            "martini",
            "it needs a 2^k + 1 square",
        ));
    }
    let mut martini = martini::Martini::new(side as u32);
    let tile = martini.create_terrain(|x, y| surface.heights[y * side + x]);
    // Martini hands the transform (u, v) = (x, 1 − y) / (side − 1).
    let max = (side - 1) as f64;
    let (positions, indices, _) = tile.construct_mesh(&mut martini, e, &mut |(u, v)| {
        (u * max, (1.0 - v) * max, 0.0)
    });
    let vertices = positions
        .chunks_exact(3)
        .map(|p| (p[1].round() as usize * side + p[0].round() as usize) as u32)
        .collect();
    let triangles = indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    Ok((vertices, triangles))
}

/// The peer's largest mesh within `n` triangles: bisection on log max error.
fn peer_within(method: Method, surface: &Surface, n: usize) -> Result<GridMesh, MeshersError> {
    let range = surface
        .valid
        .iter_ones()
        .map(|s| surface.heights[s])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let (mut lo, mut hi) = (
        ((range.1 - range.0) * 1e-6).max(1e-9),
        (range.1 - range.0).max(1e-9),
    );
    let mut best = peer(method, surface, hi)?;
    for _ in 0..16 {
        let mid = (lo * hi).sqrt();
        let mesh = peer(method, surface, mid)?;
        if mesh.triangles.len() <= n {
            hi = mid;
            if mesh.triangles.len() >= best.triangles.len() {
                best = mesh;
            }
        } else {
            lo = mid;
        }
    }
    Ok(best)
}

/// Builds and measures `method`'s mesh of `raster` (heights `surface`) meeting `budget`.
pub fn measure(
    method: Method,
    raster: &Raster,
    surface: &Surface,
    budget: Budget,
) -> Result<MeshRow, MeshersError> {
    let (start, cpu_start) = (Instant::now(), process_cpu_seconds());
    let (mesh, peak) = memory::measure(|| build(method, raster, surface, budget));
    let build_seconds = start.elapsed().as_secs_f64();
    let build_cpu_seconds = cpu_start.and_then(|s| Some(process_cpu_seconds()? - s));
    let mesh = mesh?;
    let error = mesh_error(&mesh, &surface.heights, &surface.heights, &surface.valid);
    Ok(MeshRow {
        method,
        budget,
        triangles: mesh.triangles.len(),
        vertices: mesh.vertices.len(),
        rmse: error.rmse,
        max_error: error.max_error,
        uncovered: error.uncovered_samples,
        build_seconds,
        build_cpu_seconds,
        peak_heap_bytes: peak,
    })
}

/// CPU seconds every thread of this process has run (`CLOCK_PROCESS_CPUTIME_ID`, exact
/// to the nanosecond: the building thread's and, for a mesher that splits its work, its
/// helpers'). `/proc/self/task/*/schedstat`, read before, advanced the running thread
/// only at the scheduler's tick (4 ms here), too coarse for builds of a few ms.
#[cfg(unix)]
fn process_cpu_seconds() -> Option<f64> {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid, writable timespec for the call's duration.
    let done = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut now) };
    (done == 0).then_some(now.tv_sec as f64 + now.tv_nsec as f64 * 1e-9)
}

/// No process CPU clock off Unix.
#[cfg(not(unix))]
fn process_cpu_seconds() -> Option<f64> {
    None
}

/// Every method in `methods` at every budget in `budgets` (methods that cannot mesh the
/// grid, or may need more than `max_memory` bytes for it, are left out, with the reason).
pub fn compare(
    raster: &Raster,
    methods: &[Method],
    budgets: &[Budget],
    max_memory: u64,
) -> (Vec<MeshRow>, Vec<(Method, String)>) {
    let surface = Surface::of(raster);
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for &method in methods {
        let needed = method.peak_bytes_per_sample() * raster.len() as u64;
        if needed > max_memory {
            skipped.push((
                method,
                format!("may need {needed} bytes, more than the memory limit {max_memory}"),
            ));
            continue;
        }
        for &n in budgets {
            match measure(method, raster, &surface, n) {
                Ok(row) => rows.push(row),
                Err(e) => {
                    skipped.push((method, e.to_string()));
                    break;
                }
            }
        }
    }
    (rows, skipped)
}

/// The `w × h` window at `(x0, y0)` of `raster`, or `None` when it does not fit.
pub fn window(raster: &Raster, x0: usize, y0: usize, w: usize, h: usize) -> Option<Raster> {
    if x0 + w > raster.width || y0 + h > raster.height || w == 0 || h == 0 {
        return None;
    }
    let values: Vec<f64> = (y0..y0 + h)
        .flat_map(|y| (x0..x0 + w).map(move |x| y * raster.width + x))
        .map(|i| raster.samples.get_f64(i))
        .collect();
    let samples = Samples::from_f64(raster.samples.sample_type(), &values);
    let mut out = Raster::new(w, h, samples).ok()?;
    out.nodata = raster.nodata;
    Some(out)
}

/// Log–log SVG of RMSE against triangles, one line per method.
pub fn error_plot_svg(rows: &[MeshRow], title: &str) -> Result<String, MeshersError> {
    use plotters::prelude::*;
    let plot_error = |e: String| MeshersError::Peer("plotters", e);
    let shown: Vec<&MeshRow> = rows
        .iter()
        .filter(|r| r.triangles > 0 && r.rmse > 0.0)
        .collect();
    let span = |f: fn(&MeshRow) -> f64| {
        shown
            .iter()
            .map(|r| f(r))
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (t_lo, t_hi) = span(|r| r.triangles as f64);
    let (e_lo, e_hi) = span(|r| r.rmse);
    if shown.is_empty() {
        return Err(MeshersError::Unsupported(
            "plot",
            "no mesh with error to draw",
        ));
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (800, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_error(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (t_lo * 0.8..t_hi * 1.25).log_scale(),
                (e_lo * 0.8..e_hi * 1.25).log_scale(),
            )
            .map_err(|e| plot_error(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("triangles")
            .y_desc("RMSE (data units)")
            .draw()
            .map_err(|e| plot_error(e.to_string()))?;
        for (k, method) in Method::ALL.iter().enumerate() {
            let points: Vec<(f64, f64)> = shown
                .iter()
                .filter(|r| r.method == *method)
                .map(|r| (r.triangles as f64, r.rmse))
                .collect();
            if points.is_empty() {
                continue;
            }
            let colour = Palette99::pick(k).to_rgba();
            chart
                .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                .map_err(|e| plot_error(e.to_string()))?
                .label(method.name())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(|e| plot_error(e.to_string()))?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| plot_error(e.to_string()))?;
        root.present().map_err(|e| plot_error(e.to_string()))?;
    }
    Ok(svg)
}

/// One row of the seed paper's Table 1 for a QEM mesh: its size as a triangle mesh
/// against the height raster and flag map it is extracted from.
#[derive(Debug, Clone, Serialize)]
pub struct QemMemoryRow {
    /// Share of the grid's triangles kept, percent.
    pub percent: f64,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Vertices of the mesh.
    pub vertices: usize,
    /// The mesh as the paper counts a triangle mesh with adjacency: 24 bytes a triangle,
    /// 17 a vertex.
    pub mesh_bytes: usize,
    /// The height raster at 4 bytes a sample (as the paper) and the 4-bit flag map.
    pub raster_and_flags_bytes: usize,
    /// Heap peak of the simplification (quadrics, merger pointers, heap, flag map,
    /// extracted mesh), bytes.
    pub peak_heap_bytes: usize,
    /// Seconds to simplify and extract.
    pub build_seconds: f64,
}

/// The paper's Table 1 for `raster`: QEM meshes keeping 100 %, 10 % and 1 % of the
/// grid's triangles.
pub fn qem_memory_table(raster: &Raster) -> Result<Vec<QemMemoryRow>, MeshersError> {
    let surface = Surface::of(raster);
    let (w, h) = (surface.width, surface.height);
    let all = 2 * w.saturating_sub(1) * h.saturating_sub(1);
    let mut rows = Vec::new();
    for percent in [100.0, 10.0, 1.0] {
        let budget = (all as f64 * percent / 100.0).round() as usize;
        let start = Instant::now();
        let (mesh, peak) = memory::measure(|| {
            qem_mesh(
                w,
                h,
                &surface.heights,
                &surface.valid,
                QemTarget::Triangles(budget),
            )
        });
        let build_seconds = start.elapsed().as_secs_f64();
        let out = mesh?;
        rows.push(QemMemoryRow {
            percent,
            triangles: out.mesh.triangles.len(),
            vertices: out.mesh.vertices.len(),
            mesh_bytes: 24 * out.mesh.triangles.len() + 17 * out.mesh.vertices.len(),
            raster_and_flags_bytes: 4 * w * h + out.flags.bytes(),
            peak_heap_bytes: peak,
            build_seconds,
        });
    }
    Ok(rows)
}
