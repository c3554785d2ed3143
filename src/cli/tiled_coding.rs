//! `encode` of a raster larger than a tile: read and coded one tile row at a time (see
//! [`wavemesh::tiled_encode`]), so memory holds one row of tiles, not the raster; and
//! `decode` of a whole tiled file to a GeoTIFF, decoded and written one tile row at a
//! time.

use std::path::Path;

use wavemesh::byte_source::FileSource;
use wavemesh::dem::{DemError, DemInfo, RowBands, TiledGeoTiffWriter, BLOCK_WIDTH};
use wavemesh::tiled_encode::{encode_blocked, encode_tiled, TiledEncodeError};
use wavemesh_codec::tiles::{read_header, TiledLayout};
use wavemesh_codec::{decode_windows, DecodeOptions, Raster, TileGrid, Window};

use super::coding::{encode_options, print_encode_report, DecodeOutcome, EncodeArgs, EncodeFacts};
use super::{read_failure, timed, CliError, Workload};

/// Encodes `bands` on `grid` (its tiles cut into code blocks of `code_block`, if given)
/// into `args.output` and reports it like any encode.
pub fn encode(
    args: &EncodeArgs,
    bands: &mut RowBands,
    (grid, code_block): (&TileGrid, Option<usize>),
    to_stdout: bool,
) -> Result<(), CliError> {
    let mut info = bands.info().clone();
    if args.no_metadata_items {
        info.metadata.items.clear();
    }
    let samples = (info.width * info.height) as u64;
    let options = encode_options(args, samples)?;
    let bar = TileRowBar::new(
        "encoding",
        grid,
        Workload::new(samples, info.sample_type),
        args.json,
    );
    let (written, seconds, peak) = timed(|| {
        let rows_done = &mut |k| bar.show(k);
        match code_block {
            Some(side) => encode_blocked(
                bands,
                &info,
                (grid, side),
                &options,
                BLOCK_WIDTH,
                &args.output,
                rows_done,
            ),
            None => encode_tiled(
                bands,
                &info,
                grid,
                &options,
                BLOCK_WIDTH,
                &args.output,
                rows_done,
            ),
        }
    });
    bar.finish();
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

/// A progress bar over tile rows on a terminal (stderr): rows done, Msamples, MB/s and
/// the time left; nothing under `--json` or when stderr is not a terminal.
pub struct TileRowBar {
    bar: Option<indicatif::ProgressBar>,
    rows: usize,
    load: Workload,
    start: std::time::Instant,
}

impl TileRowBar {
    /// A bar for `grid`'s tile rows (`quiet`: none).
    pub fn new(message: &str, grid: &TileGrid, load: Workload, quiet: bool) -> TileRowBar {
        use std::io::IsTerminal;
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let style = indicatif::ProgressStyle::with_template(
                "{spinner} {prefix} [{wide_bar}] {percent:>3}% {msg} ETA {eta}",
            )
            .expect("a valid template")
            .progress_chars("=> ");
            let bar = indicatif::ProgressBar::new(grid.rows() as u64)
                .with_style(style)
                .with_prefix(message.to_string());
            bar.enable_steady_tick(std::time::Duration::from_millis(100));
            bar
        });
        TileRowBar {
            bar,
            rows: grid.rows(),
            load,
            start: std::time::Instant::now(),
        }
    }

    /// `done` tile rows of the whole are through.
    pub fn show(&self, done: usize) {
        let Some(bar) = &self.bar else {
            return;
        };
        let fraction = done as f64 / self.rows.max(1) as f64;
        let seconds = self.start.elapsed().as_secs_f64().max(1e-3);
        bar.set_position(done as u64);
        bar.set_message(format!(
            "tile rows {done}/{}: {:.1} of {:.1} Msamples, {:.1} MB/s",
            self.rows,
            fraction * self.load.samples as f64 / 1e6,
            self.load.samples as f64 / 1e6,
            fraction * self.load.bytes as f64 / 1e6 / seconds
        ));
    }

    /// Clears the bar.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// Tile side of the GeoTIFFs a streaming decode writes.
const GEOTIFF_TILE: u32 = 256;

/// Tile columns a streaming decode writes at once: about [`BLOCK_WIDTH`] samples when
/// [`GEOTIFF_TILE`] divides the file's tiles (every block is whole GeoTIFF tiles, written
/// as it comes), else whole tile rows (GeoTIFF tiles straddle the file's).
fn decode_block_columns(grid: &TileGrid) -> usize {
    let tile = GEOTIFF_TILE as usize;
    if grid.tile_width.is_multiple_of(tile) && grid.tile_height.is_multiple_of(tile) {
        grid.tiles_within(BLOCK_WIDTH)
    } else {
        grid.columns()
    }
}

