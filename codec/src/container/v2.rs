//! The version-2 header: compact (varints, presence flags, short numbers), with an
//! EPSG-coded form of the georeferencing and an optional metadata block.
//! `codec/FORMAT.md` gives the byte layout.

use super::number::{short_value, write_number};
use super::{derived_bands, read_kinds, scale_to_u16, write_varint, Header, Reader, Tiling};
use crate::corrections::correction_step;
use crate::error::CodecError;
use crate::ezw::Coder;
use crate::raster::geokey::{
    GEOGRAPHIC_TYPE, MODEL_GEOGRAPHIC, MODEL_PROJECTED, MODEL_TYPE, PROJECTED_TYPE, RASTER_TYPE,
};
use crate::raster::{Georef, Metadata, MetadataItem, SampleType};
use crate::wavelet::{ShiftRule, Wavelet};
use crate::Mode;

/// Header flag bits (the `flags` varint).
mod flag {
    pub const NODATA: u64 = 1;
    pub const GEOREF: u64 = 1 << 1;
    pub const METADATA: u64 = 1 << 2;
    pub const PAYLOAD_TRUNCATED: u64 = 1 << 3;
    pub const BANDS_LISTED: u64 = 1 << 4;
    pub const MASK: u64 = 1 << 5;
    pub const RESIDUAL: u64 = 1 << 6;
    pub const MAX_ERROR: u64 = 1 << 7;
    pub const TILED: u64 = 1 << 8;
    pub const OVERLAP: u64 = 1 << 9;
    pub const RANGE_IN_LADDER: u64 = 1 << 10;
    pub const CORRECTION_STEP_IMPLIED: u64 = 1 << 11;
    pub const F32_MAPPING: u64 = 1 << 12;
    pub const COMPACT_TILES: u64 = 1 << 13;
    pub const LOWERED_SHIFTS: u64 = 1 << 14;
    pub const CODE_BLOCKS: u64 = 1 << 15;
    pub const RESIDUALS_BY_EXPONENT: u64 = 1 << 16;
    pub const ALL: u64 = (1 << 17) - 1;
}

/// Bit of the sample-type/wavelet/mode byte that says the payload is coded with
/// coder 2's models (a byte, not a `flags` bit, so that headers do not grow).
const CODER_2_BIT: u8 = 7;
/// Bit of the levels byte that says coder 2's models start from the trained
/// probabilities: [`Coder::V3`] (levels never need more than 6 bits).
const PRIMED_BIT: u8 = 1 << 6;
/// Bit of the levels byte that says each pass starts with the propagation scan:
/// [`Coder::V4`] (needs [`PRIMED_BIT`]).
const PROPAGATION_BIT: u8 = 1 << 7;

/// Georeferencing flag bits.
const NORTH_UP: u8 = 1;
const EPSG_CODED: u8 = 1 << 1;
const SQUARE_PIXELS: u8 = 1 << 2;

/// Metadata entry roles.
mod role {
    pub const SCALE: u8 = 1;
    pub const OFFSET: u8 = 2;
    pub const DESCRIPTION: u8 = 3;
    pub const UNIT_TYPE: u8 = 4;
    pub const CRS_WKT: u8 = 5;
    pub const DATASET_ITEM: u8 = 6;
    pub const BAND_ITEM: u8 = 7;
}

/// Serialises `header` (checksum included) in the version-2 layout.
pub(super) fn write(header: &Header) -> Vec<u8> {
    if let Some(tiling) = header.tiling {
        return write_tiled(header, tiling);
    }
    let mut body = Vec::with_capacity(128);
    write_varint(&mut body, flags(header));
    write_stream_fields(&mut body, header);
    write_varint(
        &mut body,
        super::framed_len(header.ladder_bytes().len()) as u64,
    );
    write_gis(&mut body, header);
    finish(&file_prefix(), body)
}

/// Serialises a single stream's header in the tile layout (the tiles of a tiled file
/// under flag 13): [`write()`]'s fields without the magic, the version and the ladder
/// length (a tile has no ladder), flag 10 clear and no valid range (the tiled file's
/// header has it), and no georeferencing or metadata.
pub(super) fn write_tile(header: &Header) -> Vec<u8> {
    debug_assert!(header.tiling.is_none() && header.georef.is_none());
    debug_assert!(header.metadata.is_empty() && header.passes.is_empty());
    let mut body = Vec::with_capacity(32);
    write_varint(&mut body, flags(header) & !flag::RANGE_IN_LADDER);
    write_stream_fields(&mut body, header);
    finish(&[], body)
}

