//! Coding a tile in code blocks: one transform, each block's pyramid coded whole (or to
//! a cap under a budget), then every block cut where one allocation says.

use super::{unit_levels, BLOCK_HEAD};
use crate::container::{
    assemble_as, frame, framed_len, physical_offset, Header, Layout, Mode, CHUNK,
};
use crate::error::CodecError;
use crate::ezw::{self, CoefficientLayout, EncodedPayload};
use crate::pipeline::{plan_stream, EncodeOptions, Encoded};
use crate::quantize::Prepared;
use crate::raster::Raster;
use crate::tiles::blocks::{Block, BlockGrid};
use crate::tiles::index::TileEntry;
use crate::tiles::stream::TileSummary;
use crate::tiles::workers::Workers;
use crate::tiles::{budget_too_small, file_head, share_budget, RasterInfo, TileGrid};

/// One block's coded stream and how much of it the file keeps.
#[derive(Debug)]
struct CodedBlock {
    top: Option<u32>,
    payload: EncodedPayload,
    /// Payload bytes kept.
    kept: usize,
}

impl CodedBlock {
    /// Codes `block` of a tile whose transform is `prepared`, up to `cap` payload bytes
    /// when given.
    fn encode(
        grid: &BlockGrid,
        block: Block,
        prepared: &Prepared,
        cap: Option<usize>,
    ) -> CodedBlock {
        let coefficients = grid.gather(&prepared.coefficients, block);
        let layout = CoefficientLayout::new(
            block.width,
            block.height,
            &grid.subbands(block),
            &prepared.shifts,
        );
        let top = ezw::top_plane(&layout, &coefficients);
        let payload = ezw::encode(
            &layout,
            &coefficients,
            top,
            &prepared.distortion_weights,
            prepared.midpoint,
            cap,
        );
        CodedBlock {
            top,
            kept: payload.bytes.len(),
            payload,
        }
    }

    /// Whether the file keeps less than the whole stream (cut by a budget or a cap).
    fn cut(&self) -> bool {
        self.kept < self.payload.bytes.len() || !self.payload.complete
    }

    /// Its pass ends and checkpoints, as (payload bytes, estimated squared error).
    fn marks(&self) -> impl Iterator<Item = (u64, f64)> + '_ {
        let passes = self.payload.passes.iter();
        let ends = passes.map(|p| (p.end_byte, p.squared_error));
        ends.chain(self.payload.checkpoints.iter().copied())
    }

    /// The block's stream as the file holds it.
    fn bytes(&self) -> Vec<u8> {
        let top = self.top.map_or(0, |t| t as u8 + 1);
        let mut bytes = vec![top | u8::from(self.cut()) << 7];
        bytes.extend_from_slice(&frame(&self.payload.bytes[..self.kept]));
        bytes
    }

    /// Its passes kept, as (prefix length, squared error).
    fn passes(&self) -> Vec<(u64, f64)> {
        self.payload
            .passes
            .iter()
            .filter(|p| p.end_byte <= self.kept as u64)
            .map(|p| (BLOCK_HEAD + physical_offset(p.end_byte), p.squared_error))
            .collect()
    }

    /// Its index entry: every pass of a whole block; a cut one lists only its end, as
    /// if a pass ended there (see [`cut_end`](Self::cut_end)).
    fn entry(&self) -> TileEntry {
        let len = BLOCK_HEAD + framed_len(self.kept) as u64;
        let passes = match self.cut() {
            true => self
                .cut_end()
                .map(|error| (len, error))
                .into_iter()
                .collect(),
            false => self.passes(),
        };
        TileEntry {
            len,
            head_len: BLOCK_HEAD,
            initial_error: self.payload.initial_error,
            passes,
        }
    }

    /// The estimated error of the kept payload (that of the last pass end or checkpoint
    /// within it; the allocation cuts there but for one block a budget), `None` when
    /// nothing is kept. The index lists no more of a cut block: each pass listed would
    /// cost about 3 bytes a block (0.013 dB on the shared DEMs at 0.25 bpp in blocks of
    /// 256), and a decode at a lower rate models the curve from the head to this end.
    fn cut_end(&self) -> Option<f64> {
        let kept = self.kept as u64;
        let at_kept = self.marks().filter(|&(end, _)| end <= kept).map(|p| p.1);
        (kept > 0).then(|| at_kept.fold(self.payload.initial_error, f64::min))
    }

    /// Every point a budget may cut the whole block at: head, checkpoints, pass ends,
    /// the whole stream (error 0 when `lossless` and not capped), each at the bytes the
    /// block takes in the file when cut there (its last chunk's checksum included).
    fn points(&self, lossless: bool) -> Vec<(u64, f64)> {
        let stored = |end: u64| BLOCK_HEAD + framed_len(end as usize) as u64;
        let mut points = vec![(BLOCK_HEAD, self.payload.initial_error)];
        points.extend(self.marks().map(|(end, e)| (stored(end), e)));
        points.sort_by_key(|p| p.0);
        let last = points.last().expect("the head").1;
        let whole = stored(self.payload.bytes.len() as u64);
        let exact = lossless && self.payload.complete;
        points.push((whole, if exact { 0.0 } else { last }));
        points
    }

    /// Keeps as much payload as fits `len` bytes of stream.
    fn cut_to(&mut self, len: u64) {
        let room = len.saturating_sub(BLOCK_HEAD) as usize;
        let framing = room.div_ceil(CHUNK + 4) * 4;
        let mut kept = room.saturating_sub(framing).min(self.payload.bytes.len());
        while framed_len(kept) > room {
            kept -= 1;
        }
        self.kept = kept;
    }
}

