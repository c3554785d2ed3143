//! Meshes of a DEM of any size, one glb per tile, read a block of tiles at a time.
//!
//! The DEM is cut on a [`TileGrid`] (as tiled `.ezw` files are). Each tile's mesh covers
//! its samples plus the first column of its right neighbour and the first row of its
//! lower neighbour, so neighbouring meshes meet on a shared line of samples. Along every
//! shared line each mesh splits its cells down to single grid cells, so both sides have
//! every sample of the line as a vertex (the same vertices, in the same segments), and
//! the vertices are placed from their whole-DEM column and row in one frame for the
//! whole DEM and stored relative to one centre: the coordinates are bit-identical on
//! both sides, and the meshes meet with no crack or T-junction. A tolerance holds at
//! every sample of every tile (checked); a triangle budget is shared among the tiles in
//! proportion to their grid cells.
//!
//! Memory: one band (a run of tiles of one tile row, about [`BLOCK_WIDTH`] columns from
//! a tiled GeoTIFF, a whole tile row from a stripped one, plus the shared column and row)
//! is meshed while the next is read, its tiles on `threads` threads, and each tile's glb is written as soon
//! as it is made. The output folder gets `tile_<row>_<column>.glb` files and, last, the
//! index `tiles.json` ([`INDEX_FILE`]); a run that fails removes the tiles it wrote.

mod tile;

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;
use wavemesh_codec::tiles::Window;
use wavemesh_codec::{CodecError, Raster, TileGrid};

use super::cells::SplitRule;
use super::export::{ExportError, Placement};
use super::FineBorders;
use crate::dem::{DemError, DemInfo, RowBands, BLOCK_WIDTH};
pub use tile::{has_valid_cell, tile_file_name, TileMeshSummary};
use tile::{mesh_tile, MeshedTile, TileSpot};

/// The index file every run writes last into its output folder.
pub const INDEX_FILE: &str = "tiles.json";

/// What every tile's mesh is asked to meet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TileTarget {
    /// The zerotree partition at the decoder's threshold (every pass of the lossless
    /// stream), or at `2^plane` when that is coarser.
    Zerotree {
        /// The threshold plane, if one was asked for.
        plane: Option<u32>,
    },
    /// No sample farther than `error` from its tile's mesh (refining the zerotree
    /// partition at `plane`, if given).
    Tolerance {
        /// The tolerance, data units.
        error: f64,
        /// The zerotree partition refined, if any.
        plane: Option<u32>,
    },
    /// At most `total` triangles over the whole DEM: each tile gets the share of its
    /// grid cells, and the largest mesh within it (searched over the zerotree thresholds
    /// when `by_threshold`, else over height tolerances).
    Triangles {
        /// The whole DEM's budget.
        total: usize,
        /// Search the thresholds instead of tolerances.
        by_threshold: bool,
    },
}

/// How a DEM is meshed tile by tile.
#[derive(Debug, Clone)]
pub struct TileMeshOptions {
    /// Largest tile side in samples (tiles as equal as the DEM allows).
    pub tile: usize,
    /// What every tile's mesh meets.
    pub target: TileTarget,
    /// Which coefficients split a cell at a threshold.
    pub rule: SplitRule,
    /// Where samples go: one frame for the whole DEM.
    pub placement: Placement,
    /// The x/y every glb stores its positions relative to (its node's translation).
    pub centre: [f64; 2],
    /// Threads meshing tiles at once (0: one per core). The output does not depend on it.
    pub threads: usize,
    /// Samples across a band of tiles read at once from a source that reads columns
    /// cheaply (a tiled GeoTIFF; [`BLOCK_WIDTH`] by default). The output does not depend
    /// on it.
    pub block_width: usize,
}

impl TileMeshOptions {
    /// Options for a DEM described by `info` placed by `placement`: the glbs' common
    /// centre is the DEM's middle sample at height 0.
    pub fn new(info: &DemInfo, placement: Placement, target: TileTarget) -> TileMeshOptions {
        let middle = placement.position((info.width - 1) / 2, (info.height - 1) / 2, 0.0);
        TileMeshOptions {
            tile: 1024,
            target,
            rule: SplitRule::Zerotree,
            placement,
            centre: [middle[0], middle[1]],
            threads: 0,
            block_width: BLOCK_WIDTH,
        }
    }
}

