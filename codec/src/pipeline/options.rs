//! What a caller asks of an encode or a decode.

use crate::quantize;
use crate::raster::Raster;
use crate::tiles::Window;
use crate::tiles::DEFAULT_TILE;
use crate::wavelet::{self, Wavelet};

/// Largest side of the centre [`EncodeOptions::wavelet_chosen_for`] transforms.
const CHOICE_SIDE: usize = 512;

/// The window at the centre of a `width × height` raster, at most 512 samples a side,
/// on which [`EncodeOptions::wavelet_chosen_for`] chooses the reversible wavelet.
pub fn wavelet_sample(width: usize, height: usize) -> Window {
    let (w, h) = (width.min(CHOICE_SIDE), height.min(CHOICE_SIDE));
    Window {
        x: (width - w) / 2,
        y: (height - h) / 2,
        width: w,
        height: h,
    }
}

/// What the encoder should achieve.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Quality {
    /// Bit-exact (a reversible wavelet) — or, with 9/7, as fine as the coefficient
    /// quantiser allows.
    Lossless,
    /// Every valid sample within this many data units (a reversible wavelet).
    MaxError(f64),
    /// Floats quantised to this step (error ≤ step / 2) (a reversible wavelet).
    Precision(f64),
}

/// Encoder settings: made by [`EncodeOptions::new`] (or [`EncodeOptions::lossless`],
/// [`EncodeOptions::max_error`], [`EncodeOptions::budget`]) and adjusted by the
/// `with_…` setters, so that fields added later break no caller.
///
/// ```
/// use wavemesh_codec::{EncodeOptions, Wavelet};
/// let options = EncodeOptions::budget(4000).with_tile_size(None).with_threads(1);
/// assert_eq!(options.wavelet, Wavelet::Cdf97);
/// ```
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct EncodeOptions {
    /// The transform; see [`EncodeOptions::new`] for the defaults.
    pub wavelet: Wavelet,
    /// Whether the encoder may replace the reversible `wavelet` by the other one (5/3,
    /// 13/11) when the raster's coefficients come out smaller with it (see
    /// [`EncodeOptions::wavelet_chosen_for`]): set by [`EncodeOptions::new`] for
    /// lossless and error-bounded coding, cleared by [`EncodeOptions::with_wavelet`].
    pub adaptive_wavelet: bool,
    /// Whether a budget encode writes the lossless file (13/11 or
    /// 5/3) instead of the 9/7 one when the lossless file fits the budget: exact, and
    /// smaller than the 9/7 file of the same budget (see
    /// [`EncodeOptions::lossless_alternative`]). Set by [`EncodeOptions::new`] when it
    /// picks the 9/7 for a budget, cleared by [`EncodeOptions::with_wavelet`].
    pub lossless_when_it_fits: bool,
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
    /// Side of code blocks (a multiple of 64), or `None`. With it, a raster larger than
    /// a block is coded as tiles of at most `tile_size` (rounded up to whole blocks; one
    /// tile when it fits), each tile one transform whose coefficients below each block
    /// form an embedded stream of their own: random access by block, and no tile borders
    /// showing in the samples as independent tiles' do (see [`crate::tiles`]).
    pub code_block: Option<u32>,
}

impl EncodeOptions {
    /// The defaults: 9/7 when only a byte budget is given (or the lossless file, for
    /// samples whose lossless file fits: see
    /// [`lossless_when_it_fits`](Self::lossless_when_it_fits)), 13/11 for lossless and
    /// error-bounded coding (or the 5/3, where the raster codes smaller with it: see
    /// [`adaptive_wavelet`](Self::adaptive_wavelet)); tiles of [`DEFAULT_TILE`] a side;
    /// every core.
    pub fn new(quality: Quality, budget_bytes: Option<u64>) -> EncodeOptions {
        let wavelet = match (quality, budget_bytes) {
            (Quality::Lossless, Some(_)) => Wavelet::Cdf97,
            _ => Wavelet::Int1311,
        };
        EncodeOptions {
            wavelet,
            adaptive_wavelet: wavelet.is_reversible(),
            lossless_when_it_fits: wavelet == Wavelet::Cdf97,
            levels: None,
            quality,
            budget_bytes,
            tile_size: Some(DEFAULT_TILE),
            threads: 0,
            code_block: None,
        }
    }

    /// Bit-exact coding (13/11 or 5/3), with the defaults of [`EncodeOptions::new`].
    pub fn lossless() -> EncodeOptions {
        EncodeOptions::new(Quality::Lossless, None)
    }

    /// Every valid sample within `error` data units (13/11 or 5/3), with the defaults of
    /// [`EncodeOptions::new`].
    pub fn max_error(error: f64) -> EncodeOptions {
        EncodeOptions::new(Quality::MaxError(error), None)
    }

    /// A 9/7 stream cut at `bytes` bytes (a rate of `8 · bytes / samples` bits per
    /// sample), or the lossless file when that fits, with the
    /// defaults of [`EncodeOptions::new`].
    pub fn budget(bytes: u64) -> EncodeOptions {
        EncodeOptions::new(Quality::Lossless, Some(bytes))
    }

    /// The same options coding one stream whatever the raster's size: what the decoder's
    /// significance map, and so the zerotree mesher, needs.
    pub fn single_stream(self) -> EncodeOptions {
        self.with_tile_size(None)
    }

