//! Inverse quantisation: the decoder's coefficients back to the samples of the source's
//! type.

use bitvec::order::Lsb0;
use bitvec::slice::BitSlice;

use super::ValueMapping;
use crate::raster::{SampleType, Samples};
use crate::wavelet::Subband;

/// Multiplies the 9/7 coefficients of every subband by the quantiser step over the
/// band's scale, undoing the encoder's scaling.
pub(crate) fn rescale_97(
    data: &mut [f32],
    width: usize,
    subbands: &[Subband],
    bands: &[(u8, f64)],
    coefficient_step: f64,
) {
    for (sub, &(_, band_scale)) in subbands.iter().zip(bands) {
        let scale = (coefficient_step / band_scale) as f32;
        for y in 0..sub.height {
            let row = (sub.y0 + y) * width + sub.x0;
            data[row..row + sub.width]
                .iter_mut()
                .for_each(|c| *c *= scale);
        }
    }
}

/// Builds output samples from reconstructed values, in place where the output type is no
/// wider than the input: integers are rounded and clamped to the type's range, floats
/// narrowed with `as f32`; where `mask` is false the sample is `nodata` (NaN if none, or
/// if an f32 raster's nodata has no f32 value: its voids were NaN, and `nodata as f32`
/// would be some other, valid value).
pub(crate) fn to_samples<X: Copy>(
    sample_type: SampleType,
    values: Vec<X>,
    value_of: impl Fn(X) -> f64,
    mask: Option<&BitSlice<u64, Lsb0>>,
    nodata: Option<f64>,
) -> Samples {
    let (lo, hi) = sample_type.value_range();
    let int = |v: f64| whole_in_range(v, lo, hi);
    let values = values.into_iter();
    // Every sample first, then the voids overwritten with the fill value.
    let mut samples = match sample_type {
        SampleType::U8 => Samples::U8(values.map(|x| int(value_of(x)) as u8).collect()),
        SampleType::U16 => Samples::U16(values.map(|x| int(value_of(x)) as u16).collect()),
        SampleType::I16 => Samples::I16(values.map(|x| int(value_of(x)) as i16).collect()),
        SampleType::I32 => Samples::I32(values.map(|x| int(value_of(x)) as i32).collect()),
        SampleType::F32 => Samples::F32(values.map(|x| value_of(x) as f32).collect()),
    };
    finish(&mut samples, mask, nodata);
    samples
}

/// The sample of the 1- or 2-byte integer `sample_type` that [`to_samples`] makes of
/// value `v`, as `i16` bits (an 8-bit sample in the low byte).
#[inline]
pub(crate) fn sample_bits(sample_type: SampleType, v: f64) -> i16 {
    let (lo, hi) = sample_type.value_range();
    let whole = whole_in_range(v, lo, hi);
    match sample_type {
        SampleType::U16 => whole as u16 as i16,
        SampleType::U8 => whole as u8 as i16,
        _ => whole as i16,
    }
}

/// The samples whose [`sample_bits`] are `bits`, voids filled as [`to_samples`] fills
/// them (in place for 16-bit types).
pub(crate) fn samples_from_bits(
    sample_type: SampleType,
    bits: Vec<i16>,
    mask: Option<&BitSlice<u64, Lsb0>>,
    nodata: Option<f64>,
) -> Samples {
    let bits = bits.into_iter();
    let mut samples = match sample_type {
        SampleType::U16 => Samples::U16(bits.map(|b| b as u16).collect()),
        SampleType::U8 => Samples::U8(bits.map(|b| b as u8).collect()),
        _ => Samples::I16(bits.collect()),
    };
    finish(&mut samples, mask, nodata);
    samples
}

/// Whether `mapping` is `q + offset` with a whole offset, so that [`integer_samples`]
/// computes in integers (|q| < 2^31 and |offset| ≤ 2^40 keep `offset + q` far inside
/// f64's 2^53).
pub(crate) fn whole_offset(mapping: ValueMapping) -> bool {
    mapping.step == 1.0
        && mapping.offset.fract() == 0.0
        && mapping.offset.abs() <= (1u64 << 40) as f64
}

