//! What a float tile's lossless file needs beyond its gradients, counted on the rows a
//! [`super::TileDetail`] reads: the value step the lossless encoder will quantise on (a
//! grid every sample lies on, else a power of two from the value range) and the bits of
//! the exact residuals that step leaves.

use crate::quantize::{default_float_step, on_float_grid, FLOAT_GRIDS, MAX_INTEGER_MAGNITUDE};

/// Binary exponents from 2^-149 to 2^127: an f32's lowest set bit and ulp are in them.
const BINS: usize = 277;

/// Bin of 2^0.
const BIN_OF_ONE: i64 = 149;

/// The counted valid samples of a float tile.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct FloatDetail {
    /// Smallest and largest counted sample.
    range: Option<(f64, f64)>,
    /// Bit `g` set while every counted sample lies on `FLOAT_GRIDS[g]`.
    grids: u16,
    /// Nonzero samples by the binary exponent of their lowest set bit.
    by_lowest_bit: Box<[u64; BINS]>,
    /// The sum of those samples' ulp exponents, by the same bins.
    ulp_sums: Box<[i64; BINS]>,
}

impl Default for FloatDetail {
    fn default() -> Self {
        FloatDetail {
            range: None,
            grids: (1 << FLOAT_GRIDS.len()) - 1,
            by_lowest_bit: Box::new([0; BINS]),
            ulp_sums: Box::new([0; BINS]),
        }
    }
}

impl FloatDetail {
    /// Counts one valid sample.
    pub(crate) fn add(&mut self, value: f32) {
        let v = f64::from(value);
        self.range = Some(match self.range {
            None => (v, v),
            Some((lo, hi)) => (lo.min(v), hi.max(v)),
        });
        let mut grids = self.grids;
        while grids != 0 {
            let g = grids.trailing_zeros() as usize;
            grids &= grids - 1;
            if !on_float_grid(value, FLOAT_GRIDS[g]) {
                self.grids &= !(1 << g);
            }
        }
        if let Some((lowest, ulp)) = lowest_bit_and_ulp(value) {
            let bin = (lowest + BIN_OF_ONE) as usize;
            self.by_lowest_bit[bin] += 1;
            self.ulp_sums[bin] += ulp;
        }
    }

    /// The step the lossless encoder quantises on (as it picks it from all the samples:
    /// the coarsest grid they lie on, else [`default_float_step`]), and the bits of the
    /// counted samples' residuals on it: a sample whose lowest bit is below the step
    /// leaves a residual of about as many bits as the step is above its ulp.
    pub(crate) fn step_and_residual_bits(&self) -> (f64, f64) {
        let Some((lo, hi)) = self.range else {
            return (1.0, 0.0);
        };
        let largest = lo.abs().max(hi.abs());
        let grid = FLOAT_GRIDS
            .iter()
            .enumerate()
            .find(|&(g, &step)| self.grids >> g & 1 != 0 && largest / step < MAX_INTEGER_MAGNITUDE);
        if let Some((_, &step)) = grid {
            return (step, 0.0);
        }
        let step = default_float_step(lo, hi);
        let k = step.log2().round() as i64;
        let below = (0..BINS).take_while(|&bin| (bin as i64 - BIN_OF_ONE) < k);
        let bits: i64 = below
            .map(|bin| k * self.by_lowest_bit[bin] as i64 - self.ulp_sums[bin])
            .sum();
        (step, bits.max(0) as f64)
    }
}

/// The binary exponents of `value`'s lowest set bit and of its ulp; `None` for ±0.
fn lowest_bit_and_ulp(value: f32) -> Option<(i64, i64)> {
    let bits = value.to_bits() & 0x7fff_ffff;
    if bits == 0 {
        return None;
    }
    let exponent = (bits >> 23) as i64;
    let mantissa = bits & 0x7f_ffff;
    let (significand, ulp) = match exponent {
        0 => (mantissa, -149),
        e => (mantissa | 1 << 23, e - 150),
    };
    Some((ulp + i64::from(significand.trailing_zeros()), ulp))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lowest_bits_and_ulps_are_binary_exponents() {
        assert_eq!(lowest_bit_and_ulp(1.0), Some((0, -23)));
        assert_eq!(lowest_bit_and_ulp(-6.0), Some((1, -21)));
        assert_eq!(lowest_bit_and_ulp(0.375), Some((-3, -25)));
        assert_eq!(lowest_bit_and_ulp(f32::from_bits(1)), Some((-149, -149)));
        assert_eq!(lowest_bit_and_ulp(-0.0), None);
        assert_eq!(lowest_bit_and_ulp(f32::MAX), Some((104, 104)));
        assert_eq!(lowest_bit_and_ulp(2f32.powi(127)), Some((127, 104)));
    }

    #[test]
    fn the_extremes_of_f32_are_counted() {
        let mut detail = FloatDetail::default();
        for v in [
            f32::MAX,
            -f32::MAX,
            2f32.powi(127),
            f32::from_bits(1),
            f32::MIN_POSITIVE,
        ] {
            detail.add(v);
        }
        let (step, bits) = detail.step_and_residual_bits();
        assert!(
            step.is_finite() && step > 0.0 && bits.is_finite(),
            "{step} {bits}"
        );
    }

    #[test]
    fn samples_on_a_grid_have_its_step_and_no_residual() {
        let mut detail = FloatDetail::default();
        for v in [12.3f32, -4.5, 1000.1, 0.0] {
            detail.add(v);
        }
        assert_eq!(detail.step_and_residual_bits(), (0.1, 0.0));
    }

    #[test]
    fn samples_off_any_grid_leave_residuals_below_a_power_of_two_step() {
        let mut detail = FloatDetail::default();
        // Range 2^16: a step of 1. 1.5 lies on it to its lowest bit 2^-1, so its residual
        // is as many bits as the step is above its ulp, 2^-23: 23 bits; 3.0 is a multiple.
        for v in [0.0f32, 65536.0, 1.5, 3.0] {
            detail.add(v);
        }
        detail.grids = 0;
        assert_eq!(detail.step_and_residual_bits(), (1.0, 23.0));
    }
}
