//! From source samples to the integer plane the 5/3 path codes (and back), and void filling.
//!
//! Every stream stores its samples as integers `q` with `value = offset + step · q`
//! (computed in `f64`, then narrowed to the sample type):
//! - integer sources, lossless: `offset = min`, `step = 1`;
//! - integer sources, `Quality::MaxError(E)`: `step = 2⌊E⌋ + 1`, `q = ⌊(v − min + ⌊E⌋) / step⌋`,
//!   which keeps every sample within `⌊E⌋` (the near-lossless quantiser of JPEG-LS);
//! - float sources whose values all lie exactly on a decimal or binary grid (Terrain-RGB's
//!   0.1 m, for instance): `offset = 0`, `step` = that grid, lossless;
//! - other float sources, lossless: a grid `step` close to the data's precision plus an
//!   exact per-sample residual on the `f32` bit patterns (see [`crate::residual`]);
//! - float sources with `Quality::MaxError(E)` or `Quality::Precision(STEP)`: `step = 2E` (or STEP),
//!   `q = round(v / step)`, checked sample by sample.
//!
//! Nodata samples are filled before the transform with a smooth continuation of their
//! surroundings ([`fill_voids`]), so the coefficients near valid samples stay small, and
//! after the transform the coefficients that reach no valid sample are zeroed
//! ([`crate::wavelet::zero_unreached`]): voids cost almost nothing; the mask restores them.

use crate::error::CodecError;
use crate::raster::Raster;

mod prepare;
mod samples;
mod voids;

pub(crate) use prepare::{
    cheaper_reversible, prepare_97, prepare_integer, FinestStep, Prepared, VoidCoefficients,
};
pub(crate) use samples::{
    integer_samples, rescale_97, sample_bits, samples_from_bits, to_samples, whole_offset,
};
pub(crate) use voids::{fill_voids, smooth_void_edges};

/// Largest |q| the integer path accepts: keeps 5/3 coefficients far below 2^31.
pub const MAX_INTEGER_MAGNITUDE: f64 = (1u64 << 26) as f64;

/// How stored integers map back to sample values: `value = offset + step · q`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValueMapping {
    /// Value of `q = 0`.
    pub offset: f64,
    /// Distance between consecutive `q`.
    pub step: f64,
}

impl ValueMapping {
    /// The sample value of integer `q`.
    #[inline]
    pub fn value(&self, q: f64) -> f64 {
        self.offset + self.step * q
    }
}

/// The integer plane of a raster, ready for the 5/3 transform.
#[derive(Debug, Clone)]
pub struct IntegerPlane {
    /// `width × height` integers, voids filled.
    pub values: Vec<i32>,
    /// How to map them back.
    pub mapping: ValueMapping,
    /// For lossless floats off any grid: `bits(original) − bits(reconstruction)` of every
    /// valid sample in raster order (empty otherwise).
    pub residuals: Vec<i32>,
}

/// Value range (min, max) of the valid samples, `None` if there are none.
pub fn valid_range(raster: &Raster, mask: &[bool]) -> Option<(f64, f64)> {
    if raster.sample_type().is_integer() {
        // Whole numbers: no −0.0 to tell from 0.0, so the bounds alone are the state.
        let (lo, hi) =
            raster
                .samples
                .fold_f64((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), i, v| {
                    let valid = mask[i];
                    (
                        if valid { lo.min(v) } else { lo },
                        if valid { hi.max(v) } else { hi },
                    )
                });
        return (lo <= hi).then_some((lo, hi));
    }
    raster.samples.fold_f64(None, |range, i, v| {
        if !mask[i] {
            return range;
        }
        Some(match range {
            None => (v, v),
            Some((lo, hi)) => (lo.min(v), hi.max(v)),
        })
    })
}

