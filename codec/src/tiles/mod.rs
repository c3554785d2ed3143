//! Tiled files: a raster cut into tiles, each an independent embedded stream, listed by
//! an index right after the header. A reader plans every byte range it needs from the
//! header and index alone: a window decode fetches only the tiles it touches, and a
//! decode at a bit rate only a prefix of each tile, chosen by [`allocate()`] so every tile
//! stops at the same rate–distortion slope. Tiles are coded in parallel; the bytes do not
//! depend on the number of threads.

mod allocate;
mod blocked;
mod blocks;
mod caps;
mod float_detail;
mod index;
mod stream;
mod verify;
mod workers;

use std::io;

pub use allocate::allocate;
pub(crate) use allocate::allocate_points;
pub(crate) use blocked::encode as encode_blocked;
pub use blocked::{blocked_head, cut_units, unit_grid, EncodedUnit};
pub use caps::{area_cap, budget_caps, lossless_may_fit, TileDetail};
pub use decode::decode_tile;
pub use index::{read_header, TileEntry, TiledLayout};
pub(crate) use stream::cut_tile;
pub use stream::{encode_tile, EncodedTile, TileSummary};

use crate::container::{frame, Header, Mode, Tiling};
use crate::error::CodecError;
use crate::pipeline::{DecodeOptions, Decoded, EncodeOptions, Encoded};
use crate::raster::{Georef, Metadata, Raster, SampleType};
pub(crate) use verify::verify_tiled;
use workers::Workers;

/// Largest tile side the encoder uses unless told otherwise: rasters with no side longer
/// than this stay a single stream.
pub const DEFAULT_TILE: u32 = 1024;

/// Samples each tile's stream codes beyond its own on every side that has a neighbour
/// (the decoder drops them): a wavelet transform reconstructs the samples on the edge of
/// what it codes worst (symmetric extension doubles their error), so those fall outside
/// the tile. Two samples bring the tile borders' error down to the interior's.
pub const TILE_OVERLAP: usize = 2;

/// A rectangle of samples: its top-left corner and size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl Window {
    /// Every sample of a `width × height` raster.
    pub fn whole(width: usize, height: usize) -> Window {
        Window {
            x: 0,
            y: 0,
            width,
            height,
        }
    }

    /// The part of this window inside `other`, if any.
    pub fn intersection(&self, other: &Window) -> Option<Window> {
        let x = self.x.max(other.x);
        let y = self.y.max(other.y);
        let right = (self.x + self.width).min(other.x + other.width);
        let bottom = (self.y + self.height).min(other.y + other.height);
        (right > x && bottom > y).then(|| Window {
            x,
            y,
            width: right - x,
            height: bottom - y,
        })
    }
}

/// How a raster is cut into tiles: `tile_width × tile_height` from the top-left corner,
/// row-major, the last column and row of tiles narrower where the raster ends. Each
/// tile's stream codes its samples and `overlap` more on every side inside the raster
/// ([`TileGrid::coded`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileGrid {
    /// Raster columns.
    pub width: usize,
    /// Raster rows.
    pub height: usize,
    /// Columns of a tile.
    pub tile_width: usize,
    /// Rows of a tile.
    pub tile_height: usize,
    /// Samples coded beyond a tile on each side (0 in files written before overlaps).
    pub overlap: usize,
}

impl TileGrid {
    /// Tiles no larger than `max_tile` a side and as equal as the raster allows (a
    /// 1201-sample side with `max_tile` 1024 gets two tiles of 601 and 600, not 1024 and
    /// 177), overlapping by [`TILE_OVERLAP`]; `None` when one tile covers the raster.
    pub fn balanced(width: usize, height: usize, max_tile: usize) -> Option<TileGrid> {
        let max_tile = max_tile.max(1);
        if width <= max_tile && height <= max_tile {
            return None;
        }
        let side = |len: usize| len.div_ceil(len.div_ceil(max_tile));
        Some(TileGrid {
            width,
            height,
            tile_width: side(width),
            tile_height: side(height),
            overlap: TILE_OVERLAP,
        })
    }

    /// Tiles across.
    pub fn columns(&self) -> usize {
        self.width.div_ceil(self.tile_width)
    }

    /// Tiles down.
    pub fn rows(&self) -> usize {
        self.height.div_ceil(self.tile_height)
    }

    /// Number of tiles.
    pub fn count(&self) -> usize {
        self.columns().saturating_mul(self.rows())
    }

