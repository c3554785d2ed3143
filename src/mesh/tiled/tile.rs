//! One tile's mesh: its samples (with the shared border lines of its right and lower
//! neighbours) coded losslessly, decoded with the significance map, meshed with every
//! sample on a shared border a vertex, measured at every sample, and encoded as a glb in
//! the whole DEM's frame.

use serde::Serialize;
use wavemesh_codec::tiles::Window;
use wavemesh_codec::{decode, encode, DecodeOptions, Decoded, EncodeOptions, Raster};

use super::{TileMeshError, TileMeshOptions, TileTarget};
use crate::lod::{decoded_plane, Surface};
use crate::mesh::export::{encode_glb_about, Placement};
use crate::mesh::rasterise::mesh_error;
use crate::mesh::{FineBorders, GridMesh, MeshTarget, Mesher};

/// Where a tile lies and which of its sides it shares with a neighbour.
#[derive(Debug, Clone, Copy)]
pub(super) struct TileSpot {
    /// Tile row in the grid.
    pub row: usize,
    /// Tile column in the grid.
    pub column: usize,
    /// The samples meshed (the tile and the first row and column of its lower and right
    /// neighbours), in whole-DEM samples.
    pub window: Window,
    /// Sides shared with a neighbouring tile.
    pub shared: FineBorders,
}

/// A tile's mesh as the index lists it.
#[derive(Debug, Clone, Serialize)]
pub struct TileMeshSummary {
    /// Tile row in the grid.
    pub row: usize,
    /// Tile column in the grid.
    pub column: usize,
    /// The glb's file name in the output folder; `None` when the tile has nothing to
    /// mesh (no 2 × 2 block of valid samples) and no file was written.
    pub file: Option<String>,
    /// First column of the samples meshed (whole-DEM samples).
    pub x: usize,
    /// First row of the samples meshed.
    pub y: usize,
    /// Columns meshed (the tile's, plus its right neighbour's first column).
    pub width: usize,
    /// Rows meshed (the tile's, plus its lower neighbour's first row).
    pub height: usize,
    /// Triangles of the mesh.
    pub triangles: usize,
    /// Vertices of the mesh.
    pub vertices: usize,
    /// Largest distance of a covered valid sample from the mesh, data units.
    pub max_error: f64,
    /// Smallest x, y, z of the vertices in the DEM's frame (before glTF's Y-up swap).
    pub min: [f64; 3],
    /// Largest x, y, z of the vertices.
    pub max: [f64; 3],
}

/// A meshed tile: what the index says of it and its glb bytes (`None`: nothing to mesh).
pub(super) struct MeshedTile {
    pub summary: TileMeshSummary,
    pub glb: Option<Vec<u8>>,
}

/// Meshes the tile at `spot` out of `band` (the DEM's samples from row `spot.window.y`
/// and column `band_x`); `cell_total` is the DEM's number of grid cells (for a budget's
/// share).
pub(super) fn mesh_tile(
    (band, band_x): (&Raster, usize),
    spot: TileSpot,
    options: &TileMeshOptions,
    cell_total: u64,
) -> Result<MeshedTile, TileMeshError> {
    let w = spot.window;
    let raster = band.crop(w.x - band_x, 0, w.width, w.height);
    let mut summary = TileMeshSummary::empty(spot);
    if !has_valid_cell(&raster) {
        return Ok(MeshedTile { summary, glb: None });
    }
    let decoded = code_losslessly(&raster)?;
    drop(raster);
    let map = decoded
        .significance
        .as_ref()
        .expect("decoded with the significance map");
    let surface = Surface::of(&decoded.raster);
    let cells = (w.width as u64 - 1) * (w.height as u64 - 1);
    let (target, base_plane) =
        tile_target(options.target, decoded_plane(&decoded), cells, cell_total);
    let mesh = Mesher::new(map, surface.heights(), &surface.valid)
        .with_fine_borders(spot.shared)
        .build(target, options.rule, base_plane)
        .mesh;
    summary.max_error = checked_error(&mesh, &surface, options.target, spot)?;
    let positions = placed_positions(&mesh, &surface.heights, &options.placement, w);
    (summary.min, summary.max) = extent(&positions);
    let glb = encode_glb_about(
        &positions,
        &mesh.triangles,
        &options.placement,
        options.centre,
    )
    .map_err(TileMeshError::Export)?;
    summary.file = Some(tile_file_name(spot.row, spot.column));
    summary.triangles = mesh.triangles.len();
    summary.vertices = mesh.vertices.len();
    Ok(MeshedTile {
        summary,
        glb: Some(glb),
    })
}

