//! Whole-file encode and decode: runs the stages (quantisation, transform, zerotree
//! coding, container) end to end.

mod decode;
mod encode;
mod options;

pub(crate) use decode::{
    apply_residual_section, check_limits, decode_parsed, reconstruct, Coefficients,
};
pub use decode::{decode, decode_window, decode_windows, Damage, Decoded};
#[cfg(feature = "research")]
pub(crate) use encode::SHIFT_RULE;
pub use encode::{encode, Encoded};
pub(crate) use encode::{encode_stream, plan_stream};
pub use options::{wavelet_sample, DecodeOptions, EncodeOptions, Limits, Quality};
