//! `view` (one view-dependent mesh for a camera) and `flythrough` (a camera path, frame
//! after frame, with incremental split/merge, geomorphing and their measurements).

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::ValueEnum;
use glam::DVec3;
use serde::Serialize;
use wavemesh::lod::{decoded_plane, Surface};
use wavemesh::mesh::cells::CellTree;
use wavemesh::mesh::export::{write_mesh, MeshFormat, Placement};
use wavemesh::mesh::GridMesh;
use wavemesh::view::camera::{Camera, View};
use wavemesh::view::checks::{count_cracks, max_jump, Surface as FrameSurface};
use wavemesh::view::compare::{area_rule_matching, screen_error, sse_rule_matching, ScreenError};
use wavemesh::view::incremental::Incremental;
use wavemesh::view::morph::{morph, MorphScratch};
use wavemesh::view::render::{top_down, write_png};
use wavemesh::view::selection::{Rule, ViewTerrain};
use wavemesh::view::ViewError;
use wavemesh_codec::tiles::TiledLayout;
use wavemesh_codec::{decode, CodecError, DecodeOptions, Decoded};

use super::coding::SCHEMA_VERSION;
use super::{CliError, LimitArgs};
use wavemesh::mesh::tiled::has_valid_cell;

/// Which rule sets the per-region thresholds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RuleKind {
    /// Screen-space error: a cell stays whole while its height error spans ≤ τ pixels.
    Sse,
    /// The seed paper's T_i = a·(A_n/A_i) + b on the zerotree.
    Area,
}

/// x/y units of the view (camera included).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ViewXy {
    /// The DEM's CRS units through the geotransform; a geographic DEM in metres east and
    /// north of its centre (the tangent plane there); pixel units without
    /// georeferencing. z = stored value × z-scale.
    Geo,
    /// x = column, y = row, z = stored value × z-scale.
    Pixel,
}

/// Camera and rule options shared by `view` and `flythrough`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewOptions {
    /// Vertical field of view, degrees.
    #[arg(long, default_value_t = 60.0)]
    fov: f64,
    /// Viewport in pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "1600x900", value_parser = parse_viewport)]
    viewport: (u32, u32),
    /// Threshold rule.
    #[arg(long, value_enum, default_value = "sse")]
    rule: RuleKind,
    /// Screen-space tolerance in pixels (--rule sse).
    #[arg(long, default_value_t = 1.0)]
    tau: f64,
    /// Area rule constant a (--rule area).
    #[arg(long, default_value_t = 1.0)]
    a: f64,
    /// Area rule constant b (--rule area).
    #[arg(long, default_value_t = 0.0)]
    b: f64,
    /// x/y units (the camera's too).
    #[arg(long, value_enum, default_value = "geo")]
    xy: ViewXy,
    /// Multiply heights by this (e.g. 0.1 for decimetre DEMs).
    #[arg(long, default_value_t = 1.0)]
    z_scale: f64,
    /// Largest side of --render images, pixels.
    #[arg(long, default_value_t = 768)]
    render_size: u32,
    #[command(flatten)]
    limit_args: LimitArgs,
}

/// `wavemesh view`.
#[derive(Debug, clap::Args)]
pub struct ViewArgs {
    /// The .ezw stream.
    input: PathBuf,
    /// Camera position x,y,z.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    camera: DVec3,
    /// Point looked at x,y,z.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    look: DVec3,
    /// Output mesh (.glb, .obj or .ply), morphed.
    #[arg(short, long)]
    output: PathBuf,
    /// Also write a top-down PNG of the mesh and the camera.
    #[arg(long)]
    render: Option<PathBuf>,
    /// Also mesh with the other rule at the same triangle count and compare screen errors.
    #[arg(long)]
    compare_rules: bool,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    options: ViewOptions,
}

/// `wavemesh flythrough`.
#[derive(Debug, clap::Args)]
pub struct FlythroughArgs {
    /// The .ezw stream.
    input: PathBuf,
    /// Camera path: CSV rows x,y,z,look_x,look_y,look_z (a header row is skipped).
    #[arg(long, conflicts_with = "orbit")]
    path: Option<PathBuf>,
    /// Orbit the terrain's centre (the default without --path).
    #[arg(long)]
    orbit: bool,
    /// Frames (default: 60 for an orbit, one per row for a path; a path is resampled).
    #[arg(long)]
    frames: Option<usize>,
    /// Write a top-down PNG of every frame into this folder.
    #[arg(long)]
    render: Option<PathBuf>,
    /// Write every frame's morphed mesh (.obj) into this folder.
    #[arg(long)]
    export_frames: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    options: ViewOptions,
}

