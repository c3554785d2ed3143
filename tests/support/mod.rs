//! Helpers shared by the integration tests (each test file that needs them says
//! `mod support;`, so not every file uses every helper).
#![allow(dead_code)]

use std::io::Write;
use std::path::{Path, PathBuf};

/// Says that `test` checked nothing and why, where `cargo test` shows it: the harness
/// captures `eprintln!` of passing tests, not a write to the stderr handle.
pub fn skipped(test: &str, why: &str) {
    let _ = writeln!(std::io::stderr(), "SKIPPED {test}: {why}");
}

/// `../shared/dem` when it holds its manifest; otherwise `None`, with a visible notice
/// that `test` was skipped.
pub fn shared_dem(test: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/dem");
    if dir.join("manifest.json").is_file() {
        Some(dir)
    } else {
        skipped(
            test,
            "../shared/dem not found (the real DEMs are not beside the repository)",
        );
        None
    }
}

/// The path of a program on `PATH`, or `None` with a visible notice that `test` was
/// skipped for the want of it.
pub fn program(test: &str, name: &str, install_hint: &str) -> Option<PathBuf> {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|dir| dir.join(name))
            .find(|candidate| candidate.is_file())
    });
    if found.is_none() {
        skipped(test, &format!("{name} not found ({install_hint})"));
    }
    found
}
