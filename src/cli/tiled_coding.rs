//! `encode` of a raster larger than a tile: read and coded one tile row at a time (see
//! [`wavemesh::tiled_encode`]), so memory holds one row of tiles, not the raster.

use wavemesh::byte_source::FileSource;
use wavemesh::dem::RowBands;
use wavemesh::tiled_encode::{encode_tiled, raster_info, TiledEncodeError};
use wavemesh_codec::tiles::read_header;
use wavemesh_codec::TileGrid;

use super::coding::{encode_options, print_encode_report, EncodeArgs, EncodeFacts};
use super::{read_failure, timed, with_codec_progress, CliError, Workload};

/// Encodes `bands` on `grid` into `args.output` and reports it like any encode.
pub fn encode(
    args: &EncodeArgs,
    bands: &mut RowBands,
    grid: &TileGrid,
    to_stdout: bool,
) -> Result<(), CliError> {
    let mut info = raster_info(bands);
    if args.no_metadata_items {
        info.metadata.items.clear();
    }
    let samples = (info.width * info.height) as u64;
    let options = encode_options(args, samples)?;
    let load = Workload::new(samples, info.sample_type);
    let (written, seconds, peak) = with_codec_progress("encoding", load, || {
        timed(|| encode_tiled(bands, &info, grid, &options, &args.output))
    });
    let written = written.map_err(|e| match e {
        TiledEncodeError::Read(e) => read_failure(&args.input, e),
        TiledEncodeError::Encode(e) => CliError::Encode(e),
        other => CliError::Output(args.output.clone(), other.to_string()),
    })?;
    if to_stdout {
        return Ok(());
    }
    let mut output = FileSource::open(&args.output)
        .map_err(|e| CliError::Output(args.output.clone(), e.to_string()))?;
    let (header, header_len) =
        read_header(&mut output).map_err(|e| CliError::Stream(args.output.clone(), e))?;
    let facts = EncodeFacts {
        header: &header,
        header_len,
        bytes: written.bytes,
        seconds,
        peak,
    };
    print_encode_report(args, &facts, false, None, None);
    Ok(())
}
