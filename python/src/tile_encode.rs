//! A tiled `.ezw` file encoded a tile at a time, for `wavemesh.dask.to_ezw`: the grid a
//! raster is cut into ([`tile_grid`]), one tile's stream and summary ([`encode_tile`],
//! run where the tile's samples are), and the file assembled from all of them
//! ([`write_tiled`]). The codec's own tile functions do the work, so the file holds the
//! bytes of a single-machine `encode` of the same raster.

use std::path::PathBuf;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use wavemesh_codec::tiles::{
    area_cap, cut_to_budget, encode_tile as encode_one_tile, lossless_may_fit, tiled_head,
    EncodedTile, RasterInfo, TileDetail, TileEntry, TileSummary,
};
use wavemesh_codec::{EncodeOptions, Header, Metadata, Mode, Raster, TileGrid, Wavelet, Window};

use crate::coding::{bpp_budget, encode_options, raster_with};
use crate::errors::{codec_error, io_error};
use crate::georef::georef_of;

/// A tile's summary as plain Python values (picklable, so it travels from a worker to
/// the driver): `len`, `head_len`, initial error, passes `(end, error)`, mode name, error
/// bound, valid range, wavelet code, levels, checkpoints `(end, error)`.
type SummaryValues = (
    u64,
    u64,
    f64,
    Vec<(u64, f64)>,
    String,
    f64,
    Option<(f64, f64)>,
    u8,
    u8,
    Vec<(u64, f64)>,
);

/// The values of `tile`'s summary and checkpoints, exactly (errors are Python floats:
/// f64 both sides).
fn summary_values(tile: EncodedTile) -> SummaryValues {
    let (summary, entry) = (tile.summary.clone(), tile.summary.entry);
    (
        entry.len,
        entry.head_len,
        entry.initial_error,
        entry.passes,
        summary.mode.name().to_string(),
        summary.max_error,
        summary.valid_range,
        summary.wavelet.code(),
        summary.levels,
        tile.checkpoints,
    )
}

/// The tile `values` describe (see [`summary_values`]) with its stream `bytes`.
fn tile_of(values: SummaryValues, bytes: Vec<u8>) -> PyResult<EncodedTile> {
    let checkpoints = values.9.clone();
    let summary = summary_of(values, bytes.len())?;
    let head_len = summary.entry.head_len;
    let in_tile = checkpoints
        .iter()
        .all(|p| p.0 >= head_len && p.0 <= bytes.len() as u64);
    if !in_tile || !checkpoints.windows(2).all(|pair| pair[0].0 <= pair[1].0) {
        return Err(PyValueError::new_err(
            "not a tile summary: checkpoints out of place",
        ));
    }
    Ok(EncodedTile {
        bytes,
        summary,
        checkpoints,
    })
}

/// The summary `values` hold (see [`summary_values`]) of a tile of `len` bytes.
fn summary_of(values: SummaryValues, tile_len: usize) -> PyResult<TileSummary> {
    let (len, head_len, initial_error, passes, mode, max_error, valid_range, wavelet, levels, _) =
        values;
    let bad = |what: &str| PyValueError::new_err(format!("not a tile summary: {what}"));
    let mut ends = std::iter::once(head_len).chain(passes.iter().map(|p| p.0));
    if len != tile_len as u64 || !ends.all(|end| end >= head_len && end <= len) {
        return Err(bad("lengths that do not fit its tile"));
    }
    if !passes.windows(2).all(|pair| pair[0].0 <= pair[1].0) {
        return Err(bad("passes out of order"));
    }
    let mode = [Mode::Lossless, Mode::Lossy, Mode::MaxError, Mode::Precision]
        .into_iter()
        .find(|m| m.name() == mode)
        .ok_or_else(|| bad("unknown mode"))?;
    Ok(TileSummary {
        entry: TileEntry {
            len,
            head_len,
            initial_error,
            passes,
        },
        mode,
        max_error,
        valid_range,
        wavelet: Wavelet::from_code(wavelet).ok_or_else(|| bad("unknown wavelet"))?,
        levels,
    })
}

