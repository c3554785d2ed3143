//! `.ezw` bytes → raster: a single stream decoded from any prefix, a tiled file by
//! the tiles it needs, a window cut out of either.

use crate::container::{physical_offset, Header, StreamSections, CHUNK};
use crate::corrections::apply_corrections;
use crate::entropy::ArithmeticDecoder;
use crate::error::CodecError;
use crate::ezw::{is_escape, CoefficientLayout, Decoder, Narrow, Store, MAX_COEFFICIENT_PLANE};
use crate::mask::Mask;
use crate::progress::{self, Stage};
use crate::quantize::{
    integer_samples, rescale_97, sample_bits, samples_from_bits, to_samples, whole_offset,
    ValueMapping,
};
use crate::raster::{Raster, SampleType, Samples};
use crate::residual::{decode_residuals, exponents, LengthContext};
use crate::significance::SignificanceMap;
use crate::tiles::{ByteSource, TiledLayout, Window};
use crate::wavelet::{self, Wavelet};
use bitvec::order::Lsb0;
use bitvec::slice::BitSlice;

use super::options::{DecodeOptions, Limits};

/// A decoded stream.
#[derive(Debug, Clone)]
#[non_exhaustive]
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
#[non_exhaustive]
pub struct Damage {
    /// Which section: "payload", "residual section", "ladder" or "trailing bytes".
    pub section: &'static str,
    /// File offset where the damage starts.
    pub offset: u64,
    /// The damaged tile of a tiled file, by index (row-major).
    pub tile: Option<u32>,
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
        return decode_tiled_window(source, &layout, window, options);
    }
    let mut decoded = decode_single(source, options)?;
    if let Some(w) = window {
        decoded.raster = crop_to_window(&decoded.raster, w)?;
    }
    Ok(decoded)
}

/// `window` (all of it when `None`) of the tiled file `layout` describes.
fn decode_tiled_window(
    source: &mut impl ByteSource,
    layout: &TiledLayout,
    window: Option<Window>,
    options: &DecodeOptions,
) -> Result<Decoded, CodecError> {
    let window = window.unwrap_or(Window {
        x: 0,
        y: 0,
        width: layout.grid.width,
        height: layout.grid.height,
    });
    let mut decoded = None;
    crate::tiles::decode_layout(
        source,
        layout,
        &[window],
        options,
        &mut || {},
        &mut |_, d| {
            decoded = Some(d);
            true
        },
    )?;
    Ok(decoded.expect("one window, one decode"))
}

/// Decodes `windows` of a `.ezw` file one after the other, handing each to `deliver`
/// (which returns `false` to stop), each as [`decode_window`] would. Of a tiled file the
/// tiles are decoded on `options.threads` threads in the order the windows need them,
/// the next window's started while the current one's last tiles finish, so no thread
/// waits at a window's end; `before_output` runs before each window's samples are
/// allocated (a writer can finish the previous window there, so that the two are never
/// held together). A single stream is decoded once and cropped to each window.
pub fn decode_windows(
    source: &mut impl ByteSource,
    windows: &[Window],
    options: &DecodeOptions,
    before_output: &mut dyn FnMut(),
    deliver: &mut dyn FnMut(Window, Decoded) -> bool,
) -> Result<(), CodecError> {
    if let Some(layout) = TiledLayout::read(source, index_limit(options))? {
        return crate::tiles::decode_layout(
            source,
            &layout,
            windows,
            options,
            before_output,
            deliver,
        );
    }
    let decoded = decode_single(source, options)?;
    for &window in windows {
        before_output();
        if !deliver(window, crop_decoded(&decoded, window)?) {
            break;
        }
    }
    Ok(())
}

/// A single stream read whole (or its `max_bytes` prefix) from `source` and decoded.
fn decode_single(
    source: &mut impl ByteSource,
    options: &DecodeOptions,
) -> Result<Decoded, CodecError> {
    let data = source
        .read_at(0, options.max_bytes.map_or(usize::MAX, |b| b as usize))
        .map_err(|e| CodecError::Read(e.to_string()))?;
    let (header, header_len) = Header::parse_with_ladder(&data, |start, len| {
        let bytes = match data.get(start..start.checked_add(len)?) {
            Some(held) => held.to_vec(),
            None => source.read_at(start as u64, len).ok()?,
        };
        (bytes.len() == len).then_some(bytes)
    })?;
    decode_parsed(&data, header, header_len, options)
}

