//! `encode`, `encode_file`, `decode` and `info`: the codec on numpy arrays, DEM files
//! and `.ezw` bytes. The GIL is released while coding.

use std::path::{Path, PathBuf};

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use wavemesh::dem::{read_dem, ReadOptions, WorkMemory};
use wavemesh_codec::format::{physical_offset, valid_sample_count};
use wavemesh_codec::{
    decode_window, encode as encode_raster,
    tiles::{TiledLayout, DEFAULT_TILE},
    DecodeOptions, Decoded, EncodeOptions, Header, Limits, Quality, Raster, Wavelet, Window,
};

use crate::arrays::{arrays_of, raster_of};
use crate::errors::{codec_error, dem_error, io_error};
use crate::georef::{add_georef, set_georef};

/// Bytes a sample the encoder allocates besides the raster, as the command line's
/// `encode` counts them against `max_memory` (measured peaks with some headroom).
const ENCODE_WORK: WorkMemory = WorkMemory {
    integer: 20,
    float: 48,
};

/// The byte budget of `bpp` bits per sample over `samples` samples.
pub fn bpp_budget(bpp: f64, samples: u64) -> PyResult<u64> {
    if bpp.is_finite() && bpp > 0.0 {
        Ok((bpp * samples as f64 / 8.0).floor() as u64)
    } else {
        Err(PyValueError::new_err(format!(
            "bpp must be positive, got {bpp}"
        )))
    }
}

/// The decoder's limits: the command line's defaults unless given.
pub fn limits(max_samples: Option<u64>, max_memory: Option<u64>) -> Limits {
    let default = Limits::default();
    Limits::new(
        max_samples.unwrap_or(default.max_samples),
        max_memory.unwrap_or(default.max_memory),
    )
}

/// The encoder's options from the keyword arguments, as the command line's `encode`
/// reads them.
pub fn encode_options(
    samples: u64,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
) -> PyResult<EncodeOptions> {
    let budget = bpp.map(|bpp| bpp_budget(bpp, samples)).transpose()?;
    let quality = match (max_error, precision) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "give max_error or precision, not both",
            ))
        }
        (Some(e), None) => Quality::MaxError(e),
        (None, Some(step)) => Quality::Precision(step),
        (None, None) => Quality::Lossless,
    };
    let mut options = EncodeOptions::new(quality, budget);
    match wavelet {
        Some("97") => options = options.with_wavelet(Wavelet::Cdf97),
        Some("53") => options = options.with_wavelet(Wavelet::Int53),
        Some("1311") => options = options.with_wavelet(Wavelet::Int1311),
        Some(other) => {
            return Err(PyValueError::new_err(format!(
                "wavelet must be '97', '53' or '1311', got {other:?}"
            )))
        }
        None => {}
    }
    if options.wavelet == Wavelet::Cdf97 && budget.is_none() {
        return Err(PyValueError::new_err(
            "the 9/7 wavelet is lossy: give a rate with bpp",
        ));
    }
    Ok(options)
}

/// The raster of a 2-D array with its nodata value and georeferencing.
pub fn raster_with(
    array: &Bound<'_, PyAny>,
    nodata: Option<f64>,
    geotransform: Option<[f64; 6]>,
    epsg: Option<i64>,
    crs_wkt: Option<String>,
) -> PyResult<Raster> {
    let mut raster = raster_of(array)?;
    raster.nodata = nodata;
    set_georef(&mut raster, geotransform, epsg, crs_wkt)?;
    Ok(raster)
}

/// Encodes a 2-D array into `.ezw` bytes.
#[pyfunction]
#[pyo3(signature = (array, *, nodata=None, bpp=None, max_error=None, precision=None,
    wavelet=None, geotransform=None, epsg=None, crs_wkt=None, tile=DEFAULT_TILE, block=None,
    threads=0))]
#[allow(clippy::too_many_arguments)]
pub fn encode<'py>(
    py: Python<'py>,
    array: &Bound<'py, PyAny>,
    nodata: Option<f64>,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
    geotransform: Option<[f64; 6]>,
    epsg: Option<i64>,
    crs_wkt: Option<String>,
    tile: u32,
    block: Option<u32>,
    threads: usize,
) -> PyResult<Bound<'py, PyBytes>> {
    let raster = raster_with(array, nodata, geotransform, epsg, crs_wkt)?;
    let options = encode_options(raster.len() as u64, bpp, max_error, precision, wavelet)?;
    let options = tiled(options, (tile, block), threads);
    let encoded = py
        .detach(|| encode_raster(&raster, &options))
        .map_err(codec_error)?;
    Ok(PyBytes::new(py, &encoded.bytes))
}

/// `options` with the largest tile side `tile` (0: one stream whatever the size), code
/// blocks of `block` and `threads` threads coding tiles (0: one per core), as `--tile`,
/// `--block` and `--threads` say.
fn tiled(
    options: EncodeOptions,
    (tile, block): (u32, Option<u32>),
    threads: usize,
) -> EncodeOptions {
    options
        .with_tile_size((tile > 0).then_some(tile))
        .with_code_block(block)
        .with_threads(threads)
}

