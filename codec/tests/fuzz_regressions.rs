//! Replays the fuzzing inputs of the codec targets on stable: every file under
//! `fuzz/regressions/<target>/` (inputs that once crashed or hung) and the seed corpora
//! `fuzz/corpus/<target>/`, through the same harnesses the `cargo fuzz` targets call
//! ([`wavemesh_codec::fuzzing`]). The DEM reader targets are replayed by the root crate's
//! `tests/fuzz_regressions.rs`, whose ignored `make_seeds` test writes the seeds.

use std::fs;
use std::path::{Path, PathBuf};

use wavemesh_codec::fuzzing::{decode_arbitrary, decode_prefixes, inspect_arbitrary, roundtrip};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
}

/// The files directly inside `dir` (none if it does not exist), sorted.
fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

/// Replays the regressions and seeds of `target` through `run`, printing the counts.
fn replay(target: &str, run: fn(&[u8])) -> usize {
    let fuzz = fuzz_dir();
    let mut counts = [0, 0];
    for (k, kind) in ["regressions", "corpus"].into_iter().enumerate() {
        for path in files_in(&fuzz.join(kind).join(target)) {
            let relative = path
                .strip_prefix(&fuzz)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            eprintln!("replaying {relative}");
            run(&fs::read(&path).unwrap());
            counts[k] += 1;
        }
    }
    println!(
        "{target}: replayed {} regression inputs and {} seeds",
        counts[0], counts[1]
    );
    assert!(counts[1] > 0, "no seeds in fuzz/corpus/{target}");
    counts[0] + counts[1]
}

#[test]
fn replay_decode_ezw() {
    replay("decode_ezw", decode_arbitrary);
}

#[test]
fn replay_inspect_ezw() {
    replay("inspect_ezw", inspect_arbitrary);
}

#[test]
fn replay_decode_prefix() {
    replay("decode_prefix", decode_prefixes);
}

#[test]
fn replay_roundtrip() {
    replay("roundtrip", roundtrip);
}

/// Files in code blocks with a few bytes changed and every checksum made to hold again
/// (so the change reaches the parser and the coder, as the fuzzer's repaired inputs do):
/// decoding and inspecting them never panics.
#[test]
fn mutated_code_block_files_never_panic() {
    use wavemesh_codec::fuzzing::repair_checksums;
    use wavemesh_codec::{encode, EncodeOptions, Raster, Samples};
    let values = (0..100 * 40)
        .map(|i| ((i % 100) * 5 + (i / 100) * 3 + (i * 7919) % 13) as i16)
        .collect();
    let raster = Raster::new(100, 40, Samples::I16(values)).unwrap();
    let blocked = |options: EncodeOptions| {
        let options = options.with_tile_size(Some(64)).with_code_block(Some(64));
        encode(&raster, &options).unwrap().bytes
    };
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for file in [
        blocked(EncodeOptions::lossless()),
        blocked(EncodeOptions::budget(1500)),
    ] {
        for _ in 0..1500 {
            let mut bytes = file.clone();
            for _ in 0..1 + next() % 3 {
                let at = (next() % bytes.len() as u64) as usize;
                bytes[at] ^= 1 << (next() % 8);
            }
            let bytes = repair_checksums(&bytes).unwrap_or(bytes);
            decode_arbitrary(&bytes);
            inspect_arbitrary(&bytes);
        }
    }
}