/// `decoded` cut to `window`.
fn crop_decoded(decoded: &Decoded, window: Window) -> Result<Decoded, CodecError> {
    Ok(Decoded {
        raster: crop_to_window(&decoded.raster, window)?,
        header: decoded.header.clone(),
        passes_decoded: decoded.passes_decoded,
        complete: decoded.complete,
        bytes_used: decoded.bytes_used,
        damage: decoded.damage,
        significance: decoded.significance.clone(),
    })
}

/// The part of `raster` inside `window`, with its metadata and a georeferencing moved to
/// the window's corner.
fn crop_to_window(raster: &Raster, w: Window) -> Result<Raster, CodecError> {
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
    Ok(part)
}

/// Largest tile index a decode reads: a quarter of its memory limit.
fn index_limit(options: &DecodeOptions) -> u64 {
    options.limits.max_memory / 4
}

/// Working memory a decode needs, in bytes (used for the limit check).
fn decode_memory(header: &Header) -> u64 {
    let n = header.sample_count();
    // coefficients (4 at most, reused for the output) + the scans' bitmaps (3 bits, counted
    // as 1) + mask (1 when present).
    n * (5 + (header.mask_len > 0) as u64)
}

/// Refuses a stream whose size or decoder memory exceeds `limits`.
pub(crate) fn check_limits(header: &Header, limits: &Limits) -> Result<(), CodecError> {
    let n = header.sample_count();
    if n > limits.max_samples {
        return Err(CodecError::LimitExceeded {
            what: "sample count",
            needed: n,
            limit: limits.max_samples,
        });
    }
    let memory = decode_memory(header);
    if memory > limits.max_memory {
        return Err(CodecError::LimitExceeded {
            what: "decoder memory",
            needed: memory,
            limit: limits.max_memory,
        });
    }
    Ok(())
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
        return decode_tiled_window(&mut data, &layout, None, options);
    }
    let whole = data;
    let data = match options.max_bytes {
        Some(limit) if (limit as usize) < data.len() => &data[..limit as usize],
        _ => data,
    };
    // The header from the prefix; its ladder from the whole data, past the cut.
    let (header, header_len) = Header::parse_with_ladder(data, |start, len| {
        whole
            .get(start..start.checked_add(len)?)
            .map(<[u8]>::to_vec)
    })?;
    decode_parsed(data, header, header_len, options)
}

/// Decodes a single stream whose header (`header_len` bytes) is parsed.
pub(crate) fn decode_parsed(
    data: &[u8],
    header: Header,
    header_len: usize,
    options: &DecodeOptions,
) -> Result<Decoded, CodecError> {
    check_limits(&header, &options.limits)?;
    let sections = StreamSections::read(data, &header, header_len, options.max_bytes)?;
    if let (true, Some(d)) = (options.strict, sections.damage) {
        return Err(CodecError::Damaged {
            section: d.section,
            offset: d.offset,
        });
    }
    decode_stream(data, header, &sections, options)
}

/// Decodes the payload of a stream whose sections are read, then applies its residual
/// section when that is complete.
fn decode_stream(
    data: &[u8],
    header: Header,
    sections: &StreamSections,
    options: &DecodeOptions,
) -> Result<Decoded, CodecError> {
    // All of the payload the encoder wrote is here, undamaged...
    let payload_present = sections.payload_check.complete;
    // ... and it is a whole stream, not a prefix: its padding is genuine.
    let payload_complete = payload_present && !header.payload_truncated;
    let mask = sections.mask.as_ref().map(Mask::as_bitslice);
    let Reconstruction {
        mut samples,
        passes_decoded,
        complete,
        significance,
    } = reconstruction(&header, sections, payload_complete, options, mask);
    let ezw_complete = complete && payload_complete;
    progress::report(Stage::Transform, 1, 1);
    let residuals_complete =
        apply_residual_section(&header, sections, &mut samples, mask, ezw_complete);
    let mut raster = Raster::new(header.width as usize, header.height as usize, samples)?;
    raster.nodata = header.nodata;
    raster.georef = header.georef.clone();
    raster.metadata = header.metadata.clone();
    let bytes_used = (if residuals_complete && header.residual_len > 0 {
        sections.ladder_start
    } else {
        let payload_end = physical_offset(sections.payload_check.data_len as u64);
        sections.payload_start + payload_end as usize
    })
    .min(data.len()) as u64;
    Ok(Decoded {
        raster,
        passes_decoded,
        complete: payload_present
            && (ezw_complete || header.payload_truncated)
            && residuals_complete,
        damage: sections.damage,
        bytes_used,
        header,
        significance,
    })
}

