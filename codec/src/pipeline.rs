//! Whole-file encode and decode: runs the stages (quantisation, transform, zerotree
//! coding, container) end to end.

mod decode;
mod encode;
mod options;

pub(crate) use decode::decode_parsed;
pub use decode::{decode, decode_window, decode_windows, Damage, Decoded};
pub(crate) use encode::encode_stream;
#[cfg(feature = "research")]
pub(crate) use encode::SHIFT_RULE;
pub use encode::{encode, Encoded};
pub use options::{DecodeOptions, EncodeOptions, Limits, Quality};