fn parse_point(text: &str) -> Result<DVec3, String> {
    let parts: Vec<f64> = text
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected x,y,z numbers, got {text:?}"))?;
    match parts[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Ok(DVec3::new(x, y, z)),
        _ => Err(format!("expected three finite numbers x,y,z, got {text:?}")),
    }
}

fn parse_viewport(text: &str) -> Result<(u32, u32), String> {
    let bad = || format!("expected WIDTHxHEIGHT in pixels, got {text:?}");
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h) = (
        w.parse::<u32>().map_err(|_| bad())?,
        h.parse::<u32>().map_err(|_| bad())?,
    );
    if w == 0 || h == 0 || w > 65536 || h > 65536 {
        return Err(bad());
    }
    Ok((w, h))
}

impl ViewOptions {
    fn rule(&self) -> Result<Rule, CliError> {
        let rule = match self.rule {
            RuleKind::Sse => Rule::ScreenSpace { tau: self.tau },
            RuleKind::Area => Rule::Area {
                a: self.a,
                b: self.b,
            },
        };
        rule.checked().map_err(|e| CliError::Usage(e.to_string()))
    }

    fn camera(&self, eye: DVec3, look: DVec3) -> Result<View, CliError> {
        Camera::new(eye, look, self.fov, self.viewport)
            .map(|c| c.view())
            .map_err(|e| CliError::Usage(e.to_string()))
    }

    fn placement(&self, decoded: &Decoded) -> Result<Placement, CliError> {
        if !(self.z_scale.is_finite() && self.z_scale != 0.0) {
            return Err(CliError::Usage(format!(
                "--z-scale must be finite and non-zero, got {}",
                self.z_scale
            )));
        }
        let raster = &decoded.raster;
        match self.xy {
            ViewXy::Geo => Placement::tangent(
                raster.georef.as_ref(),
                raster.width,
                raster.height,
                self.z_scale,
            )
            .map_err(|e| CliError::Usage(e.to_string())),
            ViewXy::Pixel => Ok(Placement::pixel(self.z_scale)),
        }
    }
}

/// Whether `data` is a tiled `.ezw` file (its header and index read).
fn is_tiled(data: &[u8]) -> bool {
    matches!(
        TiledLayout::read(&mut &data[..], data.len() as u64),
        Ok(Some(_))
    )
}

/// A decoded stream with its map, ready for views.
struct Loaded {
    decoded: Decoded,
    surface: Surface,
    placement: Placement,
    decode_seconds: f64,
}

impl Loaded {
    fn read(input: &Path, options: &ViewOptions) -> Result<Loaded, CliError> {
        let data = std::fs::read(input)
            .map_err(|e| CliError::Input(input.to_path_buf(), e.to_string()))?;
        let start = Instant::now();
        let decode_options = DecodeOptions::default()
            .with_significance_map(true)
            .with_limits(options.limit_args.limits());
        let decoded = decode(&data, &decode_options).map_err(|e| match e {
            CodecError::InvalidParameters(_) if is_tiled(&data) => CliError::Input(
                input.to_path_buf(),
                "views need a single-stream file: this one is tiled (encode with --tile 0)".into(),
            ),
            e => CliError::Stream(input.to_path_buf(), e),
        })?;
        if !has_valid_cell(&decoded.raster) {
            return Err(CliError::Input(
                input.to_path_buf(),
                format!(
                    "nothing to mesh: the {} × {} raster has no 2 × 2 block of valid samples",
                    decoded.raster.width, decoded.raster.height
                ),
            ));
        }
        let decode_seconds = start.elapsed().as_secs_f64();
        let surface = Surface::of(&decoded.raster);
        let placement = options.placement(&decoded)?;
        Ok(Loaded {
            decoded,
            surface,
            placement,
            decode_seconds,
        })
    }

    fn terrain(&self, input: &Path) -> Result<ViewTerrain<'_>, CliError> {
        let map = self
            .decoded
            .significance
            .as_ref()
            .expect("decoded with the map");
        ViewTerrain::new(
            map,
            self.surface.heights(),
            &self.surface.valid,
            self.placement,
            decoded_plane(&self.decoded),
        )
        .map_err(|e| CliError::Input(input.to_path_buf(), e.to_string()))
    }
}

