//! A raster made ready for the zerotree coder: quantised (5/3: to the integer plane;
//! 9/7: the transform's coefficients on one step), transformed, with the per-subband
//! shifts, scales and weights the coder and the header need.

use crate::container::{scale_from_u16, scale_to_u16, Mode};
use crate::error::CodecError;
use crate::ezw::{Midpoint, MAX_COEFFICIENT_PLANE};
use crate::pipeline::Quality;
use crate::raster::{Raster, Samples};
use crate::wavelet::{self, ShiftRule, Subband, Wavelet};

use super::{
    default_float_step, detect_float_grid, fill_voids, float_plane, integer_plane,
    smooth_void_edges, valid_range, IntegerPlane, ValueMapping,
};

/// Coefficients and parameters ready for the EZW coder.
pub(crate) struct Prepared {
    /// The quantised transform coefficients, raster layout.
    pub coefficients: Vec<i32>,
    /// Per subband: whole planes its coefficients are shifted up by (5/3).
    pub shifts: Vec<u32>,
    /// Per subband: the factor its coefficients were multiplied by (9/7).
    pub scales: Vec<f64>,
    /// Per subband: squared pixel error of a unit coefficient error.
    pub distortion_weights: Vec<f64>,
    /// Where the decoder reconstructs inside a known interval.
    pub midpoint: Midpoint,
    /// How coded values map back to samples.
    pub mapping: ValueMapping,
    /// What the complete stream guarantees.
    pub mode: Mode,
    /// The bound the complete stream keeps every sample within.
    pub max_error: f64,
    /// The 9/7 quantiser step (1 for 5/3).
    pub coefficient_step: f64,
    /// Exact float residuals (lossless floats off any grid), else empty.
    pub residuals: Vec<i32>,
}

/// What the coefficients that reach no valid sample hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum VoidCoefficients {
    /// Zeroed ([`wavelet::zero_unreached`]), the voids filled biharmonically near the
    /// valid samples ([`smooth_void_edges`]) and given the values their row neighbours
    /// predict ([`wavelet::forward_integer`]): what the encoder codes.
    Zeroed,
    /// The transform of the harmonically filled voids: what coder 3's prior tables were
    /// trained on (they are part of the format, so their training stays as it was).
    #[cfg(feature = "research")]
    Filled,
}

/// How fine the last plane of a 9/7 stream is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FinestStep {
    /// No finer than integer samples need ([`INTEGER_FINEST_STEP`]): what the encoder
    /// codes.
    ForTheSamples,
    /// The largest coefficient over 2^30 whatever the samples: what coder 3's prior
    /// tables were trained on (they are part of the format, so their training stays as
    /// it was).
    #[cfg(feature = "research")]
    AsTrained,
}

/// The reversible path (5/3 or 13/11, `wavelet`): samples to the integer plane `quality`
/// asks for, voids filled, transformed, the subbands shifted by `rule`.
pub(crate) fn prepare_integer(
    raster: &Raster,
    mask: &[bool],
    (wavelet, quality): (Wavelet, Quality),
    norms: &[f64],
    (voids, rule): (VoidCoefficients, ShiftRule),
) -> Result<Prepared, CodecError> {
    let (width, height) = (raster.width, raster.height);
    let (plane, mode, max_error) = integer_plane_for(raster, mask, quality)?;
    let IntegerPlane {
        values,
        mapping,
        residuals,
    } = plane;
    let mut values = filled(values, width, height, mask, voids);
    let levels = level_count(norms.len());
    let predicted = voids_of(mask).filter(|_| voids == VoidCoefficients::Zeroed);
    wavelet::forward_integer(wavelet, &mut values, (width, height), levels, predicted);
    if voids == VoidCoefficients::Zeroed {
        wavelet::zero_unreached(&mut values, width, height, levels, wavelet, mask);
    }
    // Shift each subband by its synthesis norm relative to the smallest, in whole planes.
    let shifts = wavelet::plane_shifts(norms, rule);
    let step2 = mapping.step * mapping.step;
    Ok(Prepared {
        coefficients: values,
        scales: vec![1.0; norms.len()],
        distortion_weights: norms.iter().map(|n| n * n * step2).collect(),
        shifts,
        midpoint: Midpoint::Integer,
        mapping,
        mode,
        max_error,
        coefficient_step: 1.0,
        residuals,
    })
}

