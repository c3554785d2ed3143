//! numpy arrays in and out: a 2-D array's samples as a codec [`Raster`], and a raster's
//! samples as a 2-D array.

use numpy::ndarray::Array2;
use numpy::{Element, IntoPyArray, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use wavemesh_codec::{Raster, Samples};

use crate::errors::codec_error;

/// A 2-D array's width, height and samples in row-major order, if its dtype is `T`: one
/// memory copy for a C-contiguous array, one strided pass for any other layout (Fortran
/// order, slices with steps, transposes).
fn rows_of<T: Element + Copy>(array: &Bound<'_, PyAny>) -> Option<(usize, usize, Vec<T>)> {
    let array = array.extract::<PyReadonlyArray2<T>>().ok()?;
    let view = array.as_array();
    let (height, width) = view.dim();
    let samples = match view.as_slice() {
        Some(contiguous) => contiguous.to_vec(),
        None => view.iter().copied().collect(),
    };
    Some((width, height, samples))
}

/// The raster of a 2-D numpy array of uint8, uint16, int16, int32 or float32 (native
/// byte order), without nodata or georeferencing.
pub fn raster_of(array: &Bound<'_, PyAny>) -> PyResult<Raster> {
    let (width, height, samples) = if let Some((w, h, v)) = rows_of::<u8>(array) {
        (w, h, Samples::U8(v))
    } else if let Some((w, h, v)) = rows_of::<u16>(array) {
        (w, h, Samples::U16(v))
    } else if let Some((w, h, v)) = rows_of::<i16>(array) {
        (w, h, Samples::I16(v))
    } else if let Some((w, h, v)) = rows_of::<i32>(array) {
        (w, h, Samples::I32(v))
    } else if let Some((w, h, v)) = rows_of::<f32>(array) {
        (w, h, Samples::F32(v))
    } else {
        let dtype = array
            .getattr("dtype")
            .map_or_else(|_| "unknown".to_string(), |d| d.to_string());
        return Err(PyValueError::new_err(format!(
            "cannot encode {dtype} samples: expected a 2-D numpy array of uint8, uint16, \
             int16, int32 or float32"
        )));
    };
    if width == 0 || height == 0 {
        return Err(PyValueError::new_err(format!(
            "cannot encode an empty {height} x {width} array"
        )));
    }
    Raster::new(width, height, samples).map_err(codec_error)
}

/// `values` as a `height × width` numpy array, without copying them.
fn grid<'py, T: Element>(
    py: Python<'py>,
    shape: (usize, usize),
    values: Vec<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let grid =
        Array2::from_shape_vec(shape, values).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(grid.into_pyarray(py).into_any())
}

/// A raster's samples as a 2-D numpy array of their type, and its validity (`True` where
/// a sample is neither nodata nor NaN) as a boolean array of the same shape.
pub fn arrays_of(py: Python<'_>, raster: Raster) -> PyResult<(Bound<'_, PyAny>, Bound<'_, PyAny>)> {
    let shape = (raster.height, raster.width);
    let valid = grid(py, shape, raster.valid_mask())?;
    let samples = match raster.samples {
        Samples::U8(v) => grid(py, shape, v),
        Samples::U16(v) => grid(py, shape, v),
        Samples::I16(v) => grid(py, shape, v),
        Samples::I32(v) => grid(py, shape, v),
        Samples::F32(v) => grid(py, shape, v),
    }?;
    Ok((samples, valid))
}
