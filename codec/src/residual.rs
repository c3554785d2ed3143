//! Exact residuals for lossless float coding.
//!
//! Each residual (the difference between the `f32` bit patterns of a sample and of its
//! grid reconstruction, usually a few units) is zigzag-mapped to an unsigned number and
//! coded as its bit length (unary, one adaptive model per position) followed by the bits
//! below the leading one (modelled for the top two, raw below). Coder 4 chooses the
//! length models by the bit length of the residual before: residuals come in runs of
//! similar size (a float's spacing grows with its magnitude, and neighbouring samples have
//! similar magnitudes), which takes 11 % off `srtm3_utm32_f32`'s residual section.
//! Float residuals under header flag 16 choose them by the exponent of the sample's own
//! reconstruction instead, which the decoder knows before the residual: the grid step
//! measured in the sample's float spacing sets the residual's size, and a sample's
//! exponent says it better than the residual before (`srtm3_utm32_f32`'s residual section
//! 194468 → 175672 bytes in one stream, and 29701 → 25841 with 79 % of it NaN).

use crate::entropy::{ArithmeticDecoder, ArithmeticEncoder, BitModel, BitSink};
use crate::ezw::Coder;

/// Bit lengths a residual can have: 0 ..= 32.
const LENGTHS: usize = 33;

/// Biased exponents an `f32` can have.
const EXPONENTS: usize = 256;

/// What chooses the length models of each residual.
#[derive(Debug, Clone, Copy)]
pub(crate) enum LengthContext<'a> {
    /// The stream's coder: one set (coders 1–3), or one per length of the residual
    /// before (coder 4).
    Coder(Coder),
    /// One set per biased exponent of the residual's reconstructed sample (flag 16),
    /// one exponent per residual (see [`exponents`]).
    Exponents(&'a [u8]),
}

struct Models<'a> {
    /// Unary length models: one set, or one per context value.
    length: Vec<[BitModel; LENGTHS]>,
    high: [[BitModel; 4]; LENGTHS],
    context: LengthContext<'a>,
    /// Bit length of the residual coded last.
    previous: usize,
}