    /// The samples of tile `index`.
    pub fn tile(&self, index: usize) -> Window {
        let (x, y) = (
            index % self.columns() * self.tile_width,
            index / self.columns() * self.tile_height,
        );
        Window {
            x,
            y,
            width: self.tile_width.min(self.width - x),
            height: self.tile_height.min(self.height - y),
        }
    }

    /// The samples tile `index`'s stream codes: the tile and `overlap` more on each
    /// side, within the raster.
    pub fn coded(&self, index: usize) -> Window {
        let tile = self.tile(index);
        let x = tile.x.saturating_sub(self.overlap);
        let y = tile.y.saturating_sub(self.overlap);
        Window {
            x,
            y,
            width: (tile.x + tile.width + self.overlap).min(self.width) - x,
            height: (tile.y + tile.height + self.overlap).min(self.height) - y,
        }
    }

    /// The samples the streams of tiles `columns` (tile columns) of row `row` code: a
    /// band as high as the row's coded rows and as wide as those tiles and their overlap.
    pub fn coded_block(&self, row: usize, columns: std::ops::Range<usize>) -> Window {
        let first = self.coded(row * self.columns() + columns.start);
        let last = self.coded(row * self.columns() + columns.end.max(columns.start + 1) - 1);
        Window {
            width: last.x + last.width - first.x,
            ..first
        }
    }

    /// The samples of tiles `columns` (tile columns) of row `row`, overlap left out.
    pub fn block(&self, row: usize, columns: std::ops::Range<usize>) -> Window {
        let first = self.tile(row * self.columns() + columns.start);
        let last = self.tile(row * self.columns() + columns.end.max(columns.start + 1) - 1);
        Window {
            width: last.x + last.width - first.x,
            ..first
        }
    }

    /// Tiles of a row that fit in `columns` samples across: at least one, at most the
    /// row.
    pub fn tiles_within(&self, columns: usize) -> usize {
        (columns / self.tile_width).clamp(1, self.columns())
    }

    /// Runs of `per_block` tiles (the last of a row narrower) of each tile row, in file
    /// order: row by row, left to right, as (row, tile columns).
    pub fn blocks(&self, per_block: usize) -> Vec<(usize, std::ops::Range<usize>)> {
        let (columns, per_block) = (self.columns(), per_block.max(1));
        (0..self.rows())
            .flat_map(|row| {
                (0..columns)
                    .step_by(per_block)
                    .map(move |c| (row, c..(c + per_block).min(columns)))
            })
            .collect()
    }

    /// The tiles of row `row`, by index.
    pub fn row(&self, row: usize) -> std::ops::Range<usize> {
        row * self.columns()..(row + 1) * self.columns()
    }
}

/// Random access to the bytes of a file: a slice in memory, a file on disk, or a remote
/// object read by HTTP range requests.
pub trait ByteSource {
    /// Up to `len` bytes from `offset` (fewer, or none, where the data ends: a truncated
    /// file is not an error).
    fn read_at(&mut self, offset: u64, len: usize) -> io::Result<Vec<u8>>;
}

impl ByteSource for &[u8] {
    fn read_at(&mut self, offset: u64, len: usize) -> io::Result<Vec<u8>> {
        let start = usize::try_from(offset)
            .unwrap_or(usize::MAX)
            .min(self.len());
        let end = start.saturating_add(len).min(self.len());
        Ok(self[start..end].to_vec())
    }
}

/// What a tiled file's header says about the whole raster.
#[derive(Debug, Clone, PartialEq)]
pub struct RasterInfo {
    /// Raster columns.
    pub width: usize,
    /// Raster rows.
    pub height: usize,
    /// Sample type.
    pub sample_type: SampleType,
    /// Nodata value, if any.
    pub nodata: Option<f64>,
    /// Georeferencing.
    pub georef: Option<Georef>,
    /// GIS metadata.
    pub metadata: Metadata,
}

impl RasterInfo {
    /// The description of `raster` (its samples aside).
    pub fn of(raster: &Raster) -> RasterInfo {
        RasterInfo {
            width: raster.width,
            height: raster.height,
            sample_type: raster.sample_type(),
            nodata: raster.nodata,
            georef: raster.georef.clone(),
            metadata: raster.metadata.clone(),
        }
    }
}

