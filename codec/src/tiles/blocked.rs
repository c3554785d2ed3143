//! Tiles cut into code blocks (header flag 15): each tile is one transform, and the
//! coefficients below each `side × side` square of its samples ([`BlockGrid`]) are coded
//! as an embedded stream of their own. The index lists, tile by tile, the tile's head (a
//! tile-layout header with no payload, the nodata mask and the residual section) and
//! then its blocks. Block borders do not show as tile borders do (no transform edge
//! there), while a reader still fetches only the blocks a window needs and, at a bit
//! rate, a prefix of each, shared out by [`allocate()`](super::allocate()) over every
//! block.
//!
//! A block's stream is one head byte (bit 7: the payload was cut; bits 0–6: its top
//! plane plus one, 0 when every coefficient is zero) and its payload, framed.

use super::blocks::{Block, BlockGrid};
use super::index::TileEntry;
use super::stream::TileSummary;
use super::workers::Workers;
use super::{file_head, ByteSource, RasterInfo, TileGrid, TiledLayout, Window};
use crate::container::{
    assemble_as, check_frames, frame, framed_len, physical_offset, Header, Layout, Mode,
    StreamSections, CHUNK,
};
use crate::entropy::ArithmeticDecoder;
use crate::error::CodecError;
use crate::ezw::{self, CoefficientLayout, Decoder, EncodedPayload, MAX_PLANE};
use crate::pipeline::{
    apply_residual_section, check_limits, plan_stream, reconstruct, Coefficients, Damage,
    DecodeOptions, Decoded, EncodeOptions, Encoded,
};
use crate::raster::Raster;
use crate::wavelet::{self, Wavelet};

/// Bytes of a block's stream before its payload.
const BLOCK_HEAD: u64 = 1;

/// The tiles a raster of `width × height` is coded in when its blocks are `side` a side
/// (a multiple of 64): tiles no larger than `max_tile` (rounded up to whole blocks) and
/// as equal as whole blocks allow, one tile when it fits. `None` when one block covers
/// the raster (one stream does better).
pub fn unit_grid(width: usize, height: usize, max_tile: usize, side: usize) -> Option<TileGrid> {
    if width <= side && height <= side {
        return None;
    }
    let max_tile = max_tile.div_ceil(side).max(1) * side;
    let tile_side = |len: usize| len.div_ceil(len.div_ceil(max_tile)).div_ceil(side) * side;
    Some(TileGrid {
        width,
        height,
        tile_width: tile_side(width).min(width),
        tile_height: tile_side(height).min(height),
        overlap: 0,
    })
}

/// Decomposition levels of a `width × height` tile in blocks of `side`: those asked (or
/// the default), at most what leaves each block's coarsest band 4 samples a side (6
/// levels for blocks of 256 measured best: the zerotrees keep roots to share).
fn unit_levels(width: usize, height: usize, side: usize, asked: Option<u32>) -> u32 {
    asked
        .unwrap_or_else(|| wavelet::default_levels(width, height))
        .min(side.trailing_zeros().saturating_sub(2))
        .min(wavelet::max_levels(width, height))
}

/// One block's coded stream and how much of it the file keeps.
struct CodedBlock {
    top: Option<u32>,
    payload: EncodedPayload,
    /// Payload bytes kept.
    kept: usize,
}