impl<'a> Models<'a> {
    fn new(context: LengthContext<'a>) -> Models<'a> {
        let sets = match context {
            LengthContext::Coder(coder) if coder.models_residuals() => LENGTHS,
            LengthContext::Coder(_) => 1,
            LengthContext::Exponents(_) => EXPONENTS,
        };
        Models {
            length: vec![[BitModel::new(); LENGTHS]; sets],
            high: [[BitModel::new(); 4]; LENGTHS],
            context,
            previous: 0,
        }
    }

    /// The length models for residual `index`.
    fn lengths(&mut self, index: usize) -> &mut [BitModel; LENGTHS] {
        let set = match self.context {
            LengthContext::Exponents(exponents) => exponents[index] as usize,
            _ if self.length.len() > 1 => self.previous,
            _ => 0,
        };
        &mut self.length[set]
    }
}

/// The biased exponents of reconstructed samples given by their `f32` bit patterns.
pub(crate) fn exponents(reconstructed: impl Iterator<Item = u32>) -> Vec<u8> {
    reconstructed.map(|bits| (bits >> 23) as u8).collect()
}

#[inline]
fn zigzag(r: i32) -> u32 {
    ((r << 1) ^ (r >> 31)) as u32
}

#[inline]
fn unzigzag(z: u32) -> i32 {
    ((z >> 1) as i32) ^ -((z & 1) as i32)
}

/// Encodes residuals with the length models `context` chooses.
pub(crate) fn encode_residuals(residuals: &[i32], context: LengthContext) -> Vec<u8> {
    let mut encoder = ArithmeticEncoder::new();
    let mut models = Models::new(context);
    for (index, &r) in residuals.iter().enumerate() {
        let z = zigzag(r);
        let bits = 32 - z.leading_zeros() as usize; // 0 for z = 0
        let lengths = models.lengths(index);
        for model in &mut lengths[..bits] {
            encoder.encode(true, model);
        }
        if bits < 32 {
            encoder.encode(false, &mut lengths[bits]);
        }
        models.previous = bits;
        for (position, k) in (0..bits.saturating_sub(1)).rev().enumerate() {
            let bit = (z >> k) & 1 != 0;
            if position < 2 {
                let ctx = if position == 0 {
                    0
                } else {
                    1 + ((z >> (k + 1)) & 1) as usize
                };
                encoder.encode(bit, &mut models.high[bits][ctx]);
            } else {
                encoder.encode_raw(bit);
            }
        }
    }
    encoder.finish()
}

/// Decodes `count` residuals written by [`encode_residuals`] with the same `context`
/// (its exponents, if any, one per residual).
pub(crate) fn decode_residuals(bytes: &[u8], count: usize, context: LengthContext) -> Vec<i32> {
    let mut decoder = ArithmeticDecoder::new(bytes, true);
    let mut models = Models::new(context);
    let mut out = Vec::with_capacity(count.min(bytes.len().saturating_mul(8) + 1024));
    for index in 0..count {
        let mut bits = 0;
        let lengths = models.lengths(index);
        while bits < 32 && decoder.decode(&mut lengths[bits]) {
            bits += 1;
        }
        models.previous = bits;
        let mut z: u32 = if bits > 0 { 1 } else { 0 };
        for position in 0..bits.saturating_sub(1) {
            let bit = if position < 2 {
                let ctx = if position == 0 {
                    0
                } else {
                    1 + (z & 1) as usize
                };
                decoder.decode(&mut models.high[bits][ctx])
            } else {
                decoder.decode_raw()
            };
            z = (z << 1) | bit as u32;
        }
        out.push(unzigzag(z));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn residuals_round_trip_including_extremes() {
        let values: Vec<i32> = (-2000..2000)
            .map(|i| (i * 7919) % 23 - 11)
            .chain([i32::MIN, i32::MAX, 0, -1, 1, 1 << 20])
            .collect();
        let exponents: Vec<u8> = (0..values.len()).map(|i| (i % 7 * 40) as u8).collect();
        for context in [
            LengthContext::Coder(Coder::V3),
            LengthContext::Coder(Coder::V4),
            LengthContext::Exponents(&exponents),
        ] {
            let bytes = encode_residuals(&values, context);
            assert_eq!(decode_residuals(&bytes, values.len(), context), values);
        }
    }

    #[test]
    fn coder_4_codes_runs_of_sizes_in_fewer_bytes() {
        // Runs of small and of large residuals, as floats of small and large magnitude give.
        let values: Vec<i32> = (0..20_000)
            .map(|i| {
                let wobble = (i * 7919 % 13) - 6;
                if (i / 500) % 2 == 0 {
                    wobble
                } else {
                    wobble * 997
                }
            })
            .collect();
        let old = encode_residuals(&values, LengthContext::Coder(Coder::V3)).len();
        let new = encode_residuals(&values, LengthContext::Coder(Coder::V4)).len();
        assert!(new * 10 < old * 9, "coder 4 {new} bytes, coder 3 {old}");
    }

    #[test]
    fn exponents_code_samples_of_mixed_magnitudes_in_fewer_bytes() {
        // Samples of two magnitudes in no order: the residual before says nothing of the
        // next one's size, the sample's exponent says it all.
        let hash = |i: u32| {
            let h = i.wrapping_mul(0x9E37_79B1);
            let h = (h ^ h >> 15).wrapping_mul(0x85EB_CA77);
            h ^ h >> 13
        };
        let samples: Vec<f32> = (0..20_000)
            .map(|i| if hash(i) & 1 == 0 { 1000.5 } else { 0.03 })
            .collect();
        let values: Vec<i32> = (0..20_000)
            .map(|i| {
                let wobble = (hash(i) >> 8) as i32 % 5 - 2;
                if samples[i as usize] > 1.0 {
                    wobble
                } else {
                    wobble * 997
                }
            })
            .collect();
        let exponents = exponents(samples.iter().map(|v| v.to_bits()));
        let old = encode_residuals(&values, LengthContext::Coder(Coder::V4)).len();
        let new = encode_residuals(&values, LengthContext::Exponents(&exponents)).len();
        assert!(
            new * 10 < old * 9,
            "by exponent {new} bytes, by the one before {old}"
        );
    }

    #[test]
    fn zigzag_is_a_bijection_at_the_edges() {
        for r in [0, 1, -1, i32::MAX, i32::MIN, 12345, -12345] {
            assert_eq!(unzigzag(zigzag(r)), r);
        }
    }
}