/// The start of a tiled file: its header and the framed index of `tiles` (in grid
/// order). The tiles' streams follow, in the same order.
pub fn tiled_head(info: &RasterInfo, grid: &TileGrid, tiles: &[TileSummary]) -> Vec<u8> {
    let entries: Vec<TileEntry> = tiles.iter().map(|t| t.entry.clone()).collect();
    file_head(info, (grid, None), tiles, &entries)
}

/// The header and framed index of a tiled file on `grid` (its tiles cut into code
/// blocks of `code_block` when given) whose tiles are `tiles` and whose index lists
/// `entries`.
pub(crate) fn file_head(
    info: &RasterInfo,
    (grid, code_block): (&TileGrid, Option<u32>),
    tiles: &[TileSummary],
    entries: &[TileEntry],
) -> Vec<u8> {
    let index = frame(&index::write_index(entries, true));
    let first = tiles.first().expect("a grid has tiles");
    let mut header = Header::whole_raster(
        info.width as u32,
        info.height as u32,
        info.sample_type,
        first.wavelet,
        first.levels,
        weakest_mode(tiles),
    );
    header.max_error = tiles.iter().map(|t| t.max_error).fold(0.0, f64::max);
    header.valid_range = tiles
        .iter()
        .filter_map(|t| t.valid_range)
        .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
        .unwrap_or((0.0, 0.0));
    header.nodata = info.nodata;
    header.georef = info.georef.clone();
    header.metadata = info.metadata.clone();
    header.tiling = Some(Tiling {
        tile_width: grid.tile_width as u32,
        tile_height: grid.tile_height as u32,
        overlap: grid.overlap as u32,
        index_len: index.len() as u64,
        compact_tiles: true,
        code_block,
    });
    let mut out = header.to_bytes();
    out.extend_from_slice(&index);
    out
}

/// The guarantee all tiles share: lossless only if every tile is, and so on.
fn weakest_mode(tiles: &[TileSummary]) -> Mode {
    let rank = |m: Mode| match m {
        Mode::Lossless => 0,
        Mode::Precision => 1,
        Mode::MaxError => 2,
        Mode::Lossy => 3,
    };
    tiles
        .iter()
        .map(|t| t.mode)
        .max_by_key(|&m| rank(m))
        .unwrap_or(Mode::Lossless)
}

/// Encodes `raster` as a tiled file on `grid` (see [`crate::encode`], which calls this
/// for rasters larger than a tile). With a byte budget every tile is coded up to a cap,
/// then cut where [`allocate()`] says.
pub(crate) fn encode(
    raster: &Raster,
    options: &EncodeOptions,
    grid: &TileGrid,
) -> Result<Encoded, CodecError> {
    let workers = Workers::new(options.threads)?;
    let caps = options.budget_bytes.map(|budget| {
        let details: Vec<TileDetail> = (0..grid.count())
            .map(|k| TileDetail::of(raster, &grid.coded(k)))
            .collect();
        budget_caps(&details, grid, budget)
    });
    let mut tiles: Vec<EncodedTile> = Vec::with_capacity(grid.count());
    for row in 0..grid.rows() {
        let y = row * grid.tile_height;
        let height = grid.tile_height.min(grid.height - y);
        let whole = Window {
            x: 0,
            y: 0,
            width: raster.width,
            height: raster.height,
        };
        tiles.extend(encode_tiles(
            &workers,
            (raster, &whole),
            grid,
            grid.row(row),
            options,
            caps.as_deref(),
        )?);
        let done = (y + height) as u64 * raster.width as u64;
        crate::progress::report(crate::progress::Stage::Tiles, done, raster.len() as u64);
    }
    let info = RasterInfo::of(raster);
    if let Some(budget) = options.budget_bytes {
        let mut recode = |k: usize, cap: u64| {
            let w = grid.coded(k);
            let part = raster.crop(w.x, w.y, w.width, w.height);
            encode_tile(&part, options, Some(cap))
        };
        tiles = cut_to_budget(tiles, &info, grid, budget, &mut recode)?;
    }
    let summaries: Vec<TileSummary> = tiles.iter().map(|t| t.summary.clone()).collect();
    let mut bytes = tiled_head(&info, grid, &summaries);
    let header_len = Header::declared_len(&bytes).expect("a header we wrote");
    for tile in &tiles {
        bytes.extend_from_slice(&tile.bytes);
    }
    let (header, _) = Header::parse(&bytes)?;
    Ok(Encoded {
        bytes,
        header,
        header_len,
        initial_error: summaries.iter().map(|t| t.entry.initial_error).sum(),
        checkpoints: Vec::new(),
    })
}

