//! Encoding a DEM larger than memory: read one block of samples at a time (a run of
//! tiles of one tile row, [`RowBands`]), code its tiles on every core, and keep only their (compressed)
//! streams, spooled to a temporary file; the header and index go first in the output,
//! the tiles after them. The bytes are those of an in-memory encode of the same raster.

use std::collections::VecDeque;
use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::Path;
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::Arc;

use rayon::prelude::*;
use thiserror::Error;
use wavemesh_codec::tiles::{
    blocked_head, budget_caps, cut_to_budget, cut_units, encode_block, encode_tile,
    lossless_may_fit, tiled_head, EncodedTile, EncodedUnit, RasterInfo, TileDetail, TileEntry,
    TileSummary,
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
/// coded up to its cap, [`budget_caps`], from a pass over one row in eight of the DEM)
/// until the budget is shared.
/// The wavelet is settled on the raster's centre, read once more for it, as in memory
/// ([`EncodeOptions::wavelet_chosen_for`]).
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
    let options = &wavelet_settled(bands, info, grid, &blocks, options)?;
    let caps = match options.budget_bytes {
        Some(budget) => {
            let details = tile_details(bands, grid)?;
            let coding = (&mut *bands, info, grid, block_width);
            if let Some(exact) = lossless_if_it_fits(coding, &details, options, output, rows_done)?
            {
                return Ok(exact);
            }
            Some(budget_caps(&details, grid, budget))
        }
        None => None,
    };
    let mut take = |tile: EncodedTile| -> io::Result<()> {
        summaries.push(tile.summary.clone());
        if options.budget_bytes.is_some() {
            kept.push(tile);
            Ok(())
        } else {
            spool.write_all(&tile.bytes)
        }
    };
    let mut block_done = |block: &Block| {
        if block.1.end == grid.columns() {
            rows_done(block.0 + 1);
        }
    };
    let coding = (&mut *bands, grid, &blocks[..], caps.as_deref());
    match options.threads {
        1 => code_blocks_in_turn(coding, options, &mut take, &mut block_done)?,
        n => code_blocks_ahead(coding, options, n, &mut take, &mut block_done)?,
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
    write_out(output, &head, spool, summaries)
}

/// [`encode_tiled`] for a file whose tiles are cut into code blocks of `side` (`grid`
/// from [`wavemesh_codec::tiles::unit_grid`]): a band of tiles is read (the next one
/// while this one's tiles are coded, unless `options.threads` is 1), its tiles coded on
/// `options.threads` threads (a tile a thread, or one tile's blocks on all of them when
/// the band has fewer tiles than threads) and, without a byte budget, spooled; with one, kept
/// (each block coded up to a cap, see [`EncodedUnit::encode`]) until the budget is
/// shared. The bytes are those of an in-memory encode.
pub fn encode_blocked(
    bands: &mut RowBands,
    info: &RasterInfo,
    (grid, side): (&TileGrid, usize),
    options: &EncodeOptions,
    block_width: usize,
    output: &Path,
    rows_done: &mut dyn FnMut(usize),
) -> Result<TiledEncoded, TiledEncodeError> {
    let mut spool = tempfile::tempfile()?;
    let mut kept: Vec<EncodedUnit> = Vec::new();
    let mut summaries: Vec<TileSummary> = Vec::with_capacity(grid.count());
    let mut entries: Vec<TileEntry> = Vec::new();
    let blocks = grid.blocks(bands.tiles_per_block(grid, block_width));
    let options = &wavelet_settled(bands, info, grid, &blocks, options)?;
    let samples = (grid.width * grid.height) as u64;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(options.threads)
        .build()
        .map_err(io::Error::other)?;
    let mut code_band = |b: usize, band: Result<Arc<Raster>, DemError>| {
        let ((row, columns), band) = (&blocks[b], band?);
        let origin = grid.coded_block(*row, columns.clone());
        let first = grid.row(*row).start;
        let tiles: Vec<usize> = (first + columns.start..first + columns.end).collect();
        // A band of at least a tile per thread codes its tiles at once, each on one
        // thread; a narrower one a tile at a time, its blocks on every thread.
        let each = match tiles.len() >= pool.current_num_threads() {
            true => options.clone().with_threads(1),
            false => options.clone(),
        };
        let units: Vec<Result<EncodedUnit, CodecError>> = pool.install(|| {
            tiles
                .par_iter()
                .map(|&k| {
                    let w = grid.coded(k);
                    let part = band.crop(w.x - origin.x, w.y - origin.y, w.width, w.height);
                    EncodedUnit::encode(&part, &each, side, samples)
                })
                .collect()
        });
        for unit in units {
            let unit = unit?;
            summaries.push(unit.summary());
            match options.budget_bytes {
                Some(_) => kept.push(unit),
                None => {
                    entries.extend(unit.entries());
                    spool.write_all(&unit.bytes())?;
                }
            }
        }
        if columns.end == grid.columns() {
            rows_done(row + 1);
        }
        Ok::<(), TiledEncodeError>(())
    };
    if options.threads == 1 {
        let mut outcome = Ok(());
        read_blocks(bands, grid, &blocks, &mut |b, band| {
            outcome = code_band(b, band);
            outcome.is_ok()
        });
        outcome?;
    } else {
        // The next band is read while this one's tiles are coded (their blocks on the
        // coder's threads).
        let blocks = &blocks[..];
        std::thread::scope(|scope| {
            let (send, read) = sync_channel(0);
            scope.spawn(move || {
                read_blocks(bands, grid, blocks, &mut |_, band| send.send(band).is_ok())
            });
            read.into_iter()
                .enumerate()
                .try_for_each(|(b, band)| code_band(b, band))
        })?;
    }
    if let Some(budget) = options.budget_bytes {
        cut_units(&mut kept, info, (grid, side), budget)?;
        // A cut tile is no longer lossless: its summary as the file has it.
        summaries = kept.iter().map(EncodedUnit::summary).collect();
        for unit in &kept {
            entries.extend(unit.entries());
            spool.write_all(&unit.bytes())?;
        }
    }
    let head = blocked_head(info, (grid, side), &summaries, &entries);
    write_out(output, &head, spool, summaries)
}

/// `options` with the wavelet settled on the raster's centre, read for it
/// ([`EncodeOptions::wavelet_chosen_for`], as an in-memory encode settles it). The
/// limits are checked on the first band first: a raster they refuse is refused before
/// anything is read.
fn wavelet_settled(
    bands: &mut RowBands,
    info: &RasterInfo,
    grid: &TileGrid,
    blocks: &[Block],
    options: &EncodeOptions,
) -> Result<EncodeOptions, TiledEncodeError> {
    if !(options.adaptive_wavelet && options.wavelet.is_reversible()) {
        return Ok(options.clone());
    }
    if let Some((row, columns)) = blocks.first() {
        bands.check_window(&grid.coded_block(*row, columns.clone()))?;
    }
    let centre = wavemesh_codec::wavelet_sample(info.width, info.height);
    Ok(options.wavelet_chosen_for(&bands.read_window(centre)?))
}

/// Writes `head` (the header and index), then the tiles spooled to `spool`, to `output`
/// atomically; `tiles` are their summaries.
fn write_out(
    output: &Path,
    head: &[u8],
    mut spool: File,
    tiles: Vec<TileSummary>,
) -> Result<TiledEncoded, TiledEncodeError> {
    let tiles_len = spool.stream_position()?;
    spool.seek(SeekFrom::Start(0))?;
    crate::atomic::write_atomic(output, |w| copy_out(head, &mut spool, w))?;
    Ok(TiledEncoded {
        bytes: head.len() as u64 + tiles_len,
        head_bytes: head.len() as u64,
        tiles,
    })
}

/// A streaming encode's source: the DEM, its tile grid and the blocks it is read in.
/// The DEM, its tiles, the blocks they are read in and, under a byte budget, each tile's
/// cap.
type Coding<'a> = (
    &'a mut RowBands,
    &'a TileGrid,
    &'a [Block],
    Option<&'a [u64]>,
);

