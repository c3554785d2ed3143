//! Writing a tiled (or stripped) GeoTIFF by bands of rows, one row of tiles in memory,
//! or by blocks of whole tiles in any order, one block in memory
//! ([`TiledGeoTiffWriter`]).
//!
//! The `tiff` crate (0.11) writes strips only, and its strip-at-a-time writer
//! (`ImageEncoder::write_strip`) stores them uncompressed under a Deflate tag. So chunks
//! are cut here, then predicted and Deflate-compressed by the crate's own predictor and
//! compressor, and written through the crate's directory encoder, which also writes the
//! tags: the chunk offsets and byte counts and the GeoTIFF tags of the whole-raster
//! writer. That encoder borrows the file for the life of the image directory, across
//! calls, so it lives on a writer thread fed compressed chunks (with their indices)
//! over a rendezvous channel.

use std::io::{self, BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

use tiff::encoder::colortype::{self, ColorType};
use tiff::encoder::compression::{CompressionAlgorithm, Deflate, DeflateLevel};
use tiff::encoder::{DirectoryEncoder, Rational, TiffEncoder, TiffKind, TiffValue};
use tiff::tags::{CompressionMethod, ResolutionUnit, Tag};
use tiff::TiffError;
use wavemesh_codec::{Raster, SampleType, Samples};

use super::geotiff::GeoTags;
use super::tiff_chunks::{bytes, bytes_mut, zeroed_samples};
use super::{check_raster, DemError, DemInfo};
use crate::atomic::AtomicFile;

/// A tiled, Deflate-compressed GeoTIFF written by bands of rows in row order, holding one
/// row of tiles, or by blocks of whole tiles in any order; written to a temporary file renamed into place by
/// [`TiledGeoTiffWriter::finish`] (dropped unfinished, it leaves nothing behind).
/// [`TiledGeoTiffWriter::create_striped`] writes strips the same way.
pub struct TiledGeoTiffWriter {
    path: PathBuf,
    width: usize,
    height: usize,
    sample_type: SampleType,
    chunks: Chunking,
    /// Rows received so far ([`TiledGeoTiffWriter::write_rows`]).
    rows_received: usize,
    /// Chunks sent to the writer thread, by index (rows or blocks).
    sent: Vec<bool>,
    /// Blocks were given ([`TiledGeoTiffWriter::write_block`]): rows may not be.
    by_blocks: bool,
    /// The row of chunks being gathered: a chunk's height of rows of `width` samples
    /// (allocated by the first rows given).
    gathering: Samples,
    /// Rows of `gathering` filled.
    gathered: usize,
    chunks_out: Option<SyncSender<Message>>,
    worker: Option<JoinHandle<Result<AtomicFile, DemError>>>,
    /// The threads a row of chunks is compressed on ([`TiledGeoTiffWriter::with_threads`]);
    /// none: the calling thread.
    compressors: Option<rayon::ThreadPool>,
}

/// What the writer thread receives.
enum Message {
    /// Compressed chunks and their indices (row-major), in any order.
    Chunks(Vec<(usize, Vec<u8>)>),
    /// Every chunk was sent: write the directory.
    Finish,
}

/// How the samples are cut into compressed chunks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Chunking {
    /// Square tiles of this side.
    Tiles(u32),
    /// Full-width strips of this many rows.
    Strips(u32),
}

impl Chunking {
    /// Rows of a chunk.
    fn rows(self) -> usize {
        match self {
            Chunking::Tiles(n) | Chunking::Strips(n) => n as usize,
        }
    }

    /// Chunks across a raster `width` samples wide.
    fn across(self, width: usize) -> usize {
        match self {
            Chunking::Tiles(n) => width.div_ceil(n as usize),
            Chunking::Strips(_) => 1,
        }
    }
}

/// The image's shape, for the tags.
struct Layout {
    width: u32,
    height: u32,
    chunks: Chunking,
    sample_type: SampleType,
    /// Write a BigTIFF: the chunks may pass 4 GiB.
    big: bool,
}

impl TiledGeoTiffWriter {
    /// Starts a `tile × tile` tiled GeoTIFF at `path` for a raster described by `info`
    /// (BigTIFF when its data may pass 4 GiB). `tile` must be a positive multiple of 16
    /// (TIFF's rule); `path` must name a regular file (the writer seeks).
    pub fn create(path: &Path, info: &DemInfo, tile: u32) -> Result<Self, DemError> {
        if tile == 0 || !tile.is_multiple_of(16) {
            return Err(DemError::Unsupported(format!(
                "tiles of {tile} x {tile}: TIFF tiles must be a positive multiple of 16"
            )));
        }
        TiledGeoTiffWriter::start(path, info, Chunking::Tiles(tile))
    }