/// Encodes tiles `columns` (tile columns) of row `row` of `grid` from `band`, the
/// samples of [`TileGrid::coded_block`] for them, on `options.threads` threads (0: one
/// per core), in grid order. Under a byte budget each tile is coded up to its cap in
/// `caps` (every tile's, by index: [`budget_caps`]; see [`cut_to_budget`] for the cut);
/// without one, `caps` is `None` and each tile is coded completely.
pub fn encode_block(
    band: &Raster,
    grid: &TileGrid,
    (row, columns): (usize, std::ops::Range<usize>),
    options: &EncodeOptions,
    caps: Option<&[u64]>,
) -> Result<Vec<EncodedTile>, CodecError> {
    let origin = grid.coded_block(row, columns.clone());
    let first = row * grid.columns();
    encode_tiles(
        &Workers::new(options.threads)?,
        (band, &origin),
        grid,
        first + columns.start..first + columns.end,
        options,
        caps,
    )
}

/// Tiles `tiles` (indices, in order) cut from `band`, whose top-left sample is raster
/// sample (`origin.x`, `origin.y`), each coded completely or, under a byte budget, up
/// to its cap in `caps` (by tile index).
fn encode_tiles(
    workers: &Workers,
    (band, origin): (&Raster, &Window),
    grid: &TileGrid,
    tiles: std::ops::Range<usize>,
    options: &EncodeOptions,
    caps: Option<&[u64]>,
) -> Result<Vec<EncodedTile>, CodecError> {
    workers
        .map(tiles, |k| {
            let w = grid.coded(k);
            let part = band.crop(w.x - origin.x, w.y - origin.y, w.width, w.height);
            encode_tile(&part, options, caps.map(|caps| caps[k]))
        })
        .into_iter()
        .collect()
}

/// How many times its bytes a starved tile is coded to again.
const RECODE_FACTOR: u64 = 3;

/// Cuts tiles so the whole file fits `budget` bytes. Tiles coded up to a cap that the
/// allocation reads nearly to the end of (within 64 bytes and 1/32) are first coded
/// again by `recode(k, cap)` with three times the bytes, until no cap comes near the cut
/// (at most six rounds): the allocation of a tile's prefix then does not depend on where
/// its cap stopped it. The index shrinks with the cut (fewer passes to list), so the header and
/// index are first counted without passes, then the excess of each try, if any, is
/// taken off the tiles' share.
pub fn cut_to_budget<E: From<CodecError>>(
    mut tiles: Vec<EncodedTile>,
    info: &RasterInfo,
    grid: &TileGrid,
    budget: u64,
    recode: &mut dyn FnMut(usize, u64) -> Result<EncodedTile, E>,
) -> Result<Vec<EncodedTile>, E> {
    for _ in 0..6 {
        let (cut, starved) = plan_cut(&tiles, info, grid, budget)?;
        if starved.is_empty() {
            return Ok(cut);
        }
        for (k, cap) in starved {
            tiles[k] = recode(k, cap)?;
        }
    }
    Ok(plan_cut(&tiles, info, grid, budget)?.0)
}

/// A tile as the allocation sees it: its rate–distortion points (see
/// [`EncodedTile::points`]) with its head counted as long as a cut header makes it (a
/// whole tile's may be a byte or two shorter, a capped tile's depends on where the cap
/// stopped it), its whole length and the end of its last known point in those terms.
struct Planned {
    points: Vec<(u64, f64)>,
    len: u64,
    known: u64,
}

impl Planned {
    fn of(tile: &EncodedTile, lossless: bool) -> Result<Planned, CodecError> {
        let entry = &tile.summary.entry;
        let head = cut_tile(&tile.bytes, &tile.summary, entry.head_len)?
            .summary
            .entry
            .head_len;
        let shift = |end: u64| end - entry.head_len + head;
        let points = tile.points(lossless);
        let known = entry.passes.iter().chain(&tile.checkpoints).map(|p| p.0);
        Ok(Planned {
            points: points.iter().map(|&(end, e)| (shift(end), e)).collect(),
            len: shift(tile.bytes.len() as u64),
            known: shift(known.max().unwrap_or(entry.head_len)),
        })
    }