/// The fields a stream's header has in both layouts, from the size through the
/// residual section's.
fn write_stream_fields(body: &mut Vec<u8>, header: &Header) {
    write_varint(body, header.width.into());
    write_varint(body, header.height.into());
    body.extend_from_slice(&[
        header.sample_type.code()
            | header.wavelet.code() << 3
            | header.mode.code() << 5
            | u8::from(header.coder != Coder::V1) << CODER_2_BIT,
        header.levels | levels_coder_bits(header.coder),
    ]);
    write_mapping(body, header);
    write_values(body, header, false);
    body.push(header.top_plane.map_or(0xFF, |p| p));
    if bands_listed(header) {
        for &(shift, scale) in &header.bands {
            match header.wavelet {
                Wavelet::Int53 | Wavelet::Int1311 => body.push(shift),
                Wavelet::Cdf97 => body.extend_from_slice(&scale_to_u16(scale).to_le_bytes()),
            }
        }
    }
    write_varint(body, header.payload_len);
    if header.mask_len > 0 {
        write_varint(body, header.mask_len.into());
    }
    if has_residual(header) {
        write_varint(body, header.residual_len.into());
        if !correction_step_implied(header) {
            write_number(body, header.correction_step);
        }
    }
}

/// The offset and the step: the sample step means something to 5/3 streams only, the
/// coefficient step to 9/7. Two numbers, or (flag 12) two f32s when both are f32s that
/// take more as numbers (a float raster's mean and a 9/7 step: 8 bytes instead of 10).
fn write_mapping(body: &mut Vec<u8>, header: &Header) {
    let (offset, step) = mapping_pair(header);
    if f32_mapping(header) {
        for v in [offset, step] {
            body.extend_from_slice(&(v as f32).to_bits().to_le_bytes());
        }
    } else {
        write_number(body, offset);
        write_number(body, step);
    }
}

/// The offset and the step the header stores (see [`write_mapping`]).
fn mapping_pair(header: &Header) -> (f64, f64) {
    let step = match header.wavelet {
        Wavelet::Int53 | Wavelet::Int1311 => header.mapping.step,
        Wavelet::Cdf97 => header.coefficient_step,
    };
    (header.mapping.offset, step)
}

/// Whether the offset and step are stored as two f32s (flag 12): both are f32s and two
/// numbers would take more than their 8 bytes.
fn f32_mapping(header: &Header) -> bool {
    let (offset, step) = mapping_pair(header);
    let is_f32 = |v: f64| f64::from(v as f32).to_bits() == v.to_bits();
    let mut numbers = Vec::new();
    write_number(&mut numbers, offset);
    write_number(&mut numbers, step);
    header.tiling.is_none() && is_f32(offset) && is_f32(step) && numbers.len() > 8
}

/// Serialises the header of a tiled file: the raster's description, the tile size and
/// the index length, none of a stream's fields.
fn write_tiled(header: &Header, tiling: Tiling) -> Vec<u8> {
    let mut body = Vec::with_capacity(128);
    write_varint(&mut body, flags(header));
    write_varint(&mut body, header.width.into());
    write_varint(&mut body, header.height.into());
    body.extend_from_slice(&[
        header.sample_type.code() | header.wavelet.code() << 3 | header.mode.code() << 5,
        header.levels,
    ]);
    write_varint(&mut body, tiling.tile_width.into());
    write_varint(&mut body, tiling.tile_height.into());
    if tiling.overlap > 0 {
        write_varint(&mut body, tiling.overlap.into());
    }
    if let Some(side) = tiling.code_block {
        write_varint(&mut body, side.into());
    }
    write_values(&mut body, header, true);
    write_varint(&mut body, tiling.index_len);
    write_gis(&mut body, header);
    finish(&file_prefix(), body)
}

/// The error bound (when listed), the valid range (`with_range`: a tiled header's; a
/// stream's is in its ladder) and the nodata value (when there is one), as both layouts
/// have them.
fn write_values(body: &mut Vec<u8>, header: &Header, with_range: bool) {
    if max_error_listed(header) {
        write_number(body, header.max_error);
    }
    if with_range {
        write_number(body, header.valid_range.0);
        write_number(body, header.valid_range.1);
    }
    if let Some(nodata) = header.nodata {
        write_number(body, nodata);
    }
}

/// The georeferencing and metadata block that end both layouts (each when present).
fn write_gis(body: &mut Vec<u8>, header: &Header) {
    if let Some(georef) = &header.georef {
        write_georef(body, georef);
    }
    if !header.metadata.is_empty() {
        write_metadata(body, &header.metadata);
    }
}

/// What a file's header starts with: the magic and the version.
fn file_prefix() -> Vec<u8> {
    let mut prefix = super::MAGIC.to_vec();
    prefix.extend_from_slice(&2u16.to_le_bytes());
    prefix
}

/// Prepends `prefix` (the magic and version of a file's header; nothing for a tile's)
/// and the header length, and appends the CRC.
fn finish(prefix: &[u8], body: Vec<u8>) -> Vec<u8> {
    let mut total = prefix.len() + body.len() + 4 + 1;
    while varint_len(total as u64) != total - prefix.len() - body.len() - 4 {
        total += 1;
    }
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(prefix);
    write_varint(&mut out, total as u64);
    out.extend_from_slice(&body);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    debug_assert_eq!(out.len(), total);
    out
}

