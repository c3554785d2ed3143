//! Reading a DEM by bands of rows in bounded memory ([`RowBands`]).
//!
//! A GeoTIFF (stripped, tiled, COG, BigTIFF, any compression and predictor the reader
//! supports) is decoded chunk by chunk: a band costs its own samples plus at most one row
//! of strips or tiles, whatever the raster's size. The other formats are small by nature
//! and are read whole, then sliced.

use std::path::{Path, PathBuf};

use wavemesh_codec::{Raster, SampleType, Samples, TileGrid, Window};

use super::tiff_chunks::{bytes, bytes_mut, zeroed_samples, ChunkReader};
use super::{geotiff, open_detected, read_dem, DemError, DemFormat, ReadOptions, SourceFile};

/// Everything [`read_dem`] puts in a [`Raster`] besides the samples: the codec's
/// description of a raster, the same one a tiled `.ezw` file's header holds.
pub type DemInfo = wavemesh_codec::tiles::RasterInfo;

/// Samples across a band of tiles read at once when the source reads columns cheaply
/// (a tiled TIFF decodes only the tiles a window touches): what the command line uses,
/// so a band costs about this many columns however wide the raster.
pub const BLOCK_WIDTH: usize = 16384;

/// Where a [`RowBands`] gets its rows.
enum BandSource {
    /// A TIFF, decoded chunk by chunk.
    Chunks(Box<ChunkReader<SourceFile>>),
    /// A small format, read whole.
    Whole(Samples),
}

/// A DEM read by bands of rows: [`RowBands::read_rows`] returns rows `y0..y0 + rows`
/// exactly as [`read_dem`] would have them. Increasing `y0` is the fast path (a chunk row
/// that two bands share is decoded once); any `y0` is correct.
pub struct RowBands {
    info: DemInfo,
    source: BandSource,
    path: PathBuf,
    options: ReadOptions,
}

impl RowBands {
    /// Opens `path` (format detected as [`read_dem`] does). For a GeoTIFF only the tags are
    /// read; `options.max_samples` and `options.max_memory` bound what a band holds, not
    /// the raster's size. Other formats are read whole under `options`.
    pub fn open(path: &Path, options: &ReadOptions) -> Result<RowBands, DemError> {
        let (reader, _, format) = open_detected(path, options)?;
        let (info, source) = match format {
            DemFormat::GeoTiff => {
                let (info, chunks) =
                    geotiff::open(reader, path, options).map_err(|e| e.in_file(path))?;
                (info, BandSource::Chunks(Box::new(chunks)))
            }
            _ => {
                drop(reader);
                let raster = read_dem(path, options)?;
                (DemInfo::of(&raster), BandSource::Whole(raster.samples))
            }
        };
        let bands = RowBands {
            info,
            source,
            path: path.to_path_buf(),
            options: options.clone(),
        };
        bands.check_band(bands.info.width, 1)?;
        Ok(bands)
    }

    /// The raster's size, sample type, nodata, georeferencing and metadata.
    pub fn info(&self) -> &DemInfo {
        &self.info
    }

    /// Rows of one row of chunks: a strip's or a tile's height (the raster's height for
    /// formats read whole). Bands that start and end on multiples of it decode each chunk
    /// once and keep nothing between calls.
    pub fn chunk_rows(&self) -> usize {
        match &self.source {
            BandSource::Chunks(chunks) => chunks.chunk_rows(),
            BandSource::Whole(_) => self.info.height,
        }
    }

    /// Whether a window narrower than the raster is cheaper to read than its full rows
    /// (a tiled TIFF, or a format read whole); strips are decoded at full width
    /// whatever the window.
    pub fn reads_columns(&self) -> bool {
        match &self.source {
            BandSource::Chunks(chunks) => chunks.reads_columns(),
            BandSource::Whole(_) => true,
        }
    }

    /// Tiles of `grid` a band should span across: about `block_width` samples (at least
    /// one tile) when the source reads columns cheaply ([`RowBands::reads_columns`]),
    /// else a whole tile row (a strip is decoded at full width anyway).
    pub fn tiles_per_block(&self, grid: &TileGrid, block_width: usize) -> usize {
        if self.reads_columns() {
            grid.tiles_within(block_width)
        } else {
            grid.columns()
        }
    }

    /// Rows `y0..y0 + rows` as a `width × rows` raster: samples exactly as [`read_dem`]
    /// gives them, the nodata value set, no georeferencing.
    pub fn read_rows(&mut self, y0: usize, rows: usize) -> Result<Raster, DemError> {
        let width = self.info.width;
        self.read_window(Window {
            x: 0,
            y: y0,
            width,
            height: rows,
        })
    }

