//! The `.ezw` container: header, nodata mask, embedded payload, float residuals.
//!
//! `codec/FORMAT.md` specifies the byte layout; this module is its implementation.
//! All integers are little-endian. The header ends with a CRC-32 of everything before it.
//! This build writes version 2 ([`v2`]: compact, with metadata) and reads versions 1
//! ([`v1`]) and 2; everything after the header is the same in both.

mod number;
mod sections;
mod v1;
mod v2;

pub(crate) use sections::StreamSections;

use crate::error::CodecError;
use crate::ezw::{Coder, PassRecord, MAX_PLANE};
use crate::quantize::ValueMapping;
use crate::raster::{Georef, Metadata, SampleType};
use crate::wavelet::{self, ShiftRule, Wavelet};

/// First eight bytes of every `.ezw` file.
pub const MAGIC: [u8; 8] = *b"\x89EZW\r\n\x1a\n";
/// The container version this build writes (it also reads version 1).
pub const VERSION: u16 = 2;

/// How the stream was made, which says what its complete decode guarantees.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Bit-exact reconstruction (5/3; floats via grid or residuals).
    Lossless,
    /// Rate-driven (9/7 or a cut 5/3 stream): no error bound.
    Lossy,
    /// Every valid sample within `max_error` of the original.
    MaxError,
    /// Floats quantised to a user step ([`crate::Quality::Precision`]): within `step / 2`.
    Precision,
}

impl Mode {
    fn code(self) -> u8 {
        match self {
            Mode::Lossless => 0,
            Mode::Lossy => 1,
            Mode::MaxError => 2,
            Mode::Precision => 3,
        }
    }

    fn from_code(code: u8) -> Option<Mode> {
        Some(match code {
            0 => Mode::Lossless,
            1 => Mode::Lossy,
            2 => Mode::MaxError,
            3 => Mode::Precision,
            _ => return None,
        })
    }

    /// Lower-case name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Lossless => "lossless",
            Mode::Lossy => "lossy",
            Mode::MaxError => "max-error",
            Mode::Precision => "precision",
        }
    }
}

/// Everything the decoder needs before the payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Type of the source (and decoded) samples.
    pub sample_type: SampleType,
    /// Transform.
    pub wavelet: Wavelet,
    /// Decomposition levels.
    pub levels: u8,
    /// Coding mode.
    pub mode: Mode,
    /// Sample value of the coded integers (5/3) or offset of the coded reals (9/7, step 1).
    pub mapping: ValueMapping,
    /// Bound on |decoded − original| of the complete stream (0 lossless; +∞ lossy).
    pub max_error: f64,
    /// 9/7 quantiser step in coefficient units (1 for 5/3).
    pub coefficient_step: f64,
    /// Nodata value of the source (may be NaN), if it had one.
    pub nodata: Option<f64>,
    /// Minimum and maximum valid sample value of the source. A single stream stores them
    /// in its ladder section at the end of the file: NaN when a file cut short (or with
    /// a damaged ladder) does not hold them.
    pub valid_range: (f64, f64),
    /// Global bit-plane of the first pass; `None` when every coefficient is zero.
    pub top_plane: Option<u8>,
    /// The context models the payload is coded with (version 1 files: [`Coder::V1`]).
    pub coder: Coder,
    /// How the 5/3 subbands' plane shifts are rounded from their norms, when `bands` are
    /// derived (flag 14: [`ShiftRule::Lowered`]).
    pub shift_rule: ShiftRule,
    /// Per subband: the plane shift and the scale the 9/7 coefficients were multiplied by.
    pub bands: Vec<(u8, f64)>,
    /// The bands a decoder derives for this header's size, levels and wavelet (see
    /// [`derived_bands`]), when the encoder or the parser already computed them: a
    /// written header leaves `bands` out when they equal these.
    pub(crate) derived: DerivedMemo,
    /// Bytes of the payload in the file (framed: with its chunk checksums).
    pub payload_len: u64,
    /// The payload is a prefix of a longer embedded stream (the encoder stopped at a byte
    /// budget or chose a cut): it is decoded as a truncated stream.
    pub payload_truncated: bool,
    /// Bytes of the coded nodata mask, framed (0: no mask, every sample valid).
    pub mask_len: u32,
    /// Bytes of the residual section, framed: exact float residuals (lossless), or
    /// max-error corrections when `correction_step > 0` (0: no section).
    pub residual_len: u32,
    /// Step of the max-error corrections (0: none).
    pub correction_step: f64,
    /// Float residuals choose their length models by the exponent of their sample's
    /// reconstruction (flag 16), not by `coder` (see `residual.rs`).
    pub residuals_by_exponent: bool,
    /// Bytes of the ladder section, framed, as read from a file (writing recomputes it
    /// from `passes`).
    pub ladder_len: u32,
    /// One record per pass from the top plane down, for the passes the stream holds
    /// completely. Stored in a section at the end of the file (the ladder), so a prefix
    /// spends no bytes on it; empty when the file was truncated before it.
    pub passes: Vec<PassRecord>,
    /// Georeferencing carried through.
    pub georef: Option<Georef>,
    /// GIS metadata carried through (version 2; empty in version-1 files).
    pub metadata: Metadata,
    /// The tile layout of a tiled file; `None` for a single stream. A tiled file's
    /// header describes the whole raster and holds none of a stream's fields (mapping,
    /// planes, section lengths keep their defaults): each tile is a stream of its own
    /// (see [`crate::tiles`]).
    pub tiling: Option<Tiling>,
}

/// How a tiled file cuts its raster: tiles of `tile_width × tile_height` samples from
/// the top-left corner in row-major order (those on the right and bottom edges smaller),
/// listed by an index section of `index_len` framed bytes right after the header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tiling {
    /// Columns of a tile.
    pub tile_width: u32,
    /// Rows of a tile.
    pub tile_height: u32,
    /// Samples each tile's stream codes beyond the tile on each side.
    pub overlap: u32,
    /// Bytes of the tile index, framed.
    pub index_len: u64,
    /// The tiles' streams have the tile layout (headers without magic, version or
    /// ladder; see [`Header::parse_tile`]) and the index its compact form; false in files
    /// written before it, whose tiles are single-stream files.
    pub compact_tiles: bool,
    /// Side of the code blocks each tile is cut into (flag 15): a tile is then one
    /// transform whose coefficients below each `code_block`-sample square are coded as an
    /// embedded stream of its own, listed in the index after the tile's head (see
    /// [`crate::tiles`]). `None`: every tile is one stream.
    pub code_block: Option<u32>,
}