/// [`to_samples`] of the 5/3 path's integers `q`, whose samples are `mapping.value(q)`.
/// When the mapping is `q + offset` with a whole offset (integer rasters coded exactly),
/// the samples are computed in integers: that sum is exact in `f64` too, so the result
/// is the same, at a fraction of the cost (and in place when `V` is as wide as the
/// samples).
pub(crate) fn integer_samples<V: Copy + Into<i32>>(
    sample_type: SampleType,
    values: Vec<V>,
    mapping: ValueMapping,
    mask: Option<&BitSlice<u64, Lsb0>>,
    nodata: Option<f64>,
) -> Samples {
    let general = |values: Vec<V>| {
        to_samples(
            sample_type,
            values.into_iter().map(Into::into).collect::<Vec<i32>>(),
            |q| mapping.value(q as f64),
            mask,
            nodata,
        )
    };
    if !whole_offset(mapping) {
        return general(values);
    }
    let offset = mapping.offset as i64;
    let (lo, hi) = sample_type.value_range();
    let (lo, hi) = (lo as i64, hi as i64);
    let int = move |q: V| (i64::from(q.into()) + offset).clamp(lo, hi);
    let values_in = values.into_iter();
    let mut samples = match sample_type {
        SampleType::U8 => Samples::U8(values_in.map(|q| int(q) as u8).collect()),
        SampleType::U16 => Samples::U16(values_in.map(|q| int(q) as u16).collect()),
        SampleType::I16 => Samples::I16(values_in.map(|q| int(q) as i16).collect()),
        SampleType::I32 => Samples::I32(values_in.map(|q| int(q) as i32).collect()),
        SampleType::F32 => return general(values_in.collect()),
    };
    finish(&mut samples, mask, nodata);
    samples
}

/// `v` rounded and clamped to `[lo, hi]` (whole numbers); NaN gives 0.
#[inline]
fn whole_in_range(v: f64, lo: f64, hi: f64) -> f64 {
    if v.is_nan() {
        0.0
    } else {
        // Clamping to whole-number bounds first rounds the same.
        round_small(v.clamp(lo, hi))
    }
}

/// Writes the fill value into every void of `mask` (see [`to_samples`]), then gives back
/// the capacity an in-place collect kept.
fn finish(samples: &mut Samples, mask: Option<&BitSlice<u64, Lsb0>>, nodata: Option<f64>) {
    let sample_type = samples.sample_type();
    if let Some(mask) = mask {
        let fill = match nodata {
            Some(nd) if sample_type != SampleType::F32 || f64::from(nd as f32) == nd => nd,
            _ => f64::NAN,
        };
        let (lo, hi) = sample_type.value_range();
        let whole = whole_in_range(fill, lo, hi);
        let voids = mask[..samples.len()].iter_zeros();
        match samples {
            Samples::U8(v) => voids.for_each(|i| v[i] = whole as u8),
            Samples::U16(v) => voids.for_each(|i| v[i] = whole as u16),
            Samples::I16(v) => voids.for_each(|i| v[i] = whole as i16),
            Samples::I32(v) => voids.for_each(|i| v[i] = whole as i32),
            Samples::F32(v) => voids.for_each(|i| v[i] = fill as f32),
        }
    }
    match samples {
        Samples::U8(v) => v.shrink_to_fit(),
        Samples::U16(v) => v.shrink_to_fit(),
        Samples::I16(v) => v.shrink_to_fit(),
        Samples::I32(v) => v.shrink_to_fit(),
        Samples::F32(v) => v.shrink_to_fit(),
    }
}

/// `v.round()` (halves away from zero) for `|v| < 2^62`, up to the sign of a zero result,
/// without a call into libm: the truncation, moved away from zero when the part cut off
/// is at least ½ (`v − trunc(v)` is exact).
#[inline]
fn round_small(v: f64) -> f64 {
    let truncated = v as i64 as f64;
    let cut = v - truncated;
    // Without a branch: the fractions of 9/7 reconstructions are random.
    truncated + ((cut >= 0.5) as i32 - (cut <= -0.5) as i32) as f64
}

#[cfg(test)]
mod tests {
    use super::round_small;

    #[test]
    fn round_small_matches_round() {
        let halves = (-40..=40).map(|k| k as f64 * 0.25);
        let awkward = [
            0.499_999_999_999_999_94,
            -0.499_999_999_999_999_94,
            1.5 - f64::EPSILON,
            2.5 + f64::EPSILON * 2.0,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            9_007_199_254_740_993.0,
            2_147_483_647.4,
            -2_147_483_648.6,
        ];
        for v in halves.chain(awkward) {
            assert_eq!(round_small(v), v.round(), "{v}");
        }
    }
}
