//! `cargo +nightly fuzz run decode_ezw`: see `wavemesh_codec::fuzzing::decode_arbitrary`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| wavemesh_codec::fuzzing::decode_arbitrary(data));
