//! Inverse quantisation: the decoder's coefficients back to the samples of the source's
//! type.

use bitvec::order::Lsb0;
use bitvec::slice::BitSlice;

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
    let fill = match nodata {
        Some(nd) if sample_type != SampleType::F32 || f64::from(nd as f32) == nd => nd,
        _ => f64::NAN,
    };
    let (lo, hi) = sample_type.value_range();
    let value = |i: usize, x: X| -> f64 {
        if mask.is_some_and(|m| !m[i]) {
            fill
        } else {
            value_of(x)
        }
    };
    let int = |i: usize, x: X| -> f64 {
        let v = value(i, x);
        if v.is_nan() {
            0.0
        } else {
            v.round().clamp(lo, hi)
        }
    };
    let values = values.into_iter().enumerate();
    let mut samples = match sample_type {
        SampleType::U8 => Samples::U8(values.map(|(i, x)| int(i, x) as u8).collect()),
        SampleType::U16 => Samples::U16(values.map(|(i, x)| int(i, x) as u16).collect()),
        SampleType::I16 => Samples::I16(values.map(|(i, x)| int(i, x) as i16).collect()),
        SampleType::I32 => Samples::I32(values.map(|(i, x)| int(i, x) as i32).collect()),
        SampleType::F32 => Samples::F32(values.map(|(i, x)| value(i, x) as f32).collect()),
    };
    // The in-place collect keeps the input's capacity: give the surplus back.
    match &mut samples {
        Samples::U8(v) => v.shrink_to_fit(),
        Samples::U16(v) => v.shrink_to_fit(),
        Samples::I16(v) => v.shrink_to_fit(),
        Samples::I32(v) => v.shrink_to_fit(),
        Samples::F32(v) => v.shrink_to_fit(),
    }
    samples
}