impl CodedBlock {
    fn encode(grid: &BlockGrid, block: Block, plan: &UnitPlan) -> CodedBlock {
        let prepared = &plan.prepared;
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
            None,
        );
        CodedBlock {
            top,
            kept: payload.bytes.len(),
            payload,
        }
    }

    fn cut(&self) -> bool {
        self.kept < self.payload.bytes.len() || !self.payload.complete
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
        let passes = self
            .payload
            .passes
            .iter()
            .map(|p| (p.end_byte, p.squared_error));
        let within = passes.chain(self.payload.checkpoints.iter().copied());
        let at_kept = within.filter(|&(end, _)| end <= kept).map(|p| p.1);
        (kept > 0).then(|| at_kept.fold(self.payload.initial_error, f64::min))
    }

    /// Every point a budget may cut the whole block at: head, checkpoints, pass ends,
    /// the whole stream (error 0 when `lossless`), each at the bytes the block takes in
    /// the file when cut there (its last chunk's checksum included).
    fn points(&self, lossless: bool) -> Vec<(u64, f64)> {
        let stored = |end: u64| BLOCK_HEAD + framed_len(end as usize) as u64;
        let passes = self
            .payload
            .passes
            .iter()
            .map(|p| (p.end_byte, p.squared_error));
        let marks = passes.chain(self.payload.checkpoints.iter().copied());
        let mut points = vec![(BLOCK_HEAD, self.payload.initial_error)];
        points.extend(marks.map(|(end, e)| (stored(end), e)));
        points.sort_by_key(|p| p.0);
        let last = points.last().expect("the head").1;
        let whole = stored(self.payload.bytes.len() as u64);
        points.push((whole, if lossless { 0.0 } else { last }));
        points
    }

    /// Keeps as much payload as fits `len` bytes of stream.
    fn cut_to(&mut self, len: u64) {
        let room = len.saturating_sub(BLOCK_HEAD) as usize;
        let mut kept = (room - room.div_ceil(CHUNK + 4) * 4).min(self.payload.bytes.len());
        while framed_len(kept) > room {
            kept -= 1;
        }
        self.kept = kept;
    }
}

/// A tile prepared for its blocks: the shared transform and the head's sections.
struct UnitPlan {
    prepared: crate::quantize::Prepared,
    header: Header,
    mask: Vec<u8>,
    residual: Vec<u8>,
}

/// One tile coded: its head stream, what the file header needs of it, and its blocks.
struct EncodedUnit {
    head: Vec<u8>,
    summary: TileSummary,
    blocks: Vec<CodedBlock>,
}

impl EncodedUnit {
    fn encode(
        part: &Raster,
        options: &EncodeOptions,
        side: usize,
        workers: &Workers,
    ) -> Result<EncodedUnit, CodecError> {
        let levels = unit_levels(part.width, part.height, side, options.levels);
        let plan = plan_stream(part, options, levels)?;
        let mut plan = UnitPlan {
            header: plan.header,
            prepared: plan.prepared,
            mask: plan.mask,
            residual: plan.residual,
        };
        let grid = BlockGrid::new(part.width, part.height, side, levels).expect("aligned levels");
        let blocks: Vec<Block> = grid.blocks().collect();
        let coded = workers.map(0..blocks.len(), |b| {
            CodedBlock::encode(&grid, blocks[b], &plan)
        });
        let sections: [&[u8]; 3] = [&plan.mask, &[], &plan.residual];
        let (head, _) = assemble_as(Layout::Tile, &mut plan.header, sections);
        let any_valid = (0..part.len()).any(|i| part.is_valid(i));
        let summary = TileSummary {
            entry: TileEntry {
                len: head.len() as u64,
                head_len: head.len() as u64,
                initial_error: 0.0,
                passes: Vec::new(),
            },
            mode: plan.header.mode,
            max_error: plan.header.max_error,
            valid_range: any_valid.then_some(plan.header.valid_range),
            wavelet: plan.header.wavelet,
            levels: plan.header.levels,
        };
        Ok(EncodedUnit {
            head,
            summary,
            blocks: coded,
        })
    }

    /// Its entries in index order: the head, then the blocks.
    fn entries(&self) -> impl Iterator<Item = TileEntry> + '_ {
        let head = std::iter::once(self.summary.entry.clone());
        head.chain(self.blocks.iter().map(CodedBlock::entry))
    }
}