/// Quantises an integer raster: lossless when `max_error < 1`, else with step `2⌊E⌋+1`.
pub fn integer_plane(
    raster: &Raster,
    mask: &[bool],
    max_error: f64,
) -> Result<IntegerPlane, CodecError> {
    let (min, max) = valid_range(raster, mask).unwrap_or((0.0, 0.0));
    let e = max_error.max(0.0).floor();
    let step = 2.0 * e + 1.0;
    let span = ((max - min) / step).ceil();
    if span > MAX_INTEGER_MAGNITUDE {
        return Err(CodecError::UnsupportedValues(format!(
            "sample range {} is too wide for the integer coder (at most {} steps of 2E + 1); \
             a max error of at least {} fits it",
            max - min,
            MAX_INTEGER_MAGNITUDE,
            smallest_fitting_error(max - min)
        )));
    }
    let mapping = ValueMapping { offset: min, step };
    // `v − min + e ≥ 0` for every valid sample, so truncation is the floor.
    let values = raster.samples.map_f64(|i, v| {
        if mask[i] {
            ((v - min + e) / step) as i32
        } else {
            0
        }
    });
    Ok(IntegerPlane {
        values,
        mapping,
        residuals: Vec::new(),
    })
}

/// The smallest integer max error E whose step 2E + 1 spans `range` in at most
/// [`MAX_INTEGER_MAGNITUDE`] steps.
fn smallest_fitting_error(range: f64) -> f64 {
    let mut e = ((range / MAX_INTEGER_MAGNITUDE - 1.0) / 2.0)
        .ceil()
        .max(0.0);
    while (range / (2.0 * e + 1.0)).ceil() > MAX_INTEGER_MAGNITUDE {
        e += 1.0;
    }
    e
}

/// Refuses infinite valid samples (no step spans them), naming the first one.
pub fn check_finite(values: &[f32], mask: &[bool], width: usize) -> Result<(), CodecError> {
    let first = values
        .iter()
        .zip(mask)
        .position(|(v, &valid)| valid && !v.is_finite());
    match first {
        None => Ok(()),
        Some(i) => Err(CodecError::UnsupportedValues(format!(
            "the sample at row {}, column {} is {}: only finite values can be coded; \
             make such samples nodata",
            i / width.max(1),
            i % width.max(1),
            values[i]
        ))),
    }
}

/// Grids tried for exact float data, coarsest first.
pub(crate) const FLOAT_GRIDS: [f64; 14] = [
    1.0, 0.5, 0.25, 0.2, 0.125, 0.1, 0.0625, 0.05, 0.03125, 0.025, 0.02, 0.01, 0.005, 0.001,
];

/// The coarsest grid on which every valid float sample lies exactly: its reconstruction
/// (as the decoder computes it, narrowed to `f32`) has the sample's bits. −0 is on no grid:
/// it is stored as the integer 0, which gives back +0.
pub fn detect_float_grid(values: &[f32], mask: &[bool]) -> Option<f64> {
    let max_abs = values
        .iter()
        .zip(mask)
        .filter(|(_, &m)| m)
        .map(|(v, _)| v.abs() as f64)
        .fold(0.0, f64::max);
    FLOAT_GRIDS.into_iter().find(|&step| {
        max_abs / step < MAX_INTEGER_MAGNITUDE
            && values
                .iter()
                .zip(mask)
                .filter(|(_, &m)| m)
                .all(|(&v, _)| on_float_grid(v, step))
    })
}

/// Whether `value`'s reconstruction on the grid of `step` (as the decoder computes it,
/// narrowed to `f32`) has its bits.
pub(crate) fn on_float_grid(value: f32, step: f64) -> bool {
    let mapping = ValueMapping { offset: 0.0, step };
    let back = mapping.value((value as f64 / step).round()) as f32;
    back.to_bits() == value.to_bits()
}

