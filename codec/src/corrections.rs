//! Error-bounded coding by a cut 9/7 stream plus corrections: every valid sample whose
//! reconstruction misses by more than `e` gets `k` steps of `2⌊e⌋+1` (integers) or just
//! under `2e` (floats) added, the `k` coded like float residuals in the residual section.
//! The encoder keeps this file when it is smaller than the near-lossless 5/3 stream.

use bitvec::order::Lsb0;
use bitvec::slice::BitSlice;

use crate::container::{self, Mode};
use crate::error::CodecError;
use crate::pipeline::{decode, encode_stream, DecodeOptions, EncodeOptions, Encoded};
use crate::raster::{Raster, SampleType, Samples};
use crate::residual::{encode_residuals, LengthContext};
use crate::wavelet::Wavelet;

/// The smallest corrected file below `limit` bytes, the 9/7 cut searched for it; `None`
/// if nothing smaller was found.
pub(crate) fn encode_with_corrections(
    raster: &Raster,
    levels: Option<u32>,
    e: f64,
    limit: usize,
) -> Result<Option<Encoded>, CodecError> {
    let options = EncodeOptions::budget(limit as u64)
        .with_wavelet(Wavelet::Cdf97)
        .with_levels(levels)
        .with_tile_size(None)
        .with_threads(1);
    let Ok((stream, parts)) = encode_stream(raster, &options) else {
        return Ok(None);
    };
    let step = correction_step(raster.sample_type(), e);
    let payload = &parts.payload;
    let mut best: Option<Encoded> = None;
    let mut tried: Vec<(usize, usize)> = Vec::new();
    let mut evaluate = |cut: usize| -> Result<usize, CodecError> {
        if let Some(&(_, size)) = tried.iter().find(|(c, _)| *c == cut) {
            return Ok(size);
        }
        let size = match corrected_file(raster, &stream, &parts.mask, &payload[..cut], e, step)? {
            Some(file) => {
                let size = file.bytes.len();
                if best.as_ref().is_none_or(|b| size < b.bytes.len()) {
                    best = Some(file);
                }
                size
            }
            None => usize::MAX,
        };
        tried.push((cut, size));
        Ok(size)
    };
    search_cut(payload.len(), &mut evaluate)?;
    Ok(best)
}

/// Calls `evaluate` (the file size of a cut) on cuts of a payload of `payload_len`
/// bytes: a factor √2 apart, then a golden-section search around the best. (The
/// near-lossless stream bounds the useful range from above; a 9/7 prefix 32 times
/// smaller leaves too many samples to correct.)
fn search_cut(
    payload_len: usize,
    evaluate: &mut impl FnMut(usize) -> Result<usize, CodecError>,
) -> Result<(), CodecError> {
    let mut cuts: Vec<usize> = (0..11)
        .map(|k| (payload_len as f64 * 0.5f64.powf(k as f64 / 2.0)) as usize)
        .filter(|&c| c > 16)
        .collect();
    cuts.dedup();
    let mut sizes = Vec::new();
    for &cut in &cuts {
        sizes.push(evaluate(cut)?);
    }
    if let Some((k, _)) = sizes.iter().enumerate().min_by_key(|(_, &s)| s) {
        let (mut lo, mut hi) = (cuts[(k + 1).min(cuts.len() - 1)], cuts[k.saturating_sub(1)]);
        for _ in 0..5 {
            let a = lo + (hi - lo) / 3;
            let b = hi - (hi - lo) / 3;
            if evaluate(a)? <= evaluate(b)? {
                hi = b;
            } else {
                lo = a;
            }
        }
    }
    Ok(())
}

/// The step of the corrections for the bound `e`: `2⌊e⌋ + 1` for integers, just under
/// `2e` for floats.
pub(crate) fn correction_step(sample_type: SampleType, e: f64) -> f64 {
    if sample_type.is_integer() {
        2.0 * e.floor() + 1.0
    } else {
        2.0 * e * 0.999
    }
}

