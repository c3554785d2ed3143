//! # wavemesh-codec
//!
//! The pure codec behind `wavemesh`: a lifting wavelet transform (integer 5/3 and CDF 9/7),
//! an EZW embedded zerotree coder driving an adaptive binary arithmetic coder, and the
//! `.ezw` container. No file formats and no command line live here.
//!
//! Pipeline, one module per stage: [`raster`] → [`quantize`] → [`wavelet`] → [`ezw`]
//! (with [`entropy`]) → [`container`]; [`pipeline`] runs them end to end. The decoder's
//! [`significance`] map is what the mesher builds its quadtree cells from.
//!
//! ```
//! use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples};
//! let heights: Vec<i16> = (0..64 * 48).map(|i| ((i % 64) * 3 + (i / 64) * 2) as i16).collect();
//! let raster = Raster::new(64, 48, Samples::I16(heights)).unwrap();
//! let file = encode(&raster, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
//! let decoded = decode(&file.bytes, &DecodeOptions::default()).unwrap();
//! assert_eq!(decoded.raster, raster);
//! ```

#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod container;
pub mod entropy;
pub mod error;
pub mod ezw;
pub mod fuzzing;
pub mod mask;
pub mod pipeline;
pub mod progress;
pub mod quantize;
pub mod raster;
pub mod residual;
pub mod significance;
pub mod tiles;
pub mod wavelet;

pub use container::{Header, Mode};
pub use error::CodecError;
pub use pipeline::{
    decode, decode_window, encode, DecodeOptions, Decoded, EncodeOptions, Encoded, Limits, Quality,
};
pub use raster::{geokey, Georef, Metadata, MetadataItem, Raster, SampleType, Samples};
pub use significance::SignificanceMap;
pub use tiles::{ByteSource, TileGrid, Window};
pub use wavelet::Wavelet;
