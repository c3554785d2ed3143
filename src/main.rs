//! The `wavemesh` command line.

mod cli;

use std::process::ExitCode;

use clap::Parser;

#[global_allocator]
static ALLOCATOR: wavemesh::memory::CountingAllocator = wavemesh::memory::CountingAllocator;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("wavemesh: error: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}