/// Encodes `raster` as a tiled file on `grid` whose tiles are cut into code blocks of
/// `side` (see [`crate::encode`]). Blocks are coded whole, on `options.threads`
/// threads, then cut to a byte budget where [`allocate_points`](super::allocate_points)
/// says.
pub(crate) fn encode(
    raster: &Raster,
    options: &EncodeOptions,
    grid: &TileGrid,
    side: usize,
) -> Result<Encoded, CodecError> {
    let workers = Workers::new(options.threads)?;
    let mut units = Vec::with_capacity(grid.count());
    let mut done = 0;
    for k in 0..grid.count() {
        let w = grid.tile(k);
        let part = raster.crop(w.x, w.y, w.width, w.height);
        units.push(EncodedUnit::encode(&part, options, side, &workers)?);
        done += part.len() as u64;
        crate::progress::report(crate::progress::Stage::Tiles, done, raster.len() as u64);
    }
    let info = RasterInfo::of(raster);
    if let Some(budget) = options.budget_bytes {
        cut_to_budget(&mut units, &info, (grid, side), budget)?;
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

/// The file: header, index, then tile by tile its head and its blocks.
fn assemble(units: &[EncodedUnit], info: &RasterInfo, (grid, side): (&TileGrid, usize)) -> Vec<u8> {
    let summaries: Vec<TileSummary> = units.iter().map(|u| u.summary.clone()).collect();
    let entries: Vec<TileEntry> = units.iter().flat_map(EncodedUnit::entries).collect();
    let mut bytes = file_head(info, (grid, Some(side as u32)), &summaries, &entries);
    for unit in units {
        bytes.extend_from_slice(&unit.head);
        for block in &unit.blocks {
            bytes.extend(block.bytes());
        }
    }
    bytes
}

/// Cuts the blocks so the file fits `budget` bytes: the heads, header and index first,
/// then every block's rate–distortion points shared out; the index shrinks with the cut,
/// so it is first counted without passes and any excess taken off the blocks' share.
fn cut_to_budget(
    units: &mut [EncodedUnit],
    info: &RasterInfo,
    (grid, side): (&TileGrid, usize),
    budget: u64,
) -> Result<(), CodecError> {
    let lossless = units.iter().all(|u| u.summary.mode == Mode::Lossless);
    let points: Vec<Vec<(u64, f64)>> = units
        .iter()
        .flat_map(|u| {
            let head = vec![(u.summary.entry.len, 0.0)];
            std::iter::once(head).chain(u.blocks.iter().map(|b| b.points(lossless)))
        })
        .collect();
    let summaries: Vec<TileSummary> = units.iter().map(|u| u.summary.clone()).collect();
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
    let too_small = || {
        CodecError::InvalidParameters(format!(
            "a budget of {budget} bytes is smaller than the headers, index and nodata masks ({least} bytes)"
        ))
    };
    for _ in 0..8 {
        let lengths = budget
            .checked_sub(reserve)
            .and_then(|left| super::allocate_points(&points, left))
            .ok_or_else(too_small)?;
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
    Err(too_small())
}

/// Samples beyond a window whose blocks a decode of it reads: the reach of the
/// coefficients outside them into the window through `levels` levels of `wavelet`'s
/// synthesis (a 9/7 coefficient of level `l` reaches about `4 · 2^l` samples, a 5/3 one
/// `2 · 2^l`), so the window decodes to the same samples as the whole tile.
fn reach(wavelet: Wavelet, levels: u32) -> usize {
    match wavelet {
        Wavelet::Cdf97 => 4 << levels,
        Wavelet::Int53 => 2 << levels,
    }
}

/// Decodes `windows` of a file with code blocks from `source`, reading for each tile a
/// window touches its head and the blocks within [`reach`] of the window, each
/// `lengths[e]` bytes long (entry `e`), and hands each window to `deliver` (`false`
/// stops).
pub(super) fn decode_windows(
    source: &mut impl ByteSource,
    layout: &TiledLayout,
    (windows, lengths): (&[Window], &[u64]),
    options: &DecodeOptions,
    before_output: &mut dyn FnMut(),
    deliver: &mut dyn FnMut(Window, Decoded) -> bool,
) -> Result<(), CodecError> {
    let workers = Workers::new(options.threads)?;
    for window in windows {
        before_output();
        let mut output = super::decode::Output::new(&layout.header, *window);
        for k in 0..layout.grid.count() {
            let Some(part) = layout.grid.tile(k).intersection(window) else {
                continue;
            };
            let (result, whole) =
                decode_unit(source, layout, (k, part), lengths, options, &workers)?;
            output.place(k, layout, whole, result, options.strict)?;
        }
        if !deliver(*window, output.finish(layout)) {
            break;
        }
    }
    Ok(())
}

/// Reads and decodes tile `k` for `part` of it (raster coordinates): its decode (an
/// error only when its head is missing or unreadable) and whether every byte read was
/// all of its entry. An error when `source` fails.
fn decode_unit(
    source: &mut impl ByteSource,
    layout: &TiledLayout,
    (k, part): (usize, Window),
    lengths: &[u64],
    options: &DecodeOptions,
    workers: &Workers,
) -> Result<(Result<Decoded, CodecError>, bool), CodecError> {
    let first = layout.tile_entries[k];
    let read = |source: &mut _, e: usize| read_entry(source, layout, e, lengths[e]);
    let head = read(source, first)?;
    let mut whole = head.len() as u64 == layout.entries[first].len;
    let unit = match UnitHead::parse(&head, layout, k, options) {
        Ok(unit) => unit,
        Err(e) => return Ok((Err(e), false)),
    };
    let tile = layout.grid.tile(k);
    let margin = reach(unit.header.wavelet, unit.header.levels.into());
    let needed = Window {
        x: part.x.saturating_sub(margin + tile.x),
        y: part.y.saturating_sub(margin + tile.y),
        width: part.width + 2 * margin,
        height: part.height + 2 * margin,
    };
    let mut pieces = Vec::new();
    for (b, block) in unit.grid.blocks().enumerate() {
        let area = Window {
            x: block.x,
            y: block.y,
            width: block.width,
            height: block.height,
        };
        if area.intersection(&needed).is_some() {
            let e = first + 1 + b;
            let bytes = read(source, e)?;
            whole &= bytes.len() as u64 == layout.entries[e].len;
            let at = layout.offsets[e] - layout.offsets[first];
            pieces.push(Piece {
                block,
                at,
                len: layout.entries[e].len,
                bytes,
            });
        }
    }
    let fetched = head.len() as u64 + pieces.iter().map(|p| p.bytes.len() as u64).sum::<u64>();
    Ok((
        unit.decode(&head, &pieces, (fetched, options), workers),
        whole,
    ))
}

/// Up to `len` bytes of entry `e`.
fn read_entry(
    source: &mut impl ByteSource,
    layout: &TiledLayout,
    e: usize,
    len: u64,
) -> Result<Vec<u8>, CodecError> {
    source
        .read_at(layout.offsets[e], len as usize)
        .map_err(|error| CodecError::Read(error.to_string()))
}

/// A block's stream as read: its place in the tile, its offset from the tile's head,
/// its length in the file and the bytes read (a prefix, perhaps).
struct Piece {
    block: Block,
    at: u64,
    len: u64,
    bytes: Vec<u8>,
}

/// A tile's head, parsed: its header and its blocks.
struct UnitHead {
    header: Header,
    header_len: usize,
    grid: BlockGrid,
}

impl UnitHead {
    /// Parses tile `k`'s head, refusing one that does not describe the tile, its blocks
    /// or a stream the limits allow.
    fn parse(
        head: &[u8],
        layout: &TiledLayout,
        k: usize,
        options: &DecodeOptions,
    ) -> Result<UnitHead, CodecError> {
        let (header, header_len) = Header::parse_tile(head)?;
        let tile = layout.grid.tile(k);
        let side = layout.code_block().expect("a file with code blocks");
        let (width, height) = (header.width as usize, header.height as usize);
        let grid = BlockGrid::new(width, height, side, header.levels.into())
            .filter(|_| (width, height) == (tile.width, tile.height) && header.payload_len == 0)
            .filter(|_| header.sample_type == layout.header.sample_type)
            .ok_or_else(|| {
                CodecError::InvalidHeader(format!(
                    "tile {k}'s head does not describe its {}x{} samples in blocks of {side}",
                    tile.width, tile.height
                ))
            })?;
        check_limits(&header, &options.limits)?;
        Ok(UnitHead {
            header,
            header_len,
            grid,
        })
    }

    /// Decodes the tile from its `head` and the blocks of `pieces`, the others left
    /// zero; `fetched` bytes were read.
    fn decode(
        &self,
        head: &[u8],
        pieces: &[Piece],
        (fetched, options): (u64, &DecodeOptions),
        workers: &Workers,
    ) -> Result<Decoded, CodecError> {
        let header = &self.header;
        let sections = StreamSections::read(head, header, self.header_len, None)?;
        let decodes = workers.map(0..pieces.len(), |p| {
            let piece = &pieces[p];
            let stream = (&piece.bytes[..], piece.len);
            decode_block(header, (&self.grid, piece.block), stream, options)
        });
        let samples = self.grid.width * self.grid.height;
        let mut coefficients = Coefficients::zeros(header.wavelet, samples);
        let (mut passes, mut whole, mut finished, mut damage) = (None::<u32>, true, true, None);
        for (decode, piece) in decodes.into_iter().zip(pieces) {
            let decode = decode?;
            passes = match (passes, decode.passes) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            whole &= decode.whole;
            finished &= decode.finished;
            if let (None, Some(at)) = (damage, decode.damaged_at) {
                damage = Some(Damage {
                    section: "code block",
                    offset: piece.at + at,
                    tile: None,
                });
            }
            match (&mut coefficients, decode.coefficients) {
                (Coefficients::Integer(all), Coefficients::Integer(own)) => {
                    self.grid.scatter(&own, all, piece.block)
                }
                (Coefficients::Real(all), Coefficients::Real(own)) => {
                    self.grid.scatter(&own, all, piece.block)
                }
                _ => unreachable!("one wavelet"),
            }
        }
        let damage = damage.or(sections.damage);
        if let (true, Some(d)) = (options.strict, damage) {
            return Err(CodecError::Damaged {
                section: d.section,
                offset: d.offset,
            });
        }
        let mask = sections.mask.as_ref().map(|m| m.as_bitslice());
        let mut samples = reconstruct(header, coefficients, mask);
        let residuals = apply_residual_section(header, &sections, &mut samples, mask, finished);
        let mut raster = Raster::new(self.grid.width, self.grid.height, samples)?;
        raster.nodata = header.nodata;
        Ok(Decoded {
            raster,
            header: header.clone(),
            passes_decoded: passes.unwrap_or(0),
            complete: whole && residuals,
            damage,
            bytes_used: fetched,
            significance: None,
        })
    }
}

/// What one block's stream decoded to.
struct BlockDecode {
    coefficients: Coefficients,
    /// Passes decoded (`None`: the block has none, every coefficient being zero).
    passes: Option<u32>,
    /// Whether every byte of its stream was read and its checksums hold.
    whole: bool,
    /// Whether its decode ran through plane 0 of a stream the encoder did not cut.
    finished: bool,
    /// Offset in its stream of its first damaged chunk.
    damaged_at: Option<u64>,
}

/// Decodes `block`'s stream of `len` bytes from `bytes`, a prefix of it perhaps.
fn decode_block(
    header: &Header,
    (grid, block): (&BlockGrid, Block),
    (bytes, len): (&[u8], u64),
    options: &DecodeOptions,
) -> Result<BlockDecode, CodecError> {
    let framed_total = len.saturating_sub(BLOCK_HEAD);
    let shifts: Vec<u32> = header.bands.iter().map(|&(s, _)| s.into()).collect();
    let layout = CoefficientLayout::new(block.width, block.height, &grid.subbands(block), &shifts);
    let Some((&head, framed)) = bytes.split_first() else {
        return Ok(BlockDecode {
            coefficients: Coefficients::zeros(header.wavelet, layout.len()),
            passes: Some(0),
            whole: false,
            finished: false,
            damaged_at: None,
        });
    };
    let (cut, top) = (head & 0x80 != 0, u32::from(head & 0x7f));
    if top > MAX_PLANE + 1 {
        return Err(CodecError::InvalidHeader(format!(
            "a code block's top plane {}",
            top - 1
        )));
    }
    let check = check_frames(framed, framed_total as usize);
    let source =
        ArithmeticDecoder::new_framed(framed, check.data_len, CHUNK, 4, check.complete && !cut);
    let decoder = Decoder::run_from(
        &layout,
        header.coder,
        source,
        top.checked_sub(1),
        options.max_passes,
    );
    let passes = top.checked_sub(1).map(|_| decoder.passes_completed);
    let finished = decoder.complete && !cut;
    Ok(BlockDecode {
        coefficients: Coefficients::of(decoder, header.wavelet),
        passes,
        whole: check.complete,
        finished: finished && check.complete,
        damaged_at: check.damaged_at.map(|at| BLOCK_HEAD + at as u64),
    })
}
