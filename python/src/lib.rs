//! `wavemesh._wavemesh`: the compiled half of the `wavemesh` Python package. The
//! package's `__init__.py` wraps these functions (masked arrays, rasterio transforms);
//! the GIL is released while coding and meshing.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use wavemesh::lod::{build_mesh, decoded_plane, plane_of_threshold, Surface};
use wavemesh::mesh::cells::SplitRule;
use wavemesh::mesh::MeshTarget;
use wavemesh_codec::{
    decode as decode_stream, encode as encode_raster, CodecError as RustCodecError, DecodeOptions,
    Decoded, EncodeOptions, Georef, Header, Quality, Raster, Samples, Wavelet,
};

pyo3::create_exception!(
    _wavemesh,
    CodecError,
    PyException,
    "A .ezw stream could not be decoded or a raster could not be encoded."
);

/// Bad arguments are `ValueError`s; everything else the codec says is a `CodecError`.
fn to_py(error: RustCodecError) -> PyErr {
    match error {
        RustCodecError::InvalidParameters(_) => PyValueError::new_err(error.to_string()),
        other => CodecError::new_err(other.to_string()),
    }
}

/// A 2-D numpy array's samples in row-major order (any strides), with its size.
fn raster_of(array: &Bound<'_, PyAny>) -> PyResult<Raster> {
    fn rows<T: numpy::Element + Copy>(array: &Bound<'_, PyAny>) -> Option<(usize, usize, Vec<T>)> {
        let array = array.extract::<PyReadonlyArray2<T>>().ok()?;
        let view = array.as_array();
        let (height, width) = view.dim();
        Some((width, height, view.iter().copied().collect()))
    }
    let (width, height, samples) = if let Some((w, h, v)) = rows::<u8>(array) {
        (w, h, Samples::U8(v))
    } else if let Some((w, h, v)) = rows::<u16>(array) {
        (w, h, Samples::U16(v))
    } else if let Some((w, h, v)) = rows::<i16>(array) {
        (w, h, Samples::I16(v))
    } else if let Some((w, h, v)) = rows::<i32>(array) {
        (w, h, Samples::I32(v))
    } else if let Some((w, h, v)) = rows::<f32>(array) {
        (w, h, Samples::F32(v))
    } else {
        return Err(PyValueError::new_err(
            "expected a 2-D numpy array of uint8, uint16, int16, int32 or float32",
        ));
    };
    Raster::new(width, height, samples).map_err(to_py)
}

/// The encoder's options from the keyword arguments (as the CLI's `encode` reads them).
fn encode_options(
    samples: usize,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
) -> PyResult<EncodeOptions> {
    let budget = match bpp {
        Some(bpp) if bpp.is_finite() && bpp > 0.0 => Some((bpp * samples as f64 / 8.0) as u64),
        Some(bpp) => {
            return Err(PyValueError::new_err(format!(
                "bpp must be positive, got {bpp}"
            )))
        }
        None => None,
    };
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
        Some("97") => options.wavelet = Wavelet::Cdf97,
        Some("53") => options.wavelet = Wavelet::Int53,
        Some(other) => {
            return Err(PyValueError::new_err(format!(
                "wavelet must be '97' or '53', got {other:?}"
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

/// Encodes a 2-D array into `.ezw` bytes.
#[pyfunction]
#[pyo3(signature = (array, *, nodata=None, bpp=None, max_error=None, precision=None, wavelet=None, geotransform=None))]
#[allow(clippy::too_many_arguments)]
fn encode<'py>(
    py: Python<'py>,
    array: &Bound<'py, PyAny>,
    nodata: Option<f64>,
    bpp: Option<f64>,
    max_error: Option<f64>,
    precision: Option<f64>,
    wavelet: Option<&str>,
    geotransform: Option<[f64; 6]>,
) -> PyResult<Bound<'py, PyBytes>> {
    let mut raster = raster_of(array)?;
    raster.nodata = nodata;
    raster.georef = geotransform.map(|geotransform| Georef {
        geotransform,
        ..Georef::default()
    });
    let options = encode_options(raster.len(), bpp, max_error, precision, wavelet)?;
    let encoded = py
        .detach(|| encode_raster(&raster, &options))
        .map_err(to_py)?;
    Ok(PyBytes::new(py, &encoded.bytes))
}

/// Decodes `data` (or its first `nbytes`, or `bpp`·samples/8 bytes), optionally with
/// the significance map the mesher needs.
fn decode_prefix(
    py: Python<'_>,
    data: &[u8],
    bpp: Option<f64>,
    nbytes: Option<u64>,
    significance_map: bool,
) -> PyResult<Decoded> {
    let (header, _) = Header::parse(data).map_err(to_py)?;
    let max_bytes = match (bpp, nbytes) {
        (Some(_), Some(_)) => return Err(PyValueError::new_err("give bpp or nbytes, not both")),
        (Some(bpp), None) if bpp.is_finite() && bpp > 0.0 => {
            Some((bpp * header.sample_count() as f64 / 8.0) as u64)
        }
        (Some(bpp), None) => {
            return Err(PyValueError::new_err(format!(
                "bpp must be positive, got {bpp}"
            )))
        }
        (None, nbytes) => nbytes,
    };
    let options = DecodeOptions {
        max_bytes,
        significance_map,
        ..DecodeOptions::default()
    };
    py.detach(|| decode_stream(data, &options)).map_err(to_py)
}

/// A raster's samples as a 2-D numpy array of their type.
fn samples_array<'py>(py: Python<'py>, raster: &Raster) -> PyResult<Bound<'py, PyAny>> {
    let shape = (raster.height, raster.width);
    fn array<'py, T: numpy::Element + Clone>(
        py: Python<'py>,
        shape: (usize, usize),
        values: &[T],
    ) -> PyResult<Bound<'py, PyAny>> {
        let grid = Array2::from_shape_vec(shape, values.to_vec())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(grid.into_pyarray(py).into_any())
    }
    match &raster.samples {
        Samples::U8(v) => array(py, shape, v),
        Samples::U16(v) => array(py, shape, v),
        Samples::I16(v) => array(py, shape, v),
        Samples::I32(v) => array(py, shape, v),
        Samples::F32(v) => array(py, shape, v),
    }
}