fn varint_len(value: u64) -> usize {
    (64 - value.leading_zeros() as usize).max(1).div_ceil(7)
}

fn flags(header: &Header) -> u64 {
    let mut flags = 0;
    let single = header.tiling.is_none();
    for (set, bit) in [
        (header.nodata.is_some(), flag::NODATA),
        (header.georef.is_some(), flag::GEOREF),
        (!header.metadata.is_empty(), flag::METADATA),
        (single && header.payload_truncated, flag::PAYLOAD_TRUNCATED),
        (single && bands_listed(header), flag::BANDS_LISTED),
        (single && header.mask_len > 0, flag::MASK),
        (single && has_residual(header), flag::RESIDUAL),
        (max_error_listed(header), flag::MAX_ERROR),
        (!single, flag::TILED),
        (header.tiling.is_some_and(|t| t.overlap > 0), flag::OVERLAP),
        (
            header.tiling.is_some_and(|t| t.code_block.is_some()),
            flag::CODE_BLOCKS,
        ),
        (
            header.tiling.is_some_and(|t| t.compact_tiles),
            flag::COMPACT_TILES,
        ),
        (single, flag::RANGE_IN_LADDER),
        (f32_mapping(header), flag::F32_MAPPING),
        (
            single && header.shift_rule == ShiftRule::Lowered,
            flag::LOWERED_SHIFTS,
        ),
        (
            single && has_residual(header) && correction_step_implied(header),
            flag::CORRECTION_STEP_IMPLIED,
        ),
        (
            single && header.residuals_by_exponent,
            flag::RESIDUALS_BY_EXPONENT,
        ),
    ] {
        if set {
            flags |= bit;
        }
    }
    flags
}

/// Whether the subband shifts and scales must be listed: they are not the ones a decoder
/// derives from the dimensions (see [`derived_bands`]).
fn bands_listed(header: &Header) -> bool {
    !super::bands_derivable(header)
}

/// The bound of a lossless stream is 0 and of a lossy one +∞; others are listed.
fn max_error_listed(header: &Header) -> bool {
    header.max_error.to_bits() != implied_max_error(header.mode).to_bits()
}

fn implied_max_error(mode: Mode) -> f64 {
    match mode {
        Mode::Lossless => 0.0,
        Mode::Lossy => f64::INFINITY,
        Mode::MaxError | Mode::Precision => f64::NAN,
    }
}

fn has_residual(header: &Header) -> bool {
    header.residual_len > 0 || header.correction_step != 0.0
}

/// Whether the correction step is the one the mode implies, so the header can leave it
/// out (flag 11).
fn correction_step_implied(header: &Header) -> bool {
    header.correction_step.to_bits() == implied_correction_step(header).to_bits()
}

/// A max-error stream's correction step is the encoder's for its bound and sample type;
/// any other stream's residual section holds float residuals (step 0).
fn implied_correction_step(header: &Header) -> f64 {
    match header.mode {
        Mode::MaxError => correction_step(header.sample_type, header.max_error),
        _ => 0.0,
    }
}

/// Parses the fields after the header length; `r` ends before the CRC. Also says whether
/// the valid range is in the ladder (flag 10; the header's is NaN until it is read).
pub(super) fn parse_fields(r: &mut Reader) -> Result<(Header, bool), CodecError> {
    let flags = r.varint()?;
    if flags & !flag::ALL != 0 {
        return Err(CodecError::InvalidHeader(format!(
            "unknown flags {flags:#x}"
        )));
    }
    let size = (r.varint_u32("width")?, r.varint_u32("height")?);
    let kind = read_stream_kind(r)?;
    if flags & flag::TILED != 0 {
        if matches!(kind.coder, Coder::V3 | Coder::V4) {
            return Err(CodecError::InvalidHeader(
                "a tiled header with the primed-models bit".into(),
            ));
        }
        return Ok((parse_tiled(r, flags, size, &kind)?, false));
    }
    if flags & (flag::OVERLAP | flag::COMPACT_TILES | flag::CODE_BLOCKS) != 0 {
        return Err(CodecError::InvalidHeader(format!(
            "flags {flags:#x} of a tiled file in a single stream"
        )));
    }
    let mut header = read_stream_fields(r, flags, size, &kind)?;
    header.ladder_len = r.varint_u32("ladder length")?;
    (header.georef, header.metadata) = read_gis(r, flags)?;
    Ok((header, flags & flag::RANGE_IN_LADDER != 0))
}

