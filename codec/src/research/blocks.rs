//! Code blocks under one transform, measured before the format has them: the raster is
//! transformed once, each block's pyramid ([`BlockGrid`]) coded as an embedded stream of
//! its own, a budget shared out over the blocks' rate–distortion points as a tiled
//! file's is over its tiles', and the kept prefixes decoded back into one inverse
//! transform (issue 9's tile seams).

use bitvec::prelude::{BitVec, Lsb0};

use crate::entropy::ArithmeticDecoder;
use crate::error::CodecError;
use crate::ezw::{self, Coder, CoefficientLayout, Decoder, EncodedPayload};
use crate::pipeline::{Quality, SHIFT_RULE};
use crate::quantize::{prepare_53, prepare_97, rescale_97, to_samples, Prepared, VoidCoefficients};
use crate::raster::Raster;
use crate::tiles::{allocate_points, write_index, Block, BlockGrid, TileEntry};
use crate::wavelet::{self, Wavelet};

/// What [`code_blocks`] made.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct CodeBlocks {
    /// The decoded raster (the original's sample type and nodata value).
    pub raster: Raster,
    /// Bytes each block kept, its head included.
    pub block_bytes: Vec<u64>,
    /// Bytes of a compact tile index listing the blocks with their passes.
    pub index_bytes: usize,
}

/// `raster` coded with `wavelet` in `block`-sample code blocks under one `levels`-level
/// transform, each block charged `head` bytes besides its payload, every block complete
/// (`budget` `None`: lossless 5/3 gives the samples exactly) or the blocks cut to
/// `budget` bytes in all.
pub fn code_blocks(
    raster: &Raster,
    wavelet: Wavelet,
    (block, levels): (usize, u32),
    budget: Option<u64>,
    head: u64,
) -> Result<CodeBlocks, CodecError> {
    let (width, height) = (raster.width, raster.height);
    let grid = BlockGrid::new(width, height, block, levels).ok_or_else(|| {
        CodecError::InvalidParameters(format!(
            "blocks of {block} are not aligned to {levels} levels"
        ))
    })?;
    let mask = raster.valid_mask();
    let norms = wavelet::coding_norms(wavelet, width, height, levels);
    let prepared = match wavelet {
        Wavelet::Int53 => prepare_53(
            raster,
            &mask,
            Quality::Lossless,
            &norms,
            (VoidCoefficients::Zeroed, SHIFT_RULE),
        )?,
        Wavelet::Cdf97 => prepare_97(raster, &mask, &norms, VoidCoefficients::Zeroed),
    };
    let blocks: Vec<Block> = grid.blocks().collect();
    let streams: Vec<BlockStream> = blocks
        .iter()
        .map(|&b| BlockStream::encode(&grid, &prepared, b))
        .collect();
    let points: Vec<Vec<(u64, f64)>> = streams.iter().map(|s| s.points(head)).collect();
    let block_bytes = match budget {
        Some(total) => allocate_points(&points, total).ok_or_else(|| {
            CodecError::InvalidParameters("a budget below the blocks' heads".into())
        })?,
        None => points
            .iter()
            .map(|p| p.last().expect("the head").0)
            .collect(),
    };
    let entries: Vec<TileEntry> = streams
        .iter()
        .zip(&block_bytes)
        .map(|(s, &len)| s.entry(head, len))
        .collect();
    let index_bytes = write_index(&entries, true).len();
    let cut = (block_bytes.as_slice(), head);
    let decoded = reconstruct(raster, (&grid, &prepared), &blocks, &streams, cut)?;
    Ok(CodeBlocks {
        raster: decoded,
        block_bytes,
        index_bytes,
    })
}

/// One block's layout, first plane and complete stream.
struct BlockStream {
    layout: CoefficientLayout,
    top: Option<u32>,
    payload: EncodedPayload,
}

