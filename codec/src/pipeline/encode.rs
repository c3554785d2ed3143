//! Raster → `.ezw` bytes: one stream, or the smaller of the two ways to bound the error,
//! or a tiled file.

use crate::container::{self, Header, Mode};
use crate::corrections::encode_with_corrections;
use crate::error::CodecError;
use crate::ezw::{self, CoefficientLayout, EncodedPayload};
use crate::mask::encode_mask;
use crate::progress::{self, Stage};
use crate::quantize::{self, prepare_97, prepare_integer, FinestStep, Prepared, VoidCoefficients};
use crate::raster::{Raster, SampleType, Samples};
use crate::residual::{encode_residuals, exponents, LengthContext};
use crate::tiles::{lossless_may_fit, TileDetail, TileGrid, Window};
use crate::wavelet::{self, ShiftRule, Wavelet};

use super::options::{EncodeOptions, Quality};

/// How the encoder rounds the 5/3 subbands' norms to plane shifts.
pub(crate) const SHIFT_RULE: ShiftRule = ShiftRule::Lowered;

/// The result of encoding.
#[derive(Debug, Clone)]
#[non_exhaustive]
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
    /// Truncation points inside the passes (payload bytes, estimated squared error),
    /// for allocating a budget across tiles; not stored in the file.
    pub(crate) checkpoints: Vec<(u64, f64)>,
}