    /// The samples of `window` as a raster, exactly as [`read_dem`] gives them, the
    /// nodata value set, no georeferencing. A tiled TIFF decodes only the tiles the
    /// window touches.
    pub fn read_window(&mut self, window: Window) -> Result<Raster, DemError> {
        self.check_window(&window)?;
        let mut samples = zeroed_samples(self.info.sample_type, window.width * window.height);
        self.read_into(&window, bytes_mut(&mut samples))?;
        self.band(window.width, window.height, samples)
    }

    /// `above` (the samples just above `window` in its columns, e.g. kept from the
    /// previous band) with the samples of `window` below it, as one raster: the band is
    /// allocated once, the new rows read straight into it.
    pub fn read_window_below(
        &mut self,
        above: &Raster,
        window: Window,
    ) -> Result<Raster, DemError> {
        self.check_window(&window)?;
        if above.width != window.width || above.sample_type() != self.info.sample_type {
            return Err(DemError::InvalidRaster(format!(
                "rows of {} {} samples above a band of {} {} samples a row",
                above.width,
                above.sample_type().name(),
                window.width,
                self.info.sample_type.name()
            )));
        }
        self.check_band(window.width, above.height + window.height)?;
        let rows = above.height + window.height;
        let mut samples = zeroed_samples(self.info.sample_type, window.width * rows);
        let kept = bytes(&above.samples);
        let (top, below) = bytes_mut(&mut samples).split_at_mut(kept.len());
        top.copy_from_slice(kept);
        self.read_into(&window, below)?;
        self.band(window.width, rows, samples)
    }

    /// Refuses a window outside the raster or over the limits (what reading it would).
    pub fn check_window(&self, window: &Window) -> Result<(), DemError> {
        let (width, height) = (self.info.width, self.info.height);
        let inside = |start: usize, len: usize, side: usize| {
            len > 0 && start.checked_add(len).is_some_and(|end| end <= side)
        };
        if !inside(window.x, window.width, width) || !inside(window.y, window.height, height) {
            return Err(DemError::WindowOutOfRange {
                window: (window.x, window.y, window.width, window.height),
                width,
                height,
            });
        }
        self.check_band(window.width, window.height)
    }

    /// Reads the samples of `window` (checked) into `out`, native byte order.
    fn read_into(&mut self, window: &Window, out: &mut [u8]) -> Result<(), DemError> {
        let Window {
            x,
            y,
            width,
            height,
        } = *window;
        match &mut self.source {
            BandSource::Chunks(chunks) => chunks
                .read_window_into((x, y, width, height), out)
                .map_err(|e| e.in_file(&self.path)),
            BandSource::Whole(all) => {
                let sample_bytes = self.info.sample_type.bytes();
                let all = bytes(all);
                let raster_row = self.info.width * sample_bytes;
                for (k, dest) in out.chunks_exact_mut(width * sample_bytes).enumerate() {
                    let start = (y + k) * raster_row + x * sample_bytes;
                    dest.copy_from_slice(&all[start..start + dest.len()]);
                }
                Ok(())
            }
        }
    }

    /// A band raster of `samples` with the source's nodata value.
    fn band(&self, width: usize, rows: usize, samples: Samples) -> Result<Raster, DemError> {
        let mut band = super::make_raster(width, rows, samples)?;
        band.nodata = self.info.nodata;
        Ok(band)
    }

    /// Checks that a band of `width × rows` samples plus what the source keeps (one
    /// chunk row, or the whole raster for formats read whole) fits `max_samples` and
    /// `max_memory`.
    fn check_band(&self, width: usize, rows: usize) -> Result<(), DemError> {
        let width = width as u64;
        let kept = match &self.source {
            BandSource::Chunks(chunks) => chunks.chunk_row_samples(),
            BandSource::Whole(samples) => samples.len() as u64,
        };
        let band = width.saturating_mul(rows as u64);
        let sample_type = self.info.sample_type;
        let work = match sample_type {
            SampleType::F32 => self.options.work.float,
            _ => self.options.work.integer,
        };
        let bytes = sample_type.bytes() as u128;
        let samples = u128::from(band) + u128::from(kept);
        let memory = u128::from(band) * (bytes + u128::from(work)) + u128::from(kept) * bytes;
        let over = |needed: u128, limit: u64, unit: &'static str| DemError::BandOverLimit {
            width,
            rows: rows as u64,
            kept,
            needed,
            limit,
            unit,
        };
        if samples > u128::from(self.options.max_samples) {
            return Err(over(samples, self.options.max_samples, "samples"));
        }
        if memory > u128::from(self.options.max_memory) {
            return Err(over(memory, self.options.max_memory, "bytes"));
        }
        Ok(())
    }
}
