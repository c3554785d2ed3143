//! `verify`: every checksum of a `.ezw` file, and how much of it is usable.

use std::path::{Path, PathBuf};

use serde::Serialize;
use wavemesh_codec::format::verify as verify_file;

use super::coding::SCHEMA_VERSION;
use super::{print_json, CliError};

#[derive(Debug, clap::Args)]
pub struct VerifyArgs {
    /// The .ezw file.
    input: PathBuf,
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct SectionReport {
    name: &'static str,
    tile: Option<u32>,
    offset: u64,
    bytes: u64,
    chunks: u64,
    verified_chunks: u64,
    damaged_at: Option<u64>,
    complete: bool,
}

#[derive(Serialize)]
struct VerifyReport<'a> {
    schema_version: u32,
    command: &'static str,
    input: &'a Path,
    file_bytes: u64,
    header_bytes: u64,
    header_ok: bool,
    sections: Vec<SectionReport>,
    trailing_bytes: u64,
    damaged: bool,
    truncated: bool,
    usable_bytes: u64,
    usable_passes: Option<u32>,
    total_passes: u32,
}

/// Exit status: 0 intact (complete or truncated), 3 damaged or unreadable header.
pub fn run(args: &VerifyArgs) -> Result<(), CliError> {
    let data = std::fs::read(&args.input)
        .map_err(|e| CliError::Input(args.input.clone(), e.to_string()))?;
    let found = verify_file(&data).map_err(|e| CliError::Stream(args.input.clone(), e))?;
    let report = VerifyReport {
        schema_version: SCHEMA_VERSION,
        command: "verify",
        input: &args.input,
        file_bytes: data.len() as u64,
        header_bytes: found.header_len,
        header_ok: true,
        sections: found
            .sections
            .iter()
            .map(|s| SectionReport {
                name: s.name,
                tile: s.tile,
                offset: s.offset,
                bytes: s.framed_len,
                chunks: s.chunks,
                verified_chunks: s.verified_chunks,
                damaged_at: s.damaged_at,
                complete: s.complete,
            })
            .collect(),
        trailing_bytes: found.trailing_bytes,
        damaged: found.damaged(),
        truncated: !found.complete(),
        usable_bytes: found.usable_bytes,
        usable_passes: found.usable_passes,
        total_passes: found.header.top_plane.map_or(0, |t| t as u32 + 1),
    };
    if args.json {
        print_json(&report);
    } else {
        println!(
            "{}: {} bytes, header {} bytes, checksum ok",
            args.input.display(),
            report.file_bytes,
            report.header_bytes
        );
        for s in &report.sections {
            let state = match (s.damaged_at, s.complete) {
                (Some(at), _) => format!("DAMAGED at byte {at}"),
                (None, true) => "ok".to_string(),
                (None, false) => "truncated".to_string(),
            };
            let name = match s.tile {
                Some(tile) => format!("{} {tile}", s.name),
                None => s.name.to_string(),
            };
            println!(
                "  {:<17} at {:>10}, {:>10} bytes, {}/{} chunks verified: {}",
                name, s.offset, s.bytes, s.verified_chunks, s.chunks, state
            );
        }
        if report.trailing_bytes > 0 {
            println!(
                "  {} trailing bytes of garbage after the end of the file",
                report.trailing_bytes
            );
        }
        println!(
            "  usable prefix: {} bytes{}",
            report.usable_bytes,
            report.usable_passes.map_or(String::new(), |p| format!(
                ", {p} of {} passes",
                report.total_passes
            ))
        );
    }
    if report.damaged {
        return Err(CliError::Damaged(args.input.clone()));
    }
    Ok(())
}