impl Header {
    /// A header for a `width × height` raster with every stream field at its default
    /// (no planes, no sections, unit mapping): what a tiled file's header holds, and
    /// where an encoder starts.
    pub fn whole_raster(
        width: u32,
        height: u32,
        sample_type: SampleType,
        wavelet: Wavelet,
        levels: u8,
        mode: Mode,
    ) -> Header {
        Header {
            width,
            height,
            sample_type,
            wavelet,
            levels,
            mode,
            mapping: ValueMapping {
                offset: 0.0,
                step: 1.0,
            },
            max_error: 0.0,
            coefficient_step: 1.0,
            nodata: None,
            valid_range: (0.0, 0.0),
            top_plane: None,
            coder: crate::ezw::Coder::default(),
            shift_rule: ShiftRule::Rounded,
            bands: Vec::new(),
            derived: DerivedMemo(None),
            payload_len: 0,
            payload_truncated: false,
            mask_len: 0,
            residual_len: 0,
            correction_step: 0.0,
            residuals_by_exponent: false,
            ladder_len: 0,
            passes: Vec::new(),
            georef: None,
            metadata: Metadata::default(),
            tiling: None,
        }
    }

    /// Number of samples.
    pub fn sample_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// Serialises the header (version 2), checksum included.
    pub fn to_bytes(&self) -> Vec<u8> {
        v2::write(self)
    }

    /// Parses and validates a header at the start of `data`; returns it and its length.
    pub fn parse(data: &[u8]) -> Result<(Header, usize), CodecError> {
        Header::parse_with_ladder(data, |start, len| {
            data.get(start..start.checked_add(len)?).map(<[u8]>::to_vec)
        })
    }

    /// [`Header::parse`] of `data`, a prefix of a file, with the ladder's framed bytes
    /// fetched by `ladder(start, len)` from wherever the whole file is (a decode cut
    /// short keeps the ladder's pass records that way). A ladder `ladder` cannot give,
    /// or a damaged one, is simply not shown.
    pub(crate) fn parse_with_ladder(
        data: &[u8],
        ladder: impl FnOnce(usize, usize) -> Option<Vec<u8>>,
    ) -> Result<(Header, usize), CodecError> {
        if data.len() < MAGIC.len() {
            return Err(if MAGIC.starts_with(data) {
                CodecError::TruncatedHeader("file shorter than the magic bytes")
            } else {
                CodecError::BadMagic
            });
        }
        if data[..8] != MAGIC {
            return Err(CodecError::BadMagic);
        }
        let mut r = Reader { data, pos: 8 };
        let version = r.u16()?;
        let header_len = match version {
            1 => r.u32()? as usize,
            2 => usize::try_from(r.varint()?).unwrap_or(usize::MAX),
            _ => return Err(CodecError::UnsupportedVersion(version, VERSION)),
        };
        let header_len = checked_header_len(data, header_len, r.pos)?;
        // From here on the bytes are what the encoder wrote; the checks below guard
        // against a forged checksum.
        let mut r = Reader {
            data: &data[..header_len - 4],
            pos: r.pos,
        };
        let (mut header, range_in_ladder) = match version {
            1 => (v1::parse_fields(&mut r)?, false),
            _ => v2::parse_fields(&mut r)?,
        };
        if r.pos != r.data.len() {
            return Err(CodecError::InvalidHeader(
                "trailing bytes in the header".into(),
            ));
        }
        header.validate()?;
        if let Some(tiling) = header.tiling {
            if logical_len(tiling.index_len).is_none() || tiling.index_len > MAX_FILE_LEN {
                return Err(CodecError::InvalidHeader(format!(
                    "tile index length {}",
                    tiling.index_len
                )));
            }
            return Ok((header, header_len));
        }
        check_section_lens(&header, header_len)?;
        let ladder_len = header.ladder_len as usize;
        // The ladder trails the file; a truncated or damaged one is simply not shown.
        let ladder_start = (header_len as u64)
            .saturating_add(header.mask_len as u64)
            .saturating_add(header.payload_len)
            .saturating_add(header.residual_len as u64);
        if let Some(framed) = usize::try_from(ladder_start)
            .ok()
            .and_then(|start| ladder(start, ladder_len))
        {
            let ladder = unframe(&framed, ladder_len);
            let parsed = ladder
                .complete
                .then(|| parse_ladder(&ladder.bytes, header.top_plane, range_in_ladder))
                .flatten();
            if let Some((range, passes)) = parsed {
                header.passes = passes;
                header.valid_range = range.unwrap_or(header.valid_range);
            }
        }
        Ok((header, header_len))
    }

    /// Parses and validates a header in the tile layout (the tiles of a tiled file
    /// under flag 13: no magic, version, ladder or valid range) at the start of `data`;
    /// returns it and its length.
    pub fn parse_tile(data: &[u8]) -> Result<(Header, usize), CodecError> {
        let mut r = Reader { data, pos: 0 };
        let header_len = match r.varint() {
            Ok(len) => usize::try_from(len).unwrap_or(usize::MAX),
            Err(_) => return Err(CodecError::TruncatedHeader("tile ends inside its header")),
        };
        let header_len = checked_header_len(data, header_len, r.pos)?;
        let mut r = Reader {
            data: &data[..header_len - 4],
            pos: r.pos,
        };
        let header = v2::parse_tile_fields(&mut r)?;
        if r.pos != r.data.len() {
            return Err(CodecError::InvalidHeader(
                "trailing bytes in the header".into(),
            ));
        }
        header.validate()?;
        check_section_lens(&header, header_len)?;
        Ok((header, header_len))
    }

    /// Serialises the header in the tile layout (see [`Header::parse_tile`]).
    pub(crate) fn to_tile_bytes(&self) -> Vec<u8> {
        v2::write_tile(self)
    }

    /// Checks the fields whose values no stream can have (a forged checksum).
    fn validate(&self) -> Result<(), CodecError> {
        if self.width == 0 || self.height == 0 {
            return Err(CodecError::Dimensions {
                width: self.width as u64,
                height: self.height as u64,
            });
        }
        let ValueMapping { offset, step } = self.mapping;
        if !(offset.is_finite()
            && step.is_finite()
            && step > 0.0
            && self.coefficient_step.is_finite()
            && self.coefficient_step > 0.0)
        {
            return Err(CodecError::InvalidHeader("quantisation parameters".into()));
        }
        if let Some(p) = self.top_plane.filter(|&p| p as u32 > MAX_PLANE) {
            return Err(CodecError::InvalidHeader(format!("top plane {p}")));
        }
        if !(self.correction_step.is_finite() && self.correction_step >= 0.0) {
            return Err(CodecError::InvalidHeader("correction step".into()));
        }
        Ok(())
    }

    /// The header length a file's version and length field claim (unchecked), `None` if
    /// `data` does not start with the magic bytes and a readable length field.
    pub(crate) fn declared_len(data: &[u8]) -> Option<usize> {
        if data.get(..MAGIC.len())? != MAGIC {
            return None;
        }
        let mut r = Reader { data, pos: 8 };
        match r.u16().ok()? {
            1 => r.u32().ok().map(|n| n as usize),
            2 => r.varint().ok().and_then(|n| usize::try_from(n).ok()),
            _ => None,
        }
    }