/// The tile size and overlap of a `width × height` raster cut into tiles of at most
/// `tile` a side, as equal as the raster allows, or `None` when one tile covers it (tile
/// `(row, column)` codes the samples from `column · tile_width − overlap` to
/// `(column + 1) · tile_width + overlap` across, within the raster, and likewise down);
/// checks the quality
/// keywords as `encode` would, so bad ones fail before any tile is coded.
#[pyfunction]
#[pyo3(signature = (width, height, tile, *, bpp=None, max_error=None, precision=None,
    wavelet=None))]
pub fn tile_grid(
    width: usize,
    height: usize,
    tile: usize,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
) -> PyResult<Option<(usize, usize, usize)>> {
    if tile == 0 {
        return Err(PyValueError::new_err(
            "tile must be a positive integer, got 0",
        ));
    }
    let too_large = width > u32::MAX as usize || height > u32::MAX as usize;
    if width == 0 || height == 0 || too_large {
        return Err(PyValueError::new_err(format!(
            "cannot encode a {height} x {width} array"
        )));
    }
    let samples = (width as u64).saturating_mul(height as u64);
    encode_options(samples, bpp, max_error, precision, wavelet)?;
    Ok(TileGrid::balanced(width, height, tile).map(|g| (g.tile_width, g.tile_height, g.overlap)))
}

/// Encodes the samples one tile of a `raster_width × raster_height` raster codes (the
/// tile and its overlap; the quality keywords are those of the whole raster's `encode`,
/// with `wavelet` as [`settled_wavelet`] settles it for the whole raster; a
/// `bpp` budget caps the tile at its share of the budget by area, or at `cap` bytes when
/// given; the cut, and so the file, does not depend on the cap): `(stream, summary)`, the summary opaque values for
/// [`write_tiled`].
#[pyfunction]
#[pyo3(signature = (array, *, raster_width, raster_height, nodata=None, bpp=None,
    max_error=None, precision=None, wavelet=None, cap=None))]
#[allow(clippy::too_many_arguments)]
pub fn encode_tile<'py>(
    py: Python<'py>,
    array: &Bound<'py, PyAny>,
    raster_width: usize,
    raster_height: usize,
    nodata: Option<f64>,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
    cap: Option<u64>,
) -> PyResult<(Bound<'py, PyBytes>, SummaryValues)> {
    let raster = (raster_width, raster_height);
    let (part, options, samples) =
        samples_and_options(array, nodata, raster, (bpp, max_error, precision, wavelet))?;
    let window = Window {
        x: 0,
        y: 0,
        width: part.width,
        height: part.height,
    };
    let cap = cap.or_else(|| Some(area_cap(options.budget_bytes?, &window, samples)));
    let tile = py
        .detach(|| encode_one_tile(&part, &options, cap))
        .map_err(codec_error)?;
    let bytes = PyBytes::new(py, &tile.bytes);
    Ok((bytes, summary_values(tile)))
}

/// The quality keywords of [`encode_tile`] and [`settled_wavelet`].
type Quality<'a> = (Option<f64>, Option<f64>, Option<f64>, Option<&'a str>);

/// `array` as a raster (voids at `nodata`), and the encoder's options for a
/// `raster_width × raster_height` raster with the `quality` keywords `(bpp, max_error,
/// precision, wavelet)`, and that raster's sample count.
fn samples_and_options(
    array: &Bound<'_, PyAny>,
    nodata: Option<f64>,
    (raster_width, raster_height): (usize, usize),
    (bpp, max_error, precision, wavelet): Quality<'_>,
) -> PyResult<(Raster, EncodeOptions, u64)> {
    let part = raster_with(array, nodata, None, None, None)?;
    let samples = (raster_width as u64).saturating_mul(raster_height as u64);
    let options = encode_options(samples, bpp, max_error, precision, wavelet)?;
    Ok((part, options, samples))
}