    /// Starts a GeoTIFF of `rows_per_strip`-row strips, otherwise as [`Self::create`].
    pub fn create_striped(
        path: &Path,
        info: &DemInfo,
        rows_per_strip: u32,
    ) -> Result<Self, DemError> {
        if rows_per_strip == 0 {
            return Err(DemError::Unsupported("strips of 0 rows".into()));
        }
        TiledGeoTiffWriter::start(path, info, Chunking::Strips(rows_per_strip))
    }

    /// Checks the layout, opens the temporary file and starts the writer thread.
    fn start(path: &Path, info: &DemInfo, chunks: Chunking) -> Result<Self, DemError> {
        let layout = Layout::new(info, chunks)?;
        let tags = GeoTags::new(info).map_err(|e| e.in_file(path))?;
        let io_error = |source| DemError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = AtomicFile::create(path).map_err(io_error)?;
        let (chunks_out, chunks_in) = sync_channel(0);
        let target = path.to_path_buf();
        let worker = std::thread::Builder::new()
            .name("geotiff-writer".into())
            .spawn(move || write_file(file, &target, &layout, &tags, chunks_in))
            .map_err(io_error)?;
        Ok(TiledGeoTiffWriter {
            path: path.to_path_buf(),
            width: info.width,
            height: info.height,
            sample_type: info.sample_type,
            chunks,
            rows_received: 0,
            sent: vec![false; chunks.across(info.width) * info.height.div_ceil(chunks.rows())],
            by_blocks: false,
            gathering: zeroed_samples(info.sample_type, 0),
            gathered: 0,
            chunks_out: Some(chunks_out),
            worker: Some(worker),
            compressors: None,
        })
    }