    /// The section that trails a single stream: its valid range, then the
    /// rate–distortion ladder; empty when neither is known (a tile's stream: the tiled
    /// file's header and index hold them).
    pub(crate) fn ladder_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let range_unknown = self.valid_range.0.is_nan() && self.valid_range.1.is_nan();
        if range_unknown && self.passes.is_empty() {
            return out;
        }
        if self.tiling.is_none() {
            number::write_number(&mut out, self.valid_range.0);
            number::write_number(&mut out, self.valid_range.1);
        }
        out.push(self.passes.len() as u8);
        let mut previous_end = 0;
        for pass in &self.passes {
            write_varint(&mut out, pass.end_byte - previous_end);
            previous_end = pass.end_byte;
            out.extend_from_slice(&error_to_u16(pass.squared_error).to_le_bytes());
        }
        out
    }
}

/// `header_len` as a header at the start of `data` whose fields start at `fields` claims
/// it, once its checksum (its last 4 bytes) is checked.
fn checked_header_len(data: &[u8], header_len: usize, fields: usize) -> Result<usize, CodecError> {
    if header_len < fields + 4 || header_len > data.len() {
        return Err(if header_len > data.len() && header_len <= MAX_HEADER_LEN {
            CodecError::TruncatedHeader("file ends inside the header")
        } else {
            CodecError::InvalidHeader(format!("header length {header_len}"))
        });
    }
    let stored = u32::from_le_bytes(
        data[header_len - 4..header_len]
            .try_into()
            .expect("4 bytes"),
    );
    let computed = crc32fast::hash(&data[..header_len - 4]);
    if stored != computed {
        return Err(CodecError::HeaderChecksum { stored, computed });
    }
    Ok(header_len)
}

/// Checks that the sections `header` lists after `header_len` bytes have valid framed
/// lengths and end within any file.
fn check_section_lens(header: &Header, header_len: usize) -> Result<(), CodecError> {
    let mut file_len = header_len as u64;
    for (what, len) in [
        ("nodata mask", header.mask_len as u64),
        ("payload", header.payload_len),
        ("residual section", header.residual_len as u64),
        ("ladder", header.ladder_len as u64),
    ] {
        if logical_len(len).is_none() {
            return Err(CodecError::InvalidHeader(format!("{what} length {len}")));
        }
        // Offsets are computed in usize: the whole file must be addressable.
        file_len = file_len
            .checked_add(len)
            .filter(|&end| end <= MAX_FILE_LEN)
            .ok_or_else(|| {
                CodecError::InvalidHeader(format!("{what} length {len} runs past any file"))
            })?;
    }
    Ok(())
}

/// `georef` as a version-2 file carries it: a CRS its EPSG code says completely is reduced
/// to the code's three GeoKeys (model type, raster type, code), dropping the keys that
/// only restate it (citations, degree or metre units, the WGS 84 ellipsoid of EPSG:4326);
/// any other georeferencing is kept as it is.
pub fn stored_georef(georef: &Georef) -> Georef {
    v2::stored_georef(georef)
}

/// Largest side for which a decoder derives the subband shifts and scales from the
/// dimensions instead of reading them (deriving costs O(bands · side)).
const MAX_DERIVED_SIDE: u32 = 1 << 16;

/// The subband shifts (5/3, rounded by `rule`) or scales (9/7) the encoder gives a
/// `width × height` raster with `levels` levels, computed from the transform's synthesis
/// norms; `None` above [`MAX_DERIVED_SIDE`].
fn derived_bands(
    (wavelet, rule): (Wavelet, ShiftRule),
    width: u32,
    height: u32,
    levels: u8,
) -> Option<Vec<(u8, f64)>> {
    if width.max(height) > MAX_DERIVED_SIDE
        || u32::from(levels) > wavelet::max_levels(width as usize, height as usize)
    {
        return None;
    }
    let norms = wavelet::coding_norms(wavelet, width as usize, height as usize, levels.into());
    Some(bands_from_norms((wavelet, rule), norms))
}

/// A header's [`DerivedBands`] when already computed: a memo, so it takes no part in
/// comparing headers (two headers with the same fields are equal whether or not either
/// has computed them).
#[derive(Debug, Clone)]
pub(crate) struct DerivedMemo(pub(crate) Option<DerivedBands>);

impl PartialEq for DerivedMemo {
    fn eq(&self, _: &DerivedMemo) -> bool {
        true
    }
}

/// The bands a decoder derives for a header, kept with what they were derived for.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DerivedBands {
    /// Wavelet and shift rule, width, height and levels they were derived for.
    key: ((Wavelet, ShiftRule), u32, u32, u8),
    bands: Vec<(u8, f64)>,
}

impl DerivedBands {
    /// The derived bands of `header`'s size from the coding norms of that size (the
    /// encoder's, so nobody computes them again); `None` above [`MAX_DERIVED_SIDE`].
    pub(crate) fn from_norms(header: &Header, norms: Vec<f64>) -> Option<DerivedBands> {
        (header.width.max(header.height) <= MAX_DERIVED_SIDE).then(|| DerivedBands {
            key: derivation_key(header),
            bands: bands_from_norms((header.wavelet, header.shift_rule), norms),
        })
    }

    /// `header`'s bands, which a parser derived (the header did not list them).
    pub(crate) fn as_read(header: &Header) -> DerivedBands {
        DerivedBands {
            key: derivation_key(header),
            bands: header.bands.clone(),
        }
    }

    /// The derived bands of `header`'s size, computed.
    fn of(header: &Header) -> Option<DerivedBands> {
        let (kind, width, height, levels) = derivation_key(header);
        derived_bands(kind, width, height, levels).map(|bands| DerivedBands {
            key: derivation_key(header),
            bands,
        })
    }
}

fn derivation_key(header: &Header) -> ((Wavelet, ShiftRule), u32, u32, u8) {
    let kind = (header.wavelet, header.shift_rule);
    (kind, header.width, header.height, header.levels)
}

/// Whether `header`'s bands are the ones a decoder derives from its size (computed only
/// when the header does not carry them for its current size).
fn bands_derivable(header: &Header) -> bool {
    match &header.derived.0 {
        Some(d) if d.key == derivation_key(header) => d.bands == header.bands,
        _ => DerivedBands::of(header).is_some_and(|d| d.bands == header.bands),
    }
}

/// The subband shifts (5/3, rounded by `rule`) or scales (9/7, as stored) of coding norms
/// `norms`.
fn bands_from_norms((wavelet, rule): (Wavelet, ShiftRule), norms: Vec<f64>) -> Vec<(u8, f64)> {
    match wavelet {
        Wavelet::Int53 | Wavelet::Int1311 => wavelet::plane_shifts(&norms, rule)
            .into_iter()
            .map(|shift| (shift.min(u8::MAX.into()) as u8, 1.0))
            .collect(),
        Wavelet::Cdf97 => norms
            .into_iter()
            .map(|n| (0, scale_from_u16(scale_to_u16(n))))
            .collect(),
    }
}

/// Reads the four one-byte codes: sample type, wavelet, levels, mode.
fn read_kinds(r: &mut Reader) -> Result<(SampleType, Wavelet, u8, Mode), CodecError> {
    let sample_type = SampleType::from_code(r.u8()?)
        .ok_or_else(|| CodecError::InvalidHeader("unknown sample type".into()))?;
    let wavelet = Wavelet::from_code(r.u8()?)
        .ok_or_else(|| CodecError::InvalidHeader("unknown wavelet".into()))?;
    let levels = r.u8()?;
    let mode =
        Mode::from_code(r.u8()?).ok_or_else(|| CodecError::InvalidHeader("unknown mode".into()))?;
    Ok((sample_type, wavelet, levels, mode))
}