/// Each tile's detail, for the caps of a budget encode ([`budget_caps`]), read before
/// any tile is coded: a pass over the rows [`TileDetail::rows`] counts (one in
/// [`TileDetail::ROW_STEP`], each with the row above), top to bottom.
fn tile_details(
    bands: &mut RowBands,
    grid: &TileGrid,
) -> Result<Vec<TileDetail>, TiledEncodeError> {
    let mut details = vec![TileDetail::default(); grid.count()];
    for row in 0..grid.rows() {
        let tiles = row * grid.columns()..(row + 1) * grid.columns();
        for y in TileDetail::rows(&grid.coded(tiles.start)) {
            let rows = bands.read_rows(y - 1, 2)?;
            for k in tiles.clone() {
                let w = grid.coded(k);
                details[k].add_row(&rows, w.x..w.x + w.width);
            }
        }
    }
    Ok(details)
}

/// The lossless file a budget encode writes instead of its 9/7 one, as an in-memory
/// encode does ([`EncodeOptions::lossless_alternative`]): tried when the tiles'
/// `details` say it may fit ([`lossless_may_fit`]), coded to a temporary file, and
/// copied to `output` when it fits the budget.
fn lossless_if_it_fits(
    (bands, info, grid, block_width): (&mut RowBands, &RasterInfo, &TileGrid, usize),
    details: &[TileDetail],
    options: &EncodeOptions,
    output: &Path,
    rows_done: &mut dyn FnMut(usize),
) -> Result<Option<TiledEncoded>, TiledEncodeError> {
    let (Some(lossless), Some(budget)) = (options.lossless_alternative(), options.budget_bytes)
    else {
        return Ok(None);
    };
    let estimate: f64 = details.iter().map(TileDetail::lossless_estimate).sum();
    if !lossless_may_fit(estimate, budget) {
        return Ok(None);
    }
    let trial = tempfile::NamedTempFile::new()?.into_temp_path();
    let exact = match encode_tiled(bands, info, grid, &lossless, block_width, &trial, rows_done) {
        Ok(exact) => exact,
        Err(TiledEncodeError::Encode(_)) => return Ok(None),
        Err(e) => return Err(e),
    };
    if exact.bytes > budget {
        return Ok(None);
    }
    let mut file = File::open(&trial)?;
    crate::atomic::write_atomic(output, |out| io::copy(&mut file, out).map(drop))?;
    Ok(Some(exact))
}