    /// Compresses the chunks of each row of chunks on `threads` threads (0: one per
    /// core; 1: the calling thread). The file does not depend on it.
    pub fn with_threads(mut self, threads: usize) -> Result<Self, DemError> {
        self.compressors = match threads {
            1 => None,
            n => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .thread_name(|i| format!("geotiff-deflate-{i}"))
                    .build()
                    .map_err(|e| DemError::Io {
                        path: self.path.clone(),
                        source: io::Error::other(e),
                    })?,
            ),
        };
        Ok(self)
    }

    /// Adds rows `y0..y0 + band.height`: bands come in row order, each as wide as the
    /// raster and of its sample type; any band height works.
    pub fn write_rows(&mut self, y0: usize, band: &Raster) -> Result<(), DemError> {
        self.check_band(y0, band)?;
        if self.gathering.is_empty() {
            self.gathering = zeroed_samples(self.sample_type, self.width * self.chunks.rows());
        }
        let row_bytes = self.width * self.sample_type.bytes();
        let mut done = 0;
        while done < band.height {
            let rows = (self.chunks.rows() - self.gathered).min(band.height - done);
            let to = self.gathered * row_bytes;
            let from = done * row_bytes;
            bytes_mut(&mut self.gathering)[to..to + rows * row_bytes]
                .copy_from_slice(&bytes(&band.samples)[from..from + rows * row_bytes]);
            self.gathered += rows;
            self.rows_received += rows;
            done += rows;
            if self.gathered == self.chunks.rows() || self.rows_received == self.height {
                self.send_chunk_row()?;
            }
        }
        Ok(())
    }

    /// Adds `band` at (`x0`, `y0`), a block of whole tiles of a tiled file: its corner
    /// on a tile's corner, its sides multiples of the tile side or reaching the raster's
    /// edge. Blocks come in any order, each tile once; memory holds the block only, so a
    /// file can be written in blocks narrower than the raster. Not mixed with
    /// [`TiledGeoTiffWriter::write_rows`].
    pub fn write_block(&mut self, (x0, y0): (usize, usize), band: &Raster) -> Result<(), DemError> {
        let indices = self.check_block((x0, y0), band)?;
        self.by_blocks = true;
        let Chunking::Tiles(tile) = self.chunks else {
            unreachable!("check_block refuses strips")
        };
        let tile = tile as usize;
        let row_bytes = band.width * self.sample_type.bytes();
        let io_error = |source| DemError::Io {
            path: self.path.clone(),
            source,
        };
        let mut chunks = Vec::with_capacity(indices.len());
        for y in (0..band.height).step_by(tile) {
            let rows = tile.min(band.height - y);
            let source = &bytes(&band.samples)[y * row_bytes..(y + rows) * row_bytes];
            let compressed = compress_chunk_row(
                source,
                (self.sample_type, rows, band.width),
                self.chunks,
                self.compressors.as_ref(),
            )
            .map_err(io_error)?;
            chunks.extend(compressed);
        }
        for &k in &indices {
            self.sent[k] = true;
        }
        self.send(Message::Chunks(indices.into_iter().zip(chunks).collect()))
    }

    /// The chunk indices of a block [`TiledGeoTiffWriter::write_block`] may take, row by
    /// row; an error for anything else.
    fn check_block(&self, (x0, y0): (usize, usize), band: &Raster) -> Result<Vec<usize>, DemError> {
        check_raster(band)?;
        let Chunking::Tiles(tile) = self.chunks else {
            return Err(self.misuse("blocks given to a stripped file".into()));
        };
        let tile = tile as usize;
        let fits = |start: usize, len: usize, side: usize| {
            start.is_multiple_of(tile)
                && len > 0
                && start
                    .checked_add(len)
                    .is_some_and(|end| end <= side && (end == side || len.is_multiple_of(tile)))
        };
        if band.sample_type() != self.sample_type {
            return Err(self.misuse(format!("a block of {} samples", band.sample_type().name())));
        }
        if self.rows_received > 0
            || !fits(x0, band.width, self.width)
            || !fits(y0, band.height, self.height)
        {
            return Err(self.misuse(format!(
                "a block of {}x{} at ({x0}, {y0}) is not whole tiles of {tile} of a {}x{} raster \
                 written by blocks",
                band.width, band.height, self.width, self.height
            )));
        }
        let across = self.chunks.across(self.width);
        let indices: Vec<usize> = (y0 / tile..(y0 + band.height).div_ceil(tile))
            .flat_map(|r| {
                (x0 / tile..(x0 + band.width).div_ceil(tile)).map(move |c| r * across + c)
            })
            .collect();
        if let Some(k) = indices.iter().find(|&&k| self.sent[k]) {
            return Err(self.misuse(format!("tile {k} given twice")));
        }
        Ok(indices)
    }

    /// A misuse of the writer, named with its file.
    fn misuse(&self, problem: String) -> DemError {
        DemError::InvalidRaster(format!("{}: {problem}", self.path.display()))
    }

    /// Writes the directory and renames the file into place; an error when rows are
    /// missing (and then nothing is left behind).
    pub fn finish(mut self) -> Result<(), DemError> {
        if self.by_blocks {
            let written = self.sent.iter().filter(|&&s| s).count();
            if written != self.sent.len() {
                return Err(self.misuse(format!(
                    "finished with {written} of {} tiles written",
                    self.sent.len()
                )));
            }
        } else if self.rows_received != self.height {
            return Err(DemError::InvalidRaster(format!(
                "{}: finished after {} of {} rows",
                self.path.display(),
                self.rows_received,
                self.height
            )));
        }
        self.send(Message::Finish)?;
        self.chunks_out = None;
        let file = self.join_worker()?;
        file.commit().map_err(|source| DemError::Io {
            path: self.path.clone(),
            source,
        })
    }

    /// Refuses a band of another width or type, out of row order or past the last row.
    fn check_band(&self, y0: usize, band: &Raster) -> Result<(), DemError> {
        check_raster(band)?;
        let problem = if self.by_blocks {
            "rows given to a file written by blocks".to_string()
        } else if band.width != self.width || band.sample_type() != self.sample_type {
            format!(
                "a band of {} {} samples a row for a raster of {} {} samples a row",
                band.width,
                band.sample_type().name(),
                self.width,
                self.sample_type.name()
            )
        } else if y0 != self.rows_received {
            format!(
                "rows from {y0} given where row {} comes next",
                self.rows_received
            )
        } else if y0 + band.height > self.height {
            format!(
                "rows {y0}..{} given for a raster of {} rows",
                y0 + band.height,
                self.height
            )
        } else {
            return Ok(());
        };
        Err(DemError::InvalidRaster(format!(
            "{}: {problem}",
            self.path.display()
        )))
    }

    /// Compresses the gathered row of chunks and hands it to the writer thread.
    fn send_chunk_row(&mut self) -> Result<(), DemError> {
        let rows = self.gathered * self.width * self.sample_type.bytes();
        let source = &bytes(&self.gathering)[..rows];
        let compressed = compress_chunk_row(
            source,
            (self.sample_type, self.gathered, self.width),
            self.chunks,
            self.compressors.as_ref(),
        )
        .map_err(|source| DemError::Io {
            path: self.path.clone(),
            source,
        })?;
        self.gathered = 0;
        let first = (self.rows_received - 1) / self.chunks.rows() * self.chunks.across(self.width);
        for k in first..first + compressed.len() {
            self.sent[k] = true;
        }
        let indexed = (first..).zip(compressed).collect();
        self.send(Message::Chunks(indexed))
    }

    /// Sends to the writer thread; when it has stopped, its error.
    fn send(&mut self, message: Message) -> Result<(), DemError> {
        let sent = self.chunks_out.as_ref().map(|out| out.send(message));
        match sent {
            Some(Ok(())) => Ok(()),
            _ => Err(match self.join_worker() {
                Err(e) => e,
                Ok(_) => self.worker_lost(),
            }),
        }
    }

    /// Waits for the writer thread and returns what it returned.
    fn join_worker(&mut self) -> Result<AtomicFile, DemError> {
        match self.worker.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            _ => Err(self.worker_lost()),
        }
    }

    fn worker_lost(&self) -> DemError {
        DemError::Io {
            path: self.path.clone(),
            source: io::Error::other("the GeoTIFF writer thread stopped"),
        }
    }
}