/// Why meshing by tiles failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TileMeshError {
    /// `--tile 0` or fewer.
    #[error("the tile size must be at least 1 sample, got {0}")]
    BadTile(usize),
    /// The output exists and is not a folder.
    #[error("{}: exists and is not a folder (tile meshes go into a folder)", .0.display())]
    NotAFolder(PathBuf),
    /// No tile has a 2 × 2 block of valid samples.
    #[error("nothing to mesh: the {width} × {height} raster has no 2 × 2 block of valid samples")]
    NothingToMesh {
        /// Raster columns.
        width: usize,
        /// Raster rows.
        height: usize,
    },
    /// Reading the DEM failed.
    #[error(transparent)]
    Read(#[from] DemError),
    /// Coding a tile failed.
    #[error(transparent)]
    Encode(CodecError),
    /// Decoding a tile's stream failed.
    #[error("decoding a tile: {0}")]
    Decode(CodecError),
    /// A tile's mesh missed the tolerance (a mesher fault).
    #[error("tile ({row}, {column}) is {error} from a sample, more than the tolerance {bound}")]
    BoundMissed {
        /// Tile row.
        row: usize,
        /// Tile column.
        column: usize,
        /// Its largest error.
        error: f64,
        /// The tolerance.
        bound: f64,
    },
    /// A tile's glb could not be made.
    #[error(transparent)]
    Export(ExportError),
    /// A file or the folder could not be written.
    #[error("{}: {error}", .path.display())]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// What failed.
        error: io::Error,
    },
    /// The thread pool could not start.
    #[error("cannot start {0} threads")]
    Threads(usize),
}

/// What a run wrote.
#[derive(Debug, Clone, Serialize)]
pub struct TiledMeshes {
    /// Raster columns.
    pub width: usize,
    /// Raster rows.
    pub height: usize,
    /// Columns of a tile (the last column of tiles may be narrower).
    pub tile_width: usize,
    /// Rows of a tile (the last row of tiles may be shorter).
    pub tile_height: usize,
    /// Tiles across.
    pub columns: usize,
    /// Tiles down.
    pub rows: usize,
    /// Every tile, row by row.
    pub tiles: Vec<TileMeshSummary>,
}

impl TiledMeshes {
    /// Triangles of all the tiles.
    pub fn triangles(&self) -> usize {
        self.tiles.iter().map(|t| t.triangles).sum()
    }

    /// Vertices of all the tiles (a shared border's vertices count once per tile).
    pub fn vertices(&self) -> usize {
        self.tiles.iter().map(|t| t.vertices).sum()
    }

    /// The largest error of any tile.
    pub fn max_error(&self) -> f64 {
        self.tiles.iter().map(|t| t.max_error).fold(0.0, f64::max)
    }
}

/// The index file's contents.
#[derive(Serialize)]
struct Index<'a> {
    schema_version: u32,
    /// The frame every tile is in (as each glb records it).
    frame: serde_json::Value,
    /// The x/y every glb's positions are relative to.
    centre: [f64; 2],
    #[serde(flatten)]
    meshes: &'a TiledMeshes,
}

/// The tiles of a `width × height` DEM meshed in tiles of at most `tile` a side: those of
/// a tiled `.ezw` file (as equal as the raster allows), one tile when it fits in one.
pub fn mesh_grid(width: usize, height: usize, tile: usize) -> TileGrid {
    TileGrid::balanced(width, height, tile).unwrap_or(TileGrid {
        width,
        height,
        tile_width: width,
        tile_height: height,
        overlap: 0,
    })
}

/// Meshes the DEM `bands` reads into `folder` (created if missing), one glb per tile,
/// then writes the index. `rows_done(k)` is called after each tile row.
pub fn write_tile_meshes(
    bands: &mut RowBands,
    folder: &Path,
    options: &TileMeshOptions,
    rows_done: &mut dyn FnMut(usize),
) -> Result<TiledMeshes, TileMeshError> {
    if options.tile == 0 {
        return Err(TileMeshError::BadTile(options.tile));
    }
    let info = bands.info().clone();
    let grid = mesh_grid(info.width, info.height, options.tile);
    let created = prepare_folder(folder)?;
    let result = mesh_rows(bands, &grid, folder, options, rows_done).and_then(|meshes| {
        write_index(folder, options, &meshes)?;
        Ok(meshes)
    });
    if result.is_err() {
        remove_outputs(folder, &grid, created);
    }
    result
}

/// Makes `folder` if it is missing (returns whether it did) and removes an index left
/// by an earlier run, so that the folder never holds an index of tiles not all there.
fn prepare_folder(folder: &Path) -> Result<bool, TileMeshError> {
    let write_error = |error| TileMeshError::Write {
        path: folder.to_path_buf(),
        error,
    };
    match fs::metadata(folder) {
        Ok(m) if m.is_dir() => {
            match fs::remove_file(folder.join(INDEX_FILE)) {
                Err(e) if e.kind() != io::ErrorKind::NotFound => return Err(write_error(e)),
                _ => {}
            }
            Ok(false)
        }
        Ok(_) => Err(TileMeshError::NotAFolder(folder.to_path_buf())),
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            fs::create_dir(folder).map_err(write_error)?;
            Ok(true)
        }
        Err(e) => Err(write_error(e)),
    }
}

/// Removes every tile file of `grid` from `folder`, and the folder if this run made it.
fn remove_outputs(folder: &Path, grid: &TileGrid, created: bool) {
    for index in 0..grid.count() {
        let (row, column) = (index / grid.columns(), index % grid.columns());
        let _ = fs::remove_file(folder.join(tile_file_name(row, column)));
    }
    if created {
        let _ = fs::remove_dir(folder);
    }
}