/// Quantises a float raster onto `step` (`q = round(v / step)`).
///
/// With `exact`, residuals make the round trip bit-exact; otherwise every sample is
/// checked to lie within `max_error` of its reconstruction.
pub fn float_plane(
    values: &[f32],
    mask: &[bool],
    step: f64,
    exact: bool,
    max_error: f64,
) -> Result<IntegerPlane, CodecError> {
    if !(step.is_finite() && step > 0.0) {
        return Err(CodecError::InvalidParameters(format!(
            "invalid quantisation step {step}"
        )));
    }
    let mapping = ValueMapping { offset: 0.0, step };
    let mut out = Vec::with_capacity(values.len());
    let mut residuals = Vec::new();
    for (&v, &valid) in values.iter().zip(mask) {
        if !valid {
            out.push(0);
            continue;
        }
        let q = (v as f64 / step).round();
        if q.abs() > MAX_INTEGER_MAGNITUDE {
            return Err(CodecError::InvalidParameters(format!(
                "value {v} is more than {MAX_INTEGER_MAGNITUDE} steps of {step} from zero; a larger precision step fits it"
            )));
        }
        let reconstructed = mapping.value(q) as f32;
        if exact {
            residuals.push(v.to_bits().wrapping_sub(reconstructed.to_bits()) as i32);
        } else if (reconstructed as f64 - v as f64).abs() > max_error {
            return Err(CodecError::InvalidParameters(format!(
                "cannot keep {v} within {max_error} on a grid of {step} in f32"
            )));
        }
        out.push(q as i32);
    }
    Ok(IntegerPlane {
        values: out,
        mapping,
        residuals,
    })
}