/// Reads each block, then codes its tiles, one after the other on the calling thread,
/// handing the tiles to `take` in grid order and each block to `block_done`.
fn code_blocks_in_turn(
    (bands, grid, blocks, caps): Coding,
    options: &EncodeOptions,
    take: &mut dyn FnMut(EncodedTile) -> io::Result<()>,
    block_done: &mut dyn FnMut(&Block),
) -> Result<(), TiledEncodeError> {
    let mut outcome = Ok(());
    read_blocks(bands, grid, blocks, &mut |b, band| {
        let block = &blocks[b];
        outcome = band.map_err(TiledEncodeError::from).and_then(|band| {
            for tile in encode_block(&band, grid, block.clone(), options, caps)? {
                take(tile)?;
            }
            block_done(block);
            Ok(())
        });
        outcome.is_ok()
    });
    outcome
}

/// [`code_blocks_in_turn`] on `threads` threads (0: one per core): a reader thread reads
/// the next block while the current one's tiles are coded, and tiles are coded one more
/// ahead of their collection than there are threads, across blocks, so no thread waits
/// for a block's slowest tile. The tiles, and so the file, are those of one thread.
fn code_blocks_ahead(
    (bands, grid, blocks, caps): Coding,
    options: &EncodeOptions,
    threads: usize,
    take: &mut dyn FnMut(EncodedTile) -> io::Result<()>,
    block_done: &mut dyn FnMut(&Block),
) -> Result<(), TiledEncodeError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(io::Error::other)?;
    let ahead = pool.current_num_threads() + 1;
    std::thread::scope(|scope| {
        let (send, read) = sync_channel(0);
        scope.spawn(move || {
            read_blocks(bands, grid, blocks, &mut |_, band| send.send(band).is_ok())
        });
        let mut running: VecDeque<(usize, Receiver<Result<EncodedTile, CodecError>>)> =
            VecDeque::new();
        let mut collect = |running: &mut VecDeque<_>| -> Result<(), TiledEncodeError> {
            let (b, tile): (usize, Receiver<_>) = running.pop_front().expect("a tile running");
            take(tile.recv().expect("a coded tile is sent")?)?;
            if running.front().is_none_or(|(next, _)| *next != b) {
                block_done(&blocks[b]);
            }
            Ok(())
        };
        for (b, band) in read.into_iter().enumerate() {
            let (block, band) = (&blocks[b], band?);
            let origin = grid.coded_block(block.0, block.1.clone());
            let first = block.0 * grid.columns();
            for k in first + block.1.start..first + block.1.end {
                while running.len() >= ahead {
                    collect(&mut running)?;
                }
                let w = grid.coded(k);
                let part = band.crop(w.x - origin.x, w.y - origin.y, w.width, w.height);
                let (options, cap) = (options.clone(), caps.map(|caps| caps[k]));
                let (done, tile) = sync_channel(1);
                pool.spawn_fifo(move || {
                    // The receiver is gone only when the encode stopped on an error.
                    let _ = done.send(encode_tile(&part, &options, cap));
                });
                running.push_back((b, tile));
            }
        }
        while !running.is_empty() {
            collect(&mut running)?;
        }
        Ok(())
    })
}

/// Reads `blocks` in order, handing each (by index) to `deliver`, each block's shared
/// rows taken from the one before; stops at the first error or when `deliver` says no.
fn read_blocks(
    bands: &mut RowBands,
    grid: &TileGrid,
    blocks: &[Block],
    deliver: &mut dyn FnMut(usize, Result<Arc<Raster>, DemError>) -> bool,
) {
    let mut previous: Option<(&Block, Arc<Raster>)> = None;
    for (b, block) in blocks.iter().enumerate() {
        let above = previous.as_ref().map(|(p, band)| (*p, &**band));
        let band = read_block(bands, grid, block, above).map(Arc::new);
        let next = band.as_ref().ok().map(|band| (block, Arc::clone(band)));
        if !deliver(b, band) || next.is_none() {
            return;
        }
        previous = next;
    }
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
