//! Decoding a TIFF's samples a chunk (strip or tile) at a time: rows `y0..y0 + rows`
//! come from the chunks they touch only, so a band of rows costs the band plus at most
//! one row of chunks, whatever the raster's size. [`read_dem`](super::read_dem) reads
//! the whole raster as one band through the same code.

use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

use tiff::decoder::{ChunkType, Decoder, Limits};
use wavemesh_codec::{SampleType, Samples};

use super::geotiff::tiff_error;
use super::DemError;

/// A TIFF's sample decoder, by rows, with the last partly used chunk row kept.
pub(super) struct ChunkReader<R: Read + Seek> {
    decoder: Decoder<R>,
    path: PathBuf,
    width: usize,
    height: usize,
    sample_type: SampleType,
    /// Columns of a chunk: the tile width, or the raster width for strips.
    chunk_width: usize,
    /// Rows of a chunk: the tile height or the rows a strip holds.
    chunk_height: usize,
    tiled: bool,
    /// The chunk row a band used only part of, decoded (its index and samples), so the
    /// next band in row order does not decode it again.
    cached: Option<(usize, Samples)>,
}

/// A buffer of `len` zero samples of `sample_type`.
pub(super) fn zeroed_samples(sample_type: SampleType, len: usize) -> Samples {
    match sample_type {
        SampleType::U8 => Samples::U8(vec![0; len]),
        SampleType::U16 => Samples::U16(vec![0; len]),
        SampleType::I16 => Samples::I16(vec![0; len]),
        SampleType::I32 => Samples::I32(vec![0; len]),
        SampleType::F32 => Samples::F32(vec![0.0; len]),
    }
}

/// The samples as native-endian bytes, which is what the TIFF decoder writes.
pub(super) fn bytes_mut(samples: &mut Samples) -> &mut [u8] {
    match samples {
        Samples::U8(v) => v,
        Samples::U16(v) => bytemuck::cast_slice_mut(v),
        Samples::I16(v) => bytemuck::cast_slice_mut(v),
        Samples::I32(v) => bytemuck::cast_slice_mut(v),
        Samples::F32(v) => bytemuck::cast_slice_mut(v),
    }
}

/// The samples as native-endian bytes.
pub(super) fn bytes(samples: &Samples) -> &[u8] {
    match samples {
        Samples::U8(v) => v,
        Samples::U16(v) => bytemuck::cast_slice(v),
        Samples::I16(v) => bytemuck::cast_slice(v),
        Samples::I32(v) => bytemuck::cast_slice(v),
        Samples::F32(v) => bytemuck::cast_slice(v),
    }
}

impl<R: Read + Seek> ChunkReader<R> {
    /// Wraps a decoder whose image was checked to be one band of `sample_type`; raises the
    /// decoder's buffer limits to what one chunk needs (nothing is decoded yet).
    pub(super) fn new(
        decoder: Decoder<R>,
        path: &Path,
        sample_type: SampleType,
    ) -> Result<ChunkReader<R>, DemError> {
        let mut decoder = decoder;
        let (width, height) = decoder.dimensions().map_err(|e| tiff_error(path, e))?;
        let tiled = decoder.get_chunk_type() == ChunkType::Tile;
        let (chunk_width, mut chunk_height) = decoder.chunk_dimensions();
        if !tiled {
            // RowsPerStrip may say 2^32 - 1 for "one strip".
            chunk_height = chunk_height.min(height);
        }
        if chunk_width == 0 || chunk_height == 0 {
            return Err(DemError::Malformed(format!(
                "TIFF chunks of {chunk_width} x {chunk_height} samples"
            )));
        }
        let chunk_bytes = u64::from(chunk_width)
            .saturating_mul(u64::from(chunk_height))
            .saturating_mul(sample_type.bytes() as u64);
        let chunk_bytes = usize::try_from(chunk_bytes).unwrap_or(usize::MAX);
        let mut limits = Limits::default();
        limits.decoding_buffer_size = limits.decoding_buffer_size.max(chunk_bytes);
        // A compressed chunk can be a little larger than its samples.
        let compressed = chunk_bytes.saturating_add(chunk_bytes / 8);
        limits.intermediate_buffer_size = limits.intermediate_buffer_size.max(compressed);
        Ok(ChunkReader {
            decoder: decoder.with_limits(limits),
            path: path.to_path_buf(),
            width: width as usize,
            height: height as usize,
            sample_type,
            chunk_width: chunk_width as usize,
            chunk_height: chunk_height as usize,
            tiled,
            cached: None,
        })
    }