/// Tiles of one tile row meshed from one band: (tile row, tile columns), as
/// [`TileGrid::blocks`] gives them.
type Block = (usize, std::ops::Range<usize>);

/// Meshes and writes the tiles block by block, reading the next band while one is meshed.
fn mesh_rows(
    bands: &mut RowBands,
    grid: &TileGrid,
    folder: &Path,
    options: &TileMeshOptions,
    rows_done: &mut dyn FnMut(usize),
) -> Result<TiledMeshes, TileMeshError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()
        .map_err(|_| TileMeshError::Threads(options.threads))?;
    let mut tiles = Vec::with_capacity(grid.count());
    let blocks = grid.blocks(bands.tiles_per_block(grid, options.block_width));
    let mut band = read_band(bands, grid, &blocks[0])?;
    for (k, block) in blocks.iter().enumerate() {
        let (meshed, next) = std::thread::scope(|scope| {
            let reader = scope.spawn(|| {
                blocks
                    .get(k + 1)
                    .map(|next| read_band(bands, grid, next))
                    .transpose()
            });
            let meshed = pool.install(|| mesh_band(&band, grid, block, folder, options));
            (
                meshed,
                reader.join().expect("the band reader does not panic"),
            )
        });
        tiles.extend(meshed?);
        if let Some(next) = next? {
            band = next;
        }
        if block.1.end == grid.columns() {
            rows_done(block.0 + 1);
        }
    }
    if tiles.iter().all(|t| t.file.is_none()) {
        return Err(TileMeshError::NothingToMesh {
            width: grid.width,
            height: grid.height,
        });
    }
    Ok(TiledMeshes {
        width: grid.width,
        height: grid.height,
        tile_width: grid.tile_width,
        tile_height: grid.tile_height,
        columns: grid.columns(),
        rows: grid.rows(),
        tiles,
    })
}

/// Meshes the tiles of `block` (their samples and the shared column and row are `band`,
/// from [`read_band`]) in parallel and writes their glbs; their summaries in column
/// order.
fn mesh_band(
    band: &Raster,
    grid: &TileGrid,
    (row, columns): &Block,
    folder: &Path,
    options: &TileMeshOptions,
) -> Result<Vec<TileMeshSummary>, TileMeshError> {
    let cell_total = (grid.width as u64 - 1).max(1) * (grid.height as u64 - 1).max(1);
    let band_x = grid.block(*row, columns.clone()).x;
    let first = row * grid.columns();
    (first + columns.start..first + columns.end)
        .into_par_iter()
        .map(|index| {
            let spot = tile_spot(grid, index);
            let MeshedTile { summary, glb } = mesh_tile((band, band_x), spot, options, cell_total)?;
            if let (Some(glb), Some(name)) = (glb, &summary.file) {
                let path = folder.join(name);
                crate::atomic::write_atomic(&path, |w| w.write_all(&glb))
                    .map_err(|error| TileMeshError::Write { path, error })?;
            }
            Ok(summary)
        })
        .collect()
}

/// Tile `index` of `grid`: its samples extended by the first column and row of its
/// right and lower neighbours, and which of its sides it shares.
fn tile_spot(grid: &TileGrid, index: usize) -> TileSpot {
    let (row, column) = (index / grid.columns(), index % grid.columns());
    let tile = grid.tile(index);
    let right = column + 1 < grid.columns();
    let below = row + 1 < grid.rows();
    TileSpot {
        row,
        column,
        window: Window {
            width: tile.width + usize::from(right),
            height: tile.height + usize::from(below),
            ..tile
        },
        shared: FineBorders {
            top: row > 0,
            right,
            bottom: below,
            left: column > 0,
        },
    }
}

/// The samples `block` meshes: its tiles' and the first column and row of the tiles
/// right of and below it.
fn read_band(
    bands: &mut RowBands,
    grid: &TileGrid,
    (row, columns): &Block,
) -> Result<Raster, DemError> {
    let tiles = grid.block(*row, columns.clone());
    bands.read_window(Window {
        width: tiles.width + usize::from(columns.end < grid.columns()),
        height: tiles.height + usize::from(row + 1 < grid.rows()),
        ..tiles
    })
}

/// Writes the index into `folder`, atomically.
fn write_index(
    folder: &Path,
    options: &TileMeshOptions,
    meshes: &TiledMeshes,
) -> Result<(), TileMeshError> {
    let index = Index {
        schema_version: 1,
        frame: options.placement.frame_record(),
        centre: options.centre,
        meshes,
    };
    let text = serde_json::to_string_pretty(&index).expect("the index serialises");
    let path = folder.join(INDEX_FILE);
    crate::atomic::write_atomic(&path, |w| w.write_all(text.as_bytes()))
        .map_err(|error| TileMeshError::Write { path, error })
}
