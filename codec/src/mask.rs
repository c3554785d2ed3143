//! Lossless coding of the nodata mask.
//!
//! One binary decision per sample, raster order, coded with an adaptive model chosen by
//! the four causal neighbours (west, north-west, north, north-east): 16 contexts, as in
//! JBIG's template coding. A mask without voids is never stored; large void blobs cost a
//! few bits per boundary sample.

use bitvec::prelude::{BitSlice, BitVec, Lsb0};

use crate::container::{unframe, Header};
use crate::entropy::{ArithmeticDecoder, ArithmeticEncoder, BitModel, BitSink};
use crate::error::CodecError;
use crate::pipeline::Limits;

/// A validity mask, one bit per sample (`true` = valid), as the decoder keeps it.
pub type Mask = BitVec<u64, Lsb0>;

/// Read access to a mask, whether stored as bools (encoder) or bits (decoder).
trait MaskBits {
    fn bit(&self, i: usize) -> bool;
}

impl MaskBits for [bool] {
    #[inline]
    fn bit(&self, i: usize) -> bool {
        self[i]
    }
}

impl MaskBits for BitSlice<u64, Lsb0> {
    #[inline]
    fn bit(&self, i: usize) -> bool {
        self[i]
    }
}

#[inline]
fn context<M: MaskBits + ?Sized>(mask: &M, i: usize, x: usize, y: usize, width: usize) -> usize {
    let at = |j: usize| mask.bit(j) as usize;
    let west = if x > 0 { at(i - 1) } else { 1 };
    let (north_west, north, north_east) = if y > 0 {
        let up = i - width;
        (
            if x > 0 { at(up - 1) } else { 1 },
            at(up),
            if x + 1 < width { at(up + 1) } else { 1 },
        )
    } else {
        (1, 1, 1)
    };
    west | north_west << 1 | north << 2 | north_east << 3
}

/// Encodes a validity mask (`true` = valid sample).
pub fn encode_mask(mask: &[bool], width: usize) -> Vec<u8> {
    let mut encoder = ArithmeticEncoder::new();
    let mut models = [BitModel::new(); 16];
    for (i, &valid) in mask.iter().enumerate() {
        let ctx = context(mask, i, i % width, i / width, width);
        encoder.encode(valid, &mut models[ctx]);
    }
    encoder.finish()
}

/// Valid samples of a single-stream file, `data` read from its start: all of them
/// without a nodata mask, else those its mask marks valid (a damaged or missing mask
/// decodes as far as it goes). The mask decodes to one bit a sample: a header claiming
/// more samples than `limits` allow is refused first.
pub fn valid_sample_count(
    data: &[u8],
    header: &Header,
    header_len: usize,
    limits: &Limits,
) -> Result<u64, CodecError> {
    let samples = header.sample_count();
    if header.mask_len == 0 {
        return Ok(samples);
    }
    let memory = samples / 8;
    for (what, needed, limit) in [
        ("sample count", samples, limits.max_samples),
        ("nodata mask memory", memory, limits.max_memory),
    ] {
        if needed > limit {
            return Err(CodecError::LimitExceeded {
                what,
                needed,
                limit,
            });
        }
    }
    let framed = data.get(header_len..).unwrap_or(&[]);
    let mask = unframe(framed, header.mask_len as usize);
    let mask = decode_mask(&mask.bytes, header.width as usize, samples as usize);
    Ok(mask.count_ones() as u64)
}

/// Decodes a mask of `count` samples written by [`encode_mask`].
pub fn decode_mask(bytes: &[u8], width: usize, count: usize) -> Mask {
    let mut decoder = ArithmeticDecoder::new(bytes, true);
    let mut models = [BitModel::new(); 16];
    let mut mask = Mask::repeat(false, count);
    for i in 0..count {
        let ctx = context(mask.as_bitslice(), i, i % width, i / width, width);
        let valid = decoder.decode(&mut models[ctx]);
        mask.set(i, valid);
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blobs_round_trip_compactly() {
        let (w, h) = (200, 150);
        let mask: Vec<bool> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (x - 60.0).hypot(y - 40.0) > 15.0 && (x - 150.0).hypot(y - 100.0) > 25.0
            })
            .collect();
        let bytes = encode_mask(&mask, w);
        assert!(decode_mask(&bytes, w, w * h)
            .iter()
            .by_vals()
            .eq(mask.iter().copied()));
        assert!(bytes.len() < 200, "{} bytes for two discs", bytes.len());
    }

    #[test]
    fn single_column_and_all_invalid() {
        let mask = vec![false, true, true, false, false];
        let back = decode_mask(&encode_mask(&mask, 1), 1, 5);
        assert!(back.iter().by_vals().eq(mask.iter().copied()));
        let none = vec![false; 77];
        assert!(decode_mask(&encode_mask(&none, 7), 7, 77).not_any());
    }
}