impl Drop for TiledGeoTiffWriter {
    /// Closes the channel and waits for the writer thread, which removes the unfinished
    /// temporary file.
    fn drop(&mut self) {
        self.chunks_out = None;
        if let Some(worker) = self.worker.take() {
            // The file is abandoned: its outcome does not matter.
            let _ = worker.join();
        }
    }
}

impl Layout {
    /// Checks that the raster fits TIFF's 32-bit dimensions.
    fn new(info: &DemInfo, chunks: Chunking) -> Result<Layout, DemError> {
        let dimension = |n: usize| u32::try_from(n).ok().filter(|&n| n > 0);
        let (Some(width), Some(height)) = (dimension(info.width), dimension(info.height)) else {
            return Err(DemError::InvalidRaster(format!(
                "{} x {} raster: a TIFF needs sides from 1 to 2^32 - 1",
                info.width, info.height
            )));
        };
        // The chunks (tiles padded, and Deflate's worst case on top) may pass 4 GiB.
        let (padded_width, padded_height) = match chunks {
            Chunking::Tiles(tile) => (width.next_multiple_of(tile), height.next_multiple_of(tile)),
            Chunking::Strips(_) => (width, height),
        };
        let bytes =
            u64::from(padded_width) * u64::from(padded_height) * info.sample_type.bytes() as u64;
        Ok(Layout {
            width,
            height,
            chunks,
            sample_type: info.sample_type,
            big: bytes + bytes / 64 + (64 << 20) > u64::from(u32::MAX),
        })
    }

    /// The chunk offsets and byte counts tags.
    fn offset_tags(&self) -> (Tag, Tag) {
        match self.chunks {
            Chunking::Tiles(_) => (Tag::TileOffsets, Tag::TileByteCounts),
            Chunking::Strips(_) => (Tag::StripOffsets, Tag::StripByteCounts),
        }
    }

    /// The baseline and chunking tags (the offsets and byte counts aside).
    fn write_tags<W: Write + Seek, K: TiffKind>(
        &self,
        dir: &mut DirectoryEncoder<'_, W, K>,
    ) -> tiff::TiffResult<()> {
        let (format, bits) = match self.sample_type {
            SampleType::U8 => (1u16, 8u16),
            SampleType::U16 => (1, 16),
            SampleType::I16 => (2, 16),
            SampleType::I32 => (2, 32),
            SampleType::F32 => (3, 32),
        };
        // Horizontal differencing for integers, none for floats (as the whole-raster writer).
        let predictor: u16 = if self.sample_type.is_integer() { 2 } else { 1 };
        dir.write_tag(Tag::ImageWidth, self.width)?;
        dir.write_tag(Tag::ImageLength, self.height)?;
        dir.write_tag(Tag::BitsPerSample, bits)?;
        dir.write_tag(Tag::Compression, CompressionMethod::Deflate.to_u16())?;
        dir.write_tag(Tag::PhotometricInterpretation, 1u16)?;
        dir.write_tag(Tag::SamplesPerPixel, 1u16)?;
        dir.write_tag(Tag::PlanarConfiguration, 1u16)?;
        dir.write_tag(Tag::Predictor, predictor)?;
        // As the whole-raster writer (the `tiff` crate) does, so GDAL sees the same tags.
        dir.write_tag(Tag::XResolution, Rational { n: 1, d: 1 })?;
        dir.write_tag(Tag::YResolution, Rational { n: 1, d: 1 })?;
        dir.write_tag(Tag::ResolutionUnit, ResolutionUnit::None.to_u16())?;
        match self.chunks {
            Chunking::Tiles(tile) => {
                dir.write_tag(Tag::TileWidth, tile)?;
                dir.write_tag(Tag::TileLength, tile)?;
            }
            Chunking::Strips(rows) => dir.write_tag(Tag::RowsPerStrip, rows)?,
        }
        dir.write_tag(Tag::SampleFormat, format)
    }
}

