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

/// Decodes `windows` of a file with code blocks from `source`, reading for each tile a
/// window touches its head and the blocks within [`reach`] of the window, each
/// `lengths[e]` bytes long (entry `e`), and hands each window to `deliver` (`false`
/// stops).
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
    let tile = layout.grid.coded(k);
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
        let tile = layout.grid.coded(k);
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