/// Parses a tile-layout header's fields after its length (see [`write_tile`]); `r` ends
/// before the CRC. The valid range is NaN: the tiled file's header has it.
pub(super) fn parse_tile_fields(r: &mut Reader) -> Result<Header, CodecError> {
    let flags = r.varint()?;
    let file_only = flag::GEOREF
        | flag::METADATA
        | flag::TILED
        | flag::OVERLAP
        | flag::RANGE_IN_LADDER
        | flag::COMPACT_TILES
        | flag::CODE_BLOCKS;
    if flags & !flag::ALL != 0 || flags & file_only != 0 {
        return Err(CodecError::InvalidHeader(format!(
            "tile header flags {flags:#x}"
        )));
    }
    let size = (r.varint_u32("width")?, r.varint_u32("height")?);
    let kind = read_stream_kind(r)?;
    read_stream_fields(r, flags | flag::RANGE_IN_LADDER, size, &kind)
}

/// The fields both stream layouts have after the `kinds` and levels bytes, through the
/// residual section's (see [`write_stream_fields`]).
fn read_stream_fields(
    r: &mut Reader,
    flags: u64,
    size: (u32, u32),
    kind: &StreamKind,
) -> Result<Header, CodecError> {
    let (mapping, coefficient_step) = read_mapping(r, flags, kind.wavelet)?;
    let (max_error, valid_range, nodata) = read_values(r, flags, kind.mode)?;
    let top_plane = match r.u8()? {
        0xFF => None,
        p => Some(p),
    };
    let bands = read_band_scales(r, flags, size, kind)?;
    let payload_len = r.varint()?;
    let mask_len = if flags & flag::MASK != 0 {
        r.varint_u32("mask length")?
    } else {
        0
    };
    let (residual_len, correction_step) =
        read_residual(r, flags, (kind.mode, kind.sample_type, max_error))?;
    let mut header = Header {
        mapping,
        max_error,
        coefficient_step,
        nodata,
        valid_range,
        top_plane,
        coder: kind.coder,
        shift_rule: shift_rule(flags),
        bands,
        payload_len,
        payload_truncated: flags & flag::PAYLOAD_TRUNCATED != 0,
        mask_len,
        residual_len,
        correction_step,
        residuals_by_exponent: flags & flag::RESIDUALS_BY_EXPONENT != 0,
        ..Header::whole_raster(
            size.0,
            size.1,
            kind.sample_type,
            kind.wavelet,
            kind.levels,
            kind.mode,
        )
    };
    if flags & flag::BANDS_LISTED == 0 {
        header.derived = super::DerivedMemo(Some(super::DerivedBands::as_read(&header)));
    }
    Ok(header)
}

/// The 5/3 shift rule of a stream header's `flags` (flag 14).
fn shift_rule(flags: u64) -> ShiftRule {
    match flags & flag::LOWERED_SHIFTS {
        0 => ShiftRule::Rounded,
        _ => ShiftRule::Lowered,
    }
}

/// What the `kinds` and levels bytes say: the coder, sample type, wavelet, levels and mode.
struct StreamKind {
    coder: Coder,
    sample_type: SampleType,
    wavelet: Wavelet,
    levels: u8,
    mode: Mode,
}

/// Reads the `kinds` byte and the levels byte (whose top bits name the coder).
fn read_stream_kind(r: &mut Reader) -> Result<StreamKind, CodecError> {
    let kinds = r.u8()?;
    let levels_byte = r.u8()?;
    let coder = read_coder(kinds, levels_byte)?;
    let mut codes = Reader {
        data: &[
            kinds & 7,
            kinds >> 3 & 3,
            levels_byte & !(PRIMED_BIT | PROPAGATION_BIT),
            kinds >> 5 & 3,
        ],
        pos: 0,
    };
    let (sample_type, wavelet, levels, mode) = read_kinds(&mut codes)?;
    Ok(StreamKind {
        coder,
        sample_type,
        wavelet,
        levels,
        mode,
    })
}

/// The value mapping (offset and step; two raw f32s under flag 12) and the coefficient
/// step: the stored step is the sample step of a 5/3 stream, the coefficient step of a
/// 9/7 one.
fn read_mapping(
    r: &mut Reader,
    flags: u64,
    wavelet: Wavelet,
) -> Result<(crate::quantize::ValueMapping, f64), CodecError> {
    let (offset, stored_step) = if flags & flag::F32_MAPPING != 0 {
        let mut f32_value = || Ok::<_, CodecError>(f64::from(f32::from_bits(r.u32()?)));
        (f32_value()?, f32_value()?)
    } else {
        (r.number()?, r.number()?)
    };
    let (step, coefficient_step) = match wavelet {
        Wavelet::Int53 | Wavelet::Int1311 => (stored_step, 1.0),
        Wavelet::Cdf97 => (1.0, stored_step),
    };
    Ok((
        crate::quantize::ValueMapping { offset, step },
        coefficient_step,
    ))
}

