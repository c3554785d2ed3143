//! # wavemesh-codec
//!
//! The pure codec behind `wavemesh`: a lifting wavelet transform (integer 5/3 and CDF 9/7),
//! an EZW embedded zerotree coder driving an adaptive binary arithmetic coder, and the
//! `.ezw` container. No file formats and no command line live here.
//!
//! Pipeline, one module per stage: [`raster`] → [`quantize`] → [`wavelet`] → [`ezw`]
//! (with [`entropy`]) → [`container`].

pub mod error;
pub mod raster;
pub mod wavelet;

pub use error::CodecError;
pub use raster::{Georef, Raster, SampleType, Samples};
