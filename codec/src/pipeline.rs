//! Whole-file encode and decode: raster → `.ezw` bytes → raster.

use crate::container::{check_frames, unframe, Header, Mode, Unframed, CHUNK};
use crate::entropy::ArithmeticDecoder;
use crate::error::CodecError;
use crate::ezw::{
    self, CoefficientLayout, ContextChoice, Decoder, Midpoint, MAX_COEFFICIENT_PLANE,
};
use crate::mask::{decode_mask, encode_mask, Mask};
use crate::progress::{self, Stage};
use crate::quantize::{self, IntegerPlane, ValueMapping};
use crate::raster::{Raster, SampleType, Samples};
use crate::residual::{decode_residuals, encode_residuals};
use crate::significance::SignificanceMap;
use crate::tiles::{ByteSource, TileGrid, TiledLayout, Window, DEFAULT_TILE};
use crate::wavelet::{self, Wavelet};
use bitvec::order::Lsb0;
use bitvec::slice::BitSlice;

/// What the encoder should achieve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Quality {
    /// Bit-exact (5/3) — or, with 9/7, as fine as the coefficient quantiser allows.
    Lossless,
    /// Every valid sample within this many data units (5/3).
    MaxError(f64),
    /// Floats quantised to this step (error ≤ step / 2) (5/3).
    Precision(f64),
}

/// Encoder settings.
#[derive(Debug, Clone, PartialEq)]
pub struct EncodeOptions {
    /// The transform; see [`EncodeOptions::new`] for the defaults.
    pub wavelet: Wavelet,
    /// Decomposition levels (`None`: [`wavelet::default_levels`]).
    pub levels: Option<u32>,
    /// Target quality of the complete stream.
    pub quality: Quality,
    /// Total file size to stop at, in bytes (a single stream is cut there exactly; a
    /// tiled file's tiles are cut where [`crate::tiles::allocate`] says, within it).
    pub budget_bytes: Option<u64>,
    /// Largest tile side: a raster with a longer side is coded as a tiled file (tiles
    /// as equal as the raster allows, see [`TileGrid::balanced`]); `None` codes one
    /// stream whatever the size.
    pub tile_size: Option<u32>,
    /// Threads coding tiles at once (0: one per core). The bytes do not depend on it.
    pub threads: usize,
}

impl EncodeOptions {
    /// Defaults as the command line has them: 9/7 when only a byte budget is given,
    /// 5/3 for lossless and error-bounded coding.
    pub fn new(quality: Quality, budget_bytes: Option<u64>) -> EncodeOptions {
        let wavelet = match (quality, budget_bytes) {
            (Quality::Lossless, Some(_)) => Wavelet::Cdf97,
            _ => Wavelet::Int53,
        };
        EncodeOptions {
            wavelet,
            levels: None,
            quality,
            budget_bytes,
            tile_size: Some(DEFAULT_TILE),
            threads: 0,
        }
    }

    /// The same options coding one stream whatever the raster's size: what the decoder's
    /// significance map, and so the zerotree mesher, needs.
    pub fn single_stream(self) -> EncodeOptions {
        EncodeOptions {
            tile_size: None,
            ..self
        }
    }
}

/// The result of encoding.
#[derive(Debug, Clone)]
pub struct Encoded {
    /// The complete `.ezw` file.
    pub bytes: Vec<u8>,
    /// Its header.
    pub header: Header,
    /// Bytes taken by the header.
    pub header_len: usize,
    /// Estimated sum of squared errors of a decode of no pass (the start of the
    /// rate–distortion ladder).
    pub initial_error: f64,
}

/// Encodes a raster into a `.ezw` file.
///
/// With [`Quality::MaxError`] and the 5/3 wavelet, two streams are made and the smaller
/// kept: the near-lossless one (samples quantised on `2⌊E⌋+1`, coded exactly) and a 9/7
/// stream cut where it is cheapest, followed by corrections for the samples its
/// reconstruction leaves more than E away (see [`encode_with_corrections`]).
///
/// A raster with a side longer than `options.tile_size` becomes a tiled file (see
/// [`crate::tiles`]).
pub fn encode(raster: &Raster, options: &EncodeOptions) -> Result<Encoded, CodecError> {
    let grid = options
        .tile_size
        .and_then(|t| TileGrid::balanced(raster.width, raster.height, t as usize));
    if let Some(grid) = grid {
        check_dimensions(raster)?;
        return crate::tiles::encode(raster, options, &grid);
    }
    let (near_lossless, _) = encode_stream(raster, options)?;
    match (options.wavelet, options.quality, options.budget_bytes) {
        (Wavelet::Int53, Quality::MaxError(e), None)
            if near_lossless.header.mode == Mode::MaxError =>
        {
            match encode_with_corrections(raster, options.levels, e, near_lossless.bytes.len())? {
                Some(corrected) if corrected.bytes.len() < near_lossless.bytes.len() => {
                    Ok(corrected)
                }
                _ => Ok(near_lossless),
            }
        }
        _ => Ok(near_lossless),
    }
}