/// What the zerotree decode and the inverse transform made of a stream.
struct Reconstruction {
    samples: Samples,
    passes_decoded: u32,
    /// Whether the zerotree decode ran through plane 0.
    complete: bool,
    significance: Option<SignificanceMap>,
}

/// Decodes the payload and inverts the transform: in `i16` when
/// [`narrow_reconstruction`] can, else in `i32`. Both give the same samples.
fn reconstruction(
    header: &Header,
    sections: &StreamSections,
    payload_complete: bool,
    options: &DecodeOptions,
    mask: Option<&BitSlice<u64, Lsb0>>,
) -> Reconstruction {
    let (width, height) = (header.width as usize, header.height as usize);
    let subbands = wavelet::subbands(width, height, header.levels as u32);
    let shifts: Vec<u32> = header.bands.iter().map(|&(s, _)| s as u32).collect();
    let layout = CoefficientLayout::new(width, height, &subbands, &shifts);
    let narrow = header.sample_type.bytes() <= 2
        && header.wavelet.is_reversible()
        && whole_offset(header.mapping)
        && !options.significance_map;
    if narrow {
        let payload = (sections, payload_complete);
        if let Some(done) = narrow_reconstruction(&layout, header, payload, options, mask) {
            return done;
        }
    }
    let scaled = header.sample_type.bytes() <= 2
        && header.wavelet == Wavelet::Cdf97
        && !options.significance_map;
    if scaled {
        let payload = (sections, payload_complete);
        if let Some(done) = scaled_reconstruction(&layout, header, payload, options, mask) {
            return done;
        }
    }
    let decoder = Decoder::run_from(
        &layout,
        header.coder,
        payload_source(sections, payload_complete),
        header.top_plane.map(u32::from),
        options.max_passes,
    );
    let significance = options
        .significance_map
        .then(|| decoder.significance(&layout));
    let (passes_decoded, complete) = (decoder.passes_completed, decoder.complete);
    Reconstruction {
        samples: reconstruct(header, Coefficients::of(decoder, header.wavelet), mask),
        passes_decoded,
        complete,
        significance,
    }
}

/// The 5/3 decode of a stream of 1- or 2-byte integer samples (whole offset) with
/// coefficients and inverse transform in `i16`, half the memory of `i32`, the samples
/// made in place: first with no coefficient escaped (no test on reading one), then, after
/// the first pass that shows one does not fit, with the few that do not escaped
/// ([`Narrow`]). `None` when too many coefficients or values of the inverse transform do
/// not fit, for an `i32` decode.
fn narrow_reconstruction(
    layout: &CoefficientLayout,
    header: &Header,
    (sections, payload_complete): (&StreamSections, bool),
    options: &DecodeOptions,
    mask: Option<&BitSlice<u64, Lsb0>>,
) -> Option<Reconstruction> {
    let top_plane = header.top_plane.map(u32::from);
    let source = || payload_source(sections, payload_complete);
    let (coder, max_passes) = (header.coder, options.max_passes);
    // Without escapes first; with them when a value outgrows its slot, in the decode or
    // after it (the midpoints of a prefix).
    let unescaped =
        Decoder::<Narrow<false>>::try_run_from(layout, coder, source(), top_plane, max_passes);
    if let Some(done) = unescaped.and_then(|decoder| narrow_samples(decoder, header, mask)) {
        return Some(done);
    }
    let decoder =
        Decoder::<Narrow<true>>::try_run_from(layout, coder, source(), top_plane, max_passes)?;
    narrow_samples(decoder, header, mask)
}