impl TileMeshSummary {
    /// The summary of the tile at `spot` before it is meshed: no file, no triangles.
    fn empty(spot: TileSpot) -> TileMeshSummary {
        let w = spot.window;
        TileMeshSummary {
            row: spot.row,
            column: spot.column,
            file: None,
            x: w.x,
            y: w.y,
            width: w.width,
            height: w.height,
            triangles: 0,
            vertices: 0,
            max_error: 0.0,
            min: [0.0; 3],
            max: [0.0; 3],
        }
    }
}

/// `raster` coded losslessly as one stream and decoded with its significance map: the
/// heights and the partition the zerotree mesher takes.
fn code_losslessly(raster: &Raster) -> Result<Decoded, TileMeshError> {
    let options = EncodeOptions::zerotree_mesh();
    let encoded = encode(raster, &options).map_err(TileMeshError::Encode)?;
    let decode_options = DecodeOptions::default().with_significance_map(true);
    decode(&encoded.bytes, &decode_options).map_err(TileMeshError::Decode)
}

/// The largest distance of a covered valid sample of `surface` from `mesh`, checked
/// against the tolerance when `target` is one.
fn checked_error(
    mesh: &GridMesh,
    surface: &Surface,
    target: TileTarget,
    spot: TileSpot,
) -> Result<f64, TileMeshError> {
    let error = mesh_error(mesh, &surface.heights, &surface.heights, &surface.valid).max_error;
    match target {
        TileTarget::Tolerance { error: bound, .. } if error > bound => {
            Err(TileMeshError::BoundMissed {
                row: spot.row,
                column: spot.column,
                error,
                bound,
            })
        }
        _ => Ok(error),
    }
}

/// The file name of tile (`row`, `column`).
pub fn tile_file_name(row: usize, column: usize) -> String {
    format!("tile_{row}_{column}.glb")
}

/// What one tile's mesher is asked for, and the zerotree base plane: `cells` of the
/// DEM's `cell_total` grid cells are this tile's, which gives its share of a triangle
/// budget.
fn tile_target(
    target: TileTarget,
    decoded_plane: u32,
    cells: u64,
    cell_total: u64,
) -> (MeshTarget, Option<u32>) {
    let at_least_decoded = |plane: Option<u32>| plane.map(|p| p.max(decoded_plane));
    match target {
        TileTarget::Zerotree { plane } => (
            MeshTarget::Plane(at_least_decoded(plane).unwrap_or(decoded_plane)),
            None,
        ),
        TileTarget::Tolerance { error, plane } => {
            (MeshTarget::Tolerance(error), at_least_decoded(plane))
        }
        TileTarget::Triangles {
            total,
            by_threshold,
        } => {
            let share =
                (total as u128 * u128::from(cells) / u128::from(cell_total.max(1))) as usize;
            let target = if by_threshold {
                MeshTarget::Triangles(share)
            } else {
                MeshTarget::TrianglesByTolerance(share)
            };
            (target, None)
        }
    }
}

/// Every vertex of `mesh` (a mesh of the samples in `window`) placed in the whole DEM's
/// frame from its whole-DEM column and row, so that a vertex two tiles share gets the
/// same coordinates in both.
fn placed_positions(
    mesh: &GridMesh,
    heights: &[f64],
    placement: &Placement,
    window: Window,
) -> Vec<f64> {
    let mut positions = Vec::with_capacity(mesh.vertices.len() * 3);
    for &sample in &mesh.vertices {
        let s = sample as usize;
        let (col, row) = (s % mesh.width, s / mesh.width);
        let p = placement.position(window.x + col, window.y + row, heights[s]);
        positions.extend_from_slice(&p);
    }
    positions
}

/// The smallest and largest x, y, z of flattened positions.
fn extent(positions: &[f64]) -> ([f64; 3], [f64; 3]) {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for p in positions.chunks_exact(3) {
        for k in 0..3 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    (min, max)
}

/// Whether some 2 × 2 block of `raster` has at least three valid samples (the smallest
/// mesh is the one triangle of such a grid cell).
pub fn has_valid_cell(raster: &Raster) -> bool {
    let w = raster.width;
    (1..raster.height).any(|row| {
        (1..w).any(|col| {
            let top = (row - 1) * w + col;
            let bottom = row * w + col;
            [top - 1, top, bottom - 1, bottom]
                .iter()
                .filter(|&&i| raster.is_valid(i))
                .count()
                >= 3
        })
    })
}
