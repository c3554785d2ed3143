//! One tile's stream: encoded like any single-stream file, then laid out in the tile
//! layout (a short header, no ladder: the index and the tiled file's header carry it)
//! and, under a byte budget, cut.

use super::index::TileEntry;
use crate::container::{
    assemble_as, assembled_len_as, logical_offset, physical_offset, unframe, Header, Layout, Mode,
};
use crate::error::CodecError;
use crate::pipeline::{EncodeOptions, Encoded};
use crate::raster::Raster;
use crate::wavelet::{self, Wavelet};

/// What the tiled file's header and index need to know of a tile.
#[derive(Debug, Clone, PartialEq)]
pub struct TileSummary {
    /// The tile's index entry.
    pub entry: TileEntry,
    /// Its coding mode.
    pub mode: Mode,
    /// Its error bound.
    pub max_error: f64,
    /// Minimum and maximum valid sample; `None` when the tile is all nodata.
    pub valid_range: Option<(f64, f64)>,
    /// Its transform.
    pub wavelet: Wavelet,
    /// Its decomposition levels.
    pub levels: u8,
}

/// A tile's stream as it goes into the file.
#[derive(Debug, Clone)]
pub struct EncodedTile {
    /// The stream, in the tile layout (see [`Header::parse_tile`]).
    pub bytes: Vec<u8>,
    /// What the index and header need.
    pub summary: TileSummary,
    /// Truncation points inside its passes (prefix length, estimated squared error),
    /// for the allocation of a budget: not stored in the file, so carried with the tile
    /// when tiles are coded elsewhere (an empty list allocates the tile at pass ends).
    pub checkpoints: Vec<(u64, f64)>,
}

impl EncodedTile {
    /// Every rate–distortion point the allocation may stop at, by prefix length: the
    /// index entry's (see [`TileEntry::points`]) and the checkpoints inside passes.
    pub(crate) fn points(&self, lossless: bool) -> Vec<(u64, f64)> {
        let mut points = self.summary.entry.points(lossless);
        points.extend_from_slice(&self.checkpoints);
        points.sort_by_key(|&(end, _)| end);
        points
    }
}

/// Encodes one tile (a raster cut from the whole, without georeferencing) as `options`
/// say, ignoring their tile size, byte budget, threads and
/// [`lossless_when_it_fits`](EncodeOptions::lossless_when_it_fits): completely, or up
/// to `cap` bytes.
pub fn encode_tile(
    part: &Raster,
    options: &EncodeOptions,
    cap: Option<u64>,
) -> Result<EncodedTile, CodecError> {
    let mut single = options
        .clone()
        .with_tile_size(None)
        .with_budget_bytes(cap)
        .with_threads(1)
        .with_levels(
            options
                .levels
                .map(|l| l.min(wavelet::max_levels(part.width, part.height))),
        );
    // Whether the lossless file replaces the 9/7 one is the whole file's choice.
    single.lossless_when_it_fits = false;
    let encoded = crate::progress::observe(|_| {}, || crate::pipeline::encode(part, &single))?;
    let any_valid = (0..part.len()).any(|i| part.is_valid(i));
    let passes = encoded
        .header
        .passes
        .iter()
        .map(|p| (p.end_byte, p.squared_error))
        .collect();
    let valid_range = any_valid.then_some(encoded.header.valid_range);
    lay_out(&encoded, valid_range, passes, None)
}

/// `tile` cut to at most `len` bytes: a shorter prefix of its payload, decoded as a
/// truncated stream (the residual section goes, and with it any error guarantee). The
/// cut keeps no checkpoints: it is what goes into the file.
pub fn cut_tile(tile: &[u8], summary: &TileSummary, len: u64) -> Result<EncodedTile, CodecError> {
    if len >= tile.len() as u64 {
        return Ok(EncodedTile {
            bytes: tile.to_vec(),
            summary: summary.clone(),
            checkpoints: Vec::new(),
        });
    }
    let (header, header_len) = Header::parse_tile(tile)?;
    let encoded = Encoded {
        bytes: tile.to_vec(),
        header,
        header_len,
        initial_error: summary.entry.initial_error,
        checkpoints: Vec::new(),
    };
    // The ladder left the stream when it was first laid out: the index has the passes.
    let passes = summary
        .entry
        .passes
        .iter()
        .map(|&(end, error)| (logical_offset(end - summary.entry.head_len), error))
        .collect();
    lay_out(&encoded, summary.valid_range, passes, Some(len))
}

/// Re-lays `encoded` out in the tile layout (its passes and valid range go to the index
/// and the tiled header), its payload cut to fit `cut` bytes when given, and builds its
/// summary; `passes` are its passes' payload ends and errors, `valid_range` its valid
/// samples' (`None`: all nodata).
fn lay_out(
    encoded: &Encoded,
    valid_range: Option<(f64, f64)>,
    passes: Vec<(u64, f64)>,
    cut: Option<u64>,
) -> Result<EncodedTile, CodecError> {
    let file = &encoded.bytes;
    let mut header = encoded.header.clone();
    let section = |start: usize, len: usize| unframe(file.get(start..).unwrap_or(&[]), len).bytes;
    let mask_start = encoded.header_len;
    let payload_start = mask_start + header.mask_len as usize;
    let residual_start = payload_start + header.payload_len as usize;
    let mask = section(mask_start, header.mask_len as usize);
    let mut payload = section(payload_start, header.payload_len as usize);
    let mut residual = section(residual_start, header.residual_len as usize);
    header.passes.clear();
    header.valid_range = (f64::NAN, f64::NAN);
    if let Some(limit) = cut {
        header.payload_truncated = true;
        header.correction_step = 0.0;
        header.mode = Mode::Lossy;
        header.max_error = f64::INFINITY;
        residual.clear();
        header.residuals_by_exponent = false;
        // The cut header may be a byte or two longer than the whole one: a limit below
        // it keeps no payload (the caller's total check sees the excess).
        let fits =
            |p: usize| assembled_len_as(Layout::Tile, &header, [mask.len(), p, 0]) as u64 <= limit;
        payload.truncate(largest(payload.len(), fits));
    }
    let (bytes, header_len) = assemble_as(Layout::Tile, &mut header, [&mask, &payload, &residual]);
    let head_len = (header_len + header.mask_len as usize) as u64;
    let in_tile = |points: &[(u64, f64)]| -> Vec<(u64, f64)> {
        points
            .iter()
            .filter(|&&(end, _)| end <= payload.len() as u64)
            .map(|&(end, error)| (head_len + physical_offset(end), error))
            .collect()
    };
    let passes = in_tile(&passes);
    let checkpoints = in_tile(&encoded.checkpoints);
    let summary = TileSummary {
        entry: TileEntry {
            len: bytes.len() as u64,
            head_len,
            initial_error: encoded.initial_error,
            passes,
        },
        mode: header.mode,
        max_error: header.max_error,
        valid_range,
        wavelet: header.wavelet,
        levels: header.levels,
    };
    Ok(EncodedTile {
        bytes,
        summary,
        checkpoints,
    })
}

/// The largest `p ≤ max` with `fits(p)` (`fits` holds up to some point, then not); 0
/// when nothing fits.
fn largest(max: usize, fits: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, max);
    while lo < hi {
        let mid = lo + (hi - lo).div_ceil(2);
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    lo
}
