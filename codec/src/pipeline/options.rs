//! What a caller asks of an encode or a decode.

use crate::tiles::DEFAULT_TILE;
use crate::wavelet::Wavelet;

/// What the encoder should achieve.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
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
    /// Decomposition levels (`None`: until the coarsest band is at most 8 samples wide).
    pub levels: Option<u32>,
    /// Target quality of the complete stream.
    pub quality: Quality,
    /// Total file size to stop at, in bytes (a single stream is cut there exactly; a
    /// tiled file's tiles are cut where [`crate::tiles::allocate`] says, within it).
    pub budget_bytes: Option<u64>,
    /// Largest tile side: a raster with a longer side is coded as a tiled file (tiles
    /// as equal as the raster allows, see [`crate::TileGrid::balanced`]); `None` codes
    /// one stream whatever the size.
    pub tile_size: Option<u32>,
    /// Threads coding tiles at once (0: one per core). The bytes do not depend on it.
    pub threads: usize,
}

impl EncodeOptions {
    /// The defaults: 9/7 when only a byte budget is given, 5/3 for lossless and
    /// error-bounded coding; tiles of [`DEFAULT_TILE`] a side; every core.
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

/// Resource limits checked before the decoder allocates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest `width × height` accepted.
    pub max_samples: u64,
    /// Largest working memory (bytes) the decode may need.
    pub max_memory: u64,
}

impl Limits {
    /// The defaults: 2^31 samples and 2 GiB of working memory.
    pub const DEFAULT: Limits = Limits {
        max_samples: 1 << 31,
        max_memory: 2 << 30,
    };
}

impl Default for Limits {
    fn default() -> Self {
        Limits::DEFAULT
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
    /// Also return the per-node significance map ([`crate::Decoded::significance`];
    /// single streams only).
    pub significance_map: bool,
    /// Threads decoding tiles at once (0: one per core).
    pub threads: usize,
}