/// The subbands' shifts and scales: listed (flag 2), or derived from the dimensions.
fn read_band_scales(
    r: &mut Reader,
    flags: u64,
    (width, height): (u32, u32),
    kind: &StreamKind,
) -> Result<Vec<(u8, f64)>, CodecError> {
    super::check_levels(width, height, kind.levels)?;
    if flags & flag::BANDS_LISTED != 0 {
        super::read_bands(r, kind.wavelet, kind.levels)
    } else {
        let rule = shift_rule(flags);
        derived_bands((kind.wavelet, rule), width, height, kind.levels).ok_or_else(|| {
            CodecError::InvalidHeader("subband scales must be listed at this size".into())
        })
    }
}

/// The residual section's length and correction step (flag 6; the step listed, or
/// implied by `mode`, `sample_type` and `max_error` under flag 11).
fn read_residual(
    r: &mut Reader,
    flags: u64,
    (mode, sample_type, max_error): (Mode, SampleType, f64),
) -> Result<(u32, f64), CodecError> {
    let residual = flags & (flag::RESIDUAL | flag::CORRECTION_STEP_IMPLIED);
    if residual == 0 {
        return Ok((0, 0.0));
    }
    if residual == flag::CORRECTION_STEP_IMPLIED {
        return Err(CodecError::InvalidHeader(
            "an implied correction step without a residual section".into(),
        ));
    }
    let residual_len = r.varint_u32("residual length")?;
    let step = match (residual & flag::CORRECTION_STEP_IMPLIED != 0, mode) {
        (false, _) => r.number()?,
        (true, Mode::MaxError) => correction_step(sample_type, max_error),
        (true, _) => 0.0,
    };
    Ok((residual_len, step))
}

/// The error bound, valid range and nodata value of a header.
type Values = (f64, (f64, f64), Option<f64>);

/// The error bound (flag 7, else the mode's), the valid range (NaN under flag 10: it is
/// in the ladder) and the nodata value (flag 0), in the order both header layouts have
/// them.
fn read_values(r: &mut Reader, flags: u64, mode: Mode) -> Result<Values, CodecError> {
    let max_error = if flags & flag::MAX_ERROR != 0 {
        r.number()?
    } else {
        implied_max_error(mode)
    };
    let valid_range = if flags & flag::RANGE_IN_LADDER != 0 {
        (f64::NAN, f64::NAN)
    } else {
        (r.number()?, r.number()?)
    };
    let nodata = if flags & flag::NODATA != 0 {
        Some(r.number()?)
    } else {
        None
    };
    Ok((max_error, valid_range, nodata))
}

/// The georeferencing (flag 1) and metadata block (flag 2) that end both layouts.
fn read_gis(r: &mut Reader, flags: u64) -> Result<(Option<Georef>, Metadata), CodecError> {
    let georef = if flags & flag::GEOREF != 0 {
        Some(read_georef(r)?)
    } else {
        None
    };
    let metadata = if flags & flag::METADATA != 0 {
        read_metadata(r)?
    } else {
        Metadata::default()
    };
    Ok((georef, metadata))
}

/// The bits of the levels byte that name `coder`.
fn levels_coder_bits(coder: Coder) -> u8 {
    match coder {
        Coder::V1 | Coder::V2 => 0,
        Coder::V3 => PRIMED_BIT,
        Coder::V4 => PRIMED_BIT | PROPAGATION_BIT,
    }
}

/// The coder the `kinds` and levels bytes name; the primed bit needs coder 2's, the
/// propagation bit the primed one.
fn read_coder(kinds: u8, levels_byte: u8) -> Result<Coder, CodecError> {
    let primed = levels_byte & PRIMED_BIT != 0;
    match (
        kinds >> CODER_2_BIT != 0,
        primed,
        levels_byte & PROPAGATION_BIT != 0,
    ) {
        (false, false, false) => Ok(Coder::V1),
        (true, false, false) => Ok(Coder::V2),
        (true, true, false) => Ok(Coder::V3),
        (true, true, true) => Ok(Coder::V4),
        (false, true, _) => Err(CodecError::InvalidHeader(
            "primed models without coder 2".into(),
        )),
        (_, false, true) => Err(CodecError::InvalidHeader(
            "the propagation scan without primed models".into(),
        )),
    }
}