/// The writer thread: writes the chunks it receives, then the directory on
/// [`Message::Finish`]; returns the file to commit, or an error when the channel closed
/// before `Finish` (the writer was dropped) or a write failed.
fn write_file(
    mut file: AtomicFile,
    path: &Path,
    layout: &Layout,
    tags: &GeoTags,
    chunks_in: Receiver<Message>,
) -> Result<AtomicFile, DemError> {
    let mut out = BufWriter::new(file.file());
    let finished = if layout.big {
        write_image(TiffEncoder::new_big(&mut out), layout, tags, chunks_in)
    } else {
        write_image(TiffEncoder::new(&mut out), layout, tags, chunks_in)
    };
    let finished = finished.map_err(|e| write_error(path, e))?;
    out.flush().map_err(|e| write_error(path, e.into()))?;
    drop(out);
    if finished {
        Ok(file)
    } else {
        let dropped = io::Error::other("the writer was dropped unfinished");
        Err(write_error(path, dropped.into()))
    }
}

/// The image directory, its chunks and tags; `false` when the chunks stopped coming before
/// [`Message::Finish`].
fn write_image<W: Write + Seek, K: TiffKind>(
    encoder: tiff::TiffResult<TiffEncoder<W, K>>,
    layout: &Layout,
    tags: &GeoTags,
    chunks_in: Receiver<Message>,
) -> tiff::TiffResult<bool> {
    let mut encoder = encoder?;
    let mut dir = encoder.image_directory()?;
    let count = layout.chunks.across(layout.width as usize)
        * (layout.height as usize).div_ceil(layout.chunks.rows());
    let mut offsets = vec![0u64; count];
    let mut byte_counts = vec![0u64; count];
    for message in chunks_in {
        match message {
            Message::Chunks(compressed) => {
                for (k, chunk) in compressed {
                    offsets[k] = dir.write_data(&chunk[..])?;
                    byte_counts[k] = chunk.len() as u64;
                }
            }
            Message::Finish => {
                let convert = |values: &[u64]| -> tiff::TiffResult<Vec<K::OffsetType>> {
                    values.iter().map(|&v| K::convert_offset(v)).collect()
                };
                let (offsets, byte_counts) = (convert(&offsets)?, convert(&byte_counts)?);
                layout.write_tags(&mut dir)?;
                tags.write(&mut dir)?;
                let (offsets_tag, byte_counts_tag) = layout.offset_tags();
                dir.write_tag(offsets_tag, K::convert_slice(&offsets))?;
                dir.write_tag(byte_counts_tag, K::convert_slice(&byte_counts))?;
                dir.finish()?;
                return Ok(true);
            }
        }
    }
    Ok(false)
}

/// A write failure of the writer thread on `path`.
fn write_error(path: &Path, e: TiffError) -> DemError {
    match e {
        TiffError::IoError(source) => DemError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => DemError::Unsupported(format!("{}: TIFF encoder: {other}", path.display())),
    }
}

