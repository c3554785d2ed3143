//! Encoding a DEM larger than memory: read one tile row of samples at a time
//! ([`RowBands`]), code its tiles on every core, and keep only their (compressed)
//! streams, spooled to a temporary file; the header and index go first in the output,
//! the tiles after them. The bytes are those of an in-memory encode of the same raster.

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::Path;

use thiserror::Error;
use wavemesh_codec::tiles::{
    cut_to_budget, encode_band, tiled_head, EncodedTile, RasterInfo, TileSummary,
};
use wavemesh_codec::{CodecError, EncodeOptions, Raster, TileGrid};

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

/// Encodes the raster `bands` reads (described by `info`: its [`RowBands::info`],
/// perhaps with metadata left out) as a
/// tiled file on `grid` into `output` (written atomically), holding two tile rows of
/// samples at a time: the one being coded and the next, read meanwhile (one after the
/// other when `options.threads` is 1). Without a byte budget the
/// tiles' streams wait in a temporary file; with one they are kept in memory (each
/// coded up to about four times its share of the budget) until the budget is shared.
/// `rows_done(k)` is called after each tile row, `k` rows of [`TileGrid::rows`] done.
pub fn encode_tiled(
    bands: &mut RowBands,
    info: &RasterInfo,
    grid: &TileGrid,
    options: &EncodeOptions,
    output: &Path,
    rows_done: &mut dyn FnMut(usize),
) -> Result<TiledEncoded, TiledEncodeError> {
    let mut spool = tempfile::tempfile()?;
    let mut kept: Vec<EncodedTile> = Vec::new();
    let mut summaries: Vec<TileSummary> = Vec::with_capacity(grid.count());
    let mut band = read_band(bands, grid, 0, None)?;
    for row in 0..grid.rows() {
        let (tiles, next) = code_and_read_next(&band, bands, grid, row, options);
        for tile in tiles? {
            summaries.push(tile.summary.clone());
            if options.budget_bytes.is_some() {
                kept.push(tile);
            } else {
                spool.write_all(&tile.bytes)?;
            }
        }
        if let Some(next) = next? {
            band = next;
        }
        rows_done(row + 1);
    }
    if let Some(budget) = options.budget_bytes {
        let cut = cut_to_budget(kept, info, grid, budget, &mut recoder(bands, grid, options))?;
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

/// Codes tile `k` again, up to `cap` bytes, from its rows read again (the last tile
/// row read is kept: the tiles to code again come in grid order).
fn recoder<'a>(
    bands: &'a mut RowBands,
    grid: &'a TileGrid,
    options: &'a EncodeOptions,
) -> impl FnMut(usize, u64) -> Result<EncodedTile, TiledEncodeError> + 'a {
    let mut rows: Option<(usize, Raster)> = None;
    move |k, cap| {
        let row = k / grid.columns();
        if rows.as_ref().is_none_or(|(r, _)| *r != row) {
            let band = grid.coded_rows(row);
            rows = Some((row, bands.read_rows(band.y, band.height)?));
        }
        let (_, band) = rows.as_ref().expect("rows just read");
        let w = grid.coded(k);
        let top = grid.coded_rows(row).y;
        let part = band.crop(w.x, w.y - top, w.width, w.height);
        Ok(wavemesh_codec::tiles::encode_tile(
            &part,
            options,
            Some(cap),
        )?)
    }
}

/// Codes the tiles of `band` (tile row `row`) and reads the next band: at the same time
/// on two threads, unless `options` asks for one thread, when the read follows the coding.
fn code_and_read_next(
    band: &Raster,
    bands: &mut RowBands,
    grid: &TileGrid,
    row: usize,
    options: &EncodeOptions,
) -> (
    Result<Vec<EncodedTile>, CodecError>,
    Result<Option<Raster>, DemError>,
) {
    let read_next = |bands: &mut RowBands| {
        (row + 1 < grid.rows())
            .then(|| read_band(bands, grid, row + 1, Some(band)))
            .transpose()
    };
    if options.threads == 1 {
        let tiles = encode_band(band, grid, row, options);
        return (tiles, read_next(bands));
    }
    std::thread::scope(|scope| {
        let reader = scope.spawn(|| read_next(bands));
        let tiles = encode_band(band, grid, row, options);
        let next = reader.join().expect("the band reader does not panic");
        (tiles, next)
    })
}

/// The rows the streams of tile row `row` code (its own and the overlap), with those it
/// shares with `previous` (the band of row `row - 1`) taken from it, so every row of the
/// DEM is read once.
fn read_band(
    bands: &mut RowBands,
    grid: &TileGrid,
    row: usize,
    previous: Option<&Raster>,
) -> Result<Raster, DemError> {
    let rows = grid.coded_rows(row);
    let end = rows.y + rows.height;
    let (shared, previous) = match previous {
        Some(band) if row > 0 => {
            let from = grid.coded_rows(row - 1);
            let shared = (from.y + from.height).saturating_sub(rows.y);
            (shared, Some((band, rows.y - from.y)))
        }
        _ => (0, None),
    };
    if shared == 0 {
        return bands.read_rows(rows.y, rows.height);
    }
    let (band, offset) = previous.expect("a previous band when rows are shared");
    let above = band.crop(0, offset, grid.width, shared);
    if rows.y + shared == end {
        return Ok(above);
    }
    bands.read_rows_below(&above, rows.y + shared, end - rows.y - shared)
}

/// Writes the header and index, then the spooled tiles.
fn copy_out(head: &[u8], spool: &mut File, out: &mut dyn Write) -> io::Result<()> {
    out.write_all(head)?;
    io::copy(spool, out)?;
    Ok(())
}