/// How the command line reads a DEM file to encode it.
pub fn read_options(
    terrain_rgb: bool,
    accept_lossy_input: bool,
    max_samples: Option<u64>,
    max_memory: Option<u64>,
) -> ReadOptions {
    let limits = limits(max_samples, max_memory);
    ReadOptions {
        terrain_rgb,
        max_samples: limits.max_samples,
        max_memory: limits.max_memory,
        work: ENCODE_WORK,
        accept_lossy: accept_lossy_input,
    }
}

/// Encodes a DEM file (GeoTIFF, PNG, `.hgt`, `.asc`, as the command line reads them)
/// into a `.ezw` file written atomically; returns the bytes written.
#[pyfunction]
#[pyo3(signature = (path_in, path_out, *, bpp=None, max_error=None, precision=None,
    wavelet=None, terrain_rgb=false, accept_lossy_input=false, no_metadata_items=false,
    max_samples=None, max_memory=None, tile=DEFAULT_TILE, block=None, threads=0))]
#[allow(clippy::too_many_arguments)]
pub fn encode_file(
    py: Python<'_>,
    path_in: PathBuf,
    path_out: PathBuf,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
    terrain_rgb: bool,
    accept_lossy_input: bool,
    no_metadata_items: bool,
    max_samples: Option<u64>,
    max_memory: Option<u64>,
    tile: u32,
    block: Option<u32>,
    threads: usize,
) -> PyResult<u64> {
    if let (Ok(a), Ok(b)) = (path_in.canonicalize(), path_out.canonicalize()) {
        if a == b {
            return Err(PyValueError::new_err(format!(
                "refusing to overwrite the input file {}",
                path_in.display()
            )));
        }
    }
    let read = read_options(terrain_rgb, accept_lossy_input, max_samples, max_memory);
    let mut raster = py.detach(|| read_dem(&path_in, &read)).map_err(dem_error)?;
    if no_metadata_items {
        raster.metadata.items.clear();
    }
    let options = encode_options(raster.len() as u64, bpp, max_error, precision, wavelet)?;
    let options = tiled(options, (tile, block), threads);
    let encoded = py
        .detach(|| encode_raster(&raster, &options))
        .map_err(codec_error)?;
    write_bytes(py, &path_out, &encoded.bytes)?;
    Ok(encoded.bytes.len() as u64)
}

/// Writes `data` to `path` atomically, without the GIL: readers see the old file or the
/// complete new one (a temporary file renamed into place; a symlink's target replaced).
fn write_bytes(py: Python<'_>, path: &Path, data: &[u8]) -> PyResult<()> {
    py.detach(|| wavemesh::atomic::write_atomic(path, |w| w.write_all(data)))
        .map_err(|e| io_error(path, &e))
}

/// Writes `data` to `path` atomically (see [`write_bytes`]).
#[pyfunction]
pub fn write_file(py: Python<'_>, path: PathBuf, data: &[u8]) -> PyResult<()> {
    write_bytes(py, &path, data)
}

/// What to decode: the whole stream or a prefix, with or without the significance map.
pub struct DecodeRequest {
    /// Decode the first `bpp`·samples/8 bytes only.
    pub bpp: Option<f64>,
    /// Decode the first `nbytes` bytes only.
    pub nbytes: Option<u64>,
    /// Damage is an error instead of a warning.
    pub strict: bool,
    /// The decoder's limits.
    pub limits: Limits,
    /// Also return the significance map (for meshing).
    pub significance_map: bool,
    /// Decode only this window (column, row, width, height).
    pub window: Option<Window>,
    /// Threads decoding tiles (0: one per core).
    pub threads: usize,
}

/// Decodes `data` as `request` says, without the GIL.
pub fn decode_prefix(py: Python<'_>, data: &[u8], request: &DecodeRequest) -> PyResult<Decoded> {
    let (header, _) = Header::parse(data).map_err(codec_error)?;
    let max_bytes = match (request.bpp, request.nbytes) {
        (Some(_), Some(_)) => return Err(PyValueError::new_err("give bpp or nbytes, not both")),
        (Some(bpp), None) => Some(bpp_budget(bpp, header.sample_count())?),
        (None, nbytes) => nbytes,
    };
    let options = DecodeOptions::default()
        .with_max_bytes(max_bytes)
        .with_limits(request.limits)
        .with_strict(request.strict)
        .with_significance_map(request.significance_map)
        .with_threads(request.threads);
    py.detach(|| decode_window(&mut &data[..], request.window, &options))
        .map_err(codec_error)
}

/// A decode for Python: the samples, their validity, the nodata value, and the warning
/// the command line would print about damage the decode stepped around, if any.
type DecodedArrays<'py> = (
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Option<f64>,
    Option<String>,
);

/// A tiled file's grid: tile size, count and index bytes.
fn tiling_dict<'py>(py: Python<'py>, layout: &TiledLayout) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("tile_width", layout.grid.tile_width)?;
    out.set_item("tile_height", layout.grid.tile_height)?;
    out.set_item("count", layout.grid.count())?;
    out.set_item("index_bytes", layout.head_len() - layout.header_len)?;
    Ok(out)
}

