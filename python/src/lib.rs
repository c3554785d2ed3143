//! `wavemesh._wavemesh`: the compiled half of the `wavemesh` Python package. The
//! package's `__init__.py` wraps these functions (masked arrays, rasterio transforms and
//! CRSs, warnings); the GIL is released while coding, meshing and measuring.

mod arrays;
mod coding;
mod errors;
mod georef;
mod meshing;
mod tile_decode;
mod tile_encode;

use pyo3::prelude::*;

/// The module: the codec, the mesher and the seed paper's tables on numpy arrays.
#[pymodule]
fn _wavemesh(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("CodecError", m.py().get_type::<errors::CodecError>())?;
    m.add_function(wrap_pyfunction!(coding::encode, m)?)?;
    m.add_function(wrap_pyfunction!(coding::encode_file, m)?)?;
    m.add_function(wrap_pyfunction!(coding::decode, m)?)?;
    m.add_function(wrap_pyfunction!(coding::info, m)?)?;
    m.add_function(wrap_pyfunction!(coding::write_file, m)?)?;
    m.add_function(wrap_pyfunction!(meshing::mesh, m)?)?;
    m.add_function(wrap_pyfunction!(meshing::table, m)?)?;
    m.add_function(wrap_pyfunction!(tile_encode::tile_grid, m)?)?;
    m.add_function(wrap_pyfunction!(tile_encode::encode_tile, m)?)?;
    m.add_function(wrap_pyfunction!(tile_encode::wavelet_sample, m)?)?;
    m.add_function(wrap_pyfunction!(tile_encode::settled_wavelet, m)?)?;
    m.add_function(wrap_pyfunction!(tile_encode::write_tiled, m)?)?;
    m.add_function(wrap_pyfunction!(tile_encode::tile_lossless_estimate, m)?)?;
    m.add_function(wrap_pyfunction!(tile_encode::lossless_budget, m)?)?;
    m.add_function(wrap_pyfunction!(tile_decode::tiled_plan, m)?)?;
    m.add_function(wrap_pyfunction!(tile_decode::decode_tile, m)?)?;
    m.add_function(wrap_pyfunction!(tile_decode::decode_blocked_tile, m)?)?;
    Ok(())
}