/// The window `(x, y, width, height)` at the centre of a `width × height` raster on
/// which `encode` settles the reversible wavelet (`settled_wavelet`).
#[pyfunction]
pub fn wavelet_sample(width: usize, height: usize) -> (usize, usize, usize, usize) {
    let w = wavemesh_codec::wavelet_sample(width, height);
    (w.x, w.y, w.width, w.height)
}

/// The wavelet (`"97"`, `"53"` or `"1311"`) `encode` codes a `raster_width ×
/// raster_height` raster with, given the samples of its `wavelet_sample` window and the
/// raster's keywords: what every tile of a file coded task by task must share.
#[pyfunction]
#[pyo3(signature = (array, *, raster_width, raster_height, nodata=None, bpp=None,
    max_error=None, precision=None, wavelet=None))]
#[allow(clippy::too_many_arguments)]
pub fn settled_wavelet(
    py: Python<'_>,
    array: &Bound<'_, PyAny>,
    raster_width: usize,
    raster_height: usize,
    nodata: Option<f64>,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
) -> PyResult<&'static str> {
    let raster = (raster_width, raster_height);
    let (centre, options, _) =
        samples_and_options(array, nodata, raster, (bpp, max_error, precision, wavelet))?;
    let settled = py.detach(|| options.wavelet_chosen_for(&centre));
    Ok(match settled.wavelet {
        Wavelet::Cdf97 => "97",
        Wavelet::Int53 => "53",
        Wavelet::Int1311 => "1311",
    })
}

/// The bytes one tile's lossless stream is estimated at, from its coded samples (the
/// tile and its overlap, as [`encode_tile`] gets them): what [`lossless_budget`] sums.
#[pyfunction]
#[pyo3(signature = (array, *, nodata=None))]
pub fn tile_lossless_estimate(
    py: Python<'_>,
    array: &Bound<'_, PyAny>,
    nodata: Option<f64>,
) -> PyResult<f64> {
    let part = raster_with(array, nodata, None, None, None)?;
    let whole = Window::whole(part.width, part.height);
    Ok(py.detach(|| TileDetail::of(&part, &whole).lossless_estimate()))
}

/// The byte budget of `bpp` on a `width × height` raster when `encode` tries
/// its lossless file first (its tiles' [`tile_lossless_estimate`]s summing to
/// `estimate`), else `None`: the lossless file replaces the 9/7 one when it is at most
/// that many bytes.
#[pyfunction]
#[pyo3(signature = (estimate, *, width, height, bpp))]
pub fn lossless_budget(
    estimate: f64,
    width: usize,
    height: usize,
    bpp: f64,
) -> PyResult<Option<u64>> {
    let budget = bpp_budget(bpp, (width as u64).saturating_mul(height as u64))?;
    Ok(lossless_may_fit(estimate, budget).then_some(budget))
}

/// The tiles `write_tiled` receives: `(stream, summary)` per tile, in grid order.
type TileValues<'py> = Vec<(Bound<'py, PyBytes>, SummaryValues)>;

/// Writes a tiled `.ezw` file atomically from its tiles (from [`encode_tile`], in grid
/// order, on the grid of `tile_width × tile_height` tiles overlapping by `overlap`):
/// header, index and tiles, the tiles cut to a whole-file `bpp` budget as the
/// single-machine encoder cuts them — a tile its first cap starved is coded again by
/// `recode(k, cap)` (returning what [`encode_tile`] returns). Returns the bytes written.
#[pyfunction]
#[pyo3(signature = (path, tiles, *, width, height, tile_width, tile_height, overlap,
    nodata=None, bpp=None, geotransform=None, epsg=None, crs_wkt=None, recode=None))]
