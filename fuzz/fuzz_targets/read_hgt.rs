//! `cargo +nightly fuzz run read_hgt`: `wavemesh::fuzzing::read_arbitrary` as `DemFormat::Hgt`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use wavemesh::dem::DemFormat;

fuzz_target!(|data: &[u8]| wavemesh::fuzzing::read_arbitrary(data, DemFormat::Hgt));