/// A tile coded in code blocks: its head (header, nodata mask, residual section) and its
/// blocks, each as coded until [`cut_units`] cuts them to a budget. A streaming encoder
/// holds these (compressed) until their bytes go out.
#[derive(Debug)]
pub struct EncodedUnit {
    header: Header,
    mask: Vec<u8>,
    residual: Vec<u8>,
    valid_range: Option<(f64, f64)>,
    blocks: Vec<CodedBlock>,
}

impl EncodedUnit {
    /// Codes `part`, the samples a tile's stream codes (the tile and its overlap, see
    /// [`TileGrid::coded`]) of a raster of `raster_samples` samples, in blocks of `side`
    /// as `options` say (their tile size aside), the blocks on `options.threads` threads:
    /// each whole, or under a byte budget up to 4 times its share of the
    /// budget by area (and 4 KiB).
    pub fn encode(
        part: &Raster,
        options: &EncodeOptions,
        side: usize,
        raster_samples: u64,
    ) -> Result<EncodedUnit, CodecError> {
        let levels = unit_levels(part.width, part.height, side, options.levels);
        let plan = plan_stream(part, options, levels)?;
        let grid = BlockGrid::new(part.width, part.height, side, levels).expect("aligned levels");
        let blocks: Vec<Block> = grid.blocks().collect();
        let cap = |b: Block| {
            let share = options.budget_bytes? as f64 * (b.width * b.height) as f64;
            Some((BLOCK_CAP_SHARES * share / raster_samples as f64) as usize + 4096)
        };
        let coded = Workers::new(options.threads)?.map(0..blocks.len(), |b| {
            CodedBlock::encode(&grid, blocks[b], &plan.prepared, cap(blocks[b]))
        });
        let any_valid = (0..part.len()).any(|i| part.is_valid(i));
        Ok(EncodedUnit {
            valid_range: any_valid.then_some(plan.header.valid_range),
            header: plan.header,
            mask: plan.mask,
            residual: plan.residual,
            blocks: coded,
        })
    }

    /// Whether a block was cut (by a budget or a cap): the residual section then goes,
    /// and with it any error guarantee, as from a cut stream.
    fn cut(&self) -> bool {
        self.blocks.iter().any(CodedBlock::cut)
    }

    /// The head's header as the file holds it, its sections still unsized.
    fn head_header(&self) -> Header {
        let mut header = self.header.clone();
        if self.cut() {
            header.correction_step = 0.0;
            header.residuals_by_exponent = false;
            header.mode = Mode::Lossy;
            header.max_error = f64::INFINITY;
        }
        header
    }

    /// The head's bytes and its entry: the residual section, when kept, is its tail, past
    /// `head_len` (a decode reads it last, when every block is whole).
    fn head(&self) -> (Vec<u8>, TileEntry) {
        let mut header = self.head_header();
        let residual: &[u8] = if self.cut() { &[] } else { &self.residual };
        let (bytes, header_len) =
            assemble_as(Layout::Tile, &mut header, [&self.mask, &[], residual]);
        let entry = TileEntry {
            len: bytes.len() as u64,
            head_len: (header_len + header.mask_len as usize) as u64,
            initial_error: 0.0,
            passes: Vec::new(),
        };
        (bytes, entry)
    }

    /// What the file's header needs of the tile (its entry is its head's).
    pub fn summary(&self) -> TileSummary {
        let header = self.head_header();
        TileSummary {
            entry: self.head().1,
            mode: header.mode,
            max_error: header.max_error,
            valid_range: self.valid_range,
            wavelet: header.wavelet,
            levels: header.levels,
        }
    }

    /// Its index entries: its head's, then its blocks'.
    pub fn entries(&self) -> Vec<TileEntry> {
        let head = std::iter::once(self.head().1);
        head.chain(self.blocks.iter().map(CodedBlock::entry))
            .collect()
    }

    /// Its bytes in the file: its head, then its blocks' streams.
    pub fn bytes(&self) -> Vec<u8> {
        let mut bytes = self.head().0;
        for block in &self.blocks {
            bytes.extend(block.bytes());
        }
        bytes
    }
}