/// The 9/7 decode of a stream of 1- or 2-byte integer samples whose ladder shows the
/// lowest plane its decode reads: the coefficients as `i16` slots in units of that plane
/// or above ([`Narrow`]: with no slot escaped when every magnitude fits, else with the
/// large ones escaped: those significant in the passes above the slots' 15 planes, so a
/// store that overflows does so in the first, cheap passes), dequantised as the inverse
/// reads them and the samples written over them ([`wavelet::inverse_97_i16`]), about 1.6
/// times the samples' bytes where the `i32` decode holds 2 and more. The samples are
/// those of [`reconstruct`]. `None` for that decode.
fn scaled_reconstruction(
    layout: &CoefficientLayout,
    header: &Header,
    (sections, payload_complete): (&StreamSections, bool),
    options: &DecodeOptions,
    mask: Option<&BitSlice<u64, Lsb0>>,
) -> Option<Reconstruction> {
    let available = sections.payload_check.data_len as u64;
    let (shift, escapes) = scaled_slots(header, available, options)?;
    let source = payload_source(sections, payload_complete);
    let passes = (header.top_plane.map(u32::from), options.max_passes);
    if escapes {
        let values = Narrow::<true>::with_shift(layout.len(), shift);
        let decoder = Decoder::try_run_into(values, layout, header.coder, source, passes)?;
        return Some(scaled_samples(decoder, header, mask));
    }
    let values = Narrow::<false>::with_shift(layout.len(), shift);
    let decoder = Decoder::try_run_into(values, layout, header.coder, source, passes)?;
    Some(scaled_samples(decoder, header, mask))
}

/// The slots of a [`scaled_reconstruction`] of `header`'s stream with `available`
/// payload bytes: their shift (the lowest plane the decode reads, or that of the 15 top
/// planes when it reads no deeper), and whether some may be escaped (when it reads
/// deeper). `None` when it is not known how deep it reads.
fn scaled_slots(header: &Header, available: u64, options: &DecodeOptions) -> Option<(u32, bool)> {
    let top = header.top_plane.map(u32::from)?;
    let floor = top.min(MAX_COEFFICIENT_PLANE).saturating_sub(14);
    // Without a ladder, only a stream of at most 15 planes is known to fit.
    let lowest = lowest_plane_read(header, available, options).or((floor == 0).then_some(0))?;
    Some(if lowest < floor {
        (lowest, true)
    } else {
        (floor, false)
    })
}

/// The samples of a [`scaled_reconstruction`]'s decode.
fn scaled_samples<const ESCAPES: bool>(
    decoder: Decoder<Narrow<ESCAPES>>,
    header: &Header,
    mask: Option<&BitSlice<u64, Lsb0>>,
) -> Reconstruction {
    let (passes_decoded, complete) = (decoder.passes_completed, decoder.complete);
    let (store, real) = decoder.into_real_parts();
    let (mut slots, shift, escaped) = store.into_parts();
    let step = header.coefficient_step;
    let scales: Vec<f32> = header
        .bands
        .iter()
        .map(|&(_, s)| (step / s) as f32)
        .collect();
    let (mapping, sample_type) = (header.mapping, header.sample_type);
    let size = (
        header.width as usize,
        header.height as usize,
        header.levels as u32,
    );
    let known = |i: usize, slot: i16| match ESCAPES && is_escape(slot) {
        true => escaped.get(&i).copied().unwrap_or(i32::from(slot) << shift),
        false => i32::from(slot) << shift,
    };
    wavelet::inverse_97_i16(
        &mut slots,
        size,
        |b, start, run, out| {
            for (k, (o, &slot)) in out.iter_mut().zip(run).enumerate() {
                *o = real.value(b, start + k, known(start + k, slot)) * scales[b];
            }
        },
        |x| sample_bits(sample_type, mapping.value(x as f64)),
    );
    Reconstruction {
        samples: samples_from_bits(sample_type, slots, mask, header.nodata),
        passes_decoded,
        complete,
        significance: None,
    }
}

/// The lowest plane a decode of `header`'s stream with `available` payload bytes reads,
/// by the ladder: that of the pass begun after those held whole (`None` without a
/// ladder, as in a file cut short).
fn lowest_plane_read(header: &Header, available: u64, options: &DecodeOptions) -> Option<u32> {
    let top = header.top_plane.map(u32::from)?;
    if header.passes.is_empty() {
        return None;
    }
    let whole = header
        .passes
        .iter()
        .take_while(|p| p.end_byte <= available)
        .count() as u32;
    let read = (whole + 1)
        .min(top + 1)
        .min(options.max_passes.unwrap_or(u32::MAX));
    Some(top + 1 - read)
}