    /// Whether an allocation of `len` bytes comes within 64 bytes and 1/32 of the end of
    /// what the tile's points know of (past its head): the last points of a capped tile
    /// may be off its whole stream's hull, and its last bytes are flushed at the cap.
    fn near_end(&self, len: u64) -> bool {
        let head = self.points[0].0;
        let known = self.known.saturating_sub(head);
        32 * (len.saturating_sub(head) + 64) > 31 * known
    }
}

/// A tile to code again and its new cap.
type Recode = (usize, u64);

/// The cut of [`cut_to_budget`] for the tiles as they are coded, and the tiles to code
/// again, each with its new cap ([`RECODE_FACTOR`] times its bytes): those whose cap
/// stopped their stream and that the cut reads [nearly](Planned::near_end) to their last
/// known point.
fn plan_cut(
    tiles: &[EncodedTile],
    info: &RasterInfo,
    grid: &TileGrid,
    budget: u64,
) -> Result<(Vec<EncodedTile>, Vec<Recode>), CodecError> {
    let summaries: Vec<TileSummary> = tiles.iter().map(|t| t.summary.clone()).collect();
    let lossless = weakest_mode(&summaries) == Mode::Lossless;
    let planned = tiles
        .iter()
        .map(|t| Planned::of(t, lossless))
        .collect::<Result<Vec<Planned>, CodecError>>()?;
    let (cut, lengths) = cut_planned(tiles, &planned, info, grid, budget)?;
    let mut starved = Vec::new();
    for (k, tile) in tiles.iter().enumerate() {
        if planned[k].near_end(lengths[k]) && Header::parse_tile(&tile.bytes)?.0.payload_truncated {
            starved.push((k, RECODE_FACTOR * tile.bytes.len() as u64));
        }
    }
    Ok((cut, starved))
}

/// Cuts `tiles`, seen by the allocation as `planned`, to fit `budget`; also returns the
/// bytes the allocation gave each.
fn cut_planned(
    tiles: &[EncodedTile],
    planned: &[Planned],
    info: &RasterInfo,
    grid: &TileGrid,
    budget: u64,
) -> Result<(Vec<EncodedTile>, Vec<u64>), CodecError> {
    let points: Vec<Vec<(u64, f64)>> = planned.iter().map(|p| p.points.clone()).collect();
    // The header and index without passes, each tile no longer than its head.
    let bare: Vec<TileSummary> = tiles
        .iter()
        .zip(planned)
        .map(|(t, p)| {
            let mut t = t.summary.clone();
            t.entry.passes.clear();
            (t.entry.len, t.entry.head_len) = (p.points[0].0, p.points[0].0);
            t
        })
        .collect();
    let mut reserve = tiled_head(info, grid, &bare).len() as u64;
    let least = reserve + points.iter().map(|p| p[0].0).sum::<u64>();
    for _ in 0..8 {
        let lengths = share_budget(&points, budget, (reserve, least))?;
        let cut = tiles
            .iter()
            .zip(planned)
            .zip(&lengths)
            .map(|((tile, p), &len)| {
                let len = if len >= p.len { u64::MAX } else { len };
                cut_tile(&tile.bytes, &tile.summary, len)
            })
            .collect::<Result<Vec<EncodedTile>, CodecError>>()?;
        let cut_summaries: Vec<TileSummary> = cut.iter().map(|t| t.summary.clone()).collect();
        let total = tiled_head(info, grid, &cut_summaries).len() as u64
            + cut.iter().map(|t| t.bytes.len() as u64).sum::<u64>();
        if total <= budget {
            return Ok((cut, lengths));
        }
        reserve += total - budget;
    }
    Err(budget_too_small(budget, least))
}

/// The allocation ([`allocate_points`]) of what `budget` leaves after `reserve` bytes
/// (header and index) over the entries' rate–distortion `points`; refused when not even
/// their heads fit (`least` bytes with the header and index).
pub(crate) fn share_budget(
    points: &[Vec<(u64, f64)>],
    budget: u64,
    (reserve, least): (u64, u64),
) -> Result<Vec<u64>, CodecError> {
    budget
        .checked_sub(reserve)
        .and_then(|left| allocate_points(points, left))
        .ok_or_else(|| budget_too_small(budget, least))
}