/// Decodes the tiled file `layout` describes one block at a time (a run of tiles of one
/// tile row, see [`decode_block_columns`]) into a tiled GeoTIFF at `output`, each block
/// written (its GeoTIFF tiles compressed on the decode's threads) on another thread
/// while the next one's tiles are decoded, which are placed once it is written (with one
/// thread, written before the next is decoded). Tiles are decoded a few ahead across
/// blocks (`decode_windows`), so no thread waits at a block's end: memory holds one
/// block and a few decoded tiles, not the raster, and not a tile row when the blocks are
/// narrower. `bar` shows the tile rows done.
pub fn decode_to_geotiff(
    (input, output): (&Path, &Path),
    source: &mut FileSource,
    layout: &TiledLayout,
    options: &DecodeOptions,
    bar: &TileRowBar,
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
    let writer = TiledGeoTiffWriter::create(output, &info, GEOTIFF_TILE)
        .and_then(|w| w.with_threads(options.threads))
        .map_err(CliError::DemOutput)?;
    let mut outcome = DecodeOutcome {
        width: grid.width,
        height: grid.height,
        passes_decoded: u32::MAX,
        complete: true,
        bytes_used: layout.head_len(),
        damage: None,
    };
    let per_block = decode_block_columns(grid);
    let by_rows = per_block == grid.columns();
    let blocks = grid.blocks(per_block);
    let windows: Vec<Window> = blocks
        .iter()
        .map(|(row, columns)| grid.block(*row, columns.clone()))
        .collect();
    let mut decode_all = |deliver: &mut dyn FnMut(Window, Raster) -> bool,
                          written: &mut dyn FnMut()| {
        let mut blocks_done = blocks.iter();
        decode_windows(
            source,
            &windows,
            options,
            written,
            &mut |window, decoded| {
                outcome.passes_decoded = outcome.passes_decoded.min(decoded.passes_decoded);
                outcome.complete &= decoded.complete;
                outcome.bytes_used += decoded.bytes_used - layout.head_len();
                outcome.damage = outcome.damage.or(decoded.damage);
                if !deliver(window, decoded.raster) {
                    return false; // the writer failed: its error is reported by the caller
                }
                if let Some((row, columns)) = blocks_done.next() {
                    if columns.end == grid.columns() {
                        bar.show(row + 1);
                    }
                }
                true
            },
        )
        .map_err(|e| CliError::Stream(input.to_path_buf(), e))
    };
    let write = move |writer: &mut TiledGeoTiffWriter, window: Window, band: &Raster| {
        if by_rows {
            writer.write_rows(window.y, band)
        } else {
            writer.write_block((window.x, window.y), band)
        }
    };
    if options.threads == 1 {
        // One thread: each block is written before the next is decoded.
        let mut writer = writer;
        let mut failure = None;
        decode_all(
            &mut |window, band| match write(&mut writer, window, &band) {
                Ok(()) => true,
                Err(e) => {
                    failure = Some(e);
                    false
                }
            },
            &mut || {},
        )?;
        return match failure {
            Some(e) => Err(CliError::DemOutput(e)),
            None => writer.finish().map_err(CliError::DemOutput),
        }
        .map(|()| outcome);
    }
    let (blocks, to_write) = std::sync::mpsc::sync_channel::<(Window, Raster)>(0);
    let (done, written) = std::sync::mpsc::channel::<()>();
    std::thread::scope(|scope| {
        let writing = scope.spawn(move || write_blocks(writer, to_write, done, write));
        // Blocks sent and not yet written.
        let pending = std::cell::Cell::new(0usize);
        let decoding = decode_all(
            &mut |window, band| {
                pending.set(pending.get() + 1);
                blocks.send((window, band)).is_ok()
            },
            // The previous block is written (or the writer has stopped) before the next
            // block's samples are made.
            &mut || {
                while pending.get() > 0 && written.recv().is_ok() {
                    pending.set(pending.get() - 1);
                }
            },
        );
        drop(blocks);
        let wrote = writing.join().expect("the GeoTIFF writer does not panic");
        decoding.and(wrote.map_err(CliError::DemOutput))
    })?;
    Ok(outcome)
}

/// Writes the blocks that arrive with `write`, saying on `done` when each is written
/// (and dropped), then finishes the file (nothing is left behind if a block fails or
/// the blocks stop early: the writer is dropped unfinished).
fn write_blocks(
    mut writer: TiledGeoTiffWriter,
    blocks: std::sync::mpsc::Receiver<(Window, Raster)>,
    done: std::sync::mpsc::Sender<()>,
    write: impl Fn(&mut TiledGeoTiffWriter, Window, &Raster) -> Result<(), DemError>,
) -> Result<(), DemError> {
    for (window, band) in blocks {
        write(&mut writer, window, &band)?;
        drop(band);
        // The decoder may have stopped waiting (it failed): nothing to tell it then.
        let _ = done.send(());
    }
    writer.finish()
}