/// The samples of a [`narrow_reconstruction`]'s decode.
fn narrow_samples<const ESCAPES: bool>(
    decoder: Decoder<Narrow<ESCAPES>>,
    header: &Header,
    mask: Option<&BitSlice<u64, Lsb0>>,
) -> Option<Reconstruction> {
    let (passes_decoded, complete) = (decoder.passes_completed, decoder.complete);
    // The samples are kept as their difference to the middle of their type's range.
    let (lo, hi) = header.sample_type.value_range();
    let centre = ((lo + hi) / 2.0).ceil();
    let shift = i32::try_from((centre - header.mapping.offset) as i64).ok()?;
    let (width, height) = (header.width as usize, header.height as usize);
    let levels = header.levels as u32;
    let coefficients = decoder.integer_coefficients();
    if coefficients.overflowed() {
        return None;
    }
    let values = narrow_inverse(header.wavelet, coefficients, (width, height, levels), shift)?;
    let mapping = ValueMapping {
        offset: centre,
        step: 1.0,
    };
    Some(Reconstruction {
        samples: integer_samples(header.sample_type, values, mapping, mask, header.nodata),
        passes_decoded,
        complete,
        significance: None,
    })
}

/// The inverse of the reversible `wavelet` of `coefficients` (a `width × height`
/// transform of `levels` levels) shifted down by `shift`, in `i16`
/// ([`wavelet::inverse_integer_i16`]; the escaped coefficients and the values that do
/// not fit are kept beside). Shifting the LL band shifts every output of the integer
/// transforms by as much, exactly (each lifting step adds to one band the floor of a sum
/// of the other band's values whose weights sum to 0 or 1, which the shift leaves alone
/// or shifts by as much, as in JPEG 2000's DC level shift), so the samples are those of
/// the `i32` inverse minus `shift`. A sample that still does not fit is saturated, as its
/// type's range clamps it later. `None` when too many values do not fit.
fn narrow_inverse<const ESCAPES: bool>(
    wavelet: Wavelet,
    coefficients: Narrow<ESCAPES>,
    (width, height, levels): (usize, usize, u32),
    shift: i32,
) -> Option<Vec<i16>> {
    // Integer slots are in units of 1; a shifted value that leaves its slot is kept
    // beside it, as the inverse keeps what does not fit.
    let (mut values, _, mut spilled) = coefficients.into_parts();
    let ll = (region_side(width, levels), region_side(height, levels));
    for i in (0..ll.1).flat_map(|y| (y * width..).take(ll.0)) {
        let value = spilled.get(&i).copied().unwrap_or(values[i].into());
        let shifted = value.wrapping_sub(shift);
        match i16::try_from(shifted) {
            Ok(narrow) => {
                values[i] = narrow;
                spilled.remove(&i);
            }
            Err(_) => {
                spilled.insert(i, shifted);
            }
        }
    }
    if !wavelet::inverse_integer_i16(wavelet, &mut values, &mut spilled, width, height, levels) {
        return None;
    }
    for (i, v) in spilled {
        values[i] = v.clamp(i16::MIN.into(), i16::MAX.into()) as i16;
    }
    Some(values)
}

/// Side of the LL region after `levels` levels of a side of `n` samples.
fn region_side(n: usize, levels: u32) -> usize {
    (0..levels).fold(n, |s, _| s.div_ceil(2))
}

/// The range decoder over the stream's payload, read in place.
fn payload_source<'a>(
    sections: &StreamSections<'a>,
    payload_complete: bool,
) -> ArithmeticDecoder<'a> {
    ArithmeticDecoder::new_framed(
        sections.payload_framed,
        sections.payload_check.data_len,
        CHUNK,
        4,
        payload_complete,
    )
}

/// Decoded coefficients: integers (5/3) or reals (9/7, quantised units).
pub(crate) enum Coefficients {
    Integer(Vec<i32>),
    Real(Vec<f32>),
}

impl Coefficients {
    /// `len` zeros.
    pub(crate) fn zeros(wavelet: Wavelet, len: usize) -> Coefficients {
        match wavelet {
            Wavelet::Int53 | Wavelet::Int1311 => Coefficients::Integer(vec![0; len]),
            Wavelet::Cdf97 => Coefficients::Real(vec![0.0; len]),
        }
    }

    /// What `decoder` decoded, as `wavelet` inverts them.
    pub(crate) fn of(decoder: Decoder, wavelet: Wavelet) -> Coefficients {
        match wavelet {
            Wavelet::Int53 | Wavelet::Int1311 => {
                Coefficients::Integer(decoder.integer_coefficients())
            }
            Wavelet::Cdf97 => Coefficients::Real(decoder.into_real_coefficients()),
        }
    }
}

