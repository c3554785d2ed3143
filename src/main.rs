//! The `wavemesh` command line.

mod cli;

use std::process::ExitCode;

use clap::Parser;

#[global_allocator]
static ALLOCATOR: wavemesh::memory::CountingAllocator = wavemesh::memory::CountingAllocator;

fn main() -> ExitCode {
    die_quietly_on_closed_pipes();
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("wavemesh: error: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}

/// When the reader of stdout goes away (`wavemesh info x.ezw | head -1`), end the way
/// command-line tools do, by SIGPIPE, silently: Rust ignores the signal, and every
/// `println!` after it would panic.
#[cfg(unix)]
fn die_quietly_on_closed_pipes() {
    // SAFETY: sets one signal's disposition to its default, at startup, before any
    // other thread exists; no handler code is installed.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn die_quietly_on_closed_pipes() {}