/// The fields of a tiled file's header after `levels` (see [`write_tiled`]).
fn parse_tiled(
    r: &mut Reader,
    flags: u64,
    (width, height): (u32, u32),
    kind: &StreamKind,
) -> Result<Header, CodecError> {
    let stream_only = flag::PAYLOAD_TRUNCATED
        | flag::BANDS_LISTED
        | flag::MASK
        | flag::RESIDUAL
        | flag::RANGE_IN_LADDER
        | flag::CORRECTION_STEP_IMPLIED
        | flag::F32_MAPPING
        | flag::LOWERED_SHIFTS
        | flag::RESIDUALS_BY_EXPONENT;
    if flags & stream_only != 0 {
        return Err(CodecError::InvalidHeader(format!(
            "flags {flags:#x} of a tiled file"
        )));
    }
    let tile_width = r.varint_u32("tile width")?;
    let tile_height = r.varint_u32("tile height")?;
    if tile_width == 0 || tile_height == 0 {
        return Err(CodecError::InvalidHeader("tile size 0".into()));
    }
    let overlap = if flags & flag::OVERLAP != 0 {
        r.varint_u32("tile overlap")?
    } else {
        0
    };
    let code_block = match flags & flag::CODE_BLOCKS != 0 {
        true => Some(r.varint_u32("code block side")?).filter(|&side| side > 0),
        false => None,
    };
    if flags & flag::CODE_BLOCKS != 0 && code_block.is_none() {
        return Err(CodecError::InvalidHeader("code blocks of side 0".into()));
    }
    let (max_error, valid_range, nodata) = read_values(r, flags, kind.mode)?;
    let index_len = r.varint()?;
    let (georef, metadata) = read_gis(r, flags)?;
    Ok(Header {
        max_error,
        valid_range,
        nodata,
        georef,
        metadata,
        tiling: Some(Tiling {
            tile_width,
            tile_height,
            overlap,
            index_len,
            compact_tiles: flags & flag::COMPACT_TILES != 0,
            code_block,
        }),
        ..Header::whole_raster(
            width,
            height,
            kind.sample_type,
            kind.wavelet,
            kind.levels,
            kind.mode,
        )
    })
}

fn write_string(out: &mut Vec<u8>, text: &str) {
    write_varint(out, text.len() as u64);
    out.extend_from_slice(text.as_bytes());
}

fn write_georef(out: &mut Vec<u8>, georef: &Georef) {
    let gt = georef.geotransform;
    let north_up = gt[2] == 0.0 && gt[4] == 0.0;
    let square = north_up && gt[5].to_bits() == (-gt[1]).to_bits();
    let epsg = epsg_form(georef);
    let mut flags = 0;
    for (set, bit) in [
        (north_up, NORTH_UP),
        (epsg.is_some(), EPSG_CODED),
        (square, SQUARE_PIXELS),
    ] {
        if set {
            flags |= bit;
        }
    }
    out.push(flags);
    let values: &[f64] = match (north_up, square) {
        (true, true) => &[gt[0], gt[1], gt[3]],
        (true, false) => &[gt[0], gt[1], gt[3], gt[5]],
        _ => &gt,
    };
    for &v in values {
        write_number(out, v);
    }
    match epsg {
        Some(crs) => {
            out.push((crs.model | crs.raster << 4) as u8);
            write_varint(out, crs.code.into());
        }
        None => {
            write_varint(out, georef.geo_key_directory.len() as u64);
            for &key in &georef.geo_key_directory {
                write_varint(out, key.into());
            }
            write_varint(out, georef.geo_double_params.len() as u64);
            for &v in &georef.geo_double_params {
                write_number(out, v);
            }
            write_string(out, &georef.geo_ascii_params);
        }
    }
}

fn read_georef(r: &mut Reader) -> Result<Georef, CodecError> {
    let flags = r.u8()?;
    let slots: &[usize] = match flags & !EPSG_CODED {
        NORTH_UP => &[0, 1, 3, 5],
        f if f == NORTH_UP | SQUARE_PIXELS => &[0, 1, 3],
        0 => &[0, 1, 2, 3, 4, 5],
        _ => return Err(CodecError::InvalidHeader("georeferencing flags".into())),
    };
    let mut gt = [0.0; 6];
    for &i in slots {
        gt[i] = r.number()?;
    }
    if flags & SQUARE_PIXELS != 0 {
        gt[5] = -gt[1];
    }
    if flags & EPSG_CODED != 0 {
        let types = r.u8()?;
        let model = u16::from(types & 15);
        let raster = u16::from(types >> 4);
        let code = r.varint()?;
        let crs = EpsgCrs {
            model,
            raster,
            code: u16::try_from(code).unwrap_or(0),
        };
        if !crs.is_valid() {
            return Err(CodecError::InvalidHeader(format!(
                "EPSG-coded CRS (model {model}, raster {raster}, code {code})"
            )));
        }
        return Ok(Georef {
            geotransform: gt,
            geo_key_directory: crs.keys(),
            ..Georef::default()
        });
    }
    let n = r.varint_count(1)?;
    let geo_key_directory = (0..n)
        .map(|_| {
            u16::try_from(r.varint()?)
                .map_err(|_| CodecError::InvalidHeader("a GeoKey value above 65535".into()))
        })
        .collect::<Result<_, _>>()?;
    let n = r.varint_count(1)?;
    let geo_double_params = (0..n).map(|_| r.number()).collect::<Result<_, _>>()?;
    let geo_ascii_params = r.string()?;
    Ok(Georef {
        geotransform: gt,
        geo_key_directory,
        geo_double_params,
        geo_ascii_params,
    })
}