/// The decoded coefficients through the inverse transform to samples. In place: the
/// coefficient buffer becomes the image, then the samples (narrower ones packed inside
/// it first, see [`narrow`]), so the decode never holds more than the coefficients
/// (4 bytes a sample).
pub(crate) fn reconstruct(
    header: &Header,
    coefficients: Coefficients,
    mask: Option<&BitSlice<u64, Lsb0>>,
) -> Samples {
    let (width, height) = (header.width as usize, header.height as usize);
    let levels = header.levels as u32;
    let mapping = header.mapping;
    // Samples of 4 bytes are made in the coefficients' buffer; narrower ones go through
    // i32 (rounded and clamped the same way) and are narrowed in place.
    let wide_type = match header.sample_type {
        SampleType::F32 => SampleType::F32,
        _ => SampleType::I32,
    };
    let samples = match coefficients {
        Coefficients::Integer(mut coefficients) => {
            wavelet::inverse_integer(header.wavelet, &mut coefficients, width, height, levels);
            integer_samples(wide_type, coefficients, mapping, mask, header.nodata)
        }
        Coefficients::Real(mut data) => {
            let subbands = wavelet::subbands(width, height, levels);
            rescale_97(
                &mut data,
                width,
                &subbands,
                &header.bands,
                header.coefficient_step,
            );
            wavelet::inverse_97(&mut data, width, height, levels);
            to_samples(
                wide_type,
                data,
                |x| mapping.value(x as f64),
                mask,
                header.nodata,
            )
        }
    };
    match samples {
        Samples::I32(values) => narrow(values, header.sample_type),
        other => other,
    }
}

/// `values` (whole numbers in i32) as the integer `sample_type`, clamped to its range.
fn narrow(values: Vec<i32>, sample_type: SampleType) -> Samples {
    match sample_type {
        SampleType::U8 => Samples::U8(narrowed(values, sample_type, |v| v as u8)),
        SampleType::U16 => Samples::U16(narrowed(values, sample_type, |v| v as u16)),
        SampleType::I16 => Samples::I16(narrowed(values, sample_type, |v| v as u16 as i16)),
        SampleType::I32 | SampleType::F32 => Samples::I32(values),
    }
}

/// `values` clamped to the range of the 1- or 2-byte `sample_type`, each made a `T` from
/// its low bits by `from_bits`. They are packed into the front of `values`' own buffer
/// first (two 16-bit or four 8-bit samples an i32), the buffer shrunk to that, then
/// copied out: the decode holds at most the i32 buffer, never the i32 buffer and the
/// narrow samples beside it.
fn narrowed<T>(
    mut values: Vec<i32>,
    sample_type: SampleType,
    from_bits: impl Fn(u32) -> T,
) -> Vec<T> {
    let bits = 8 * sample_type.bytes() as u32;
    let (lo, hi) = sample_type.value_range();
    let (lo, hi) = (lo as i32, hi as i32);
    let per_word = (32 / bits) as usize;
    let lane_mask = (1u32 << bits) - 1;
    let n = values.len();
    // Sample i goes to word i / per_word ≤ i, whose own value was read before.
    for i in 0..n {
        let v = values[i].clamp(lo, hi) as u32 & lane_mask;
        let (word, lane) = (i / per_word, (i % per_word) as u32);
        let kept = if lane == 0 { 0 } else { values[word] as u32 };
        values[word] = (kept | v << (bits * lane)) as i32;
    }
    values.truncate(n.div_ceil(per_word));
    values.shrink_to_fit();
    (0..n)
        .map(|i| {
            from_bits(values[i / per_word] as u32 >> (bits * (i % per_word) as u32) & lane_mask)
        })
        .collect()
}

/// Applies the residual section: exact float residuals once the whole stream is decoded
/// (`ezw_complete`), or max-error corrections once the whole (cut) payload is. Returns
/// whether the section is complete and applied (true when there is none).
pub(crate) fn apply_residual_section(
    header: &Header,
    sections: &StreamSections,
    samples: &mut Samples,
    mask: Option<&BitSlice<u64, Lsb0>>,
    ezw_complete: bool,
) -> bool {
    let residual = &sections.residual;
    let bytes = residual.complete.then_some(&residual.bytes[..]);
    let n = header.sample_count() as usize;
    let valid_count = || mask.map_or(n, |m| m.count_ones());
    match bytes {
        _ if header.residual_len == 0 => true,
        Some(bytes) if header.correction_step > 0.0 && sections.payload_check.complete => {
            let context = LengthContext::Coder(header.coder);
            let mut corrections = decode_residuals(bytes, valid_count(), context).into_iter();
            apply_corrections(samples, mask, header.correction_step, &mut corrections);
            true
        }
        Some(bytes) if ezw_complete => match samples {
            Samples::F32(floats) => {
                apply_float_residuals(header, bytes, floats, mask);
                true
            }
            _ => false,
        },
        _ => false,
    }
}