/// The refusal of a budget below the `least` bytes a file can take.
pub(crate) fn budget_too_small(budget: u64, least: u64) -> CodecError {
    CodecError::InvalidParameters(format!(
        "a budget of {budget} bytes is smaller than the headers, index and nodata masks ({least} bytes)"
    ))
}

/// Decodes `windows` of a tiled file from `source` one after the other, handing each to
/// `deliver` (`false` stops), reading only the bytes they need: the header and index,
/// then for each tile a window touches the prefix [`allocate()`] gives it under
/// `options.max_bytes` (all of it without a budget). Tiles are decoded ahead of their
/// placing, across windows (see [`decode::TilesAhead`]). `before_output` runs before
/// each window's samples are allocated (after its first tile is decoded).
pub(crate) fn decode_layout(
    source: &mut impl ByteSource,
    layout: &TiledLayout,
    windows: &[Window],
    options: &DecodeOptions,
    before_output: &mut dyn FnMut(),
    deliver: &mut dyn FnMut(Window, Decoded) -> bool,
) -> Result<(), CodecError> {
    let whole = Window {
        x: 0,
        y: 0,
        width: layout.grid.width,
        height: layout.grid.height,
    };
    let workers = Workers::new(options.threads)?;
    for w in windows {
        if w.intersection(&whole) != Some(*w) {
            return Err(CodecError::InvalidParameters(format!(
                "window {}x{} at ({}, {}) is not inside the {}x{} raster",
                w.width, w.height, w.x, w.y, whole.width, whole.height
            )));
        }
        check_memory(layout, w, options, workers.count())?;
    }
    let lengths = tile_lengths(layout, options.max_bytes)?;
    if layout.code_block().is_some() {
        let plan = (windows, &lengths[..]);
        return blocked::decode_windows(source, layout, plan, options, before_output, deliver);
    }
    let touched: Vec<Vec<usize>> = windows
        .iter()
        .map(|w| {
            (0..layout.grid.count())
                .filter(|&k| layout.grid.tile(k).intersection(w).is_some())
                .collect()
        })
        .collect();
    let order = touched.iter().flatten().copied().collect();
    let mut tiles = decode::TilesAhead::new((source, layout, &lengths), options, &workers, order);
    for (window, tile_count) in windows.iter().zip(touched.iter().map(Vec::len)) {
        let mut output = None;
        for _ in 0..tile_count {
            let (k, fetched, result) = tiles.next()?;
            let output = output.get_or_insert_with(|| {
                before_output();
                decode::Output::new(&layout.header, *window)
            });
            let whole = fetched == layout.entries[k].len;
            output.place(k, layout, whole, result, options.strict)?;
        }
        let output = output.unwrap_or_else(|| {
            before_output();
            decode::Output::new(&layout.header, *window)
        });
        if !deliver(*window, output.finish(layout)) {
            break;
        }
    }
    Ok(())
}

mod decode;

/// Bytes of each tile a decode reads: all of them, or the budget's allocation.
pub fn tile_lengths(layout: &TiledLayout, max_bytes: Option<u64>) -> Result<Vec<u64>, CodecError> {
    let full: Vec<u64> = layout.entries.iter().map(|e| e.len).collect();
    let Some(budget) = max_bytes.filter(|&b| b < layout.file_len()) else {
        return Ok(full);
    };
    let lossless = layout.header.mode == Mode::Lossless;
    budget
        .checked_sub(layout.head_len())
        .and_then(|left| allocate(&layout.entries, lossless, left))
        .ok_or(CodecError::TruncatedHeader(
            "the byte budget ends before the tiles' headers and masks",
        ))
}

/// Refuses a decode whose output and tiles in flight would pass the memory limit.
fn check_memory(
    layout: &TiledLayout,
    window: &Window,
    options: &DecodeOptions,
    threads: usize,
) -> Result<(), CodecError> {
    let samples = (window.width * window.height) as u64;
    if samples > options.limits.max_samples {
        return Err(CodecError::LimitExceeded {
            what: "sample count",
            needed: samples,
            limit: options.limits.max_samples,
        });
    }
    let tile = layout.grid.coded(0);
    let tile = (tile.width * tile.height) as u64;
    let needed = samples * layout.header.sample_type.bytes() as u64 + threads as u64 * tile * 10;
    if needed > options.limits.max_memory {
        return Err(CodecError::LimitExceeded {
            what: "decoder memory",
            needed,
            limit: options.limits.max_memory,
        });
    }
    Ok(())
}