/// One frame's mesh, from a selection.
struct Frame {
    tree: CellTree,
    mesh: GridMesh,
    morphed: Vec<f64>,
    triangulate_ms: f64,
    morph_ms: f64,
}

fn make_frame(
    terrain: &ViewTerrain<'_>,
    view: &View,
    rule: Rule,
    tree: CellTree,
    scratch: &mut MorphScratch,
) -> Frame {
    let start = Instant::now();
    let mesh = terrain.triangulate(&tree);
    let triangulate_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    let morphed = morph(terrain, view, rule, &tree, &mesh, scratch);
    let morph_ms = start.elapsed().as_secs_f64() * 1e3;
    Frame {
        tree,
        mesh,
        morphed,
        triangulate_ms,
        morph_ms,
    }
}

/// Writes `mesh` with per-vertex heights `vertex_heights`.
fn write_frame_mesh(
    path: &Path,
    loaded: &Loaded,
    mesh: &GridMesh,
    vertex_heights: &[f64],
) -> Result<(), CliError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| {
        CliError::Usage(format!(
            "{}: unknown mesh format (use .glb, .obj or .ply)",
            path.display()
        ))
    })?;
    let mut heights = loaded.surface.heights.clone();
    for (&s, &z) in mesh.vertices.iter().zip(vertex_heights) {
        heights[s as usize] = z;
    }
    write_mesh(path, mesh, &heights, &loaded.placement, format)
        .map_err(|e| CliError::Output(path.to_path_buf(), e.to_string()))
}

fn render_error(path: &Path, e: ViewError) -> CliError {
    CliError::Output(path.to_path_buf(), e.to_string())
}

/// What `view --json` prints.
#[derive(Debug, Serialize)]
struct ViewReport {
    schema_version: u32,
    output: PathBuf,
    rule: String,
    xy_units: &'static str,
    triangles: usize,
    vertices: usize,
    cells: usize,
    cracks: usize,
    decode_seconds: f64,
    prepare_seconds: f64,
    selection_ms: f64,
    triangulate_ms: f64,
    morph_ms: f64,
    screen_error: ScreenError,
    other_rule: Option<RuleComparison>,
}

/// The other rule at the same triangle count.
#[derive(Debug, Serialize)]
struct RuleComparison {
    rule: String,
    triangles: usize,
    screen_error: ScreenError,
}

/// Runs `wavemesh view`.
pub fn view(args: &ViewArgs) -> Result<(), CliError> {
    let rule = args.options.rule()?;
    let view = args.options.camera(args.camera, args.look)?;
    MeshFormat::from_path(&args.output).ok_or_else(|| {
        CliError::Usage(format!(
            "{}: unknown mesh format (use .glb, .obj or .ply)",
            args.output.display()
        ))
    })?;
    let loaded = Loaded::read(&args.input, &args.options)?;
    let start = Instant::now();
    let terrain = loaded.terrain(&args.input)?;
    let prepare_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let tree = terrain.select(&view, rule);
    let selection_ms = start.elapsed().as_secs_f64() * 1e3;
    let frame = make_frame(&terrain, &view, rule, tree, &mut MorphScratch::default());
    write_frame_mesh(&args.output, &loaded, &frame.mesh, &frame.morphed)?;
    if let Some(path) = &args.render {
        write_png(
            path,
            &top_down(&terrain, &frame.tree, &view, args.options.render_size),
        )
        .map_err(|e| render_error(path, e))?;
    }
    let report = ViewReport {
        schema_version: SCHEMA_VERSION,
        output: args.output.clone(),
        rule: format!("{rule:?}"),
        xy_units: loaded.placement.frame_name(),
        triangles: frame.mesh.triangles.len(),
        vertices: frame.mesh.vertices.len(),
        cells: frame.tree.leaves().len(),
        cracks: count_cracks(&terrain, &frame.mesh, |_, v| frame.morphed[v as usize]),
        decode_seconds: loaded.decode_seconds,
        prepare_seconds,
        selection_ms,
        triangulate_ms: frame.triangulate_ms,
        morph_ms: frame.morph_ms,
        screen_error: screen_error(&terrain, &view, &frame.mesh, &frame.morphed),
        other_rule: args
            .compare_rules
            .then(|| other_rule(&terrain, &view, rule, frame.mesh.triangles.len())),
    };
    print_view(&report, args.json);
    Ok(())
}