/// Refuses more levels than the raster allows.
fn check_levels(width: u32, height: u32, levels: u8) -> Result<(), CodecError> {
    if levels as u32 > wavelet::max_levels(width as usize, height as usize) {
        return Err(CodecError::InvalidHeader(format!(
            "{levels} levels for {width}x{height}"
        )));
    }
    Ok(())
}

/// Reads the listed subband shifts (5/3, one u8 each) or scales (9/7, one u16 each in
/// 1/8192 units), `3 · levels + 1` of them (1 when `levels` is 0).
fn read_bands(r: &mut Reader, wavelet: Wavelet, levels: u8) -> Result<Vec<(u8, f64)>, CodecError> {
    let count = if levels == 0 {
        1
    } else {
        3 * levels as usize + 1
    };
    let mut bands = Vec::with_capacity(count);
    for _ in 0..count {
        let (shift, scale) = match wavelet {
            Wavelet::Int53 | Wavelet::Int1311 => (r.u8()?, 1.0),
            Wavelet::Cdf97 => (0, scale_from_u16(r.u16()?)),
        };
        if shift as u32 > MAX_PLANE || !(scale.is_finite() && scale > 0.0) {
            return Err(CodecError::InvalidHeader("subband shift or scale".into()));
        }
        bands.push((shift, scale));
    }
    Ok(bands)
}

/// Bytes of section data per checksummed chunk. Every section after the header (mask,
/// payload, residuals, ladder) is stored as chunks of this many bytes (the last one
/// shorter), each followed by the CRC-32 of its bytes.
pub const CHUNK: usize = 16 * 1024;

/// Size in the file of a section of `logical` bytes.
pub fn framed_len(logical: usize) -> usize {
    logical + 4 * logical.div_ceil(CHUNK)
}

/// Bytes of data in a framed section of `framed` bytes; `None` if no section has that size.
pub fn logical_len(framed: u64) -> Option<u64> {
    let chunks = framed.div_ceil(CHUNK as u64 + 4);
    let logical = framed.checked_sub(4 * chunks)?;
    (framed_len(usize::try_from(logical).ok()?) as u64 == framed).then_some(logical)
}

/// File offset, within a framed section, of logical byte `logical`.
pub fn physical_offset(logical: u64) -> u64 {
    logical + 4 * (logical / CHUNK as u64)
}

/// Data byte of a framed section at file offset `physical` within it (the inverse of
/// [`physical_offset`]).
pub(crate) fn logical_offset(physical: u64) -> u64 {
    physical - 4 * (physical / (CHUNK as u64 + 4))
}

/// Splits `section` into checksummed chunks.
pub fn frame(section: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(framed_len(section.len()));
    for chunk in section.chunks(CHUNK) {
        out.extend_from_slice(chunk);
        out.extend_from_slice(&crc32fast::hash(chunk).to_le_bytes());
    }
    out
}

/// A framed section read back.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Unframed {
    /// The data of every verified chunk, then the unverified bytes of a final chunk cut
    /// short by the end of the file (truncation is not damage).
    pub bytes: Vec<u8>,
    /// Offset within the section of the first chunk whose checksum failed; nothing from
    /// it on is in `bytes`.
    pub damaged_at: Option<usize>,
    /// Every chunk was present and verified.
    pub complete: bool,
}

/// What the checksums of a framed section say, without copying it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameCheck {
    /// Data bytes usable: every verified chunk, then the unverified bytes of a final
    /// chunk cut short by the end of the file.
    pub data_len: usize,
    /// Offset within the section of the first chunk whose checksum failed.
    pub damaged_at: Option<usize>,
    /// Every chunk was present and verified.
    pub complete: bool,
}

/// Checks a framed section of `framed_total` bytes of which `available` is what the
/// file holds (a prefix when the file is truncated).
pub fn check_frames(available: &[u8], framed_total: usize) -> FrameCheck {
    let available = &available[..available.len().min(framed_total)];
    let mut data_len = 0;
    let mut start = 0;
    while start < available.len() {
        let chunk_len = CHUNK.min(framed_total.saturating_sub(start + 4));
        let end = start + chunk_len;
        if end + 4 > available.len() {
            // Cut short by the end of the file: what there is counts, unverified.
            return FrameCheck {
                data_len: data_len + end.min(available.len()) - start,
                damaged_at: None,
                complete: false,
            };
        }
        let stored = u32::from_le_bytes(available[end..end + 4].try_into().expect("4 bytes"));
        if crc32fast::hash(&available[start..end]) != stored {
            return FrameCheck {
                data_len,
                damaged_at: Some(start),
                complete: false,
            };
        }
        data_len += chunk_len;
        start = end + 4;
    }
    FrameCheck {
        data_len,
        damaged_at: None,
        complete: available.len() == framed_total,
    }
}

/// Reads a framed section of `framed_total` bytes of which `available` is what the file
/// holds (a prefix when the file is truncated), copying its data out.
pub fn unframe(available: &[u8], framed_total: usize) -> Unframed {
    let check = check_frames(available, framed_total);
    let mut bytes = Vec::with_capacity(check.data_len);
    for (k, chunk) in available.chunks(CHUNK + 4).enumerate() {
        let take = (check.data_len - k * CHUNK).min(CHUNK).min(chunk.len());
        bytes.extend_from_slice(&chunk[..take]);
        if bytes.len() == check.data_len {
            break;
        }
    }
    Unframed {
        bytes,
        damaged_at: check.damaged_at,
        complete: check.complete,
    }
}

/// Lays out a file: header, then the framed mask, payload, residual section and ladder.
/// Sets the header's section lengths; returns the bytes and the header's length.
pub fn assemble(
    header: &mut Header,
    mask: &[u8],
    payload: &[u8],
    residual: &[u8],
) -> (Vec<u8>, usize) {
    assemble_as(Layout::File, header, [mask, payload, residual])
}

/// Size of the file [`assemble`] makes from sections of these logical sizes.
pub fn assembled_len(header: &Header, mask: usize, payload: usize, residual: usize) -> usize {
    assembled_len_as(Layout::File, header, [mask, payload, residual])
}

/// How a stream is laid out: as a file, or as a tile of a tiled file (a header in the
/// tile layout, no ladder: see [`Header::parse_tile`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Layout {
    File,
    Tile,
}