    /// Rows of one row of chunks.
    pub(super) fn chunk_rows(&self) -> usize {
        self.chunk_height
    }

    /// Samples one row of chunks holds at most (padding of edge tiles included).
    pub(super) fn chunk_row_samples(&self) -> u64 {
        let across = self.width.div_ceil(self.chunk_width) as u64;
        across * (self.chunk_width * self.chunk_height) as u64
    }

    /// Rows `y0..y0 + rows` (within the raster) as `width × rows` samples.
    pub(super) fn read_rows(&mut self, y0: usize, rows: usize) -> Result<Samples, DemError> {
        let mut band = zeroed_samples(self.sample_type, self.width * rows);
        self.read_rows_into(y0, rows, bytes_mut(&mut band))?;
        Ok(band)
    }

    /// Rows `y0..y0 + rows` (within the raster) into `band`, their bytes in native order.
    pub(super) fn read_rows_into(
        &mut self,
        y0: usize,
        rows: usize,
        band: &mut [u8],
    ) -> Result<(), DemError> {
        let row_bytes = self.width * self.sample_type.bytes();
        let end = y0 + rows;
        for chunk_row in y0 / self.chunk_height..end.div_ceil(self.chunk_height) {
            let top = chunk_row * self.chunk_height;
            let bottom = (top + self.chunk_height).min(self.height);
            let (from, to) = (top.max(y0), bottom.min(end));
            let out = &mut band[(from - y0) * row_bytes..(to - y0) * row_bytes];
            if from == top && to == bottom {
                self.decode_chunk_row(chunk_row, out)?;
            } else {
                let cached = self.cached_chunk_row(chunk_row)?;
                out.copy_from_slice(
                    &bytes(cached)[(from - top) * row_bytes..(to - top) * row_bytes],
                );
            }
        }
        Ok(())
    }

    /// Whether a window narrower than the raster costs less than its full rows: the TIFF
    /// is tiled, so only the tiles the window touches are decoded (a strip spans the
    /// raster's width and is decoded whole whatever the window).
    pub(super) fn reads_columns(&self) -> bool {
        self.tiled
    }

    /// The `width × height` samples at (`x`, `y`) (within the raster) into `out`, their
    /// bytes in native order. A tiled TIFF decodes the tiles the window touches, nothing
    /// else and nothing kept; strips go through [`ChunkReader::read_rows_into`]'s path
    /// and keep the window's columns.
    pub(super) fn read_window_into(
        &mut self,
        (x, y, width, height): (usize, usize, usize, usize),
        out: &mut [u8],
    ) -> Result<(), DemError> {
        if x == 0 && width == self.width {
            return self.read_rows_into(y, height, out);
        }
        let sample_bytes = self.sample_type.bytes();
        let out_row = width * sample_bytes;
        if !self.tiled {
            let raster_row = self.width * sample_bytes;
            let mut rows = vec![0u8; raster_row];
            for (k, dest) in out.chunks_exact_mut(out_row).enumerate() {
                self.read_rows_into(y + k, 1, &mut rows)?;
                dest.copy_from_slice(&rows[x * sample_bytes..(x + width) * sample_bytes]);
            }
            return Ok(());
        }
        let (cw, ch) = (self.chunk_width, self.chunk_height);
        let mut tile = vec![0u8; cw * ch * sample_bytes];
        for chunk_row in y / ch..(y + height).div_ceil(ch) {
            for chunk_column in x / cw..(x + width).div_ceil(cw) {
                let (tx, ty) = (chunk_column * cw, chunk_row * ch);
                let tile_width = cw.min(self.width - tx);
                let tile_height = ch.min(self.height - ty);
                let bytes = &mut tile[..tile_width * tile_height * sample_bytes];
                self.decode_tile(chunk_row, chunk_column, bytes)?;
                let (x0, x1) = (tx.max(x), (tx + tile_width).min(x + width));
                let (row_from, row_to) = (ty.max(y), (ty + tile_height).min(y + height));
                for row in row_from..row_to {
                    let src = ((row - ty) * tile_width + x0 - tx) * sample_bytes;
                    let dest = (row - y) * out_row + (x0 - x) * sample_bytes;
                    let len = (x1 - x0) * sample_bytes;
                    out[dest..dest + len].copy_from_slice(&bytes[src..src + len]);
                }
            }
        }
        Ok(())
    }