#[allow(clippy::too_many_arguments)]
pub fn write_tiled(
    py: Python<'_>,
    path: PathBuf,
    tiles: TileValues<'_>,
    width: usize,
    height: usize,
    tile_width: usize,
    tile_height: usize,
    overlap: usize,
    nodata: Option<f64>,
    bpp: Option<f64>,
    geotransform: Option<[f64; 6]>,
    epsg: Option<i64>,
    crs_wkt: Option<String>,
    recode: Option<Bound<'_, PyAny>>,
) -> PyResult<u64> {
    if [width, height, tile_width, tile_height].contains(&0) {
        return Err(PyValueError::new_err(format!(
            "a {width} x {height} raster in {tile_width} x {tile_height} tiles"
        )));
    }
    let grid = TileGrid {
        width,
        height,
        tile_width,
        tile_height,
        overlap,
    };
    if tiles.len() != grid.count() {
        return Err(PyValueError::new_err(format!(
            "a {width} x {height} raster in {tile_width} x {tile_height} tiles has {} tiles, got {}",
            grid.count(),
            tiles.len()
        )));
    }
    let tiles = tiles
        .into_iter()
        .map(|(bytes, values)| tile_of(values, bytes.as_bytes().to_vec()))
        .collect::<PyResult<Vec<EncodedTile>>>()?;
    let (georef, crs_wkt) = georef_of(geotransform, epsg, crs_wkt)?;
    let (first, _) = Header::parse_tile(&tiles[0].bytes).map_err(codec_error)?;
    let info = RasterInfo {
        width,
        height,
        sample_type: first.sample_type,
        nodata,
        georef,
        metadata: Metadata {
            crs_wkt,
            ..Metadata::default()
        },
    };
    let budget = bpp
        .map(|bpp| bpp_budget(bpp, (width * height) as u64))
        .transpose()?;
    let recode = recode.map(Bound::unbind);
    py.detach(|| write_file(&path, tiles, &info, &grid, budget, recode.as_ref()))
}

/// Why [`write_file`]'s cut failed: the codec, or the Python `recode`.
enum CutError {
    Codec(wavemesh_codec::CodecError),
    Python(PyErr),
}

impl From<wavemesh_codec::CodecError> for CutError {
    fn from(e: wavemesh_codec::CodecError) -> CutError {
        CutError::Codec(e)
    }
}

/// Tile `k` coded again up to `cap` bytes by the Python `recode`.
fn recoded(recode: Option<&Py<PyAny>>, k: usize, cap: u64) -> Result<EncodedTile, CutError> {
    let recode = recode.ok_or_else(|| {
        CutError::Python(PyValueError::new_err(
            "a tile needs coding again under the budget, and no recode was given",
        ))
    })?;
    Python::attach(|py| {
        let (bytes, values): (Vec<u8>, SummaryValues) = recode.call1(py, (k, cap))?.extract(py)?;
        tile_of(values, bytes)
    })
    .map_err(CutError::Python)
}

/// Cuts `tiles` to `budget` (if any) and writes the file: header and index, then tiles.
fn write_file(
    path: &std::path::Path,
    mut tiles: Vec<EncodedTile>,
    info: &RasterInfo,
    grid: &TileGrid,
    budget: Option<u64>,
    recode: Option<&Py<PyAny>>,
) -> PyResult<u64> {
    if let Some(budget) = budget {
        let mut recode = |k, cap| recoded(recode, k, cap);
        tiles = cut_to_budget(tiles, info, grid, budget, &mut recode).map_err(|e| match e {
            CutError::Codec(e) => codec_error(e),
            CutError::Python(e) => e,
        })?;
    }
    let summaries: Vec<TileSummary> = tiles.iter().map(|t| t.summary.clone()).collect();
    let head = tiled_head(info, grid, &summaries);
    wavemesh::atomic::write_atomic(path, |w| {
        w.write_all(&head)?;
        tiles.iter().try_for_each(|t| w.write_all(&t.bytes))
    })
    .map_err(|e| io_error(path, &e))?;
    Ok(head.len() as u64 + tiles.iter().map(|t| t.bytes.len() as u64).sum::<u64>())
}