/// The reversible wavelet, 5/3 or 13/11, whose `levels`-level transform of `raster`'s
/// integer plane for `quality` (voids filled) has the fewest coefficient bits (the sum
/// of their bit lengths) once the coefficients reaching no valid sample are zeroed: a
/// measure of what the coder spends that ranks the two as their coded sizes do
/// (README, *The 13/11 wavelet*). The 13/11 on a tie; the 5/3 for planes wider than
/// [`wavelet::MAX_EXACT_1311`], where the 13/11's sums would wrap.
pub(crate) fn cheaper_reversible(
    raster: &Raster,
    quality: Quality,
    levels: u32,
) -> Result<Wavelet, CodecError> {
    let mask = raster.valid_mask();
    let (width, height) = (raster.width, raster.height);
    let (IntegerPlane { values, .. }, _, _) = integer_plane_for(raster, &mask, quality)?;
    let values = filled(values, width, height, &mask, VoidCoefficients::Zeroed);
    let widest = values.iter().map(|v| v.unsigned_abs()).max().unwrap_or(0);
    if widest > wavelet::MAX_EXACT_1311.unsigned_abs() {
        return Ok(Wavelet::Int53);
    }
    let bits = |wavelet: Wavelet| -> u64 {
        let mut coefficients = values.clone();
        wavelet::forward_integer(
            wavelet,
            &mut coefficients,
            (width, height),
            levels,
            voids_of(&mask),
        );
        wavelet::zero_unreached(&mut coefficients, width, height, levels, wavelet, &mask);
        let bit_length = |c: &i32| u64::from(32 - c.unsigned_abs().leading_zeros());
        coefficients.iter().map(bit_length).sum()
    };
    Ok(match bits(Wavelet::Int53) < bits(Wavelet::Int1311) {
        true => Wavelet::Int53,
        false => Wavelet::Int1311,
    })
}

/// `mask` when it holds a void, else `None`.
fn voids_of(mask: &[bool]) -> Option<&[bool]> {
    mask.iter().any(|&m| !m).then_some(mask)
}

/// Fills the samples `mask` says are voids: harmonically, then (what the encoder codes,
/// [`VoidCoefficients::Zeroed`]) biharmonically near the valid samples.
fn fill(
    values: &mut [f64],
    (width, height): (usize, usize),
    mask: &[bool],
    voids: VoidCoefficients,
) {
    fill_voids(values, width, height, mask);
    if voids == VoidCoefficients::Zeroed {
        smooth_void_edges(values, width, height, mask);
    }
}

/// `values` with the samples `mask` says are voids filled smoothly (rounded), as `voids`
/// says ([`fill`]).
fn filled(
    mut values: Vec<i32>,
    width: usize,
    height: usize,
    mask: &[bool],
    voids: VoidCoefficients,
) -> Vec<i32> {
    if mask.iter().any(|&m| !m) {
        let mut smooth: Vec<f64> = values.iter().map(|&v| v as f64).collect();
        fill(&mut smooth, (width, height), mask, voids);
        for (v, f) in values.iter_mut().zip(smooth) {
            *v = f.round() as i32;
        }
    }
    values
}