    /// Decodes the tile at (`chunk_row`, `chunk_column`) of a tiled TIFF into `out`
    /// (its samples within the raster, row by row).
    fn decode_tile(
        &mut self,
        chunk_row: usize,
        chunk_column: usize,
        out: &mut [u8],
    ) -> Result<(), DemError> {
        let index = chunk_row * self.width.div_ceil(self.chunk_width) + chunk_column;
        let index = u32::try_from(index).map_err(|_| chunk_index_error(index))?;
        self.decoder
            .read_chunk_bytes(index, out)
            .map_err(|e| tiff_error(&self.path, e))
    }

    /// Chunk row `chunk_row`, from the cache or decoded into it (replacing what it held).
    fn cached_chunk_row(&mut self, chunk_row: usize) -> Result<&Samples, DemError> {
        if self.cached.as_ref().map(|(row, _)| *row) != Some(chunk_row) {
            self.cached = None;
            let top = chunk_row * self.chunk_height;
            let rows = (top + self.chunk_height).min(self.height) - top;
            let mut samples = zeroed_samples(self.sample_type, self.width * rows);
            self.decode_chunk_row(chunk_row, bytes_mut(&mut samples))?;
            self.cached = Some((chunk_row, samples));
        }
        Ok(&self.cached.as_ref().expect("just filled").1)
    }

    /// Decodes every chunk of chunk row `chunk_row` into `out`, its rows at full width.
    fn decode_chunk_row(&mut self, chunk_row: usize, out: &mut [u8]) -> Result<(), DemError> {
        let err = |e| tiff_error(&self.path, e);
        if !self.tiled {
            let strip = u32::try_from(chunk_row).map_err(|_| chunk_index_error(chunk_row))?;
            return self.decoder.read_chunk_bytes(strip, out).map_err(err);
        }
        let across = self.width.div_ceil(self.chunk_width);
        let sample_bytes = self.sample_type.bytes();
        let row_bytes = self.width * sample_bytes;
        let mut tile = vec![0u8; self.chunk_width * self.chunk_height * sample_bytes];
        for column in 0..across {
            let x0 = column * self.chunk_width * sample_bytes;
            let tile_row_bytes =
                (self.width - column * self.chunk_width).min(self.chunk_width) * sample_bytes;
            let tile_bytes = out.len() / row_bytes * tile_row_bytes;
            self.decode_tile(chunk_row, column, &mut tile[..tile_bytes])?;
            for (dest, src) in out
                .chunks_exact_mut(row_bytes)
                .zip(tile[..tile_bytes].chunks_exact(tile_row_bytes))
            {
                dest[x0..x0 + tile_row_bytes].copy_from_slice(src);
            }
        }
        Ok(())
    }
}

/// A chunk index past what a TIFF can number.
fn chunk_index_error(index: usize) -> DemError {
    DemError::Malformed(format!(
        "TIFF chunk {index} is past the 2^32 a TIFF can hold"
    ))
}