/// Decodes `.ezw` bytes: `(samples, valid, nodata, damage)`.
#[pyfunction]
#[pyo3(signature = (data, *, bpp=None, nbytes=None, strict=false, max_samples=None,
    max_memory=None, window=None, threads=0))]
#[allow(clippy::too_many_arguments)]
pub fn decode<'py>(
    py: Python<'py>,
    data: &[u8],
    bpp: Option<f64>,
    nbytes: Option<u64>,
    strict: bool,
    max_samples: Option<u64>,
    max_memory: Option<u64>,
    window: Option<(usize, usize, usize, usize)>,
    threads: usize,
) -> PyResult<DecodedArrays<'py>> {
    let request = DecodeRequest {
        bpp,
        nbytes,
        strict,
        limits: limits(max_samples, max_memory),
        significance_map: false,
        window: window.map(|(x, y, width, height)| Window {
            x,
            y,
            width,
            height,
        }),
        threads,
    };
    let decoded = decode_prefix(py, data, &request)?;
    let damage = decoded.damage.map(|d| {
        format!(
            "{}{} damaged at byte {}; decoded what precedes it (strict=True makes this an error)",
            d.tile.map_or(String::new(), |t| format!("tile {t} ")),
            d.section,
            d.offset
        )
    });
    let nodata = decoded.raster.nodata;
    let (samples, valid) = arrays_of(py, decoded.raster)?;
    Ok((samples, valid, nodata, damage))
}

/// The pass ladder: per pass its plane, the file byte where it ends, bits per sample
/// there and the encoder's estimate of the RMSE and PSNR of a decode that stops there.
fn pass_ladder<'py>(
    py: Python<'py>,
    header: &Header,
    payload_start: u64,
    valid: usize,
) -> PyResult<Bound<'py, PyList>> {
    let range = header.valid_range.1 - header.valid_range.0;
    let samples = header.sample_count() as f64;
    let passes = PyList::empty(py);
    for pass in &header.passes {
        let end_byte = payload_start + physical_offset(pass.end_byte);
        let rmse = (pass.squared_error / valid.max(1) as f64).sqrt();
        let entry = PyDict::new(py);
        entry.set_item("plane", pass.plane)?;
        entry.set_item("end_byte", end_byte)?;
        entry.set_item("bpp", end_byte as f64 * 8.0 / samples)?;
        entry.set_item("estimated_rmse", rmse)?;
        entry.set_item("estimated_psnr_db", wavemesh::metrics::psnr(range, rmse))?;
        passes.append(entry)?;
    }
    Ok(passes)
}

/// The header of `.ezw` bytes, its georeferencing and metadata, and its pass ladder.
#[pyfunction]
#[pyo3(signature = (data, *, max_samples=None, max_memory=None))]
pub fn info<'py>(
    py: Python<'py>,
    data: &[u8],
    max_samples: Option<u64>,
    max_memory: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let (header, header_len) = Header::parse(data).map_err(codec_error)?;
    let limits = limits(max_samples, max_memory);
    let samples = header.sample_count();
    if samples > limits.max_samples || samples / 8 > limits.max_memory {
        return Err(crate::errors::CodecError::new_err(format!(
            "the header's raster covers {samples} samples, over max_samples {} or max_memory {}",
            limits.max_samples, limits.max_memory
        )));
    }
    let valid = py
        .detach(|| valid_sample_count(data, &header, header_len, &limits))
        .map_err(codec_error)? as usize;
    let payload_start = (header_len + header.mask_len as usize) as u64;
    let expected = payload_start + header.payload_len + u64::from(header.residual_len);
    let out = PyDict::new(py);
    out.set_item("width", header.width)?;
    out.set_item("height", header.height)?;
    out.set_item("sample_type", header.sample_type.name())?;
    out.set_item("wavelet", header.wavelet.name())?;
    out.set_item("levels", header.levels)?;
    out.set_item("mode", header.mode.name())?;
    out.set_item(
        "max_error_bound",
        header.max_error.is_finite().then_some(header.max_error),
    )?;
    out.set_item("nodata", header.nodata)?;
    out.set_item("valid_samples", valid)?;
    out.set_item("valid_min", header.valid_range.0)?;
    out.set_item("valid_max", header.valid_range.1)?;
    out.set_item("header_bytes", header_len)?;
    out.set_item("mask_bytes", header.mask_len)?;
    out.set_item("payload_bytes", header.payload_len)?;
    out.set_item("residual_bytes", header.residual_len)?;
    out.set_item("file_bytes", data.len())?;
    let layout = TiledLayout::read(&mut &data[..], limits.max_memory / 4).map_err(codec_error)?;
    let expected = layout.as_ref().map_or(expected, |l| l.file_len());
    out.set_item("truncated", (data.len() as u64) < expected)?;
    out.set_item("tiles", layout.map(|l| tiling_dict(py, &l)).transpose()?)?;
    add_georef(&out, header.georef.as_ref(), &header.metadata)?;
    out.set_item("passes", pass_ladder(py, &header, payload_start, valid)?)?;
    Ok(out)
}
