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

/// Runs the `wavemesh` binary built for these tests.
pub fn wavemesh(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_wavemesh"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Runs a command that must succeed; returns its stdout.
pub fn stdout(args: &[&str]) -> String {
    let output = wavemesh(args);
    assert!(
        output.status.success(),
        "wavemesh {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8(output.stdout).expect("stdout is UTF-8")
}

/// Runs a command that must succeed and parses its stdout as one JSON object.
pub fn json(args: &[&str]) -> serde_json::Value {
    let out = stdout(args);
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("wavemesh {args:?}: {e}\n{out}"))
}

/// A file of the bundled `samples/`.
pub fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("samples")
        .join(name)
}

/// A fresh temporary folder under the tests' scratch space (`tag` names the test file).
pub fn scratch(tag: &str) -> tempfile::TempDir {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join(tag);
    std::fs::create_dir_all(&root).unwrap();
    tempfile::tempdir_in(root).unwrap()
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
