//! `cargo +nightly fuzz run inspect_ezw`: see `wavemesh_codec::fuzzing::inspect_arbitrary`.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| wavemesh_codec::fuzzing::inspect_arbitrary(data));