/// The file made of `stream`'s header and `mask`, `payload` (a prefix of `stream`'s),
/// and the corrections that bring every valid sample within `e`; `None` if some sample
/// cannot be corrected.
fn corrected_file(
    raster: &Raster,
    stream: &Encoded,
    mask: &[u8],
    payload: &[u8],
    e: f64,
    step: f64,
) -> Result<Option<Encoded>, CodecError> {
    let mut header = stream.header.clone();
    header.payload_truncated = true;
    header.passes.retain(|p| p.end_byte <= payload.len() as u64);
    header.correction_step = 0.0;
    let (file, _) = container::assemble(&mut header, mask, payload, &[]);
    let decoded = decode(&file, &DecodeOptions::default())?;
    drop(file);
    let Some(corrections) = corrections(raster, &decoded.raster, e, step) else {
        return Ok(None);
    };
    let correction_bytes = encode_residuals(&corrections, LengthContext::Coder(header.coder));
    header.correction_step = step;
    header.mode = Mode::MaxError;
    header.max_error = e;
    let (bytes, header_len) = container::assemble(&mut header, mask, payload, &correction_bytes);
    Ok(Some(Encoded {
        header_len,
        bytes,
        initial_error: stream.initial_error,
        header,
        checkpoints: Vec::new(),
    }))
}

/// The correction steps of every valid sample of `decoded` that bring it within `e` of
/// `raster`; `None` if some sample cannot be brought there.
fn corrections(raster: &Raster, decoded: &Raster, e: f64, step: f64) -> Option<Vec<i32>> {
    let (lo, hi) = raster.sample_type().value_range();
    let mut corrections = Vec::new();
    for i in 0..raster.len() {
        if !raster.is_valid(i) {
            continue;
        }
        let original = raster.samples.get_f64(i);
        let got = decoded.samples.get_f64(i);
        let mut k = 0.0;
        if (original - got).abs() > e {
            k = ((original - got) / step).round();
            let corrected = apply_correction(raster.sample_type(), got, k, step, lo, hi);
            if (original - corrected).abs() > e || k.abs() > i32::MAX as f64 {
                return None;
            }
        }
        corrections.push(k as i32);
    }
    Some(corrections)
}

/// A decoded sample moved by `k` correction steps, as the sample type stores it.
fn apply_correction(
    sample_type: SampleType,
    value: f64,
    k: f64,
    step: f64,
    lo: f64,
    hi: f64,
) -> f64 {
    let moved = value + k * step;
    if sample_type.is_integer() {
        moved.round().clamp(lo, hi)
    } else {
        moved as f32 as f64
    }
}

/// Adds `k · step` to every valid sample, `k` taken in order from `corrections` (the
/// decoder's side of [`encode_with_corrections`]).
pub(crate) fn apply_corrections(
    samples: &mut Samples,
    mask: Option<&BitSlice<u64, Lsb0>>,
    step: f64,
    corrections: &mut impl Iterator<Item = i32>,
) {
    fn each<T: Copy>(
        values: &mut [T],
        mask: Option<&BitSlice<u64, Lsb0>>,
        corrections: &mut impl Iterator<Item = i32>,
        mut apply: impl FnMut(T, f64) -> T,
    ) {
        for (i, v) in values.iter_mut().enumerate() {
            if mask.is_none_or(|m| m[i]) {
                let k = corrections.next().unwrap_or(0);
                if k != 0 {
                    *v = apply(*v, k as f64);
                }
            }
        }
    }
    let int = |v: f64, k: f64, lo: f64, hi: f64| (v + k * step).round().clamp(lo, hi);
    match samples {
        Samples::U8(v) => each(v, mask, corrections, |x, k| {
            int(x as f64, k, 0.0, 255.0) as u8
        }),
        Samples::U16(v) => each(v, mask, corrections, |x, k| {
            int(x as f64, k, 0.0, 65535.0) as u16
        }),
        Samples::I16(v) => each(v, mask, corrections, |x, k| {
            int(x as f64, k, -32768.0, 32767.0) as i16
        }),
        Samples::I32(v) => each(v, mask, corrections, |x, k| {
            int(x as f64, k, i32::MIN as f64, i32::MAX as f64) as i32
        }),
        Samples::F32(v) => each(v, mask, corrections, |x, k| (x as f64 + k * step) as f32),
    }
}