/// The integer plane of `raster` for `quality`, with the mode and error bound of the
/// stream that codes it exactly.
fn integer_plane_for(
    raster: &Raster,
    mask: &[bool],
    quality: Quality,
) -> Result<(IntegerPlane, Mode, f64), CodecError> {
    Ok(match (&raster.samples, quality) {
        (Samples::F32(values), Quality::Lossless) => {
            let step = detect_float_grid(values, mask);
            let on_grid = step.is_some();
            let step = step.unwrap_or_else(|| {
                let (lo, hi) = valid_range(raster, mask).unwrap_or((0.0, 0.0));
                default_float_step(lo, hi)
            });
            let plane = float_plane(values, mask, step, !on_grid, 0.0)?;
            (plane, Mode::Lossless, 0.0)
        }
        (Samples::F32(values), Quality::MaxError(e)) => {
            check_positive(e, "the max error")?;
            (bounded_float_plane(values, mask, e)?, Mode::MaxError, e)
        }
        (Samples::F32(values), Quality::Precision(step)) => {
            check_positive(step, "the precision")?;
            // The grid's half step, plus the rounding of the reconstruction to f32.
            let largest = values
                .iter()
                .zip(mask)
                .filter(|(_, &m)| m)
                .map(|(v, _)| v.abs() as f64)
                .fold(0.0, f64::max);
            let bound = step / 2.0 + largest * f32::EPSILON as f64;
            let plane = float_plane(values, mask, step, false, bound)?;
            (plane, Mode::Precision, bound)
        }
        (_, Quality::Lossless) => (integer_plane(raster, mask, 0.0)?, Mode::Lossless, 0.0),
        (_, Quality::MaxError(e)) => {
            check_positive(e, "the max error")?;
            let plane = integer_plane(raster, mask, e)?;
            let mode = if e >= 1.0 { Mode::MaxError } else { Mode::Lossless };
            (plane, mode, e.floor())
        }
        (_, Quality::Precision(_)) => {
            return Err(CodecError::InvalidParameters(
                "a precision applies to float rasters; integer rasters are coded exactly or with a max error".into(),
            ))
        }
    })
}

/// The 9/7 path: samples centred on their mean, voids filled, transformed, and the
/// coefficients scaled by their subband's norm and quantised on one step.
pub(crate) fn prepare_97(
    raster: &Raster,
    mask: &[bool],
    norms: &[f64],
    (voids, finest): (VoidCoefficients, FinestStep),
) -> Prepared {
    let (width, height) = (raster.width, raster.height);
    let (mean, mut data) = centred_samples(raster, mask, voids);
    let levels = level_count(norms.len());
    wavelet::forward_97(&mut data, width, height, levels);
    if voids == VoidCoefficients::Zeroed {
        wavelet::zero_unreached(&mut data, width, height, levels, Wavelet::Cdf97, mask);
    }
    // Scale every subband by its norm so one quantiser step means the same pixel error
    // everywhere, then quantise finely enough that the cut, not the quantiser, limits
    // the quality: the largest scaled coefficient gets 30 bits.
    let subbands = wavelet::subbands(width, height, levels);
    // The header stores the scales in 1/8192 units: quantise with exactly those values.
    let norms: Vec<f64> = norms
        .iter()
        .map(|&n| scale_from_u16(scale_to_u16(n)))
        .collect();
    let mut step = coefficient_step(&data, width, &subbands, &norms);
    if finest == FinestStep::ForTheSamples && raster.sample_type().is_integer() {
        step = integer_finest_step(step);
    }
    let mut coefficients = vec![0i32; data.len()];
    for (sub, &norm) in subbands.iter().zip(&norms) {
        let scale = norm / step;
        for y in 0..sub.height {
            let row = (sub.y0 + y) * width + sub.x0;
            for x in row..row + sub.width {
                // Truncating the magnitude is its floor.
                let q = (data[x] as f64 * scale).abs() as i32;
                coefficients[x] = if data[x] < 0.0 { -q } else { q };
            }
        }
    }
    Prepared {
        coefficients,
        shifts: vec![0; norms.len()],
        distortion_weights: vec![step * step; norms.len()],
        scales: norms,
        midpoint: Midpoint::Real,
        mapping: ValueMapping {
            offset: mean,
            step: 1.0,
        },
        mode: Mode::Lossy,
        max_error: f64::INFINITY,
        coefficient_step: step,
        residuals: Vec::new(),
    }
}

/// The mean of the valid samples (a whole number for integers, an f32 for floats: any
/// offset works, these are shorter to store) and the samples less it as f32, voids
/// filled as `voids` says.
fn centred_samples(raster: &Raster, mask: &[bool], voids: VoidCoefficients) -> (f64, Vec<f32>) {
    let valid = mask.iter().filter(|&&m| m).count();
    // From −0.0, as `Iterator::sum` starts: the same mean, sign of zero included.
    let sum = raster
        .samples
        .fold_f64(-0.0, |sum, i, v| if mask[i] { sum + v } else { sum });
    let mean = sum / valid.max(1) as f64;
    let mean = if raster.sample_type().is_integer() {
        mean.round()
    } else {
        f64::from(mean as f32)
    };
    let centre = |i: usize, v: f64| if mask[i] { v - mean } else { 0.0 };
    if valid == raster.len() {
        // No voids to fill: straight to f32.
        return (mean, raster.samples.map_f64(|i, v| centre(i, v) as f32));
    }
    let mut centred = raster.samples.map_f64(centre);
    fill(&mut centred, (raster.width, raster.height), mask, voids);
    (mean, centred.iter().map(|&v| v as f32).collect())
}

