//! A tiled `.ezw` file decoded a tile at a time, for `wavemesh.dask.open_ezw`: the plan
//! read from the header and index alone ([`tiled_plan`]: where each tile lies and how
//! many of its bytes a decode at a budget reads), then one tile from its own byte range
//! ([`decode_tile`], run wherever the task runs).

use std::path::{Path, PathBuf};

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use wavemesh::byte_source::FileSource;
use wavemesh_codec::tiles::{tile_lengths, TiledLayout};
use wavemesh_codec::{ByteSource, CodecError as RustCodecError, DecodeOptions, Limits};

use crate::arrays::arrays_of;
use crate::coding::bpp_budget;
use crate::errors::{codec_error, io_error, CodecError};

/// `path` opened for range reads.
fn open(path: &Path) -> PyResult<FileSource> {
    FileSource::open(path).map_err(|e| io_error(path, &e))
}

/// The plan of a decode of the tiled file at `path`, whole or at a budget of `bpp` bits
/// per sample or `nbytes` bytes (as `decode` shares it among tiles), read from its header
/// and index only: a dict of `width`, `height`, `tile_width`, `tile_height`, `overlap`
/// (samples each tile's stream codes beyond the tile on each side, within the raster),
/// `sample_type`, `nodata`, `compact_tiles` (the tiles' streams have the tile layout, as
/// `decode_tile` needs to know), `max_bytes` (the budget in bytes, if any), `code_block` (the side of the code blocks the tiles are
/// cut into, or `None`: a tile of such a file is decoded with `decode_blocked_tile`),
/// and per index entry (per tile in grid order without code blocks) `offsets` (file byte
/// where its stream starts), `lengths` (bytes of it the decode reads) and `passes` (its
/// index entry's prefix length and error per pass, for `decode_tile`).
#[pyfunction]
#[pyo3(signature = (path, *, bpp=None, nbytes=None))]
pub fn tiled_plan<'py>(
    py: Python<'py>,
    path: PathBuf,
    bpp: Option<f64>,
    nbytes: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut source = open(&path)?;
    let index_limit = Limits::default().max_memory / 4;
    let layout = py
        .detach(|| TiledLayout::read(&mut source, index_limit))
        .map_err(|e| CodecError::new_err(format!("{}: {e}", path.display())))?
        .ok_or_else(|| {
            PyValueError::new_err(format!(
                "{} is a single-stream .ezw file, not a tiled one: decode it with wavemesh.decode",
                path.display()
            ))
        })?;
    let max_bytes = match (bpp, nbytes) {
        (Some(_), Some(_)) => return Err(PyValueError::new_err("give bpp or nbytes, not both")),
        (Some(bpp), None) => Some(bpp_budget(bpp, layout.header.sample_count())?),
        (None, nbytes) => nbytes,
    };
    let lengths = tile_lengths(&layout, max_bytes).map_err(codec_error)?;
    let out = PyDict::new(py);
    out.set_item("width", layout.grid.width)?;
    out.set_item("height", layout.grid.height)?;
    out.set_item("tile_width", layout.grid.tile_width)?;
    out.set_item("tile_height", layout.grid.tile_height)?;
    out.set_item("overlap", layout.grid.overlap)?;
    out.set_item("sample_type", layout.header.sample_type.name())?;
    out.set_item("nodata", layout.header.nodata)?;
    out.set_item("compact_tiles", layout.compact_tiles())?;
    out.set_item("code_block", layout.code_block())?;
    out.set_item("max_bytes", max_bytes)?;
    out.set_item("offsets", &layout.offsets)?;
    out.set_item("lengths", lengths)?;
    let passes: Vec<&[(u64, f64)]> = layout.entries.iter().map(|e| &e.passes[..]).collect();
    out.set_item("passes", passes)?;
    Ok(out)
}

/// Decodes one tile of a tiled file: the `length` bytes from `offset` of `path` (one
/// range read), a `width × height` tile whose voids are `nodata` (the file's), as
/// `decode` decodes it; `(samples, valid)`. The stream codes the tile and its overlap:
/// `coded = (x, y, coded_width, coded_height)` says where the tile lies in what it codes
/// (the tile alone when not given); `compact_tiles` and the tile's `passes` are the
/// plan's (without them a 9/7 tile decodes in more memory, to the same samples).
/// Damage, a tile cut short by the end of the file, or a tile of another size raise
/// `CodecError`.
#[pyfunction]
#[pyo3(signature = (path, offset, length, *, width, height, nodata=None, coded=None,
    compact_tiles=false, passes=Vec::new()))]
#[allow(clippy::too_many_arguments)]
pub fn decode_tile<'py>(
    py: Python<'py>,
    path: PathBuf,
    offset: u64,
    length: usize,
    width: usize,
    height: usize,
    nodata: Option<f64>,
    coded: Option<(usize, usize, usize, usize)>,
    compact_tiles: bool,
    passes: Vec<(u64, f64)>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let (x, y, coded_width, coded_height) = coded.unwrap_or((0, 0, width, height));
    if x + width > coded_width || y + height > coded_height {
        return Err(PyValueError::new_err(format!(
            "a {width} x {height} tile at ({x}, {y}) of {coded_width} x {coded_height} samples"
        )));
    }
    let mut source = open(&path)?;
    let bytes = py
        .detach(|| source.read_at(offset, length))
        .map_err(|e| io_error(&path, &e))?;
    let at = |e: RustCodecError| {
        CodecError::new_err(format!("{}: tile at byte {offset}: {e}", path.display()))
    };
    let options = DecodeOptions::default().with_strict(true).with_threads(1);
    let decoded = py
        .detach(|| wavemesh_codec::tiles::decode_tile(&bytes, compact_tiles, &passes, &options))
        .map_err(at)?;
    let raster = &decoded.raster;
    if (raster.width, raster.height) != (coded_width, coded_height) {
        return Err(CodecError::new_err(format!(
            "{}: tile at byte {offset} is {} x {}, the index says {coded_width} x {coded_height}",
            path.display(),
            raster.width,
            raster.height
        )));
    }
    let mut tile = decoded.raster.crop(x, y, width, height);
    tile.nodata = nodata;
    arrays_of(py, tile)
}

/// Decodes tile `(x, y, width, height)` (samples) of a file whose tiles are cut into code
/// blocks, at a budget of `nbytes` for the whole file (shared as `decode` shares it) or
/// whole: its head and blocks read by range, as `decode` of that window does;
/// `(samples, valid)`. Damage, or a tile cut short by the end of the file, raise
/// `CodecError`.
#[pyfunction]
#[pyo3(signature = (path, x, y, width, height, *, nbytes=None))]
pub fn decode_blocked_tile<'py>(
    py: Python<'py>,
    path: PathBuf,
    x: usize,
    y: usize,
    width: usize,
    height: usize,
    nbytes: Option<u64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let mut source = open(&path)?;
    let window = wavemesh_codec::Window {
        x,
        y,
        width,
        height,
    };
    let options = DecodeOptions::default()
        .with_strict(true)
        .with_threads(1)
        .with_max_bytes(nbytes);
    let at = |e: RustCodecError| {
        CodecError::new_err(format!("{}: tile at ({x}, {y}): {e}", path.display()))
    };
    let decoded = py
        .detach(|| wavemesh_codec::decode_window(&mut source, Some(window), &options))
        .map_err(at)?;
    if !decoded.complete && nbytes.is_none() {
        return Err(at(RustCodecError::TruncatedHeader(
            "the file ends inside the tile",
        )));
    }
    let mut tile = decoded.raster;
    tile.georef = None;
    arrays_of(py, tile)
}