/// A power-of-two step near the data's own precision, for lossless floats off any grid:
/// about 2^-16 of the value range (the residual then holds the few remaining bits).
pub fn default_float_step(min: f64, max: f64) -> f64 {
    let range = (max - min).max(f64::MIN_POSITIVE);
    let largest = min.abs().max(max.abs()).max(1e-30);
    // At least the smallest normal: `powi` underflows to 0 below 2^-1022, and a zero step
    // would never grow in the loop below (constant rasters have `range` = MIN_POSITIVE).
    let mut step = 2f64
        .powi((range / 65536.0).log2().floor() as i32)
        .max(f64::MIN_POSITIVE);
    // Keep |q| within the integer coder's limit.
    while largest / step > MAX_INTEGER_MAGNITUDE {
        step *= 2.0;
    }
    step
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::Samples;

    #[test]
    fn too_wide_ranges_name_the_error_bound_that_fits() {
        let full_i32 = 4294967295.0;
        let e = smallest_fitting_error(full_i32);
        assert_eq!(e, 32.0);
        assert!((full_i32 / (2.0 * e + 1.0)).ceil() <= MAX_INTEGER_MAGNITUDE);
        assert!((full_i32 / (2.0 * (e - 1.0) + 1.0)).ceil() > MAX_INTEGER_MAGNITUDE);
        assert_eq!(smallest_fitting_error(1000.0), 0.0);
    }

    #[test]
    fn infinite_valid_samples_are_named() {
        let values = [1.0, 2.0, f32::NAN, f32::NEG_INFINITY];
        assert!(check_finite(&values, &[true, true, false, false], 2).is_ok());
        let err = check_finite(&values, &[true, true, false, true], 2).unwrap_err();
        assert!(err.to_string().contains("row 1, column 1 is -inf"), "{err}");
    }

    #[test]
    fn integer_max_error_bound_holds() {
        let samples: Vec<i16> = (-300..300).map(|v| (v * 7 % 251) as i16).collect();
        let raster = Raster::new(600, 1, Samples::I16(samples.clone())).unwrap();
        let mask = vec![true; 600];
        for e in [0.0, 0.5, 1.0, 2.0, 3.7, 10.0] {
            let plane = integer_plane(&raster, &mask, e).unwrap();
            for (q, &v) in plane.values.iter().zip(&samples) {
                let back = plane.mapping.value(*q as f64);
                assert!((back - v as f64).abs() <= e.floor(), "e={e}: {v} -> {back}");
            }
        }
    }

    #[test]
    fn grid_detection_finds_tenths_and_rejects_noise() {
        let tenths: Vec<f32> = (0..1000)
            .map(|i| (-10000.0 + (i * 37 + 100_137) as f64 * 0.1) as f32)
            .collect();
        let mask = vec![true; tenths.len()];
        assert_eq!(detect_float_grid(&tenths, &mask), Some(0.1));
        let noisy: Vec<f32> = (0..1000)
            .map(|i| (i as f32 * 0.737_123_4).sin() * 1234.567)
            .collect();
        assert_eq!(detect_float_grid(&noisy, &mask), None);
    }

    #[test]
    fn float_residuals_are_exact() {
        let values: Vec<f32> = (0..2000)
            .map(|i| (i as f32 * 0.311).cos() * 812.25 + 1000.0)
            .collect();
        let mask = vec![true; values.len()];
        let step = default_float_step(180.0, 1820.0);
        let plane = float_plane(&values, &mask, step, true, 0.0).unwrap();
        for ((&q, &r), &v) in plane.values.iter().zip(&plane.residuals).zip(&values) {
            let base = plane.mapping.value(q as f64) as f32;
            assert_eq!(f32::from_bits(base.to_bits().wrapping_add(r as u32)), v);
        }
    }

    #[test]
    fn negative_zero_is_on_no_grid() {
        let mask = vec![true; 3];
        assert_eq!(detect_float_grid(&[1.0, 0.0, 2.5], &mask), Some(0.5));
        assert_eq!(detect_float_grid(&[1.0, -0.0, 2.5], &mask), None);
    }

    #[test]
    fn default_step_of_a_constant_raster_is_positive() {
        for v in [0.0, -0.0, 1e-30, 0.123_456_79, 3.0e38] {
            let step = default_float_step(v, v);
            assert!(step > 0.0 && step.is_finite(), "{v}: step {step}");
            assert!(v.abs() / step <= MAX_INTEGER_MAGNITUDE, "{v}: step {step}");
        }
    }

    #[test]
    fn void_edges_continue_the_slope() {
        // A paraboloid (biharmonic, not harmonic) with a hole: the harmonic fill sags
        // away from it, the biharmonic one near the edges follows it.
        let (w, h) = (32, 32);
        let surface = |i: usize| {
            let (x, y) = ((i % w) as f64 - 12.0, (i / w) as f64 - 14.0);
            0.2 * (x * x + y * y)
        };
        let mask: Vec<bool> = (0..w * h)
            .map(|i| !((10..14).contains(&(i % w)) && (11..15).contains(&(i / w))))
            .collect();
        let worst = |values: &[f64]| {
            (0..w * h)
                .map(|i| (values[i] - surface(i)).abs())
                .fold(0.0, f64::max)
        };
        let mut harmonic: Vec<f64> = (0..w * h)
            .map(|i| if mask[i] { surface(i) } else { 0.0 })
            .collect();
        fill_voids(&mut harmonic, w, h, &mask);
        let mut smooth = harmonic.clone();
        smooth_void_edges(&mut smooth, w, h, &mask);
        let (before, after) = (worst(&harmonic), worst(&smooth));
        assert!(before > 0.5, "the harmonic fill is off by {before}");
        assert!(after < before / 4.0, "{after} against {before}");
    }

    #[test]
    fn voids_are_filled_smoothly() {
        let (w, h) = (32, 16);
        let mut values: Vec<f64> = (0..w * h).map(|i| (i % w) as f64 * 2.0).collect();
        let mask: Vec<bool> = (0..w * h)
            .map(|i| !((8..20).contains(&(i % w)) && (4..12).contains(&(i / w))))
            .collect();
        let original = values.clone();
        for (v, &m) in values.iter_mut().zip(&mask) {
            if !m {
                *v = -32768.0;
            }
        }
        fill_voids(&mut values, w, h, &mask);
        for i in 0..w * h {
            assert!(
                (values[i] - original[i]).abs() < 12.0,
                "sample {i}: {} vs {}",
                values[i],
                original[i]
            );
        }
    }
}