/// Cuts `source` (`rows` rows of `width` samples of `sample_type`, native byte order) into
/// chunks, left to right, and compresses each (on `compressors` when given): tiles padded
/// with zeros to full tiles, a strip of `rows`.
fn compress_chunk_row(
    source: &[u8],
    (sample_type, rows, width): (SampleType, usize, usize),
    chunks: Chunking,
    compressors: Option<&rayon::ThreadPool>,
) -> io::Result<Vec<Vec<u8>>> {
    let (chunk_width, chunk_rows) = match chunks {
        Chunking::Tiles(tile) => (tile as usize, tile as usize),
        Chunking::Strips(_) => (width, rows),
    };
    let sample_bytes = sample_type.bytes();
    let row_bytes = width * sample_bytes;
    let chunk = |x0: usize| {
        let used = (width - x0).min(chunk_width) * sample_bytes;
        let mut block = zeroed_samples(sample_type, chunk_width * chunk_rows);
        for (dest, row) in bytes_mut(&mut block)
            .chunks_exact_mut(chunk_width * sample_bytes)
            .zip(source.chunks_exact(row_bytes))
        {
            dest[..used].copy_from_slice(&row[x0 * sample_bytes..x0 * sample_bytes + used]);
        }
        compress_chunk(&block, chunk_width)
    };
    let starts = (0..width).step_by(chunk_width);
    match compressors {
        Some(pool) if starts.len() > 1 => {
            use rayon::prelude::*;
            let starts: Vec<usize> = starts.collect();
            pool.install(|| starts.into_par_iter().map(chunk).collect())
        }
        _ => starts.map(chunk).collect(),
    }
}

/// One chunk `width` samples wide, predicted as the whole-raster writer predicts and
/// Deflate-compressed.
fn compress_chunk(block: &Samples, width: usize) -> io::Result<Vec<u8>> {
    match block {
        Samples::U8(v) => predicted_deflate::<colortype::Gray8>(v, width),
        Samples::U16(v) => predicted_deflate::<colortype::Gray16>(v, width),
        Samples::I16(v) => predicted_deflate::<colortype::GrayI16>(v, width),
        Samples::I32(v) => predicted_deflate::<colortype::GrayI32>(v, width),
        Samples::F32(v) => deflate(bytemuck::cast_slice(v)),
    }
}

/// Horizontal differencing row by row (the `tiff` crate's predictor), then Deflate.
fn predicted_deflate<C: ColorType>(samples: &[C::Inner], width: usize) -> io::Result<Vec<u8>>
where
    [C::Inner]: TiffValue,
{
    let mut predicted = Vec::with_capacity(samples.len());
    for row in samples.chunks_exact(width) {
        C::horizontal_predict(row, &mut predicted);
    }
    deflate(&predicted[..].data())
}

/// Deflate (zlib) at the fast level, as the whole-raster writer compresses.
fn deflate(data: &[u8]) -> io::Result<Vec<u8>> {
    let mut out = Vec::with_capacity(data.len() / 2);
    Deflate::with_level(DeflateLevel::Fast).write_to(&mut out, data)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::{read_dem, ReadOptions};

    fn i16_info(width: usize, height: usize) -> DemInfo {
        DemInfo {
            width,
            height,
            sample_type: SampleType::I16,
            nodata: Some(-32768.0),
            georef: None,
            metadata: Default::default(),
        }
    }

    #[test]
    fn bigtiff_past_4_gib_and_it_reads_back() {
        let big = |w, h, chunks| Layout::new(&i16_info(w, h), chunks).unwrap().big;
        assert!(!big(16384, 16384, Chunking::Tiles(512)));
        assert!(big(65536, 32768, Chunking::Tiles(512)));
        assert!(big(65536, 32768, Chunking::Strips(16)));
        assert!(!big(40000, 40000, Chunking::Strips(16)));
        // A small raster through the same writer thread, as BigTIFF.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.tif");
        let samples = Samples::I16((0..1200).map(|i| i as i16 * 53 - 600).collect());
        let mut raster = Raster::new(40, 30, samples).unwrap();
        raster.nodata = Some(-32768.0);
        let info = DemInfo::of(&raster);
        let mut layout = Layout::new(&info, Chunking::Tiles(32)).unwrap();
        layout.big = true;
        let (send, receive) = sync_channel(2);
        let source = bytes(&raster.samples);
        let row =
            compress_chunk_row(source, (SampleType::I16, 30, 40), layout.chunks, None).unwrap();
        send.send(Message::Chunks(row.into_iter().enumerate().collect()))
            .unwrap();
        send.send(Message::Finish).unwrap();
        let file = AtomicFile::create(&path).unwrap();
        let tags = GeoTags::new(&info).unwrap();
        write_file(file, &path, &layout, &tags, receive)
            .unwrap()
            .commit()
            .unwrap();
        assert_eq!(&std::fs::read(&path).unwrap()[..4], b"II+\0");
        assert_eq!(read_dem(&path, &ReadOptions::default()).unwrap(), raster);
    }
}
