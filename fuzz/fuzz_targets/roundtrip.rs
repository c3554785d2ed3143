//! `cargo +nightly fuzz run roundtrip`: see `wavemesh_codec::fuzzing::roundtrip`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| wavemesh_codec::fuzzing::roundtrip(data));
