//! Decoding windows of a file with code blocks: per tile a window touches, its head and
//! the blocks within [`reach`] of the window, each decoded into the tile's pyramid (the
//! others zero), then one inverse transform.

use super::{reach, BLOCK_HEAD};
use crate::container::{check_frames, Header, StreamSections, CHUNK};
use crate::entropy::ArithmeticDecoder;
use crate::error::CodecError;
use crate::ezw::{CoefficientLayout, Decoder, MAX_PLANE};
use crate::pipeline::{
    apply_residual_section, check_limits, reconstruct, Coefficients, Damage, DecodeOptions, Decoded,
};
use crate::raster::Raster;
use crate::tiles::blocks::{Block, BlockGrid};
use crate::tiles::workers::Workers;
use crate::tiles::{ByteSource, TiledLayout, Window};
use crate::wavelet::max_levels;

/// Decodes `windows` of a file with code blocks from `source`, reading for each tile a
/// window touches its head and the blocks within [`reach`] of the window, each
/// `lengths[e]` bytes long (entry `e`), and hands each window to `deliver` (`false`
/// stops). As many tiles as there are threads are read, then decoded at once (each
/// one's blocks on the same threads).
pub(crate) fn decode_windows(
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
        let mut output = crate::tiles::decode::Output::new(&layout.header, *window);
        let touched: Vec<(usize, Window)> = (0..layout.grid.count())
            .filter_map(|k| Some((k, layout.grid.tile(k).intersection(window)?)))
            .collect();
        for run in touched.chunks(workers.count()) {
            let fetched = run
                .iter()
                .map(|&(k, part)| FetchedUnit::read(source, layout, (k, part), lengths, options))
                .collect::<Result<Vec<_>, CodecError>>()?;
            let decodes = workers.map(0..fetched.len(), |u| {
                let unit = fetched[u].as_ref().ok()?;
                Some(unit.decode(options, &workers))
            });
            for ((&(k, _), unit), decoded) in run.iter().zip(fetched).zip(decodes) {
                let (whole, result) = match unit {
                    Ok(unit) => (unit.whole, decoded.expect("a tile read is decoded")),
                    Err(head) => (false, Err(head)),
                };
                output.place(k, layout, whole, result, options.strict)?;
            }
        }
        if !deliver(*window, output.finish(layout)) {
            break;
        }
    }
    Ok(())
}

/// A tile's bytes as a window needs them: its head, parsed, and the blocks within
/// [`reach`] of the window.
struct FetchedUnit {
    head: Vec<u8>,
    unit: UnitHead,
    pieces: Vec<Piece>,
    /// Every entry read is all there is of it.
    whole: bool,
}

impl FetchedUnit {
    /// Reads tile `k`'s head and the blocks `part` of it (raster coordinates) needs: an
    /// error when `source` fails; else the tile, or why its head could not be parsed
    /// (the file ends inside it, or damage).
    fn read(
        source: &mut impl ByteSource,
        layout: &TiledLayout,
        (k, part): (usize, Window),
        lengths: &[u64],
        options: &DecodeOptions,
    ) -> Result<Result<FetchedUnit, CodecError>, CodecError> {
        let first = layout.tile_entries[k];
        let read = |source: &mut _, e: usize| read_entry(source, layout, e, lengths[e]);
        let head = read(source, first)?;
        let mut whole = head.len() as u64 == layout.entries[first].len;
        let unit = match UnitHead::parse(&head, layout, k, options) {
            Ok(unit) => unit,
            Err(e) => return Ok(Err(e)),
        };
        let needed = within_reach(part, layout.grid.coded(k), &unit.header);
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
                let len = layout.entries[e].len;
                pieces.push(Piece {
                    block,
                    at,
                    len,
                    bytes,
                });
            }
        }
        Ok(Ok(FetchedUnit {
            head,
            unit,
            pieces,
            whole,
        }))
    }

    /// The tile's decode from what was read.
    fn decode(&self, options: &DecodeOptions, workers: &Workers) -> Result<Decoded, CodecError> {
        let fetched = self.head.len() as u64;
        let fetched = fetched
            + self
                .pieces
                .iter()
                .map(|p| p.bytes.len() as u64)
                .sum::<u64>();
        self.unit
            .decode(&self.head, &self.pieces, (fetched, options), workers)
    }
}

/// The samples of a tile coding `coded` (raster coordinates) whose blocks a decode of
/// `part` of it reads, in the tile's coordinates: `part`, [`reach`] wider on every side.
fn within_reach(part: Window, coded: Window, header: &Header) -> Window {
    let margin = reach(header.wavelet, header.levels.into());
    let (x, y) = (part.x - coded.x, part.y - coded.y);
    let (left, top) = (x.saturating_sub(margin), y.saturating_sub(margin));
    Window {
        x: left,
        y: top,
        width: x + part.width + margin - left,
        height: y + part.height + margin - top,
    }
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
    /// Parses tile `k`'s head, refusing one that does not describe the tile, blocks that
    /// cannot have its levels, or a stream the limits allow.
    fn parse(
        head: &[u8],
        layout: &TiledLayout,
        k: usize,
        options: &DecodeOptions,
    ) -> Result<UnitHead, CodecError> {
        let (header, header_len) = Header::parse_tile(head)?;
        let tile = layout.grid.coded(k);
        let side = layout.code_block().expect("a file with code blocks");
        let (width, height) = (header.width as usize, header.height as usize);
        let levels = u32::from(header.levels);
        let grid = BlockGrid::new(width, height, side, levels)
            .filter(|_| (width, height) == (tile.width, tile.height) && header.payload_len == 0)
            .filter(|_| header.sample_type == layout.header.sample_type)
            .filter(|g| g.blocks().all(|b| levels <= max_levels(b.width, b.height)))
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