/// See [`super::stored_georef`].
pub(super) fn stored_georef(georef: &Georef) -> Georef {
    match epsg_form(georef) {
        Some(crs) => Georef {
            geotransform: georef.geotransform,
            geo_key_directory: crs.keys(),
            ..Georef::default()
        },
        None => georef.clone(),
    }
}

/// A CRS given by its EPSG code, as the GeoKeys GTModelType, GTRasterType and
/// GeographicType or ProjectedCSType say it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct EpsgCrs {
    model: u16,
    raster: u16,
    code: u16,
}

impl EpsgCrs {
    fn is_valid(&self) -> bool {
        matches!(self.model, MODEL_PROJECTED | MODEL_GEOGRAPHIC)
            && matches!(self.raster, 1 | 2)
            && (1024..32767).contains(&self.code)
    }

    fn code_key(&self) -> u16 {
        if self.model == MODEL_PROJECTED {
            PROJECTED_TYPE
        } else {
            GEOGRAPHIC_TYPE
        }
    }

    /// The GeoKey directory that says this CRS and nothing more.
    fn keys(&self) -> Vec<u16> {
        #[rustfmt::skip]
        let keys = vec![
            1, 1, 0, 3,
            MODEL_TYPE, 0, 1, self.model,
            RASTER_TYPE, 0, 1, self.raster,
            self.code_key(), 0, 1, self.code,
        ];
        keys
    }
}

/// The EPSG code, model and raster type of `georef`'s GeoKeys when they say no more than
/// an EPSG code does: besides those three keys, only keys that restate the code
/// (citations, degree or metre units, and the WGS 84 ellipsoid of EPSG:4326).
fn epsg_form(georef: &Georef) -> Option<EpsgCrs> {
    let dir = &georef.geo_key_directory;
    if dir.get(..3)? != [1, 1, 0] || dir.len() != 4 + 4 * usize::from(dir[3]) {
        return None;
    }
    let value = |id: u16| {
        dir[4..]
            .chunks_exact(4)
            .find(|k| k[0] == id && k[1] == 0 && k[2] == 1)
            .map(|k| k[3])
    };
    let model = value(MODEL_TYPE)?;
    let crs = EpsgCrs {
        model,
        raster: value(RASTER_TYPE)?,
        code: value(if model == MODEL_PROJECTED {
            PROJECTED_TYPE
        } else {
            GEOGRAPHIC_TYPE
        })?,
    };
    let wgs84 = crs.model == MODEL_GEOGRAPHIC && crs.code == 4326;
    let restates = |k: &[u16]| match (k[0], k[1]) {
        (MODEL_TYPE | RASTER_TYPE, 0) => true,
        (id, 0) if id == crs.code_key() => true,
        // GTCitation, GeogCitation, PCSCitation.
        (1026 | 2049 | 3073, 34737) => true,
        // Angular unit degree (GDAL writes it for projected CRSs too); linear unit metre.
        (2054, 0) => k[3] == 9102,
        (3076, 0) => crs.model == MODEL_PROJECTED && k[3] == 9001,
        // Semi-major, semi-minor axis, inverse flattening of WGS 84.
        (2057, 34736) => wgs84 && double(georef, k) == Some(6378137.0),
        (2058, 34736) => wgs84 && double(georef, k) == Some(6356752.314245179),
        (2059, 34736) => wgs84 && double(georef, k) == Some(298.257223563),
        _ => false,
    };
    (crs.is_valid() && dir[4..].chunks_exact(4).all(restates)).then_some(crs)
}

/// The single GeoDoubleParams value a key points at.
fn double(georef: &Georef, key: &[u16]) -> Option<f64> {
    (key[2] == 1)
        .then(|| georef.geo_double_params.get(usize::from(key[3])).copied())
        .flatten()
}

fn write_metadata(out: &mut Vec<u8>, metadata: &Metadata) {
    let mut entries: Vec<(u8, Vec<u8>)> = Vec::new();
    for (role, value) in [
        (role::SCALE, metadata.scale),
        (role::OFFSET, metadata.offset),
    ] {
        if let Some(v) = value {
            let mut body = Vec::new();
            write_number(&mut body, v);
            entries.push((role, body));
        }
    }
    for (role, text) in [
        (role::DESCRIPTION, &metadata.description),
        (role::UNIT_TYPE, &metadata.unit_type),
        (role::CRS_WKT, &metadata.crs_wkt),
    ] {
        if let Some(text) = text {
            let mut body = Vec::new();
            write_string(&mut body, text);
            entries.push((role, body));
        }
    }
    for item in &metadata.items {
        let mut body = Vec::new();
        write_string(&mut body, &item.name);
        write_string(&mut body, &item.domain);
        write_string(&mut body, &item.value);
        let role = if item.band {
            role::BAND_ITEM
        } else {
            role::DATASET_ITEM
        };
        entries.push((role, body));
    }
    write_varint(out, entries.len() as u64);
    for (role, body) in entries {
        out.push(role);
        write_varint(out, body.len() as u64);
        out.extend_from_slice(&body);
    }
}