/// Error-bounded coding by a cut 9/7 stream plus corrections: every valid sample whose
/// reconstruction misses by more than `e` gets `k` steps of `2⌊e⌋+1` (integers) or just
/// under `2e` (floats) added, `k` coded like float residuals. The cut is searched for the
/// smallest total size, below `limit` bytes; `None` if nothing smaller was found.
pub fn encode_with_corrections(
    raster: &Raster,
    levels: Option<u32>,
    e: f64,
    limit: usize,
) -> Result<Option<Encoded>, CodecError> {
    let options = EncodeOptions {
        wavelet: Wavelet::Cdf97,
        levels,
        quality: Quality::Lossless,
        budget_bytes: Some(limit as u64),
        tile_size: None,
        threads: 1,
    };
    let Ok((stream, parts)) = encode_stream(raster, &options) else {
        return Ok(None);
    };
    let step = if raster.sample_type().is_integer() {
        2.0 * e.floor() + 1.0
    } else {
        2.0 * e * 0.999
    };
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
    // Coarse: cuts a factor √2 apart; then a golden-section search around the best.
    // (The near-lossless stream bounds the useful range from above; a 9/7 prefix 32 times
    // smaller leaves too many samples to correct.)
    let mut cuts: Vec<usize> = (0..11)
        .map(|k| (payload.len() as f64 * 0.5f64.powf(k as f64 / 2.0)) as usize)
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
    Ok(best)
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
    let (file, _) = crate::container::assemble(&mut header, mask, payload, &[]);
    let decoded = decode(&file, &DecodeOptions::default())?;
    drop(file);
    let (lo, hi) = raster.sample_type().value_range();
    let mut corrections = Vec::new();
    for i in 0..raster.len() {
        if !raster.is_valid(i) {
            continue;
        }
        let original = raster.samples.get_f64(i);
        let got = decoded.raster.samples.get_f64(i);
        let mut k = 0.0;
        if (original - got).abs() > e {
            k = ((original - got) / step).round();
            let corrected = apply_correction(raster.sample_type(), got, k, step, lo, hi);
            if (original - corrected).abs() > e || k.abs() > i32::MAX as f64 {
                return Ok(None);
            }
        }
        corrections.push(k as i32);
    }
    let correction_bytes = encode_residuals(&corrections);
    header.correction_step = step;
    header.mode = Mode::MaxError;
    header.max_error = e;
    let (bytes, header_len) =
        crate::container::assemble(&mut header, mask, payload, &correction_bytes);
    Ok(Some(Encoded {
        header_len,
        bytes,
        initial_error: stream.initial_error,
        header,
    }))
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

/// The sections of an encoded file before framing.
struct Parts {
    mask: Vec<u8>,
    payload: Vec<u8>,
}

/// Refuses a raster without samples, whose sample count is not its size, or with a side
/// of 2^32 or more.
fn check_dimensions(raster: &Raster) -> Result<(), CodecError> {
    let (width, height) = (raster.width, raster.height);
    if width == 0
        || height == 0
        || raster.samples.len() != width * height
        || width > u32::MAX as usize
        || height > u32::MAX as usize
    {
        return Err(CodecError::Dimensions {
            width: width as u64,
            height: height as u64,
        });
    }
    Ok(())
}

/// Encodes one stream as `options` say (no choice between methods).
fn encode_stream(raster: &Raster, options: &EncodeOptions) -> Result<(Encoded, Parts), CodecError> {
    check_dimensions(raster)?;
    let (width, height) = (raster.width, raster.height);
    let max_levels = wavelet::max_levels(width, height);
    let levels = options
        .levels
        .unwrap_or_else(|| wavelet::default_levels(width, height));
    if levels > max_levels {
        return Err(CodecError::InvalidParameters(format!(
            "{levels} levels requested; a {width}x{height} raster allows at most {max_levels}"
        )));
    }
    let mask = raster.valid_mask();
    let has_voids = mask.iter().any(|&m| !m);
    let valid_range = quantize::valid_range(raster, &mask).unwrap_or((0.0, 0.0));
    let subbands = wavelet::subbands(width, height, levels);
    let norms = wavelet::coding_norms(options.wavelet, width, height, levels);

    if let Samples::F32(values) = &raster.samples {
        quantize::check_finite(values, &mask, width)?;
    }
    let prepared = match options.wavelet {
        Wavelet::Int53 => prepare_53(raster, &mask, options.quality, &norms)?,
        Wavelet::Cdf97 => {
            if options.quality != Quality::Lossless {
                return Err(CodecError::InvalidParameters(
                    "the 9/7 wavelet is lossy: error bounds need the 5/3 wavelet".into(),
                ));
            }
            let prepared = prepare_97(raster, &mask, &norms);
            // Infinities, or finite samples whose transform overflows f32, leave no finite
            // mean or step for the header (the decoder would refuse the stream).
            if !(prepared.mapping.offset.is_finite() && prepared.coefficient_step.is_finite()) {
                return Err(CodecError::UnsupportedValues(
                    "the 9/7 wavelet needs samples whose transform stays finite in f32".into(),
                ));
            }
            prepared
        }
    };
    let layout = CoefficientLayout::new(width, height, &subbands, &prepared.shifts);
    let mask_bytes = if has_voids {
        let mut bytes = encode_mask(&mask, width);
        if bytes.is_empty() {
            // A mask of nothing but voids codes to no bytes at all (trailing zeros are
            // dropped); one zero byte decodes the same and says that there is a mask.
            bytes.push(0);
        }
        bytes
    } else {
        Vec::new()
    };
    let residual_bytes = if prepared.residuals.is_empty() {
        Vec::new()
    } else {
        encode_residuals(&prepared.residuals)
    };

    let top = ezw::top_plane(&layout, &prepared.coefficients);
    let steps = top.map_or(1, |t| u64::from(t) + 2);
    let samples = (width * height) as u64;
    progress::report(Stage::Transform, samples, samples * steps);
    let mut header = Header {
        width: width as u32,
        height: height as u32,
        sample_type: raster.sample_type(),
        wavelet: options.wavelet,
        levels: levels as u8,
        mode: prepared.mode,
        mapping: prepared.mapping,
        max_error: prepared.max_error,
        coefficient_step: prepared.coefficient_step,
        nodata: raster
            .nodata
            .or((has_voids && raster.sample_type() == SampleType::F32).then_some(f64::NAN)),
        valid_range,
        top_plane: top.map(|t| t as u8),
        // What `ezw::encode` codes with.
        coder: ezw::Coder::default(),
        bands: prepared
            .shifts
            .iter()
            .zip(&prepared.scales)
            .map(|(&s, &c)| (s as u8, c))
            .collect(),
        payload_len: 0,
        payload_truncated: false,
        mask_len: mask_bytes.len() as u32,
        residual_len: residual_bytes.len() as u32,
        correction_step: 0.0,
        ladder_len: 0,
        passes: Vec::new(),
        georef: raster.georef.clone(),
        metadata: raster.metadata.clone(),
        tiling: None,
    };
    // With a budget, the payload may use what the smallest possible header leaves.
    let budget = options.budget_bytes.map(|b| b as usize);
    // The smallest file there is: header, framed mask, empty payload, empty ladder.
    let fixed = crate::container::assembled_len(&header, mask_bytes.len(), 0, 0);
    if let Some(total) = budget {
        if total < fixed {
            return Err(CodecError::InvalidParameters(format!(
                "a budget of {total} bytes is smaller than the header and nodata mask ({fixed} bytes)"
            )));
        }
    }
    let payload = ezw::encode(
        &layout,
        &prepared.coefficients,
        &prepared.distortion_weights,
        prepared.midpoint,
        budget.map(|total| total - fixed),
    );
    let payload_initial_error = payload.initial_error;
    let mut payload_bytes = payload.bytes;
    // File: header | mask | payload | residuals | ladder (sections framed).
    let file_len = |header: &Header, payload_len: usize, residual_len: usize| {
        crate::container::assembled_len(header, mask_bytes.len(), payload_len, residual_len)
    };
    header.passes = payload.passes.clone();
    let cut = !payload.complete
        || budget.is_some_and(|total| {
            file_len(&header, payload_bytes.len(), residual_bytes.len()) > total
        });
    let mut residual_bytes = residual_bytes;
    if cut {
        // Cut the payload so the whole file is exactly the budget. The ladder lists only
        // the passes the kept payload holds and framing adds 4 bytes a chunk, so the
        // size depends on the cut: iterate to the fixed point (it shrinks monotonically,
        // in a few steps).
        let total = budget.expect("only a budget cuts a stream");
        header.payload_truncated = true;
        residual_bytes.clear();
        header.mode = Mode::Lossy;
        header.max_error = f64::INFINITY;
        let mut keep = payload_bytes.len();
        loop {
            header.passes = payload
                .passes
                .iter()
                .copied()
                .filter(|p| p.end_byte <= keep as u64)
                .collect();
            let over = file_len(&header, keep, 0).saturating_sub(total);
            if over == 0 {
                // Dropping a pass record or a chunk checksum may leave a few bytes of
                // room: fill them (a pass they complete simply goes unlisted).
                while keep < payload_bytes.len() && file_len(&header, keep + 1, 0) <= total {
                    keep += 1;
                }
                break;
            }
            // `fixed <= total` guarantees an empty payload fits, so this terminates.
            keep = keep.saturating_sub(over);
        }
        payload_bytes.truncate(keep);
    }
    let (bytes, header_len) =
        crate::container::assemble(&mut header, &mask_bytes, &payload_bytes, &residual_bytes);
    Ok((
        Encoded {
            header_len,
            bytes,
            header,
            initial_error: payload_initial_error,
        },
        Parts {
            mask: mask_bytes,
            payload: payload_bytes,
        },
    ))
}

/// What each context buys on `raster`'s lossless 5/3 coefficients: the ideal code length
/// (bits) with every context, with each one removed in turn, and with none.
pub fn context_ablation(raster: &Raster) -> Result<Vec<(&'static str, f64)>, CodecError> {
    let (width, height) = (raster.width, raster.height);
    let levels = wavelet::default_levels(width, height);
    let norms = wavelet::coding_norms(Wavelet::Int53, width, height, levels);
    let mask = raster.valid_mask();
    let prepared = prepare_53(raster, &mask, Quality::Lossless, &norms)?;
    let subbands = wavelet::subbands(width, height, levels);
    let layout = CoefficientLayout::new(width, height, &subbands, &prepared.shifts);
    let all = ContextChoice::ALL;
    let choices = [
        ("all contexts", all),
        (
            "without subband class",
            ContextChoice {
                subband_class: false,
                ..all
            },
        ),
        (
            "without neighbours",
            ContextChoice {
                neighbours: false,
                ..all
            },
        ),
        (
            "without parent",
            ContextChoice {
                parent: false,
                ..all
            },
        ),
        (
            "without neighbour signs",
            ContextChoice {
                neighbour_signs: false,
                ..all
            },
        ),
        (
            "without refinement age",
            ContextChoice {
                refinement_age: false,
                ..all
            },
        ),
        ("no contexts", ContextChoice::NONE),
    ];
    Ok(choices
        .into_iter()
        .map(|(name, choice)| {
            (
                name,
                ezw::count_bits(&layout, &prepared.coefficients, choice),
            )
        })
        .collect())
}

/// Adds to `tally` the first decisions of every context model in `raster`'s complete
/// stream with `wavelet` (lossless 5/3, or 9/7 at its finest step): the training of
/// coder 3's starting probabilities (see [`ezw::PriorTally`]).
pub fn tally_priors(
    raster: &Raster,
    wavelet: Wavelet,
    tally: &mut ezw::PriorTally,
) -> Result<(), CodecError> {
    let (width, height) = (raster.width, raster.height);
    let levels = wavelet::default_levels(width, height);
    let norms = wavelet::coding_norms(wavelet, width, height, levels);
    let mask = raster.valid_mask();
    let prepared = match wavelet {
        Wavelet::Int53 => prepare_53(raster, &mask, Quality::Lossless, &norms)?,
        Wavelet::Cdf97 => prepare_97(raster, &mask, &norms),
    };
    let subbands = wavelet::subbands(width, height, levels);
    let layout = CoefficientLayout::new(width, height, &subbands, &prepared.shifts);
    ezw::tally_priors(&layout, &prepared.coefficients, tally);
    Ok(())
}

/// Coefficients and parameters ready for the EZW coder.
struct Prepared {
    coefficients: Vec<i32>,
    shifts: Vec<u32>,
    scales: Vec<f64>,
    distortion_weights: Vec<f64>,
    midpoint: Midpoint,
    mapping: ValueMapping,
    mode: Mode,
    max_error: f64,
    coefficient_step: f64,
    residuals: Vec<i32>,
}

fn prepare_53(
    raster: &Raster,
    mask: &[bool],
    quality: Quality,
    norms: &[f64],
) -> Result<Prepared, CodecError> {
    let (width, height) = (raster.width, raster.height);
    let (plane, mode, max_error) = match (&raster.samples, quality) {
        (Samples::F32(values), Quality::Lossless) => {
            match quantize::detect_float_grid(values, mask) {
                Some(step) => (quantize::float_plane(values, mask, step, false, 0.0)?, Mode::Lossless, 0.0),
                None => {
                    let (lo, hi) = quantize::valid_range(raster, mask).unwrap_or((0.0, 0.0));
                    let step = quantize::default_float_step(lo, hi);
                    (quantize::float_plane(values, mask, step, true, 0.0)?, Mode::Lossless, 0.0)
                }
            }
        }
        (Samples::F32(values), Quality::MaxError(e)) => {
            check_positive(e, "the max error")?;
            (bounded_float_plane(values, mask, e)?, Mode::MaxError, e)
        }
        (Samples::F32(values), Quality::Precision(step)) => {
            check_positive(step, "the precision")?;
            // The grid's half step, plus the rounding of the reconstruction to f32.
            let largest = values.iter().zip(mask).filter(|(_, &m)| m).map(|(v, _)| v.abs() as f64).fold(0.0, f64::max);
            let bound = step / 2.0 + largest * f32::EPSILON as f64;
            (quantize::float_plane(values, mask, step, false, bound)?, Mode::Precision, bound)
        }
        (_, Quality::Lossless) => (quantize::integer_plane(raster, mask, 0.0)?, Mode::Lossless, 0.0),
        (_, Quality::MaxError(e)) => {
            check_positive(e, "the max error")?;
            let plane = quantize::integer_plane(raster, mask, e)?;
            let mode = if e >= 1.0 { Mode::MaxError } else { Mode::Lossless };
            (plane, mode, e.floor())
        }
        (_, Quality::Precision(_)) => {
            return Err(CodecError::InvalidParameters(
                "a precision applies to float rasters; integer rasters are coded exactly or with a max error".into(),
            ))
        }
    };
    let IntegerPlane {
        mut values,
        mapping,
        residuals,
    } = plane;
    if mask.iter().any(|&m| !m) {
        let mut filled: Vec<f64> = values.iter().map(|&v| v as f64).collect();
        quantize::fill_voids(&mut filled, width, height, mask);
        for (v, f) in values.iter_mut().zip(filled) {
            *v = f.round() as i32;
        }
    }
    let levels = level_count(norms.len());
    wavelet::forward_53(&mut values, width, height, levels);
    // Shift each subband by its synthesis norm relative to the smallest, in whole planes.
    let shifts = wavelet::plane_shifts(norms);
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

fn prepare_97(raster: &Raster, mask: &[bool], norms: &[f64]) -> Prepared {
    let (width, height) = (raster.width, raster.height);
    let valid = mask.iter().filter(|&&m| m).count().max(1);
    let mean = (0..raster.len())
        .filter(|&i| mask[i])
        .map(|i| raster.samples.get_f64(i))
        .sum::<f64>()
        / valid as f64;
    // Any offset works: a whole number (integers) or an f32 (floats) is shorter to store.
    let mean = if raster.sample_type().is_integer() {
        mean.round()
    } else {
        f64::from(mean as f32)
    };
    let mut centred: Vec<f64> = (0..raster.len())
        .map(|i| {
            if mask[i] {
                raster.samples.get_f64(i) - mean
            } else {
                0.0
            }
        })
        .collect();
    quantize::fill_voids(&mut centred, width, height, mask);
    let mut data: Vec<f32> = centred.iter().map(|&v| v as f32).collect();
    drop(centred);
    let levels = level_count(norms.len());
    wavelet::forward_97(&mut data, width, height, levels);
    // Scale every subband by its norm so one quantiser step means the same pixel error
    // everywhere, then quantise finely enough that the cut, not the quantiser, limits
    // the quality: the largest scaled coefficient gets 30 bits.
    let subbands = wavelet::subbands(width, height, levels);
    // The header stores the scales in 1/8192 units: quantise with exactly those values.
    let norms: Vec<f64> = norms
        .iter()
        .map(|&n| crate::container::scale_from_u16(crate::container::scale_to_u16(n)))
        .collect();
    let mut largest = 0f64;
    for (sub, &norm) in subbands.iter().zip(&norms) {
        for y in 0..sub.height {
            let row = (sub.y0 + y) * width + sub.x0;
            for &c in &data[row..row + sub.width] {
                largest = largest.max((c as f64 * norm).abs());
            }
        }
    }
    let step = if largest > 0.0 {
        // Rounded up to an f32, which the header stores in 4 bytes instead of 8.
        let step = largest / (1u64 << MAX_COEFFICIENT_PLANE) as f64 * 1.0001;
        let rounded = f64::from(step as f32);
        if rounded >= step {
            rounded
        } else {
            f64::from(f32::from_bits((step as f32).to_bits() + 1))
        }
    } else {
        1.0
    };
    let mut coefficients = vec![0i32; data.len()];
    for (sub, &norm) in subbands.iter().zip(&norms) {
        let scale = norm / step;
        for y in 0..sub.height {
            let row = (sub.y0 + y) * width + sub.x0;
            for x in row..row + sub.width {
                let q = (data[x] as f64 * scale).abs().floor() as i32;
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

/// Quantises floats so every sample stays within `e` after rounding back to f32: the grid
/// step starts just under `2e` and shrinks until the check passes.
fn bounded_float_plane(values: &[f32], mask: &[bool], e: f64) -> Result<IntegerPlane, CodecError> {
    let mut step = 2.0 * e * 0.999;
    let mut last_error = None;
    for _ in 0..8 {
        match quantize::float_plane(values, mask, step, false, e) {
            Ok(plane) => return Ok(plane),
            Err(err) => last_error = Some(err),
        }
        step *= 0.75;
    }
    Err(last_error.expect("at least one attempt"))
}

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

/// Resource limits checked before the decoder allocates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest `width × height` accepted.
    pub max_samples: u64,
    /// Largest working memory (bytes) the decode may need.
    pub max_memory: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_samples: 1 << 31,
            max_memory: 2 << 30,
        }
    }
}

/// Decoder settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DecodeOptions {
    /// Decode only the first this many bytes of the file (progressive decoding).
    pub max_bytes: Option<u64>,
    /// Stop after this many passes.
    pub max_passes: Option<u32>,
    /// Resource limits.
    pub limits: Limits,
    /// Treat any damage (a failed chunk checksum, trailing garbage) as an error instead of
    /// decoding the undamaged prefix.
    pub strict: bool,
    /// Also return the per-node significance map ([`Decoded::significance`]; single
    /// streams only).
    pub significance_map: bool,
    /// Threads decoding tiles at once (0: one per core).
    pub threads: usize,
}

/// A decoded stream.
#[derive(Debug, Clone)]
pub struct Decoded {
    /// The reconstructed raster, with the source's type, nodata and georeferencing.
    pub raster: Raster,
    /// The file's header.
    pub header: Header,
    /// Passes decoded completely.
    pub passes_decoded: u32,
    /// Whether every bit of the stream was decoded (the mode's guarantee holds).
    pub complete: bool,
    /// File bytes the decode used.
    pub bytes_used: u64,
    /// Where the file is damaged, if it is (the decode used only what precedes it).
    pub damage: Option<Damage>,
    /// The decoder's per-node significance map, when [`DecodeOptions::significance_map`]
    /// asked for it.
    pub significance: Option<SignificanceMap>,
}

/// The first damaged place of a file: a chunk whose checksum fails, or trailing garbage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Damage {
    /// Which section: "payload", "residual section", "ladder" or "trailing bytes".
    pub section: &'static str,
    /// File offset where the damage starts.
    pub offset: u64,
    /// The damaged tile of a tiled file, by index (row-major).
    pub tile: Option<u32>,
}

/// Builds output samples from reconstructed values, in place where the output type is no
/// wider than the input: integers are rounded and clamped to the type's range, floats
/// narrowed with `as f32`; where `mask` is false the sample is `nodata` (NaN if none, or
/// if an f32 raster's nodata has no f32 value: its voids were NaN, and `nodata as f32`
/// would be some other, valid value).
fn to_samples<X: Copy>(
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

/// Adds `k · step` to every valid sample, `k` taken in order from `corrections`.
fn apply_corrections(
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

/// Decodes `window` of a `.ezw` file (all of it when `None`) read from `source`, fetching
/// only the bytes needed: of a tiled file the header, the index and the tiles the window
/// touches (each cut as [`decode`] cuts it under `options.max_bytes`); of a single stream
/// the whole file (or its `max_bytes` prefix), decoded and cropped.
pub fn decode_window(
    source: &mut impl ByteSource,
    window: Option<Window>,
    options: &DecodeOptions,
) -> Result<Decoded, CodecError> {
    if let Some(layout) = TiledLayout::read(source, index_limit(options))? {
        return crate::tiles::decode_layout(source, &layout, window, options);
    }
    let data = source
        .read_at(0, options.max_bytes.map_or(usize::MAX, |b| b as usize))
        .map_err(|e| CodecError::Read(e.to_string()))?;
    let mut decoded = decode(&data, options)?;
    if let Some(w) = window {
        let raster = &decoded.raster;
        let whole = Window {
            x: 0,
            y: 0,
            width: raster.width,
            height: raster.height,
        };
        if w.intersection(&whole) != Some(w) {
            return Err(CodecError::InvalidParameters(format!(
                "window {}x{} at ({}, {}) is not inside the {}x{} raster",
                w.width, w.height, w.x, w.y, whole.width, whole.height
            )));
        }
        let mut part = raster.crop(w.x, w.y, w.width, w.height);
        part.metadata = raster.metadata.clone();
        part.georef = raster.georef.clone().map(|mut georef| {
            let gt = &mut georef.geotransform;
            gt[0] += w.x as f64 * gt[1] + w.y as f64 * gt[2];
            gt[3] += w.x as f64 * gt[4] + w.y as f64 * gt[5];
            georef
        });
        decoded.raster = part;
    }
    Ok(decoded)
}

/// Largest tile index a decode reads: a quarter of its memory limit.
fn index_limit(options: &DecodeOptions) -> u64 {
    options.limits.max_memory / 4
}

/// Working memory a decode needs, in bytes (used for the limit check).
pub fn decode_memory(header: &Header) -> u64 {
    let n = header.sample_count();
    // coefficients (4, reused for the output) + flags (1) + mask (1 when present).
    n * (5 + (header.mask_len > 0) as u64)
}

/// Decodes a `.ezw` file, or as much of it as `options.max_bytes` (or the data) holds:
/// a prefix of a single stream, or of a tiled file the prefix of each tile that
/// [`crate::tiles::allocate`] gives it under that budget.
pub fn decode(mut data: &[u8], options: &DecodeOptions) -> Result<Decoded, CodecError> {
    if let Some(layout) = TiledLayout::read(&mut data, index_limit(options))? {
        if options.significance_map {
            return Err(CodecError::InvalidParameters(
                "significance maps come from single-stream files, not tiled ones".into(),
            ));
        }
        return crate::tiles::decode_layout(&mut data, &layout, None, options);
    }
    let data = match options.max_bytes {
        Some(limit) if (limit as usize) < data.len() => &data[..limit as usize],
        _ => data,
    };
    let (header, header_len) = Header::parse(data)?;
    let n = header.sample_count();
    if n > options.limits.max_samples {
        return Err(CodecError::LimitExceeded {
            what: "sample count",
            needed: n,
            limit: options.limits.max_samples,
        });
    }
    let memory = decode_memory(&header);
    if memory > options.limits.max_memory {
        return Err(CodecError::LimitExceeded {
            what: "decoder memory",
            needed: memory,
            limit: options.limits.max_memory,
        });
    }
    let (width, height) = (header.width as usize, header.height as usize);
    let n = n as usize;
    // Sections: header | mask | payload | residuals | ladder, each framed in
    // checksummed chunks. Damage is the first chunk whose checksum fails, or bytes past
    // the end of the file the header describes.
    let section = |start: usize, len: usize| -> Unframed {
        unframe(data.get(start.min(data.len())..).unwrap_or(&[]), len)
    };
    let mut damage: Option<Damage> = None;
    let mut note_damage = |what: &'static str, offset: usize| {
        if damage.is_none_or(|d| (offset as u64) < d.offset) {
            damage = Some(Damage {
                section: what,
                offset: offset as u64,
                tile: None,
            });
        }
    };
    let mask_start = header_len;
    let payload_start = mask_start + header.mask_len as usize;
    let residual_start = payload_start + header.payload_len as usize;
    let ladder_start = residual_start + header.residual_len as usize;
    let mask = if header.mask_len > 0 {
        let framed = section(mask_start, header.mask_len as usize);
        if let Some(at) = framed.damaged_at {
            return Err(CodecError::Damaged {
                section: "nodata mask",
                offset: (mask_start + at) as u64,
            });
        }
        if !framed.complete {
            return Err(CodecError::TruncatedHeader(
                "file ends inside the nodata mask",
            ));
        }
        Some(decode_mask(&framed.bytes, width, n))
    } else {
        None
    };
    // The payload is read in place (no copy): its checksums are checked first.
    let payload_framed = data.get(payload_start.min(data.len())..).unwrap_or(&[]);
    let payload_check = check_frames(payload_framed, header.payload_len as usize);
    if let Some(at) = payload_check.damaged_at {
        note_damage("payload", payload_start + at);
    }
    // All of the payload the encoder wrote is here, undamaged...
    let payload_present = payload_check.complete;
    // ... and it is a whole stream, not a prefix: its padding is genuine.
    let payload_complete = payload_present && !header.payload_truncated;
    let residual_framed = section(residual_start, header.residual_len as usize);
    if let Some(at) = residual_framed.damaged_at {
        note_damage("residual section", residual_start + at);
    }
    let ladder_framed = section(ladder_start, header.ladder_len as usize);
    if let Some(at) = ladder_framed.damaged_at {
        note_damage("ladder", ladder_start + at);
    }
    let file_end = ladder_start + header.ladder_len as usize;
    if data.len() > file_end && options.max_bytes.is_none_or(|m| m as usize > file_end) {
        note_damage("trailing bytes", file_end);
    }
    if let (true, Some(d)) = (options.strict, damage) {
        return Err(CodecError::Damaged {
            section: d.section,
            offset: d.offset,
        });
    }
    let levels = header.levels as u32;
    let subbands = wavelet::subbands(width, height, levels);
    let shifts: Vec<u32> = header.bands.iter().map(|&(s, _)| s as u32).collect();
    let layout = CoefficientLayout::new(width, height, &subbands, &shifts);
    let source = ArithmeticDecoder::new_framed(
        payload_framed,
        payload_check.data_len,
        CHUNK,
        4,
        payload_complete,
    );
    let decoder = Decoder::run_from(
        &layout,
        header.coder,
        source,
        header.top_plane.map(u32::from),
        options.max_passes,
    );
    let significance = options
        .significance_map
        .then(|| decoder.significance(&layout));
    let payload_data_len = payload_check.data_len;
    let passes_decoded = decoder.passes_completed;
    let ezw_complete = decoder.complete && payload_complete;
    // Reconstruct in place: the coefficient buffer becomes the image, then the samples,
    // so the decode holds at most the coefficients (4 bytes a sample) and the output.
    let mapping = header.mapping;
    let nodata = header.nodata;
    let mask_ref = mask.as_ref().map(Mask::as_bitslice);
    let mut samples = match header.wavelet {
        Wavelet::Int53 => {
            let mut coefficients = decoder.integer_coefficients();
            wavelet::inverse_53(&mut coefficients, width, height, levels);
            to_samples(
                header.sample_type,
                coefficients,
                |q| mapping.value(q as f64),
                mask_ref,
                nodata,
            )
        }
        Wavelet::Cdf97 => {
            let mut data = decoder.into_real_coefficients();
            for (sub, &(_, band_scale)) in subbands.iter().zip(&header.bands) {
                let scale = (header.coefficient_step / band_scale) as f32;
                for y in 0..sub.height {
                    let row = (sub.y0 + y) * width + sub.x0;
                    data[row..row + sub.width]
                        .iter_mut()
                        .for_each(|c| *c *= scale);
                }
            }
            wavelet::inverse_97(&mut data, width, height, levels);
            to_samples(
                header.sample_type,
                data,
                |x| mapping.value(x as f64),
                mask_ref,
                nodata,
            )
        }
    };
    progress::report(Stage::Transform, 1, 1);
    // The residual section: exact float residuals once the whole stream is decoded, or
    // max-error corrections once the whole (cut) payload is.
    let residual_bytes = residual_framed
        .complete
        .then_some(&residual_framed.bytes[..]);
    let valid_count = || mask_ref.map_or(n, |m| m.count_ones());
    let residuals_complete = match residual_bytes {
        _ if header.residual_len == 0 => true,
        Some(bytes) if header.correction_step > 0.0 && payload_present => {
            let mut corrections = decode_residuals(bytes, valid_count()).into_iter();
            apply_corrections(
                &mut samples,
                mask_ref,
                header.correction_step,
                &mut corrections,
            );
            true
        }
        Some(bytes) if ezw_complete => match &mut samples {
            Samples::F32(floats) => {
                let mut residuals = decode_residuals(bytes, valid_count()).into_iter();
                for (i, value) in floats.iter_mut().enumerate() {
                    if mask_ref.is_none_or(|m| m[i]) {
                        let r = residuals.next().unwrap_or(0);
                        *value = f32::from_bits(value.to_bits().wrapping_add(r as u32));
                    }
                }
                true
            }
            _ => false,
        },
        _ => false,
    };
    let mut raster = Raster::new(width, height, samples)?;
    raster.nodata = header.nodata;
    raster.georef = header.georef.clone();
    raster.metadata = header.metadata.clone();
    let bytes_used = (if residuals_complete && header.residual_len > 0 {
        ladder_start
    } else {
        payload_start + crate::container::physical_offset(payload_data_len as u64) as usize
    })
    .min(data.len()) as u64;
    Ok(Decoded {
        raster,
        passes_decoded,
        complete: payload_present
            && (ezw_complete || header.payload_truncated)
            && residuals_complete,
        damage,
        bytes_used,
        header,
        significance,
    })
}