/// A block's cap under a budget, in shares of the budget by its area (see
/// [`EncodedUnit::encode`]). It bounds the memory of a streaming encode (coded blocks
/// wait for the allocation); at 0.25 bpp the four seam DEMs (`tests/tile_seams.rs`)
/// decode to the same PSNR, to the thousandth of a dB, as with blocks coded whole.
const BLOCK_CAP_SHARES: f64 = 4.0;

/// Encodes `raster` as a tiled file on `grid` whose tiles are cut into code blocks of
/// `side` (see [`crate::encode`]), then cuts the blocks to the byte budget, if any
/// ([`cut_units`]).
pub(crate) fn encode(
    raster: &Raster,
    options: &EncodeOptions,
    grid: &TileGrid,
    side: usize,
) -> Result<Encoded, CodecError> {
    let mut units = Vec::with_capacity(grid.count());
    let mut done = 0;
    for k in 0..grid.count() {
        let w = grid.coded(k);
        let part = raster.crop(w.x, w.y, w.width, w.height);
        units.push(EncodedUnit::encode(
            &part,
            options,
            side,
            raster.len() as u64,
        )?);
        done += part.len() as u64;
        crate::progress::report(crate::progress::Stage::Tiles, done, raster.len() as u64);
    }
    let info = RasterInfo::of(raster);
    if let Some(budget) = options.budget_bytes {
        cut_units(&mut units, &info, (grid, side), budget)?;
    }
    let bytes = assemble(&units, &info, (grid, side));
    let (header, header_len) = Header::parse(&bytes)?;
    Ok(Encoded {
        bytes,
        header,
        header_len,
        initial_error: units
            .iter()
            .flat_map(|u| &u.blocks)
            .map(|b| b.payload.initial_error)
            .sum(),
        checkpoints: Vec::new(),
    })
}

/// The header and framed index of a file on `grid` whose tiles are cut into code blocks
/// of `side`: `tiles` the tiles' summaries, `entries` every entry in index order (each
/// tile's [`EncodedUnit::entries`] in turn). Their bytes follow, tile by tile.
pub fn blocked_head(
    info: &RasterInfo,
    (grid, side): (&TileGrid, usize),
    tiles: &[TileSummary],
    entries: &[TileEntry],
) -> Vec<u8> {
    file_head(info, (grid, Some(side as u32)), tiles, entries)
}

/// The file: header, index, then tile by tile its head and its blocks.
fn assemble(units: &[EncodedUnit], info: &RasterInfo, (grid, side): (&TileGrid, usize)) -> Vec<u8> {
    let summaries: Vec<TileSummary> = units.iter().map(EncodedUnit::summary).collect();
    let entries: Vec<TileEntry> = units.iter().flat_map(EncodedUnit::entries).collect();
    let mut bytes = blocked_head(info, (grid, side), &summaries, &entries);
    for unit in units {
        bytes.extend(unit.bytes());
    }
    bytes
}

/// Cuts the blocks of `units` (the tiles of `grid`, in order) so that the file fits
/// `budget` bytes: the header, index and heads first, then every block's
/// rate–distortion points shared out by one allocation; the index shrinks with the cut,
/// so it is first counted without passes and any excess taken off the blocks' share.
pub fn cut_units(
    units: &mut [EncodedUnit],
    info: &RasterInfo,
    (grid, side): (&TileGrid, usize),
    budget: u64,
) -> Result<(), CodecError> {
    let lossless = units.iter().all(|u| u.header.mode == Mode::Lossless);
    let points: Vec<Vec<(u64, f64)>> = units
        .iter()
        .flat_map(|u| {
            // Without its residual section: a cut tile drops it.
            let head = vec![(u.head().1.head_len, 0.0)];
            std::iter::once(head).chain(u.blocks.iter().map(|b| b.points(lossless)))
        })
        .collect();
    let summaries: Vec<TileSummary> = units.iter().map(EncodedUnit::summary).collect();
    let bare: Vec<TileEntry> = points
        .iter()
        .map(|p| TileEntry {
            len: p[0].0,
            head_len: p[0].0,
            initial_error: p[0].1,
            passes: Vec::new(),
        })
        .collect();
    let mut reserve = file_head(info, (grid, Some(side as u32)), &summaries, &bare).len() as u64;
    let least = reserve + bare.iter().map(|e| e.len).sum::<u64>();
    for _ in 0..8 {
        let lengths = share_budget(&points, budget, (reserve, least))?;
        let mut lengths = lengths.into_iter();
        for unit in units.iter_mut() {
            lengths.next();
            for (block, len) in unit.blocks.iter_mut().zip(&mut lengths) {
                block.cut_to(len);
            }
        }
        let total = assemble(units, info, (grid, side)).len() as u64;
        if total <= budget {
            return Ok(());
        }
        reserve += total - budget;
    }
    Err(budget_too_small(budget, least))
}