/// The area rule at the triangle count of a screen-space mesh (or the other way round,
/// by searching τ).
fn other_rule(
    terrain: &ViewTerrain<'_>,
    view: &View,
    rule: Rule,
    triangles: usize,
) -> RuleComparison {
    let (rule, tree, mesh) = match rule {
        Rule::ScreenSpace { .. } => area_rule_matching(terrain, view, triangles),
        Rule::Area { .. } => sse_rule_matching(terrain, view, triangles),
    };
    let morphed = morph(
        terrain,
        view,
        rule,
        &tree,
        &mesh,
        &mut MorphScratch::default(),
    );
    RuleComparison {
        rule: format!("{rule:?}"),
        triangles: mesh.triangles.len(),
        screen_error: screen_error(terrain, view, &mesh, &morphed),
    }
}

fn print_view(report: &ViewReport, json: bool) {
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(report).expect("serialisable")
        );
        return;
    }
    println!(
        "view {} ({}): {} triangles, {} vertices, {} cells, {} cracks; selection {:.2} ms, morph {:.2} ms; screen error max {:.2} px, mean {:.3} px",
        report.output.display(),
        report.rule,
        report.triangles,
        report.vertices,
        report.cells,
        report.cracks,
        report.selection_ms,
        report.morph_ms,
        report.screen_error.max_pixels,
        report.screen_error.mean_pixels,
    );
    if let Some(other) = &report.other_rule {
        println!(
            "  {} at {} triangles: screen error max {:.2} px, mean {:.3} px",
            other.rule,
            other.triangles,
            other.screen_error.max_pixels,
            other.screen_error.mean_pixels
        );
    }
}

/// One frame of `flythrough --json`.
#[derive(Debug, Serialize)]
struct FrameReport {
    frame: usize,
    camera: [f64; 3],
    look: [f64; 3],
    triangles: usize,
    vertices: usize,
    split: usize,
    merged: usize,
    revisited: usize,
    incremental_ms: f64,
    rebuild_ms: f64,
    matches_rebuild: bool,
    triangulate_ms: f64,
    morph_ms: f64,
    cracks: usize,
    max_jump: f64,
    max_jump_unmorphed: f64,
}

/// What `flythrough --json` prints.
#[derive(Debug, Serialize)]
struct FlythroughReport {
    schema_version: u32,
    rule: String,
    xy_units: &'static str,
    viewport: (u32, u32),
    decode_seconds: f64,
    prepare_seconds: f64,
    median_incremental_ms: f64,
    median_rebuild_ms: f64,
    rebuild_over_incremental: f64,
    median_morph_ms: f64,
    all_match_rebuild: bool,
    total_cracks: usize,
    max_jump: f64,
    max_jump_unmorphed: f64,
    frames: Vec<FrameReport>,
}

/// Runs `wavemesh flythrough`.
pub fn flythrough(args: &FlythroughArgs) -> Result<(), CliError> {
    let rule = args.options.rule()?;
    if args.frames == Some(0) {
        return Err(CliError::Usage("--frames must be at least 1".into()));
    }
    for dir in [&args.render, &args.export_frames].into_iter().flatten() {
        std::fs::create_dir_all(dir).map_err(|e| CliError::Output(dir.clone(), e.to_string()))?;
    }
    let path = args.path.as_ref().map(|p| read_path(p)).transpose()?;
    let loaded = Loaded::read(&args.input, &args.options)?;
    let start = Instant::now();
    let terrain = loaded.terrain(&args.input)?;
    let prepare_seconds = start.elapsed().as_secs_f64();
    let cameras = match path {
        Some(rows) => resample(&rows, args.frames.unwrap_or(rows.len())),
        None => orbit(&terrain, args.frames.unwrap_or(60))
            .ok_or_else(|| CliError::Input(args.input.clone(), "no grid cell to orbit".into()))?,
    };
    let views = cameras
        .iter()
        .map(|&(eye, look)| args.options.camera(eye, look))
        .collect::<Result<Vec<_>, _>>()?;
    let frames = fly(args, &loaded, &terrain, rule, &views)?;
    let report = summarise(args, &loaded, rule, prepare_seconds, frames);
    print_flythrough(&report, args.json);
    Ok(())
}