    /// These options with `wavelet`, kept whatever the raster (no
    /// [`adaptive_wavelet`](Self::adaptive_wavelet)).
    #[must_use]
    pub fn with_wavelet(mut self, wavelet: Wavelet) -> EncodeOptions {
        self.wavelet = wavelet;
        self.adaptive_wavelet = false;
        self.lossless_when_it_fits = false;
        self
    }

    /// The options of the lossless file a budget encode writes instead of its 9/7 file
    /// when that fits the budget ([`lossless_when_it_fits`](Self::lossless_when_it_fits)):
    /// `None` unless these options ask for a 9/7 file of a byte budget, without code
    /// blocks, and allow it. The encoder tries it only where the raster's detail says
    /// it may fit ([`crate::tiles::lossless_may_fit`]).
    pub fn lossless_alternative(&self) -> Option<EncodeOptions> {
        let asked = self.lossless_when_it_fits
            && self.wavelet == Wavelet::Cdf97
            && self.quality == Quality::Lossless
            && self.budget_bytes.is_some()
            && self.code_block.is_none();
        asked.then(|| EncodeOptions {
            budget_bytes: None,
            ..EncodeOptions::lossless()
                .with_levels(self.levels)
                .with_tile_size(self.tile_size)
                .with_threads(self.threads)
        })
    }

    /// These options with the wavelet settled for `raster`: with
    /// [`adaptive_wavelet`](Self::adaptive_wavelet), the reversible one (5/3 or 13/11)
    /// whose transform of the raster's centre ([`wavelet_sample`]; quantised and voids
    /// filled as coded) has the fewest coefficient bits once the coefficients reaching no
    /// valid sample are zeroed. Smooth terrain takes the 13/11; resampled or ragged data
    /// (jagged at the sample scale) the 5/3, whose shorter filters ring less. `raster`
    /// may also be just that centre (what a streaming encoder reads of a large raster):
    /// the choice is the same. Samples the encoder refuses (infinities, a range too wide)
    /// leave the wavelet as it is, for the encode to name them.
    pub fn wavelet_chosen_for(&self, raster: &Raster) -> EncodeOptions {
        if !(self.adaptive_wavelet && self.wavelet.is_reversible()) {
            return self.clone();
        }
        let w = wavelet_sample(raster.width, raster.height);
        let centre = raster.crop(w.x, w.y, w.width, w.height);
        let (width, height) = (w.width, w.height);
        let levels = self
            .levels
            .unwrap_or(u32::MAX)
            .min(wavelet::default_levels(width, height));
        let wavelet = quantize::cheaper_reversible(&centre, self.quality, levels);
        self.clone().with_wavelet(wavelet.unwrap_or(self.wavelet))
    }

    /// One lossless 5/3 stream: the significance map the zerotree mesher's partition is
    /// made from, as its measured figures (README) were.
    pub fn zerotree_mesh() -> EncodeOptions {
        EncodeOptions::lossless()
            .with_wavelet(Wavelet::Int53)
            .single_stream()
    }
}

impl Default for EncodeOptions {
    /// [`EncodeOptions::lossless`].
    fn default() -> Self {
        EncodeOptions::lossless()
    }
}

/// `with_FIELD(value)` setters, each returning the options with that field set.
macro_rules! setters {
    ($options:ident { $($setter:ident => $field:ident: $type:ty),* $(,)? }) => {
        impl $options {
            $(
                #[doc = concat!("These options with [`", stringify!($field), "`](Self::",
                    stringify!($field), ") set to `", stringify!($field), "`.")]
                #[must_use]
                pub fn $setter(mut self, $field: $type) -> $options {
                    self.$field = $field;
                    self
                }
            )*
        }
    };
}

setters!(EncodeOptions {
    with_levels => levels: Option<u32>,
    with_quality => quality: Quality,
    with_budget_bytes => budget_bytes: Option<u64>,
    with_tile_size => tile_size: Option<u32>,
    with_threads => threads: usize,
    with_code_block => code_block: Option<u32>,
});

/// Resource limits checked before the decoder allocates: [`Limits::DEFAULT`] or
/// [`Limits::new`], adjusted by the `with_…` setters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct Limits {
    /// Largest `width × height` accepted.
    pub max_samples: u64,
    /// Largest working memory (bytes) the decode may need.
    pub max_memory: u64,
}

impl Limits {
    /// The defaults: 2^31 samples and 2 GiB of working memory.
    pub const DEFAULT: Limits = Limits::new(1 << 31, 2 << 30);

    /// At most `max_samples` samples and `max_memory` bytes of working memory.
    pub const fn new(max_samples: u64, max_memory: u64) -> Limits {
        Limits {
            max_samples,
            max_memory,
        }
    }
}

impl Default for Limits {
    fn default() -> Self {
        Limits::DEFAULT
    }
}

setters!(Limits {
    with_max_samples => max_samples: u64,
    with_max_memory => max_memory: u64,
});

/// Decoder settings: [`DecodeOptions::default`] (everything in the file, default limits,
/// every core) adjusted by the `with_…` setters.
///
/// ```
/// use wavemesh_codec::DecodeOptions;
/// let prefix = DecodeOptions::default().with_max_bytes(Some(300)).with_strict(true);
/// assert_eq!(prefix.max_bytes, Some(300));
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[non_exhaustive]
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

setters!(DecodeOptions {
    with_max_bytes => max_bytes: Option<u64>,
    with_max_passes => max_passes: Option<u32>,
    with_limits => limits: Limits,
    with_strict => strict: bool,
    with_significance_map => significance_map: bool,
    with_threads => threads: usize,
});
