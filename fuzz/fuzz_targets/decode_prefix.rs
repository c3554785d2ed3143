//! `cargo +nightly fuzz run decode_prefix`: see `wavemesh_codec::fuzzing::decode_prefixes`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| wavemesh_codec::fuzzing::decode_prefixes(data));
