//! `encode` of a raster larger than a tile: read and coded one tile row at a time (see
//! [`wavemesh::tiled_encode`]), so memory holds one row of tiles, not the raster; and
//! `decode` of a whole tiled file to a GeoTIFF, decoded and written one tile row at a
//! time.

use std::path::Path;

use wavemesh::byte_source::FileSource;
use wavemesh::dem::{DemInfo, RowBands, TiledGeoTiffWriter};
use wavemesh::tiled_encode::{encode_tiled, TiledEncodeError};
use wavemesh_codec::tiles::{read_header, TiledLayout};
use wavemesh_codec::{decode_window, DecodeOptions, TileGrid, Window};

use super::coding::{encode_options, print_encode_report, DecodeOutcome, EncodeArgs, EncodeFacts};
use super::{read_failure, timed, with_codec_progress, CliError, Workload};

/// Encodes `bands` on `grid` into `args.output` and reports it like any encode.
pub fn encode(
    args: &EncodeArgs,
    bands: &mut RowBands,
    grid: &TileGrid,
    to_stdout: bool,
) -> Result<(), CliError> {
    let mut info = bands.info().clone();
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

/// Tile side of the GeoTIFFs a streaming decode writes.
const GEOTIFF_TILE: u32 = 256;

/// Decodes the tiled file `layout` describes one tile row at a time into a tiled
/// GeoTIFF at `output`: memory holds one row of tiles, not the raster.
pub fn decode_rows(
    (input, output): (&Path, &Path),
    source: &mut FileSource,
    layout: &TiledLayout,
    options: &DecodeOptions,
) -> Result<DecodeOutcome, CliError> {
    let header = &layout.header;
    let grid = &layout.grid;
    let info = DemInfo {
        width: grid.width,
        height: grid.height,
        sample_type: header.sample_type,
        nodata: header.nodata,
        georef: header.georef.clone(),
        metadata: header.metadata.clone(),
    };
    let mut writer =
        TiledGeoTiffWriter::create(output, &info, GEOTIFF_TILE).map_err(CliError::DemOutput)?;
    let mut outcome = DecodeOutcome {
        width: grid.width,
        height: grid.height,
        passes_decoded: u32::MAX,
        complete: true,
        bytes_used: layout.head_len(),
        damage: None,
    };
    for row in 0..grid.rows() {
        let y = row * grid.tile_height;
        let window = Window {
            x: 0,
            y,
            width: grid.width,
            height: grid.tile_height.min(grid.height - y),
        };
        let decoded = decode_window(source, Some(window), options)
            .map_err(|e| CliError::Stream(input.to_path_buf(), e))?;
        outcome.passes_decoded = outcome.passes_decoded.min(decoded.passes_decoded);
        outcome.complete &= decoded.complete;
        outcome.bytes_used += decoded.bytes_used - layout.head_len();
        outcome.damage = outcome.damage.or(decoded.damage);
        writer
            .write_rows(y, &decoded.raster)
            .map_err(CliError::DemOutput)?;
    }
    writer.finish().map_err(CliError::DemOutput)?;
    Ok(outcome)
}