/// Every frame: the incremental update and a rebuild (timed), the morphed mesh, its
/// cracks and the popping against the previous frame; files as asked.
fn fly(
    args: &FlythroughArgs,
    loaded: &Loaded,
    terrain: &ViewTerrain<'_>,
    rule: Rule,
    views: &[View],
) -> Result<Vec<FrameReport>, CliError> {
    let mut scratch = MorphScratch::default();
    let start = Instant::now();
    let mut incremental = Incremental::new(terrain, &views[0], rule);
    let first_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut previous: Option<(Frame, Vec<f64>)> = None;
    let mut reports = Vec::with_capacity(views.len());
    for (f, view) in views.iter().enumerate() {
        let start = Instant::now();
        let stats = if f == 0 {
            Default::default()
        } else {
            incremental.update(terrain, view)
        };
        let incremental_ms = if f == 0 {
            first_ms
        } else {
            start.elapsed().as_secs_f64() * 1e3
        };
        let start = Instant::now();
        let rebuilt = terrain.select(view, rule);
        let rebuild_ms = start.elapsed().as_secs_f64() * 1e3;
        let frame = make_frame(
            terrain,
            view,
            rule,
            incremental.tree().clone(),
            &mut scratch,
        );
        let truth: Vec<f64> = frame
            .mesh
            .vertices
            .iter()
            .map(|&s| loaded.surface.heights[s as usize])
            .collect();
        let (max_jump, max_jump_unmorphed) = match &previous {
            Some((before, before_truth)) => jumps(
                terrain,
                (before, before_truth),
                (&frame, &truth),
                [&views[f - 1], view],
            ),
            None => (0.0, 0.0),
        };
        write_frame_files(args, loaded, terrain, view, &frame, f)?;
        reports.push(FrameReport {
            frame: f,
            camera: view.camera.eye.to_array(),
            look: view.camera.look.to_array(),
            triangles: frame.mesh.triangles.len(),
            vertices: frame.mesh.vertices.len(),
            split: stats.split,
            merged: stats.merged,
            revisited: stats.revisited,
            incremental_ms,
            rebuild_ms,
            matches_rebuild: rebuilt.leaves() == incremental.tree().leaves(),
            triangulate_ms: frame.triangulate_ms,
            morph_ms: frame.morph_ms,
            cracks: count_cracks(terrain, &frame.mesh, |_, v| frame.morphed[v as usize]),
            max_jump,
            max_jump_unmorphed,
        });
        previous = Some((frame, truth));
    }
    Ok(reports)
}

/// Largest surface change at a seen vertex between two frames, morphed and not.
fn jumps(
    terrain: &ViewTerrain<'_>,
    before: (&Frame, &[f64]),
    after: (&Frame, &[f64]),
    cameras: [&View; 2],
) -> (f64, f64) {
    fn surface<'a>(frame: &'a Frame, heights: &'a [f64]) -> FrameSurface<'a> {
        FrameSurface {
            tree: &frame.tree,
            mesh: &frame.mesh,
            heights,
        }
    }
    let morphed = max_jump(
        terrain,
        surface(before.0, &before.0.morphed),
        surface(after.0, &after.0.morphed),
        cameras,
    );
    let unmorphed = max_jump(
        terrain,
        surface(before.0, before.1),
        surface(after.0, after.1),
        cameras,
    );
    (morphed, unmorphed)
}

fn write_frame_files(
    args: &FlythroughArgs,
    loaded: &Loaded,
    terrain: &ViewTerrain<'_>,
    view: &View,
    frame: &Frame,
    index: usize,
) -> Result<(), CliError> {
    if let Some(dir) = &args.export_frames {
        write_frame_mesh(
            &dir.join(format!("frame_{index:04}.obj")),
            loaded,
            &frame.mesh,
            &frame.morphed,
        )?;
    }
    if let Some(dir) = &args.render {
        let path = dir.join(format!("frame_{index:04}.png"));
        write_png(
            &path,
            &top_down(terrain, &frame.tree, view, args.options.render_size),
        )
        .map_err(|e| render_error(&path, e))?;
    }
    Ok(())
}