fn read_metadata(r: &mut Reader) -> Result<Metadata, CodecError> {
    let mut metadata = Metadata::default();
    let count = r.varint_count(2)?;
    for _ in 0..count {
        let role = r.u8()?;
        let len = r.varint_count(1)?;
        let mut entry = Reader {
            data: r.bytes(len)?,
            pos: 0,
        };
        let repeated = || CodecError::InvalidHeader(format!("metadata role {role} repeated"));
        match role {
            role::SCALE | role::OFFSET => {
                let slot = if role == role::SCALE {
                    &mut metadata.scale
                } else {
                    &mut metadata.offset
                };
                if slot.replace(entry.number()?).is_some() {
                    return Err(repeated());
                }
            }
            role::DESCRIPTION | role::UNIT_TYPE | role::CRS_WKT => {
                let slot = match role {
                    role::DESCRIPTION => &mut metadata.description,
                    role::UNIT_TYPE => &mut metadata.unit_type,
                    _ => &mut metadata.crs_wkt,
                };
                if slot.replace(entry.string()?).is_some() {
                    return Err(repeated());
                }
            }
            role::DATASET_ITEM | role::BAND_ITEM => metadata.items.push(MetadataItem {
                name: entry.string()?,
                domain: entry.string()?,
                value: entry.string()?,
                band: role == role::BAND_ITEM,
            }),
            // Roles a later version defines: skipped.
            _ => entry.pos = entry.data.len(),
        }
        if entry.pos != entry.data.len() {
            return Err(CodecError::InvalidHeader(format!(
                "metadata entry of role {role} has trailing bytes"
            )));
        }
    }
    Ok(metadata)
}

impl Reader<'_> {
    /// A varint that must fit in a u32.
    fn varint_u32(&mut self, what: &str) -> Result<u32, CodecError> {
        u32::try_from(self.varint()?)
            .map_err(|_| CodecError::InvalidHeader(format!("{what} above 2^32")))
    }

    /// A *number* (see [`write_number`]).
    pub(super) fn number(&mut self) -> Result<f64, CodecError> {
        let v = self.varint()?;
        match (v & 3, v >> 2) {
            (0, z) => Ok(((z >> 1) as i64 ^ -((z & 1) as i64)) as f64),
            (1, p) => {
                short_value(p).ok_or_else(|| CodecError::InvalidHeader(format!("number code {v}")))
            }
            (2, 0) => self.f64(),
            (3, 0) => Ok(f64::from(f32::from_bits(self.u32()?))),
            _ => Err(CodecError::InvalidHeader(format!("number code {v}"))),
        }
    }

    /// A varint element count whose elements of at least `size` bytes fit in what is left.
    fn varint_count(&mut self, size: usize) -> Result<usize, CodecError> {
        let n = usize::try_from(self.varint()?).unwrap_or(usize::MAX);
        if n.saturating_mul(size) > self.data.len() - self.pos {
            return Err(CodecError::InvalidHeader(
                "a list runs past the header".into(),
            ));
        }
        Ok(n)
    }

    /// A varint length, then that many bytes of UTF-8.
    fn string(&mut self) -> Result<String, CodecError> {
        let len = self.varint_count(1)?;
        String::from_utf8(self.bytes(len)?.to_vec())
            .map_err(|_| CodecError::InvalidHeader("header text is not UTF-8".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primed_models_need_coder_2_and_propagation_needs_them() {
        let coder_2 = 1 << CODER_2_BIT;
        assert_eq!(read_coder(0, 6).unwrap(), Coder::V1);
        assert_eq!(read_coder(coder_2, 6).unwrap(), Coder::V2);
        assert_eq!(read_coder(coder_2, PRIMED_BIT | 6).unwrap(), Coder::V3);
        let both = PRIMED_BIT | PROPAGATION_BIT | 6;
        assert_eq!(read_coder(coder_2, both).unwrap(), Coder::V4);
        assert!(read_coder(0, PRIMED_BIT | 6).is_err());
        assert!(read_coder(0, both).is_err());
        assert!(read_coder(coder_2, PROPAGATION_BIT | 6).is_err());
        for coder in [Coder::V1, Coder::V2, Coder::V3, Coder::V4] {
            let kinds = u8::from(coder != Coder::V1) << CODER_2_BIT;
            assert_eq!(
                read_coder(kinds, levels_coder_bits(coder) | 6).unwrap(),
                coder
            );
        }
    }
}