/// Decodes `.ezw` bytes: `(samples, valid, nodata)` with `valid` a boolean array.
#[pyfunction]
#[pyo3(signature = (data, *, bpp=None, nbytes=None))]
fn decode<'py>(
    py: Python<'py>,
    data: &[u8],
    bpp: Option<f64>,
    nbytes: Option<u64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Option<f64>)> {
    let decoded = decode_prefix(py, data, bpp, nbytes, false)?;
    let raster = &decoded.raster;
    let valid: Vec<bool> = (0..raster.len()).map(|i| raster.is_valid(i)).collect();
    let valid = Array2::from_shape_vec((raster.height, raster.width), valid)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok((
        samples_array(py, raster)?,
        valid.into_pyarray(py).into_any(),
        raster.nodata,
    ))
}

/// The header of `.ezw` bytes and its pass ladder, as a dict.
#[pyfunction]
fn info<'py>(py: Python<'py>, data: &[u8]) -> PyResult<Bound<'py, PyDict>> {
    let (header, header_len) = Header::parse(data).map_err(to_py)?;
    let out = PyDict::new(py);
    out.set_item("width", header.width)?;
    out.set_item("height", header.height)?;
    out.set_item("sample_type", header.sample_type.name())?;
    out.set_item("wavelet", header.wavelet.name())?;
    out.set_item("levels", header.levels)?;
    out.set_item("mode", header.mode.name())?;
    out.set_item("max_error", header.max_error)?;
    out.set_item("nodata", header.nodata)?;
    out.set_item("valid_min", header.valid_range.0)?;
    out.set_item("valid_max", header.valid_range.1)?;
    out.set_item("header_bytes", header_len)?;
    out.set_item("file_bytes", data.len())?;
    out.set_item(
        "geotransform",
        header.georef.as_ref().map(|g| g.geotransform),
    )?;
    let passes = PyList::empty(py);
    for pass in &header.passes {
        let entry = PyDict::new(py);
        entry.set_item("plane", pass.plane)?;
        entry.set_item("payload_end_byte", pass.end_byte)?;
        entry.set_item("estimated_squared_error", pass.squared_error)?;
        passes.append(entry)?;
    }
    out.set_item("passes", passes)?;
    Ok(out)
}

/// The mesh of a decode: `(vertices, triangles)`, vertices as (column, row, height)
/// float64 rows, triangles as uint32 index rows (counter-clockwise seen from above).
#[pyfunction]
#[pyo3(signature = (data, *, bpp=None, nbytes=None, triangles=None, mesh_error=None, threshold=None))]
fn mesh<'py>(
    py: Python<'py>,
    data: &[u8],
    bpp: Option<f64>,
    nbytes: Option<u64>,
    triangles: Option<usize>,
    mesh_error: Option<f64>,
    threshold: Option<f64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let decoded = decode_prefix(py, data, bpp, nbytes, true)?;
    let decoder_plane = decoded_plane(&decoded);
    let threshold_plane = match threshold {
        Some(t) if t.is_finite() && t >= 0.0 => Some(plane_of_threshold(t).max(decoder_plane)),
        Some(t) => {
            return Err(PyValueError::new_err(format!(
                "threshold must be a non-negative number, got {t}"
            )))
        }
        None => None,
    };
    let (target, base_plane) = match (mesh_error, triangles) {
        (Some(e), _) if e.is_finite() && e >= 0.0 => (MeshTarget::Tolerance(e), threshold_plane),
        (Some(e), _) => {
            return Err(PyValueError::new_err(format!(
                "mesh_error must be a non-negative number, got {e}"
            )))
        }
        (None, Some(n)) => (MeshTarget::TrianglesByTolerance(n), None),
        (None, None) => (
            MeshTarget::Plane(threshold_plane.unwrap_or(decoder_plane)),
            None,
        ),
    };
    let map = decoded
        .significance
        .as_ref()
        .ok_or_else(|| CodecError::new_err("the decoder returned no significance map"))?;
    let surface = Surface::of(&decoded.raster);
    let built = py.detach(|| build_mesh(map, &surface, target, SplitRule::Zerotree, base_plane));
    let mesh = built.mesh;
    let vertices: Vec<f64> = (0..mesh.vertices.len() as u32)
        .flat_map(|v| {
            let (column, row) = mesh.vertex_position(v);
            let height = surface.heights[mesh.vertices[v as usize] as usize];
            [column as f64, row as f64, height]
        })
        .collect();
    let triangles: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let to_array = |e: numpy::ndarray::ShapeError| PyValueError::new_err(e.to_string());
    let vertices = Array2::from_shape_vec((mesh.vertices.len(), 3), vertices).map_err(to_array)?;
    let triangles =
        Array2::from_shape_vec((mesh.triangles.len(), 3), triangles).map_err(to_array)?;
    Ok((
        vertices.into_pyarray(py).into_any(),
        triangles.into_pyarray(py).into_any(),
    ))
}

/// The module.
#[pymodule]
fn _wavemesh(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("CodecError", m.py().get_type::<CodecError>())?;
    m.add_function(wrap_pyfunction!(encode, m)?)?;
    m.add_function(wrap_pyfunction!(decode, m)?)?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(mesh, m)?)?;
    Ok(())
}