/// Encodes a raster into a `.ezw` file.
///
/// With [`Quality::MaxError`] and the 5/3 wavelet, two streams are made and the smaller
/// kept: the near-lossless one (samples quantised on `2⌊E⌋+1`, coded exactly) and a 9/7
/// stream cut where it is cheapest, followed by corrections for the samples its
/// reconstruction leaves more than E away.
///
/// A raster with a side longer than `options.tile_size` becomes a tiled file (see
/// [`crate::tiles`]).
pub fn encode(raster: &Raster, options: &EncodeOptions) -> Result<Encoded, CodecError> {
    if let Some(exact) = lossless_within_budget(raster, options)? {
        return Ok(exact);
    }
    if let Some(side) = options.code_block {
        if side == 0 || !side.is_multiple_of(64) {
            return Err(CodecError::InvalidParameters(format!(
                "code blocks of {side} samples: the side must be a multiple of 64"
            )));
        }
        let max_tile = options.tile_size.unwrap_or(u32::MAX) as usize;
        let side = side as usize;
        if let Some(grid) = crate::tiles::unit_grid(raster.width, raster.height, max_tile, side) {
            check_dimensions(raster)?;
            let options = options.wavelet_chosen_for(raster);
            return crate::tiles::encode_blocked(raster, &options, &grid, side);
        }
    }
    let grid = options
        .tile_size
        .and_then(|t| TileGrid::balanced(raster.width, raster.height, t as usize));
    if let Some(grid) = grid {
        check_dimensions(raster)?;
        let options = options.wavelet_chosen_for(raster);
        return crate::tiles::encode(raster, &options, &grid);
    }
    check_dimensions(raster)?;
    let options = &options.wavelet_chosen_for(raster);
    let (near_lossless, _) = encode_stream(raster, options)?;
    match (options.wavelet, options.quality, options.budget_bytes) {
        (wavelet, Quality::MaxError(e), None)
            if wavelet.is_reversible() && near_lossless.header.mode == Mode::MaxError =>
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

/// The lossless file of `raster`, when `options` let a budget encode write it instead of
/// a 9/7 one ([`EncodeOptions::lossless_alternative`]), the samples' detail (per tile, as
/// a streaming encode reads it) says the file may fit and it does.
fn lossless_within_budget(
    raster: &Raster,
    options: &EncodeOptions,
) -> Result<Option<Encoded>, CodecError> {
    let (Some(lossless), Some(budget)) = (options.lossless_alternative(), options.budget_bytes)
    else {
        return Ok(None);
    };
    check_dimensions(raster)?;
    let (width, height) = (raster.width, raster.height);
    let grid = options
        .tile_size
        .and_then(|t| TileGrid::balanced(width, height, t as usize));
    let windows = match grid {
        Some(grid) => (0..grid.count()).map(|k| grid.coded(k)).collect(),
        None => vec![Window::whole(width, height)],
    };
    let estimate: f64 = windows
        .iter()
        .map(|w| TileDetail::of(raster, w).lossless_estimate())
        .sum();
    if !lossless_may_fit(estimate, budget) {
        return Ok(None);
    }
    Ok(encode(raster, &lossless)
        .ok()
        .filter(|exact| exact.bytes.len() as u64 <= budget))
}

/// The sections of an encoded file before framing.
pub(crate) struct Parts {
    /// The coded nodata mask (empty without voids).
    pub mask: Vec<u8>,
    /// The payload as the file holds it (cut to the budget).
    pub payload: Vec<u8>,
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

/// The decomposition levels `requested` (the default when `None`), refused above what
/// the raster allows.
fn checked_levels(raster: &Raster, requested: Option<u32>) -> Result<u32, CodecError> {
    let (width, height) = (raster.width, raster.height);
    let max_levels = wavelet::max_levels(width, height);
    let levels = requested.unwrap_or_else(|| wavelet::default_levels(width, height));
    if levels > max_levels {
        return Err(CodecError::InvalidParameters(format!(
            "{levels} levels requested; a {width}x{height} raster allows at most {max_levels}"
        )));
    }
    Ok(levels)
}

/// Quantises and transforms the raster as `options.wavelet` codes it.
fn prepare(
    raster: &Raster,
    mask: &[bool],
    options: &EncodeOptions,
    norms: &[f64],
) -> Result<Prepared, CodecError> {
    if let Samples::F32(values) = &raster.samples {
        quantize::check_finite(values, mask, raster.width)?;
    }
    match options.wavelet {
        Wavelet::Int53 | Wavelet::Int1311 => prepare_integer(
            raster,
            mask,
            (options.wavelet, options.quality),
            norms,
            (VoidCoefficients::Zeroed, SHIFT_RULE),
        ),
        Wavelet::Cdf97 => {
            if options.quality != Quality::Lossless {
                return Err(CodecError::InvalidParameters(
                    "the 9/7 wavelet is lossy: error bounds need the 5/3 wavelet".into(),
                ));
            }
            let prepared = prepare_97(
                raster,
                mask,
                norms,
                (VoidCoefficients::Zeroed, FinestStep::ForTheSamples),
            );
            // Infinities, or finite samples whose transform overflows f32, leave no finite
            // mean or step for the header (the decoder would refuse the stream).
            if !(prepared.mapping.offset.is_finite() && prepared.coefficient_step.is_finite()) {
                return Err(CodecError::UnsupportedValues(
                    "the 9/7 wavelet needs samples whose transform stays finite in f32".into(),
                ));
            }
            Ok(prepared)
        }
    }
}

/// The coded nodata mask: empty without voids.
fn mask_section(mask: &[bool], width: usize, has_voids: bool) -> Vec<u8> {
    if !has_voids {
        return Vec::new();
    }
    let mut bytes = encode_mask(mask, width);
    if bytes.is_empty() {
        // A mask of nothing but voids codes to no bytes at all (trailing zeros are
        // dropped); one zero byte decodes the same and says that there is a mask.
        bytes.push(0);
    }
    bytes
}

/// Encodes one stream as `options` say (no choice between methods).
pub(crate) fn encode_stream(
    raster: &Raster,
    options: &EncodeOptions,
) -> Result<(Encoded, Parts), CodecError> {
    check_dimensions(raster)?;
    let levels = checked_levels(raster, options.levels)?;
    let plan = plan_stream(raster, options, levels)?;
    let (mut header, prepared) = (plan.header, plan.prepared);
    let layout = CoefficientLayout::new(
        raster.width,
        raster.height,
        &wavelet::subbands(raster.width, raster.height, levels),
        &prepared.shifts,
    );
    let mut sections = Sections {
        mask: plan.mask,
        payload: Vec::new(),
        residual: plan.residual,
    };
    let top = ezw::top_plane(&layout, &prepared.coefficients);
    header.top_plane = top.map(|t| t as u8);
    let steps = top.map_or(1, |t| u64::from(t) + 2);
    let samples = raster.len() as u64;
    progress::report(Stage::Transform, samples, samples * steps);
    let budget = options.budget_bytes.map(|b| b as usize);
    let payload = ezw::encode(
        &layout,
        &prepared.coefficients,
        top,
        &prepared.distortion_weights,
        prepared.midpoint,
        payload_budget(&header, sections.mask.len(), budget)?,
    );
    let initial_error = payload.initial_error;
    let mut checkpoints = payload.checkpoints.clone();
    fit_to_budget(&mut header, &mut sections, payload, budget);
    checkpoints.retain(|&(end, _)| end <= sections.payload.len() as u64);
    Ok(assemble(header, sections, (initial_error, checkpoints)))
}

/// A stream ready for its payload: its header (no top plane; the mask and residual
/// sections' lengths set), its prepared coefficients, and those two sections.
pub(crate) struct StreamPlan {
    pub header: Header,
    pub prepared: Prepared,
    pub mask: Vec<u8>,
    pub residual: Vec<u8>,
}

/// Quantises and transforms `raster` with `levels` levels as `options` say, and builds
/// the header and the sections besides the payload.
pub(crate) fn plan_stream(
    raster: &Raster,
    options: &EncodeOptions,
    levels: u32,
) -> Result<StreamPlan, CodecError> {
    let (width, height) = (raster.width, raster.height);
    let mask = raster.valid_mask();
    let has_voids = mask.iter().any(|&m| !m);
    let norms = wavelet::coding_norms(options.wavelet, width, height, levels);
    let prepared = prepare(raster, &mask, options, &norms)?;
    let mask_bytes = mask_section(&mask, width, has_voids);
    let residual = residual_section(raster, &mask, &prepared.residuals);
    let mut header = stream_header(raster, options.wavelet, levels, &prepared, &mask, has_voids);
    header.derived = container::DerivedMemo(container::DerivedBands::from_norms(&header, norms));
    header.mask_len = mask_bytes.len() as u32;
    header.residual_len = residual.len() as u32;
    header.residuals_by_exponent = !residual.is_empty();
    Ok(StreamPlan {
        header,
        prepared,
        mask: mask_bytes,
        residual,
    })
}

/// The file of `header` and `sections`, and the sections a corrected file reuses;
/// `estimates` are the payload's initial error and checkpoints.
fn assemble(
    mut header: Header,
    sections: Sections,
    (initial_error, checkpoints): (f64, Vec<(u64, f64)>),
) -> (Encoded, Parts) {
    let (bytes, header_len) = container::assemble(
        &mut header,
        &sections.mask,
        &sections.payload,
        &sections.residual,
    );
    let encoded = Encoded {
        header_len,
        bytes,
        header,
        initial_error,
        checkpoints,
    };
    let parts = Parts {
        mask: sections.mask,
        payload: sections.payload,
    };
    (encoded, parts)
}

/// The coded exact float residuals of the valid samples of `raster`, their lengths
/// modelled by the exponents of the samples' reconstructions: empty when there are none.
fn residual_section(raster: &Raster, mask: &[bool], residuals: &[i32]) -> Vec<u8> {
    let Samples::F32(values) = &raster.samples else {
        return Vec::new();
    };
    if residuals.is_empty() {
        return Vec::new();
    }
    let valid = values.iter().zip(mask).filter(|&(_, &m)| m);
    let reconstructed = valid
        .zip(residuals)
        .map(|((v, _), &r)| v.to_bits().wrapping_sub(r as u32));
    encode_residuals(
        residuals,
        LengthContext::Exponents(&exponents(reconstructed)),
    )
}

/// What a file of at most `budget` bytes leaves the payload: the budget less the
/// smallest possible file (header, framed mask, empty payload, empty ladder); refused
/// when not even that fits.
fn payload_budget(
    header: &Header,
    mask_len: usize,
    budget: Option<usize>,
) -> Result<Option<usize>, CodecError> {
    let fixed = container::assembled_len(header, mask_len, 0, 0);
    match budget {
        Some(total) if total < fixed => Err(CodecError::InvalidParameters(format!(
            "a budget of {total} bytes is smaller than the header and nodata mask ({fixed} bytes)"
        ))),
        _ => Ok(budget.map(|total| total - fixed)),
    }
}

/// The header of a stream of `prepared` coefficients, its sections still empty and
/// its top plane unset.
fn stream_header(
    raster: &Raster,
    wavelet: Wavelet,
    levels: u32,
    prepared: &Prepared,
    mask: &[bool],
    has_voids: bool,
) -> Header {
    let sample_type = raster.sample_type();
    let whole = Header::whole_raster(
        raster.width as u32,
        raster.height as u32,
        sample_type,
        wavelet,
        levels as u8,
        prepared.mode,
    );
    Header {
        mapping: prepared.mapping,
        max_error: prepared.max_error,
        coefficient_step: prepared.coefficient_step,
        nodata: raster
            .nodata
            .or((has_voids && sample_type == SampleType::F32).then_some(f64::NAN)),
        valid_range: quantize::valid_range(raster, mask).unwrap_or((0.0, 0.0)),
        // What `ezw::encode` codes with.
        coder: ezw::Coder::default(),
        shift_rule: match wavelet {
            Wavelet::Int53 | Wavelet::Int1311 => SHIFT_RULE,
            Wavelet::Cdf97 => ShiftRule::Rounded,
        },
        bands: prepared
            .shifts
            .iter()
            .zip(&prepared.scales)
            .map(|(&s, &c)| (s as u8, c))
            .collect(),
        georef: raster.georef.clone(),
        metadata: raster.metadata.clone(),
        ..whole
    }
}

/// The sections a stream's file holds after the header.
struct Sections {
    mask: Vec<u8>,
    payload: Vec<u8>,
    residual: Vec<u8>,
}

/// Puts `payload` into `sections`, cut (with the residuals dropped and the header made
/// lossy) when the encoder stopped early or the file would exceed `budget` bytes.
fn fit_to_budget(
    header: &mut Header,
    sections: &mut Sections,
    payload: EncodedPayload,
    budget: Option<usize>,
) {
    let mask_len = sections.mask.len();
    let file_len = |header: &Header, payload_len: usize, residual_len: usize| {
        container::assembled_len(header, mask_len, payload_len, residual_len)
    };
    header.passes = payload.passes.clone();
    let cut = !payload.complete
        || budget.is_some_and(|total| {
            file_len(header, payload.bytes.len(), sections.residual.len()) > total
        });
    sections.payload = payload.bytes;
    if !cut {
        return;
    }
    // Cut the payload so the whole file is exactly the budget. The ladder lists only
    // the passes the kept payload holds and framing adds 4 bytes a chunk, so the
    // size depends on the cut: iterate to the fixed point (it shrinks monotonically,
    // in a few steps).
    let total = budget.expect("only a budget cuts a stream");
    header.payload_truncated = true;
    sections.residual.clear();
    header.residuals_by_exponent = false;
    header.mode = Mode::Lossy;
    header.max_error = f64::INFINITY;
    let full_len = sections.payload.len();
    let mut keep = full_len;
    loop {
        header.passes = payload
            .passes
            .iter()
            .copied()
            .filter(|p| p.end_byte <= keep as u64)
            .collect();
        let over = file_len(header, keep, 0).saturating_sub(total);
        if over == 0 {
            // Dropping a pass record or a chunk checksum may leave a few bytes of
            // room: fill them (a pass they complete simply goes unlisted).
            while keep < full_len && file_len(header, keep + 1, 0) <= total {
                keep += 1;
            }
            break;
        }
        // `payload_budget` made sure an empty payload fits, so this terminates.
        keep = keep.saturating_sub(over);
    }
    sections.payload.truncate(keep);
}