/// [`assemble`] in either layout, from the mask, payload and residual section.
pub(crate) fn assemble_as(
    layout: Layout,
    header: &mut Header,
    [mask, payload, residual]: [&[u8]; 3],
) -> (Vec<u8>, usize) {
    header.mask_len = framed_len(mask.len()) as u32;
    header.payload_len = framed_len(payload.len()) as u64;
    header.residual_len = framed_len(residual.len()) as u32;
    let ladder = match layout {
        Layout::File => header.ladder_bytes(),
        Layout::Tile => Vec::new(),
    };
    header.ladder_len = framed_len(ladder.len()) as u32;
    let header_bytes = match layout {
        Layout::File => header.to_bytes(),
        Layout::Tile => header.to_tile_bytes(),
    };
    let sizes = [mask.len(), payload.len(), residual.len()];
    let mut out = Vec::with_capacity(assembled_len_as(layout, header, sizes));
    out.extend_from_slice(&header_bytes);
    for section in [mask, payload, residual, &ladder] {
        out.extend_from_slice(&frame(section));
    }
    (out, header_bytes.len())
}

/// [`assembled_len`] in either layout.
pub(crate) fn assembled_len_as(
    layout: Layout,
    header: &Header,
    [mask, payload, residual]: [usize; 3],
) -> usize {
    // The header's size depends on the section lengths (varints).
    let sized = Header {
        mask_len: framed_len(mask) as u32,
        payload_len: framed_len(payload) as u64,
        residual_len: framed_len(residual) as u32,
        ..header.clone()
    };
    let (header_len, ladder_len) = match layout {
        Layout::File => (sized.to_bytes().len(), header.ladder_bytes().len()),
        Layout::Tile => (sized.to_tile_bytes().len(), 0),
    };
    header_len
        + framed_len(mask)
        + framed_len(payload)
        + framed_len(residual)
        + framed_len(ladder_len)
}

/// The state of one framed section of a file, as [`verify`] finds it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SectionCheck {
    /// "nodata mask", "payload", "residual section" or "ladder"; in a tiled file "tile
    /// index" or "tile" (a tile's header and sections together).
    pub name: &'static str,
    /// The tile, for a tile of a tiled file.
    pub tile: Option<u32>,
    /// File offset of the section.
    pub offset: u64,
    /// Framed length the header gives.
    pub framed_len: u64,
    /// Chunks the section has.
    pub chunks: u64,
    /// Chunks present in the file whose checksum holds.
    pub verified_chunks: u64,
    /// File offset of the first chunk whose checksum fails.
    pub damaged_at: Option<u64>,
    /// Every chunk present and verified.
    pub complete: bool,
}

/// What [`verify`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Verification {
    /// The parsed header (its checksum holds).
    pub header: Header,
    /// Bytes of the header.
    pub header_len: u64,
    /// The framed sections in file order.
    pub sections: Vec<SectionCheck>,
    /// Bytes past the end of the file the header describes.
    pub trailing_bytes: u64,
    /// Bytes before the first damage (the whole file when there is none).
    pub usable_bytes: u64,
    /// Passes of the ladder whose bytes all lie in the usable prefix (when the ladder is
    /// readable).
    pub usable_passes: Option<u32>,
}

impl Verification {
    /// Whether some checksum failed or garbage trails the file.
    pub fn damaged(&self) -> bool {
        self.trailing_bytes > 0 || self.sections.iter().any(|s| s.damaged_at.is_some())
    }

    /// Whether every section is present (not truncated).
    pub fn complete(&self) -> bool {
        self.sections.iter().all(|s| s.complete)
    }
}

/// Checks the header checksum and every chunk checksum of a `.ezw` file.
pub fn verify(data: &[u8]) -> Result<Verification, CodecError> {
    let (header, header_len) = Header::parse(data)?;
    if header.tiling.is_some() {
        return crate::tiles::verify_tiled(data);
    }
    Ok(verify_sections(data, header, header_len))
}

/// [`verify`] of a tile's stream in the tile layout (see [`Header::parse_tile`]).
pub(crate) fn verify_tile(data: &[u8]) -> Result<Verification, CodecError> {
    let (header, header_len) = Header::parse_tile(data)?;
    Ok(verify_sections(data, header, header_len))
}

/// The checks of a single stream's sections, after its header.
fn verify_sections(data: &[u8], header: Header, header_len: usize) -> Verification {
    let mut offset = header_len as u64;
    let mut sections = Vec::new();
    for (name, len) in [
        ("nodata mask", header.mask_len as u64),
        ("payload", header.payload_len),
        ("residual section", header.residual_len as u64),
        ("ladder", header.ladder_len as u64),
    ] {
        let start = (offset as usize).min(data.len());
        let available = &data[start..(start as u64 + len).min(data.len() as u64) as usize];
        let read = unframe(available, len as usize);
        let chunks = (len as usize).div_ceil(CHUNK + 4) as u64;
        let verified = match read.damaged_at {
            Some(at) => (at / (CHUNK + 4)) as u64,
            None => {
                (available.len() / (CHUNK + 4)) as u64
                    + u64::from(read.complete && !available.len().is_multiple_of(CHUNK + 4))
            }
        };
        sections.push(SectionCheck {
            name,
            tile: None,
            offset,
            framed_len: len,
            chunks,
            verified_chunks: verified,
            damaged_at: read.damaged_at.map(|at| offset + at as u64),
            complete: read.complete,
        });
        offset += len;
    }
    let trailing_bytes = (data.len() as u64).saturating_sub(offset);
    let usable_bytes = sections
        .iter()
        .filter_map(|s| s.damaged_at)
        .min()
        .unwrap_or(if trailing_bytes > 0 {
            offset
        } else {
            data.len() as u64
        });
    let payload = &sections[1];
    let usable_passes = (!header.passes.is_empty()).then(|| {
        header
            .passes
            .iter()
            .filter(|p| payload.offset + physical_offset(p.end_byte) <= usable_bytes)
            .count() as u32
    });
    Verification {
        header,
        header_len: header_len as u64,
        sections,
        trailing_bytes,
        usable_bytes,
        usable_passes,
    }
}

/// A 9/7 subband scale (a synthesis norm, about 0.5–3) in 1/8192 units.
pub fn scale_to_u16(scale: f64) -> u16 {
    (scale * 8192.0).round().clamp(1.0, u16::MAX as f64) as u16
}

/// Inverse of [`scale_to_u16`].
pub fn scale_from_u16(code: u16) -> f64 {
    code as f64 / 8192.0
}

/// A squared error on a logarithmic scale: 1/256 of a bit (≈ 0.012 dB) per step,
/// `log2(1 + e) · 256`.
pub fn error_to_u16(squared_error: f64) -> u16 {
    ((1.0 + squared_error.max(0.0)).log2() * 256.0)
        .round()
        .min(u16::MAX as f64) as u16
}

/// Inverse of [`error_to_u16`] (to its precision).
pub fn error_from_u16(code: u16) -> f64 {
    (code as f64 / 256.0).exp2() - 1.0
}