/// Camera rows of a path file: x,y,z,look_x,look_y,look_z per line; a first line that
/// does not parse is a header.
fn read_path(path: &Path) -> Result<Vec<(DVec3, DVec3)>, CliError> {
    let bad =
        |line: usize, why: &str| CliError::Input(path.to_path_buf(), format!("line {line}: {why}"));
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::Input(path.to_path_buf(), e.to_string()))?;
    let mut rows = Vec::new();
    for (k, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let values: Result<Vec<f64>, _> =
            line.split(',').map(|v| v.trim().parse::<f64>()).collect();
        match values {
            Ok(v) if v.len() == 6 && v.iter().all(|x| x.is_finite()) => {
                rows.push((DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5])))
            }
            Err(_) if k == 0 => continue,
            _ => {
                return Err(bad(
                    k + 1,
                    "expected six finite numbers x,y,z,look_x,look_y,look_z",
                ))
            }
        }
    }
    if rows.is_empty() {
        return Err(CliError::Input(path.to_path_buf(), "no camera rows".into()));
    }
    Ok(rows)
}

/// `frames` cameras evenly along the polyline of `rows` (by row index).
fn resample(rows: &[(DVec3, DVec3)], frames: usize) -> Vec<(DVec3, DVec3)> {
    if rows.len() == 1 || frames == 1 {
        return vec![rows[0]; frames];
    }
    (0..frames)
        .map(|f| {
            let t = f as f64 * (rows.len() - 1) as f64 / (frames - 1) as f64;
            let k = (t.floor() as usize).min(rows.len() - 2);
            let u = t - k as f64;
            (
                rows[k].0.lerp(rows[k + 1].0, u),
                rows[k].1.lerp(rows[k + 1].1, u),
            )
        })
        .collect()
}

/// A full circle around the terrain's centre, above its highest point, looking at the
/// centre (`None` for a grid without cells).
fn orbit(terrain: &ViewTerrain<'_>, frames: usize) -> Option<Vec<(DVec3, DVec3)>> {
    let (lo, hi) = terrain.extent();
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let centre = 0.5 * (lo + hi);
    let size = (hi.x - lo.x).max(hi.y - lo.y);
    let radius = 0.6 * size;
    let cameras = (0..frames)
        .map(|f| {
            let angle = std::f64::consts::TAU * f as f64 / frames as f64;
            let eye = DVec3::new(
                centre.x + radius * angle.cos(),
                centre.y + radius * angle.sin(),
                hi.z + 0.2 * size,
            );
            (eye, centre)
        })
        .collect();
    Some(cameras)
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(0.0)
}

fn summarise(
    args: &FlythroughArgs,
    loaded: &Loaded,
    rule: Rule,
    prepare_seconds: f64,
    frames: Vec<FrameReport>,
) -> FlythroughReport {
    // The first frame is built from scratch: medians over the updates.
    let updates = if frames.len() > 1 {
        &frames[1..]
    } else {
        &frames[..]
    };
    let incremental = median(updates.iter().map(|f| f.incremental_ms).collect());
    let rebuild = median(updates.iter().map(|f| f.rebuild_ms).collect());
    FlythroughReport {
        schema_version: SCHEMA_VERSION,
        rule: format!("{rule:?}"),
        xy_units: loaded.placement.frame_name(),
        viewport: args.options.viewport,
        decode_seconds: loaded.decode_seconds,
        prepare_seconds,
        median_incremental_ms: incremental,
        median_rebuild_ms: rebuild,
        rebuild_over_incremental: rebuild / incremental.max(1e-9),
        median_morph_ms: median(frames.iter().map(|f| f.morph_ms).collect()),
        all_match_rebuild: frames.iter().all(|f| f.matches_rebuild),
        total_cracks: frames.iter().map(|f| f.cracks).sum(),
        max_jump: frames.iter().map(|f| f.max_jump).fold(0.0, f64::max),
        max_jump_unmorphed: frames
            .iter()
            .map(|f| f.max_jump_unmorphed)
            .fold(0.0, f64::max),
        frames,
    }
}

fn print_flythrough(report: &FlythroughReport, json: bool) {
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(report).expect("serialisable")
        );
        return;
    }
    let triangles: Vec<f64> = report.frames.iter().map(|f| f.triangles as f64).collect();
    println!(
        "flythrough ({}): {} frames, median {:.0} triangles; selection median {:.3} ms incremental vs {:.3} ms rebuild ({:.1}×), morph {:.3} ms; {} cracks; max jump {:.3} (unmorphed {:.3}); incremental {} the rebuild",
        report.rule,
        report.frames.len(),
        median(triangles),
        report.median_incremental_ms,
        report.median_rebuild_ms,
        report.rebuild_over_incremental,
        report.median_morph_ms,
        report.total_cracks,
        report.max_jump,
        report.max_jump_unmorphed,
        if report.all_match_rebuild { "equals" } else { "DIFFERS FROM" },
    );
}
