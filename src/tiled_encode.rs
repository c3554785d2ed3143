//! Encoding a DEM larger than memory: read one block of samples at a time (a run of
//! tiles of one tile row, [`RowBands`]), code its tiles on every core, and keep only their (compressed)
//! streams, spooled to a temporary file; the header and index go first in the output,
//! the tiles after them. The bytes are those of an in-memory encode of the same raster.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::Path;

use thiserror::Error;
use wavemesh_codec::tiles::{
    cut_to_budget, encode_block, encode_tile, tiled_head, EncodedTile, RasterInfo, TileSummary,
};
use wavemesh_codec::{CodecError, EncodeOptions, Raster, TileGrid, Window};

use crate::dem::{DemError, RowBands};

/// Why a streaming encode failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TiledEncodeError {
    /// Reading the DEM failed.
    #[error(transparent)]
    Read(#[from] DemError),
    /// The coder refused.
    #[error(transparent)]
    Encode(#[from] CodecError),
    /// The spool file or the output failed.
    #[error("{0}")]
    Write(#[from] io::Error),
}

/// What a streaming encode wrote.
#[derive(Debug, Clone)]
pub struct TiledEncoded {
    /// Bytes of the output file.
    pub bytes: u64,
    /// Bytes of its header and index.
    pub head_bytes: u64,
    /// The tiles' summaries, in grid order.
    pub tiles: Vec<TileSummary>,
}

/// Tiles of one tile row coded from one band of samples: (tile row, tile columns),
/// as [`TileGrid::blocks`] gives them.
type Block = (usize, Range<usize>);

/// Encodes the raster `bands` reads (described by `info`: its [`RowBands::info`],
/// perhaps with metadata left out) as a tiled file on `grid` into `output` (written
/// atomically), holding two blocks of samples at a time: the one being coded and the
/// next, read meanwhile (one after the other when `options.threads` is 1). A block is
/// the coded samples of a run of tiles of one tile row, about `block_width` samples
/// wide (at least a tile) when the source reads columns cheaply (a tiled TIFF), else
/// the whole row, so memory does not grow with the raster's width. The bytes do not
/// depend on `block_width`. Without a byte budget the
/// tiles' streams wait in a temporary file; with one they are kept in memory (each
/// coded up to about four times its share of the budget) until the budget is shared.
/// `rows_done(k)` is called after each tile row, `k` rows of [`TileGrid::rows`] done.
pub fn encode_tiled(
    bands: &mut RowBands,
    info: &RasterInfo,
    grid: &TileGrid,
    options: &EncodeOptions,
    block_width: usize,
    output: &Path,
    rows_done: &mut dyn FnMut(usize),
) -> Result<TiledEncoded, TiledEncodeError> {
    let mut spool = tempfile::tempfile()?;
    let mut kept: Vec<EncodedTile> = Vec::new();
    let mut summaries: Vec<TileSummary> = Vec::with_capacity(grid.count());
    let blocks = grid.blocks(bands.tiles_per_block(grid, block_width));
    let mut band = read_block(bands, grid, &blocks[0], None)?;
    for (k, block) in blocks.iter().enumerate() {
        let next = blocks.get(k + 1);
        let (tiles, next_band) = code_and_read_next((block, &band), next, bands, grid, options);
        for tile in tiles? {
            summaries.push(tile.summary.clone());
            if options.budget_bytes.is_some() {
                kept.push(tile);
            } else {
                spool.write_all(&tile.bytes)?;
            }
        }
        if let Some(next_band) = next_band? {
            band = next_band;
        }
        if block.1.end == grid.columns() {
            rows_done(block.0 + 1);
        }
    }
    if let Some(budget) = options.budget_bytes {
        let mut recode = |k: usize, cap: u64| -> Result<EncodedTile, TiledEncodeError> {
            let part = bands.read_window(grid.coded(k))?;
            Ok(encode_tile(&part, options, Some(cap))?)
        };
        let cut = cut_to_budget(kept, info, grid, budget, &mut recode)?;
        summaries = cut.iter().map(|t| t.summary.clone()).collect();
        for tile in &cut {
            spool.write_all(&tile.bytes)?;
        }
    }
    let head = tiled_head(info, grid, &summaries);
    let tiles_len = spool.stream_position()?;
    spool.seek(SeekFrom::Start(0))?;
    crate::atomic::write_atomic(output, |w| copy_out(&head, &mut spool, w))?;
    Ok(TiledEncoded {
        bytes: head.len() as u64 + tiles_len,
        head_bytes: head.len() as u64,
        tiles: summaries,
    })
}

/// Codes the tiles of `block` from `band` and reads the `next` block's band: at the
/// same time on two threads, unless `options` asks for one thread, when the read follows
/// the coding.
fn code_and_read_next(
    (block, band): (&Block, &Raster),
    next: Option<&Block>,
    bands: &mut RowBands,
    grid: &TileGrid,
    options: &EncodeOptions,
) -> (
    Result<Vec<EncodedTile>, CodecError>,
    Result<Option<Raster>, DemError>,
) {
    let read_next = |bands: &mut RowBands| {
        next.map(|next| read_block(bands, grid, next, Some((block, band))))
            .transpose()
    };
    let code = || encode_block(band, grid, block.0, block.1.clone(), options);
    if options.threads == 1 {
        let tiles = code();
        return (tiles, read_next(bands));
    }
    std::thread::scope(|scope| {
        let reader = scope.spawn(|| read_next(bands));
        let tiles = code();
        let next = reader.join().expect("the band reader does not panic");
        (tiles, next)
    })
}

/// The samples the streams of `block` code (its tiles and their overlap), with the rows
/// it shares with `previous` taken from it when that is the block just above (blocks as
/// wide as the raster), so every row of the DEM is read once.
fn read_block(
    bands: &mut RowBands,
    grid: &TileGrid,
    block: &Block,
    previous: Option<(&Block, &Raster)>,
) -> Result<Raster, DemError> {
    let window = grid.coded_block(block.0, block.1.clone());
    let above = previous.filter(|(p, _)| p.0 + 1 == block.0 && p.1 == block.1);
    let Some((above, band)) = above else {
        return bands.read_window(window);
    };
    let from = grid.coded_block(above.0, above.1.clone());
    let shared = (from.y + from.height).saturating_sub(window.y);
    if shared == 0 {
        return bands.read_window(window);
    }
    let kept = band.crop(0, window.y - from.y, window.width, shared);
    if shared == window.height {
        return Ok(kept);
    }
    let below = Window {
        y: window.y + shared,
        height: window.height - shared,
        ..window
    };
    bands.read_window_below(&kept, below)
}

/// Writes the header and index, then the spooled tiles.
fn copy_out(head: &[u8], spool: &mut File, out: &mut dyn Write) -> io::Result<()> {
    out.write_all(head)?;
    io::copy(spool, out)?;
    Ok(())
}