/// Adds the exact residuals of `bytes` to the valid `floats` (their reconstructions).
fn apply_float_residuals(
    header: &Header,
    bytes: &[u8],
    floats: &mut [f32],
    mask: Option<&BitSlice<u64, Lsb0>>,
) {
    let valid = |i: usize| mask.is_none_or(|m| m[i]);
    let valid_bits = floats.iter().enumerate().filter(|&(i, _)| valid(i));
    let exponents = exponents(valid_bits.map(|(_, v)| v.to_bits()));
    let context = match header.residuals_by_exponent {
        true => LengthContext::Exponents(&exponents),
        false => LengthContext::Coder(header.coder),
    };
    let mut residuals = decode_residuals(bytes, exponents.len(), context).into_iter();
    for (i, value) in floats.iter_mut().enumerate() {
        if valid(i) {
            let r = residuals.next().unwrap_or(0);
            *value = f32::from_bits(value.to_bits().wrapping_add(r as u32));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{encode, EncodeOptions};

    /// A single-stream 9/7 file of smooth terrain in `sample_type`, `width × height`,
    /// cut at `bytes` (the whole stream when `None`).
    fn file_97(
        sample_type: SampleType,
        (width, height): (usize, usize),
        bytes: Option<u64>,
        gain: f64,
    ) -> Vec<u8> {
        let values: Vec<f64> = (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as f64, (i / width) as f64);
                let wave = 100.0 * (x * 0.11).sin() * (y * 0.07).cos() + 9.0 * (x * 1.3 + y).sin();
                120.0 * gain + wave * gain
            })
            .collect();
        let raster = Raster::new(width, height, Samples::from_f64(sample_type, &values)).unwrap();
        let mut options =
            EncodeOptions::budget(bytes.unwrap_or(u64::MAX)).with_wavelet(Wavelet::Cdf97);
        options.budget_bytes = bytes;
        options.tile_size = None;
        encode(&raster, &options).unwrap().bytes
    }

    /// The samples of `data` by the `i32` decode and by [`reconstruction`], and the slots
    /// of the `i16` decode the latter may take ([`scaled_slots`]).
    fn both_decodes(
        data: &[u8],
        options: &DecodeOptions,
    ) -> (Samples, Samples, Option<(u32, bool)>) {
        let data = &data[..options.max_bytes.map_or(data.len(), |b| b as usize)];
        let (header, header_len) = Header::parse(data).unwrap();
        let sections = StreamSections::read(data, &header, header_len, options.max_bytes).unwrap();
        let complete = sections.payload_check.complete && !header.payload_truncated;
        let mask = sections.mask.as_ref().map(Mask::as_bitslice);
        let (w, h, levels) = (
            header.width as usize,
            header.height as usize,
            header.levels as u32,
        );
        let subbands = wavelet::subbands(w, h, levels);
        let layout = CoefficientLayout::new(w, h, &subbands, &vec![0; subbands.len()]);
        let top = header.top_plane.map(u32::from);
        let source = payload_source(&sections, complete);
        let wide = Decoder::run_from(&layout, header.coder, source, top, options.max_passes);
        let wide = reconstruct(&header, Coefficients::of(wide, header.wavelet), mask);
        let available = sections.payload_check.data_len as u64;
        let scaled = scaled_slots(&header, available, options);
        let samples = reconstruction(&header, &sections, complete, options, mask).samples;
        (wide, samples, scaled)
    }

    #[test]
    fn the_i16_97_decode_makes_the_samples_of_the_i32_one() {
        let types = [
            (SampleType::U16, (97, 61)),
            (SampleType::I16, (64, 64)),
            (SampleType::U8, (33, 47)),
        ];
        for (sample_type, size) in types {
            let n = (size.0 * size.1) as u64;
            let cut = file_97(sample_type, size, Some(n / 8 + 64), 1.0);
            let (wide, narrow, scaled) = both_decodes(&cut, &DecodeOptions::default());
            assert!(scaled.is_some(), "{sample_type:?} at 1 bpp");
            assert_eq!(narrow, wide, "{sample_type:?} at 1 bpp");
            let whole = file_97(sample_type, size, None, 1.0);
            let few = DecodeOptions::default().with_max_passes(Some(6));
            for options in [few, DecodeOptions::default()] {
                let (wide, narrow, _) = both_decodes(&whole, &options);
                assert_eq!(narrow, wide, "{sample_type:?}, {options:?}");
            }
        }
        for size in [(97, 61), (1, 40), (40, 1), (2, 3)] {
            let cut = file_97(SampleType::U16, size, Some(60), 1.0);
            let (wide, narrow, _) = both_decodes(&cut, &DecodeOptions::default());
            assert_eq!(narrow, wide, "{size:?} at 40 bytes");
        }
        // A prefix has no ladder: the i32 decode.
        let whole = file_97(SampleType::I16, (64, 64), None, 140.0);
        let prefix = DecodeOptions::default().with_max_bytes(Some(300));
        let (wide, narrow, scaled) = both_decodes(&whole, &prefix);
        assert_eq!(scaled, None);
        assert_eq!(narrow, wide);
    }

    #[test]
    fn the_i16_97_decode_escapes_the_coefficients_that_do_not_fit() {
        // Heights spanning nearly all the 16-bit range, decoded to each depth: within the
        // slots' 15 planes, then with the coefficients that do not fit escaped, until
        // too many do not (an `i32` decode then).
        let whole = file_97(SampleType::U16, (128, 96), None, 280.0);
        let (header, header_len) = Header::parse(&whole).unwrap();
        let top = u32::from(header.top_plane.unwrap());
        let floor = top - 14;
        assert!(floor >= 6, "top plane {top}");
        for lowest in 0..=floor + 2 {
            let options = DecodeOptions::default().with_max_passes(Some(top + 1 - lowest));
            let (wide, narrow, scaled) = both_decodes(&whole, &options);
            assert_eq!(narrow, wide, "to plane {lowest}");
            assert_eq!(scaled.map(|(_, escapes)| escapes), Some(lowest < floor));
        }
        let sections = StreamSections::read(&whole, &header, header_len, None).unwrap();
        let (w, h) = (header.width as usize, header.height as usize);
        let subbands = wavelet::subbands(w, h, header.levels as u32);
        let shifts: Vec<u32> = header.bands.iter().map(|&(s, _)| s as u32).collect();
        let layout = CoefficientLayout::new(w, h, &subbands, &shifts);
        let escaped = |lowest: u32| {
            let values = Narrow::<true>::with_shift(layout.len(), lowest);
            let source = payload_source(&sections, true);
            let passes = (Some(top), Some(top + 1 - lowest));
            let decoder = Decoder::try_run_into(values, &layout, header.coder, source, passes);
            decoder.map(|d| d.into_real_parts().0.into_parts().2.len())
        };
        // One plane deeper escapes a few; the last plane (six deeper: a 16-bit raster's
        // 9/7 stream ends at a quarter unit), more than the table holds.
        assert!(escaped(floor - 1).is_some_and(|n| (1..layout.len() / 64).contains(&n)));
        assert_eq!(escaped(0), None);
    }

    #[test]
    fn narrowing_clamps_and_keeps_every_sample_in_order() {
        let values = vec![-70000, -1, 0, 1, 255, 256, 40000, 70000, 12345];
        let clamp = |lo: i32, hi: i32| values.iter().map(move |v| (*v).clamp(lo, hi));
        assert_eq!(
            narrow(values.clone(), SampleType::U8),
            Samples::U8(clamp(0, 255).map(|v| v as u8).collect())
        );
        assert_eq!(
            narrow(values.clone(), SampleType::U16),
            Samples::U16(clamp(0, 65535).map(|v| v as u16).collect())
        );
        assert_eq!(
            narrow(values.clone(), SampleType::I16),
            Samples::I16(clamp(-32768, 32767).map(|v| v as i16).collect())
        );
        assert_eq!(
            narrow(values.clone(), SampleType::I32),
            Samples::I32(values)
        );
        assert_eq!(
            narrow(Vec::new(), SampleType::U16),
            Samples::U16(Vec::new())
        );
    }
}