/// Appends `value` as LEB128 (7 bits a byte, low first, high bit = more follows).
pub(crate) fn write_varint(out: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        out.push((value as u8) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// The valid range of a ladder section that starts with it, and the passes.
type Ladder = (Option<(f64, f64)>, Vec<PassRecord>);

/// Parses the ladder section (starting with the valid range when `with_range`); `None`
/// if it is malformed.
fn parse_ladder(bytes: &[u8], top_plane: Option<u8>, with_range: bool) -> Option<Ladder> {
    let mut r = Reader {
        data: bytes,
        pos: 0,
    };
    let range = if with_range {
        Some((r.number().ok()?, r.number().ok()?))
    } else {
        None
    };
    let count = r.u8().ok()? as usize;
    let top = top_plane.map_or(0, u32::from);
    if count > top as usize + 1 || (top_plane.is_none() && count > 0) {
        return None;
    }
    let mut passes = Vec::with_capacity(count);
    let mut end_byte = 0u64;
    for k in 0..count {
        end_byte = end_byte.checked_add(r.varint().ok()?)?;
        let squared_error = error_from_u16(r.u16().ok()?);
        passes.push(PassRecord {
            plane: top - k as u32,
            end_byte,
            squared_error,
        });
    }
    (r.pos == bytes.len()).then_some((range, passes))
}

/// Largest file the container describes (2^48 bytes, far beyond any DEM, and well inside
/// `usize` arithmetic on 64-bit targets).
pub(crate) const MAX_FILE_LEN: u64 = 1 << 48;

/// Largest header this build writes (georeferencing included) — a bigger claimed length
/// is corruption, not truncation.
pub(crate) const MAX_HEADER_LEN: usize = 1 << 24;

/// Bounds-checked little-endian reader.
pub(crate) struct Reader<'a> {
    pub(crate) data: &'a [u8],
    pub(crate) pos: usize,
}

impl<'a> Reader<'a> {
    fn bytes(&mut self, n: usize) -> Result<&'a [u8], CodecError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        let end = end.ok_or(CodecError::TruncatedHeader(
            "header fields run past its end",
        ))?;
        let slice = &self.data[self.pos..end];
        self.pos = end;
        Ok(slice)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], CodecError> {
        Ok(self.bytes(N)?.try_into().expect("exact length"))
    }
    pub(crate) fn u8(&mut self) -> Result<u8, CodecError> {
        Ok(self.bytes(1)?[0])
    }
    pub(crate) fn u16(&mut self) -> Result<u16, CodecError> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    fn u32(&mut self) -> Result<u32, CodecError> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    fn u64(&mut self) -> Result<u64, CodecError> {
        Ok(u64::from_le_bytes(self.array()?))
    }
    pub(crate) fn varint(&mut self) -> Result<u64, CodecError> {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = self.u8()?;
            value |= ((byte & 0x7F) as u64) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(CodecError::InvalidHeader(
            "varint longer than 64 bits".into(),
        ))
    }
    fn f64(&mut self) -> Result<f64, CodecError> {
        Ok(f64::from_le_bytes(self.array()?))
    }
    /// A u32 element count whose elements of `size` bytes must fit in what is left.
    fn count(&mut self, size: usize) -> Result<usize, CodecError> {
        let n = self.u32()? as usize;
        if n.saturating_mul(size) > self.data.len() - self.pos {
            return Err(CodecError::InvalidHeader(
                "a georeferencing list runs past the header".into(),
            ));
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_header() -> Header {
        Header {
            width: 403,
            height: 344,
            sample_type: SampleType::I16,
            wavelet: Wavelet::Int53,
            levels: 6,
            mode: Mode::Lossless,
            mapping: ValueMapping {
                offset: 236.0,
                step: 1.0,
            },
            max_error: 0.0,
            coefficient_step: 1.0,
            nodata: Some(f64::NAN),
            valid_range: (236.0, 1076.0),
            top_plane: Some(17),
            coder: Coder::V2,
            shift_rule: ShiftRule::Rounded,
            bands: (0..19).map(|b| (b as u8 / 3, 1.0)).collect(),
            derived: DerivedMemo(None),
            payload_len: 12345,
            payload_truncated: false,
            mask_len: 17,
            residual_len: 0,
            correction_step: 0.0,
            residuals_by_exponent: false,
            ladder_len: 0,
            passes: vec![
                PassRecord {
                    plane: 17,
                    end_byte: 3,
                    squared_error: error_from_u16(error_to_u16(1e9)),
                },
                PassRecord {
                    plane: 16,
                    end_byte: 300,
                    squared_error: error_from_u16(error_to_u16(0.25)),
                },
            ],
            georef: Some(Georef {
                geotransform: [-84.4, 0.000833, 0.0, 36.7, 0.0, -0.000833],
                geo_key_directory: vec![1, 1, 0, 1, 1024, 0, 1, 2],
                geo_double_params: vec![6378137.0],
                geo_ascii_params: "WGS 84|".into(),
            }),
            metadata: Metadata {
                scale: Some(0.1),
                offset: Some(-100.0),
                description: Some("elevation".into()),
                unit_type: Some("m".into()),
                crs_wkt: None,
                items: vec![crate::raster::MetadataItem {
                    name: "DTED_VerticalDatum".into(),
                    value: "E08".into(),
                    domain: String::new(),
                    band: false,
                }],
            },
            tiling: None,
        }
    }

    #[test]
    fn header_round_trips() {
        let mut h = sample_header();
        h.mask_len = 0;
        let (bytes, header_len) = assemble(&mut h, &[], &[1, 2, 3], &[]);
        let (parsed, len) = Header::parse(&bytes).unwrap();
        assert_eq!(len, header_len);
        assert_eq!(parsed.payload_len, 7);
        assert_eq!(parsed.passes, h.passes);
        // NaN != NaN: compare the nodata bits separately.
        assert_eq!(parsed.nodata.map(f64::to_bits), h.nodata.map(f64::to_bits));
        assert_eq!(
            Header {
                nodata: None,
                ..parsed
            },
            Header { nodata: None, ..h }
        );
    }

    #[test]
    fn every_coder_round_trips() {
        for coder in [Coder::V1, Coder::V2, Coder::V3, Coder::V4] {
            let mut h = sample_header();
            h.coder = coder;
            h.mask_len = 0;
            let (bytes, _) = assemble(&mut h, &[], &[1, 2, 3], &[]);
            assert_eq!(Header::parse(&bytes).unwrap().0.coder, coder);
        }
    }

    #[test]
    fn framing_detects_damage_and_tolerates_truncation() {
        let data: Vec<u8> = (0..40_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let framed = frame(&data);
        assert_eq!(framed.len(), framed_len(data.len()));
        assert_eq!(logical_len(framed.len() as u64), Some(data.len() as u64));
        let whole = unframe(&framed, framed.len());
        assert!(whole.complete && whole.damaged_at.is_none());
        assert_eq!(whole.bytes, data);
        // A flipped bit in the second chunk: the first chunk survives.
        let mut damaged = framed.clone();
        damaged[CHUNK + 4 + 100] ^= 0x10;
        let read = unframe(&damaged, framed.len());
        assert_eq!(read.damaged_at, Some(CHUNK + 4));
        assert_eq!(read.bytes, &data[..CHUNK]);
        // Truncation inside the third chunk: everything present is kept, unverified.
        let cut = 2 * (CHUNK + 4) + 50;
        let read = unframe(&framed[..cut], framed.len());
        assert!(!read.complete && read.damaged_at.is_none());
        assert_eq!(read.bytes, &data[..2 * CHUNK + 50]);
        for bad in [1u64, 2, 3, 4, CHUNK as u64 + 5] {
            assert_eq!(logical_len(bad), None, "{bad}");
        }
    }

    #[test]
    fn every_truncation_and_bit_flip_is_an_error() {
        let bytes = sample_header().to_bytes();
        for cut in 0..bytes.len() {
            assert!(Header::parse(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut damaged = bytes.clone();
                damaged[i] ^= 1 << bit;
                assert!(
                    Header::parse(&damaged).is_err(),
                    "flip at byte {i} bit {bit}"
                );
            }
        }
    }

    /// EPSG:4326 as GDAL writes it: the code plus keys that only restate it.
    fn gdal_epsg4326() -> Georef {
        Georef {
            geotransform: [-84.41375, 1.0 / 1200.0, 0.0, 36.7329, 0.0, -1.0 / 1200.0],
            geo_key_directory: vec![
                1, 1, 0, 7, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326, 2049, 34737, 7, 0,
                2054, 0, 1, 9102, 2057, 34736, 1, 1, 2059, 34736, 1, 0,
            ],
            geo_double_params: vec![298.257223563, 6378137.0],
            geo_ascii_params: "WGS 84|".into(),
        }
    }

    #[test]
    fn an_epsg_coded_crs_is_stored_as_its_code() {
        let mut h = sample_header();
        h.georef = Some(gdal_epsg4326());
        let (parsed, _) = Header::parse(&h.to_bytes()).unwrap();
        let georef = parsed.georef.unwrap();
        assert_eq!(georef.geotransform, gdal_epsg4326().geotransform);
        assert_eq!(
            georef.geo_key_directory,
            [1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326]
        );
        assert!(georef.geo_double_params.is_empty() && georef.geo_ascii_params.is_empty());
        // UTM zone 32N as GDAL writes it.
        let utm = Georef {
            geotransform: [618181.9, 90.0, 0.0, 6432695.2, 0.0, -90.0],
            geo_key_directory: vec![
                1, 1, 0, 7, 1024, 0, 1, 1, 1025, 0, 1, 1, 1026, 34737, 22, 0, 2049, 34737, 7, 22,
                2054, 0, 1, 9102, 3072, 0, 1, 32632, 3076, 0, 1, 9001,
            ],
            geo_double_params: vec![],
            geo_ascii_params: "WGS 84 / UTM zone 32N|WGS 84|".into(),
        };
        assert_eq!(
            stored_georef(&utm).geo_key_directory,
            [1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32632]
        );
        h.georef = Some(utm.clone());
        let (parsed, _) = Header::parse(&h.to_bytes()).unwrap();
        assert_eq!(parsed.georef, Some(stored_georef(&utm)));
        // A key the code does not imply (a vertical datum) keeps the full form.
        let mut vertical = gdal_epsg4326();
        vertical.geo_key_directory[3] += 1;
        vertical.geo_key_directory.extend([4096, 0, 1, 5773]);
        vertical.geotransform[2] = 0.5;
        h.georef = Some(vertical.clone());
        let (parsed, _) = Header::parse(&h.to_bytes()).unwrap();
        assert_eq!(parsed.georef, Some(vertical));
    }

    #[test]
    fn the_valid_range_is_in_the_ladder_and_a_prefix_without_it_does_not_know_it() {
        let mut h = sample_header();
        let (bytes, header_len) = assemble(&mut h, &[0], &[1, 2, 3], &[]);
        assert_eq!(
            Header::parse(&bytes).unwrap().0.valid_range,
            (236.0, 1076.0)
        );
        let (cut, _) = Header::parse(&bytes[..bytes.len() - 1]).unwrap();
        assert!(cut.valid_range.0.is_nan() && cut.valid_range.1.is_nan());
        assert!(cut.passes.is_empty());
        // The range is not in the header: another range leaves it the same length.
        h.valid_range = (-1e6, 1e6 + 0.25);
        assert_eq!(assemble(&mut h, &[0], &[1, 2, 3], &[]).1, header_len);
    }

    #[test]
    fn the_correction_step_of_a_max_error_stream_is_implied() {
        for (sample_type, max_error, step) in
            [(SampleType::U16, 2.5, 5.0), (SampleType::F32, 0.25, 0.4995)]
        {
            let mut h = sample_header();
            (h.sample_type, h.mode, h.max_error) = (sample_type, Mode::MaxError, max_error);
            h.correction_step = step;
            let (bytes, implied_len) = assemble(&mut h, &[0], &[1, 2, 3], &[9, 9]);
            let (parsed, _) = Header::parse(&bytes).unwrap();
            assert_eq!(parsed.correction_step, step, "{sample_type:?}");
            // Any other step is listed, and still read back.
            h.correction_step = step * 1.5;
            let (bytes, listed_len) = assemble(&mut h, &[0], &[1, 2, 3], &[9, 9]);
            assert!(listed_len > implied_len, "{sample_type:?}");
            assert_eq!(Header::parse(&bytes).unwrap().0.correction_step, step * 1.5);
        }
    }

    #[test]
    fn the_residual_length_flag_round_trips() {
        let mut h = sample_header();
        (h.sample_type, h.residuals_by_exponent) = (SampleType::F32, true);
        let (bytes, _) = assemble(&mut h, &[0], &[1, 2, 3], &[9, 9]);
        assert!(Header::parse(&bytes).unwrap().0.residuals_by_exponent);
        h.residuals_by_exponent = false;
        let (bytes, _) = assemble(&mut h, &[0], &[1, 2, 3], &[9, 9]);
        assert!(!Header::parse(&bytes).unwrap().0.residuals_by_exponent);
    }

    /// The 9/7 scales a decoder derives for `h`'s size.
    fn derived_97(h: &Header) -> Vec<(u8, f64)> {
        let kind = (Wavelet::Cdf97, ShiftRule::Rounded);
        derived_bands(kind, h.width, h.height, h.levels).unwrap()
    }

    #[test]
    fn derived_bands_are_left_out_only_when_they_are_those_of_the_size() {
        let mut h = sample_header();
        h.wavelet = Wavelet::Cdf97;
        h.bands = derived_97(&h);
        let computed = h.to_bytes();
        h.derived = DerivedMemo(Some(DerivedBands::as_read(&h)));
        assert_eq!(h.to_bytes(), computed);
        let (parsed, _) = Header::parse(&computed).unwrap();
        assert_eq!((&parsed.bands, &parsed.derived.0), (&h.bands, &h.derived.0));
        // Bands changed after the derivation: listed.
        let mut other = h.clone();
        other.bands[0].1 *= 2.0;
        let bytes = other.to_bytes();
        assert!(bytes.len() > computed.len());
        assert_eq!(Header::parse(&bytes).unwrap().0.bands, other.bands);
        // Another size: listed unless that size derives the same bands.
        for (width, height) in [(h.width + 40, h.height), (9, 300), (100_000, 8)] {
            let mut resized = h.clone();
            (resized.width, resized.height) = (width, height);
            let (parsed, _) = Header::parse(&resized.to_bytes()).unwrap();
            assert_eq!(parsed.bands, h.bands, "{width}x{height}");
        }
    }

    #[test]
    fn lowered_shifts_are_flag_14_and_derived_by_their_rule() {
        let mut h = sample_header();
        h.wavelet = Wavelet::Int53;
        let kind = |rule| (Wavelet::Int53, rule);
        let rounded = derived_bands(kind(ShiftRule::Rounded), h.width, h.height, h.levels);
        let lowered = derived_bands(kind(ShiftRule::Lowered), h.width, h.height, h.levels);
        assert_ne!(rounded, lowered);
        (h.shift_rule, h.bands) = (ShiftRule::Lowered, lowered.unwrap());
        let bytes = h.to_bytes();
        let (parsed, _) = Header::parse(&bytes).unwrap();
        assert_eq!(
            (parsed.shift_rule, &parsed.bands),
            (ShiftRule::Lowered, &h.bands)
        );
        // Derived, not listed: one byte longer than the rounded rule's header (flag 14
        // takes the flags varint to a third byte), not 19.
        let mut old = h.clone();
        (old.shift_rule, old.bands) = (ShiftRule::Rounded, rounded.unwrap());
        old.derived = DerivedMemo(None);
        assert_eq!(old.to_bytes().len() + 1, bytes.len());
        assert_eq!(Header::parse(&old.to_bytes()).unwrap().0.bands, old.bands);
    }

    #[test]
    fn an_f32_offset_and_step_are_stored_as_two_f32s() {
        let mut h = sample_header();
        (h.sample_type, h.wavelet) = (SampleType::F32, Wavelet::Cdf97);
        h.bands = derived_97(&h);
        // f32s with long mantissas (no short decimal): 5 bytes each as numbers.
        h.mapping.offset = f64::from(f32::from_bits(0x449A_5123));
        h.coefficient_step = f64::from(f32::from_bits(0x3698_7654));
        let (bytes, f32_len) = assemble(&mut h, &[0], &[1, 2, 3], &[]);
        let (parsed, _) = Header::parse(&bytes).unwrap();
        assert_eq!(parsed.mapping.offset, h.mapping.offset);
        assert_eq!(parsed.coefficient_step, h.coefficient_step);
        // A step that is no f32 goes as a number (9 bytes), and so does the offset (2).
        h.mapping.offset = 1234.0;
        h.coefficient_step = 0.1 + 0.2;
        let (bytes, numbers_len) = assemble(&mut h, &[0], &[1, 2, 3], &[]);
        assert_eq!(numbers_len, f32_len + 3);
        assert_eq!(Header::parse(&bytes).unwrap().0.coefficient_step, 0.1 + 0.2);
    }

    #[test]
    fn v2_numbers_keep_every_bit() {
        let mut h = sample_header();
        for v in [
            0.0,
            -0.0,
            1.5,
            -7.0,
            1e300,
            0.1,
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
        ] {
            h.nodata = Some(v);
            h.valid_range = (v, 3.0);
            let (bytes, _) = assemble(&mut h, &[0], &[1, 2, 3], &[]);
            let (parsed, _) = Header::parse(&bytes).unwrap();
            assert_eq!(parsed.nodata.map(f64::to_bits), Some(v.to_bits()), "{v}");
            assert_eq!(parsed.valid_range.0.to_bits(), v.to_bits(), "{v}");
        }
    }

    #[test]
    fn every_truncation_and_bit_flip_of_a_compact_header_is_an_error() {
        let mut h = sample_header();
        h.georef = Some(gdal_epsg4326());
        h.metadata.crs_wkt = Some("GEOGCS[\"WGS 84\"]".into());
        let bytes = h.to_bytes();
        for cut in 0..bytes.len() {
            assert!(Header::parse(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut damaged = bytes.clone();
                damaged[i] ^= 1 << bit;
                assert!(Header::parse(&damaged).is_err(), "flip at {i}.{bit}");
            }
        }
    }

    #[test]
    fn wrong_magic_and_version() {
        assert!(matches!(
            Header::parse(b"GIF89a.........."),
            Err(CodecError::BadMagic)
        ));
        let mut bytes = sample_header().to_bytes();
        bytes[8] = 9;
        assert!(matches!(
            Header::parse(&bytes),
            Err(CodecError::UnsupportedVersion(9, 2))
        ));
    }

    /// A tile's stream: the sample header without its file-only parts.
    fn tile_header() -> Header {
        Header {
            georef: None,
            metadata: Metadata::default(),
            passes: Vec::new(),
            valid_range: (f64::NAN, f64::NAN),
            ..sample_header()
        }
    }

    #[test]
    fn a_tile_header_round_trips_without_magic_version_ladder_or_range() {
        let mut tile = tile_header();
        let (bytes, header_len) = assemble_as(Layout::Tile, &mut tile, [&[0], &[1, 2, 3], &[]]);
        assert_eq!(
            bytes.len(),
            header_len + 5 + 7,
            "mask and payload, no ladder"
        );
        let (parsed, len) = Header::parse_tile(&bytes).unwrap();
        assert_eq!(len, header_len);
        assert_eq!(
            (parsed.ladder_len, parsed.payload_len, parsed.mask_len),
            (0, 7, 5)
        );
        assert!(parsed.valid_range.0.is_nan() && parsed.valid_range.1.is_nan());
        let same = |h: &Header| Header {
            nodata: None,
            valid_range: (0.0, 0.0),
            ..h.clone()
        };
        assert_eq!(same(&parsed), same(&tile));
        // The file layout of the same stream: magic (8), version (2), ladder length (1)
        // and a second flags byte (flag 10) more.
        let mut file = tile_header();
        let (_, file_header_len) = assemble(&mut file, &[0], &[1, 2, 3], &[]);
        assert_eq!(file_header_len, header_len + 12);
        assert!(matches!(Header::parse(&bytes), Err(CodecError::BadMagic)));
    }

    #[test]
    fn a_tile_header_is_checked_like_a_file_header() {
        let mut tile = tile_header();
        let (bytes, header_len) = assemble_as(Layout::Tile, &mut tile, [&[], &[1, 2, 3], &[]]);
        for cut in 0..header_len {
            assert!(
                matches!(
                    Header::parse_tile(&bytes[..cut]),
                    Err(CodecError::TruncatedHeader(_))
                ),
                "cut at {cut}"
            );
        }
        for byte in 0..header_len {
            let mut flipped = bytes.clone();
            flipped[byte] ^= 0x10;
            assert!(Header::parse_tile(&flipped).is_err(), "flip in byte {byte}");
        }
        // Flags only a file's header has (here georeferencing, flag 1) are refused, with
        // a valid checksum too.
        let mut forged = bytes[..header_len].to_vec();
        assert!(forged[1] < 0x80, "one flags byte after the one-byte length");
        forged[1] |= 1 << 1;
        let crc = crc32fast::hash(&forged[..header_len - 4]);
        forged[header_len - 4..].copy_from_slice(&crc.to_le_bytes());
        assert!(matches!(
            Header::parse_tile(&forged),
            Err(CodecError::InvalidHeader(_))
        ));
    }
}