impl BlockStream {
    fn encode(grid: &BlockGrid, prepared: &Prepared, block: Block) -> BlockStream {
        let coefficients = grid.gather(&prepared.coefficients, block);
        let subbands = grid.subbands(block);
        let layout = CoefficientLayout::new(block.width, block.height, &subbands, &prepared.shifts);
        let top = ezw::top_plane(&layout, &coefficients);
        let payload = ezw::encode(
            &layout,
            &coefficients,
            top,
            &prepared.distortion_weights,
            prepared.midpoint,
            None,
        );
        BlockStream {
            layout,
            top,
            payload,
        }
    }

    /// Rate–distortion points: the head, then checkpoints and pass ends in stream order.
    fn points(&self, head: u64) -> Vec<(u64, f64)> {
        let mut marks = self.payload.checkpoints.clone();
        marks.extend(self.passes());
        marks.sort_by_key(|m| m.0);
        let mut points = vec![(head, self.payload.initial_error)];
        points.extend(marks.into_iter().map(|(end, e)| (end + head, e)));
        points
    }

    fn passes(&self) -> impl Iterator<Item = (u64, f64)> + '_ {
        self.payload
            .passes
            .iter()
            .map(|r| (r.end_byte, r.squared_error))
    }

    /// The index entry of the block cut to `len` bytes.
    fn entry(&self, head: u64, len: u64) -> TileEntry {
        TileEntry {
            len,
            head_len: head,
            initial_error: self.payload.initial_error,
            passes: self
                .passes()
                .map(|(end, e)| (end + head, e))
                .filter(|&(end, _)| end <= len)
                .collect(),
        }
    }

    fn decoder(&self, len: u64, head: u64) -> Decoder {
        let bytes = &self.payload.bytes;
        let n = (len.saturating_sub(head) as usize).min(bytes.len());
        let source = ArithmeticDecoder::new(&bytes[..n], n == bytes.len());
        Decoder::run_from(&self.layout, Coder::default(), source, self.top, None)
    }
}

/// The samples the blocks' kept prefixes decode to through one inverse transform, as
/// `raster`'s type (voids hold its nodata value).
fn reconstruct(
    raster: &Raster,
    (grid, prepared): (&BlockGrid, &Prepared),
    blocks: &[Block],
    streams: &[BlockStream],
    (block_bytes, head): (&[u64], u64),
) -> Result<Raster, CodecError> {
    let (width, height, levels) = (grid.width, grid.height, grid.levels);
    let parts = blocks.iter().zip(streams).zip(block_bytes);
    let values: Vec<f64> = if prepared.midpoint == ezw::Midpoint::Integer {
        let mut all = vec![0i32; width * height];
        for ((&b, s), &len) in parts {
            grid.scatter(&s.decoder(len, head).integer_coefficients(), &mut all, b);
        }
        wavelet::inverse_53(&mut all, width, height, levels);
        all.into_iter().map(f64::from).collect()
    } else {
        let mut all = vec![0f32; width * height];
        for ((&b, s), &len) in parts {
            grid.scatter(&s.decoder(len, head).into_real_coefficients(), &mut all, b);
        }
        let bands: Vec<(u8, f64)> = prepared.scales.iter().map(|&s| (0, s)).collect();
        let subbands = wavelet::subbands(width, height, levels);
        rescale_97(
            &mut all,
            width,
            &subbands,
            &bands,
            prepared.coefficient_step,
        );
        wavelet::inverse_97(&mut all, width, height, levels);
        all.into_iter().map(f64::from).collect()
    };
    let mask: BitVec<u64, Lsb0> = raster.valid_mask().into_iter().collect();
    let value_of = |v: f64| prepared.mapping.value(v);
    let samples = to_samples(
        raster.sample_type(),
        values,
        value_of,
        Some(&mask),
        raster.nodata,
    );
    let mut decoded = Raster::new(width, height, samples)?;
    decoded.nodata = raster.nodata;
    Ok(decoded)
}