/// The 9/7 quantiser step: the largest norm-scaled coefficient over 2^30, rounded up to
/// an f32 (which the header stores in 4 bytes instead of 8); 1 when every coefficient
/// is zero.
fn coefficient_step(data: &[f32], width: usize, subbands: &[Subband], norms: &[f64]) -> f64 {
    let mut largest = 0f64;
    for (sub, &norm) in subbands.iter().zip(norms) {
        for y in 0..sub.height {
            let row = (sub.y0 + y) * width + sub.x0;
            largest = largest.max(largest_magnitude(&data[row..row + sub.width], norm));
        }
    }
    if largest > 0.0 {
        let step = largest / (1u64 << MAX_COEFFICIENT_PLANE) as f64 * 1.0001;
        let rounded = f64::from(step as f32);
        if rounded >= step {
            rounded
        } else {
            f64::from(f32::from_bits((step as f32).to_bits() + 1))
        }
    } else {
        1.0
    }
}

/// The finest 9/7 step an integer raster needs: `step` doubled while it stays at most
/// [`INTEGER_FINEST_STEP`]. The planes below that only refine errors that the rounding to
/// whole units removes, so they would be bytes a budget spends for nothing; doubling
/// drops them exactly (every coefficient is the finer one shifted right), and leaves every
/// plane above as it was.
fn integer_finest_step(mut step: f64) -> f64 {
    while step * 2.0 <= INTEGER_FINEST_STEP {
        step *= 2.0;
    }
    step
}

/// The coarsest interval of the last 9/7 plane of an integer raster, in data units. Its
/// error (roughly a Gaussian of σ = step / √12 ≈ 0.07) stays about 7 σ inside the ±½
/// that rounding to the nearest unit forgives: the complete streams of the six integer
/// DEMs of the development set decode every sample exactly (with ½, four of six are off
/// by one somewhere).
const INTEGER_FINEST_STEP: f64 = 0.25;

/// The largest `|c · norm|` over `values` (0 when there are none; NaNs are passed over).
/// Four running maxima: a maximum of magnitudes does not depend on the order it is taken
/// in, and independent chains keep the processor busy.
fn largest_magnitude(values: &[f32], norm: f64) -> f64 {
    let mut lanes = [0f64; 4];
    let chunks = values.chunks_exact(4);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (lane, &c) in lanes.iter_mut().zip(chunk) {
            *lane = lane.max((c as f64 * norm).abs());
        }
    }
    for &c in rest {
        lanes[0] = lanes[0].max((c as f64 * norm).abs());
    }
    lanes.iter().fold(0.0, |a, &b| a.max(b))
}

/// Quantises floats so every sample stays within `e` after rounding back to f32: the grid
/// step starts just under `2e` and shrinks until the check passes.
fn bounded_float_plane(values: &[f32], mask: &[bool], e: f64) -> Result<IntegerPlane, CodecError> {
    let mut step = 2.0 * e * 0.999;
    let mut last_error = None;
    for _ in 0..8 {
        match float_plane(values, mask, step, false, e) {
            Ok(plane) => return Ok(plane),
            Err(err) => last_error = Some(err),
        }
        step *= 0.75;
    }
    Err(last_error.expect("at least one attempt"))
}

/// Refuses a parameter that is not a positive finite number.
fn check_positive(value: f64, what: &str) -> Result<(), CodecError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(CodecError::InvalidParameters(format!(
            "{what} must be a positive number, got {value}"
        )))
    }
}

/// Levels from the number of subbands (1 + 3·levels).
fn level_count(bands: usize) -> u32 {
    (bands.saturating_sub(1) / 3) as u32
}
