//! # wavemesh-codec
//!
//! The pure codec behind `wavemesh`: a lifting wavelet transform (integer 5/3 and CDF 9/7),
//! an EZW embedded zerotree coder driving an adaptive binary arithmetic coder, and the
//! `.ezw` container. No file formats and no command line live here.
//!
//! ```
//! use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Raster, Samples};
//! let heights: Vec<i16> = (0..64 * 48).map(|i| ((i % 64) * 3 + (i / 64) * 2) as i16).collect();
//! let raster = Raster::new(64, 48, Samples::I16(heights)).unwrap();
//! let file = encode(&raster, &EncodeOptions::lossless()).unwrap();
//! let decoded = decode(&file.bytes, &DecodeOptions::default()).unwrap();
//! assert_eq!(decoded.raster, raster);
//! // Any prefix decodes: the first half of the file gives a coarser DEM.
//! let half = DecodeOptions::default().with_max_bytes(Some(file.bytes.len() as u64 / 2));
//! assert!(!decode(&file.bytes, &half).unwrap().complete);
//! ```
//!
//! The option structs ([`EncodeOptions`], [`DecodeOptions`], [`Limits`]) are
//! `#[non_exhaustive]`: make them with their constructors or `Default` and adjust them
//! with their `with_…` setters (or by assigning a field), so new settings break no
//! caller.
//!
//! ## What is public
//!
//! - At the root: [`encode`], [`decode`] and [`decode_window`] with their options,
//!   results and [`CodecError`]; the [`Raster`] they code with its georeferencing and
//!   metadata; the file's [`Header`].
//! - [`format`](mod@format): reading a file without decoding it (the header's records, checksums,
//!   byte offsets), as `info` and `verify` tools need.
//! - [`tiles`]: the tiled layout of large rasters, for windowed and remote decoding and
//!   for encoding a tile (or a block of tiles) at a time.
//! - [`significance`]: the decoder's per-node significance map, the seam to a mesher.
//! - [`progress`]: observing a long encode or decode.
//!
//! ## Features (none is on by default; none is a stable API)
//!
//! - `fuzzing`: the `fuzzing` module, the harnesses of the cargo-fuzz targets.
//! - `internals`: the coder's stages as public modules (`entropy`, `ezw`, `wavelet`),
//!   for benchmarks.
//! - `research`: the `research` module, measurements of the coder's design choices.
//!
//! ## Inside, one module per stage
//!
//! raster → `quantize` (samples to coefficients' input, and back) → `wavelet` → `ezw`
//! (with `entropy`) → `container`; `corrections` adds the max-error corrections of a cut
//! 9/7 stream, `mask` and `residual` code the nodata mask and the exact float residuals,
//! and `pipeline` runs the stages end to end.

#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod container;
mod corrections;
#[cfg(feature = "internals")]
pub mod entropy;
#[cfg(not(feature = "internals"))]
mod entropy;
mod error;
#[cfg(feature = "internals")]
pub mod ezw;
#[cfg(not(feature = "internals"))]
mod ezw;
pub mod format;
#[cfg(feature = "fuzzing")]
pub mod fuzzing;
mod mask;
mod pipeline;
pub mod progress;
mod quantize;
mod raster;
#[cfg(feature = "research")]
pub mod research;
mod residual;
pub mod significance;
pub mod tiles;
#[cfg(feature = "internals")]
pub mod wavelet;
#[cfg(not(feature = "internals"))]
mod wavelet;

pub use container::{Header, Mode};
pub use error::CodecError;
pub use pipeline::{
    decode, decode_window, decode_windows, encode, wavelet_sample, Damage, DecodeOptions, Decoded,
    EncodeOptions, Encoded, Limits, Quality,
};
pub use raster::{geokey, Georef, Metadata, MetadataItem, Raster, SampleType, Samples};
pub use significance::SignificanceMap;
pub use tiles::{ByteSource, TileGrid, Window};
pub use wavelet::{ShiftRule, Wavelet};
