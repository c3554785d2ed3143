//! Exact residuals for lossless float coding.
//!
//! Each residual (the difference between the `f32` bit patterns of a sample and of its
//! grid reconstruction, usually a few units) is zigzag-mapped to an unsigned number and
//! coded as its bit length (unary, one adaptive model per position) followed by the bits
//! below the leading one (modelled for the top two, raw below).

use crate::entropy::{ArithmeticDecoder, ArithmeticEncoder, BitModel, BitSink};

struct Models {
    length: [BitModel; 33],
    high: [[BitModel; 4]; 33],
}

impl Models {
    fn new() -> Models {
        Models {
            length: [BitModel::new(); 33],
            high: [[BitModel::new(); 4]; 33],
        }
    }
}

#[inline]
fn zigzag(r: i32) -> u32 {
    ((r << 1) ^ (r >> 31)) as u32
}

#[inline]
fn unzigzag(z: u32) -> i32 {
    ((z >> 1) as i32) ^ -((z & 1) as i32)
}

/// Encodes residuals.
pub fn encode_residuals(residuals: &[i32]) -> Vec<u8> {
    let mut encoder = ArithmeticEncoder::new();
    let mut models = Models::new();
    for &r in residuals {
        let z = zigzag(r);
        let bits = 32 - z.leading_zeros() as usize; // 0 for z = 0
        for k in 0..bits {
            encoder.encode(true, &mut models.length[k]);
        }
        if bits < 32 {
            encoder.encode(false, &mut models.length[bits]);
        }
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

/// Decodes `count` residuals written by [`encode_residuals`].
pub fn decode_residuals(bytes: &[u8], count: usize) -> Vec<i32> {
    let mut decoder = ArithmeticDecoder::new(bytes, true);
    let mut models = Models::new();
    let mut out = Vec::with_capacity(count.min(bytes.len().saturating_mul(8) + 1024));
    for _ in 0..count {
        let mut bits = 0;
        while bits < 32 && decoder.decode(&mut models.length[bits]) {
            bits += 1;
        }
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
        let bytes = encode_residuals(&values);
        assert_eq!(decode_residuals(&bytes, values.len()), values);
    }

    #[test]
    fn zigzag_is_a_bijection_at_the_edges() {
        for r in [0, 1, -1, i32::MAX, i32::MIN, 12345, -12345] {
            assert_eq!(unzigzag(zigzag(r)), r);
        }
    }
}
