//! `mesh` (the zerotree mesh of a decode, as the command line writes it) and `table`
//! (the seed paper's Tables 1 and 2). The GIL is released while meshing and measuring.

use std::path::PathBuf;

use numpy::ndarray::Array2;
use numpy::IntoPyArray;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use wavemesh::dem::read_dem;
use wavemesh::lod::{self, build_mesh, decoded_plane, plane_of_threshold, Surface, TableRows};
use wavemesh::mesh::cells::SplitRule;
use wavemesh::mesh::export::{placed_mesh, Placement};
use wavemesh::mesh::MeshTarget;
use wavemesh_codec::{encode as encode_raster, Decoded, EncodeOptions, Raster, Wavelet};

use crate::coding::{decode_prefix, limits, raster_with, read_options, DecodeRequest};
use crate::errors::{codec_error, dem_error, CodecError};

/// The split rule named `rule`: `zerotree` or `own`.
fn split_rule(rule: &str) -> PyResult<SplitRule> {
    match rule {
        "zerotree" => Ok(SplitRule::Zerotree),
        "own" => Ok(SplitRule::OwnCoefficients),
        other => Err(PyValueError::new_err(format!(
            "rule must be 'zerotree' or 'own', got {other:?}"
        ))),
    }
}

/// Which mesh to build, as the command line's `--threshold`, `--triangles`,
/// `--mesh-error` and `--search` choose it.
struct MeshChoice {
    threshold: Option<f64>,
    triangles: Option<usize>,
    mesh_error: Option<f64>,
    search: String,
}

impl MeshChoice {
    /// The target and the base plane for a stream decoded to `decoded_plane`.
    fn target(&self, decoded_plane: u32) -> PyResult<(MeshTarget, Option<u32>)> {
        let bad = |message: String| Err(PyValueError::new_err(message));
        if self.triangles.is_some() && (self.mesh_error.is_some() || self.threshold.is_some()) {
            return bad("give triangles alone, without mesh_error or threshold".into());
        }
        let threshold_plane = match self.threshold {
            Some(t) if t.is_finite() && t >= 0.0 => Some(plane_of_threshold(t).max(decoded_plane)),
            Some(t) => return bad(format!("threshold must be a non-negative number, got {t}")),
            None => None,
        };
        match (self.mesh_error, self.triangles, self.search.as_str()) {
            (Some(e), _, _) if e.is_finite() && e >= 0.0 => {
                Ok((MeshTarget::Tolerance(e), threshold_plane))
            }
            (Some(e), _, _) => bad(format!("mesh_error must be a non-negative number, got {e}")),
            (None, Some(n), "error") => Ok((MeshTarget::TrianglesByTolerance(n), None)),
            (None, Some(n), "threshold") => Ok((MeshTarget::Triangles(n), None)),
            (None, Some(_), other) => bad(format!(
                "search must be 'error' or 'threshold', got {other:?}"
            )),
            (None, None, _) => Ok((
                MeshTarget::Plane(threshold_plane.unwrap_or(decoded_plane)),
                None,
            )),
        }
    }
}

/// Where the samples of `raster` go: `xy` is `geo`, `degrees` or `pixel`, as the
/// command line's `--xy`.
fn placement(raster: &Raster, xy: &str, z_scale: f64) -> PyResult<Placement> {
    if !(z_scale.is_finite() && z_scale != 0.0) {
        return Err(PyValueError::new_err(format!(
            "z_scale must be finite and non-zero, got {z_scale}"
        )));
    }
    let georef = raster.georef.as_ref();
    match xy {
        "pixel" => Ok(Placement::pixel(z_scale)),
        "degrees" => Ok(Placement::crs_units(georef, z_scale)),
        "geo" => Placement::metric(georef, raster.width, raster.height, z_scale)
            .map_err(|e| CodecError::new_err(e.to_string())),
        other => Err(PyValueError::new_err(format!(
            "xy must be 'geo', 'degrees' or 'pixel', got {other:?}"
        ))),
    }
}

/// The vertices (N × 3) and triangles (M × 3) of the mesh `choice` picks from a decode
/// made with the significance map.
fn mesh_arrays(
    py: Python<'_>,
    decoded: &Decoded,
    choice: &MeshChoice,
    rule: SplitRule,
    placement: &Placement,
) -> PyResult<(Vec<f64>, Vec<[u32; 3]>)> {
    let (target, base_plane) = choice.target(decoded_plane(decoded))?;
    let map = decoded
        .significance
        .as_ref()
        .ok_or_else(|| CodecError::new_err("the decoder returned no significance map"))?;
    let surface = Surface::of(&decoded.raster);
    let built = py.detach(|| build_mesh(map, &surface, target, rule, base_plane));
    if built.mesh.triangles.is_empty() {
        return Err(CodecError::new_err(format!(
            "nothing to mesh: the {} × {} raster has no 2 × 2 block of valid samples",
            decoded.raster.width, decoded.raster.height
        )));
    }
    placed_mesh(&built.mesh, &surface.heights, placement)
        .map_err(|e| CodecError::new_err(e.to_string()))
}

/// The mesh of a decode of `.ezw` bytes: `(vertices, triangles)`.
#[pyfunction]
#[pyo3(signature = (data, *, bpp=None, nbytes=None, triangles=None, mesh_error=None,
    threshold=None, search="error", rule="zerotree", xy="geo", z_scale=1.0,
    max_samples=None, max_memory=None))]
#[allow(clippy::too_many_arguments)]
pub fn mesh<'py>(
    py: Python<'py>,
    data: &[u8],
    bpp: Option<f64>,
    nbytes: Option<u64>,
    triangles: Option<usize>,
    mesh_error: Option<f64>,
    threshold: Option<f64>,
    search: &str,
    rule: &str,
    xy: &str,
    z_scale: f64,
    max_samples: Option<u64>,
    max_memory: Option<u64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let choice = MeshChoice {
        threshold,
        triangles,
        mesh_error,
        search: search.to_string(),
    };
    choice.target(0)?;
    let rule = split_rule(rule)?;
    let request = DecodeRequest {
        bpp,
        nbytes,
        strict: false,
        limits: limits(max_samples, max_memory),
        significance_map: true,
        window: None,
        threads: 1,
    };
    let decoded = decode_prefix(py, data, &request)?;
    let placement = placement(&decoded.raster, xy, z_scale)?;
    let (positions, triangles) = mesh_arrays(py, &decoded, &choice, rule, &placement)?;
    let shape_error = |e: numpy::ndarray::ShapeError| PyValueError::new_err(e.to_string());
    let vertices =
        Array2::from_shape_vec((positions.len() / 3, 3), positions).map_err(shape_error)?;
    let rows = triangles.len();
    let indices = triangles.into_iter().flatten().collect();
    let triangles = Array2::from_shape_vec((rows, 3), indices).map_err(shape_error)?;
    Ok((
        vertices.into_pyarray(py).into_any(),
        triangles.into_pyarray(py).into_any(),
    ))
}

/// The rows of a table: given thresholds, given bit rates, or every pass.
fn table_rows(thresholds: Option<Vec<f64>>, bpp: Option<Vec<f64>>) -> PyResult<TableRows> {
    match (thresholds, bpp) {
        (Some(_), Some(_)) => Err(PyValueError::new_err("give thresholds or bpp, not both")),
        (Some(ts), None) => match ts.iter().find(|t| !(t.is_finite() && **t >= 0.0)) {
            Some(t) => Err(PyValueError::new_err(format!("bad threshold {t}"))),
            None => Ok(TableRows::Thresholds(ts)),
        },
        (None, Some(rates)) => match rates.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
            Some(r) => Err(PyValueError::new_err(format!("bad bit rate {r}"))),
            None => Ok(TableRows::BitRates(rates)),
        },
        (None, None) => Ok(TableRows::AllPasses),
    }
}

/// The encoder's options for a table: one lossless 5/3 stream, or a 9/7 stream cut at
/// the largest of the rows' rates.
fn table_encoding(samples: usize, wavelet: &str, rows: &TableRows) -> PyResult<EncodeOptions> {
    let mut options = EncodeOptions::zerotree_mesh();
    match (wavelet, rows) {
        ("53", _) => Ok(options),
        ("97", TableRows::BitRates(rates)) => {
            let top = rates.iter().copied().fold(0.0, f64::max);
            options = options.with_wavelet(Wavelet::Cdf97);
            options.budget_bytes = Some((top * samples as f64 / 8.0).ceil() as u64);
            Ok(options)
        }
        ("97", _) => Err(PyValueError::new_err(
            "wavelet='97' is lossy: give the rows' rates with bpp",
        )),
        (other, _) => Err(PyValueError::new_err(format!(
            "wavelet must be '97' or '53', got {other:?}"
        ))),
    }
}

/// The seed paper's Tables 1 and 2 for a DEM (an array, or a file read as the command
/// line reads it), one row per threshold, bit rate or pass, as the command line's
/// `table --format json` rows (a JSON array).
#[pyfunction]
#[pyo3(signature = (*, array=None, path=None, nodata=None, thresholds=None, bpp=None,
    wavelet="53", rule="zerotree", runs=5, terrain_rgb=false, max_samples=None,
    max_memory=None))]
#[allow(clippy::too_many_arguments)]
pub fn table(
    py: Python<'_>,
    array: Option<&Bound<'_, PyAny>>,
    path: Option<PathBuf>,
    nodata: Option<f64>,
    thresholds: Option<Vec<f64>>,
    bpp: Option<Vec<f64>>,
    wavelet: &str,
    rule: &str,
    runs: usize,
    terrain_rgb: bool,
    max_samples: Option<u64>,
    max_memory: Option<u64>,
) -> PyResult<String> {
    let raster = match (array, path) {
        (Some(array), None) => raster_with(array, nodata, None, None, None)?,
        (None, Some(path)) => {
            let read = read_options(terrain_rgb, false, max_samples, max_memory);
            py.detach(|| read_dem(&path, &read)).map_err(dem_error)?
        }
        _ => return Err(PyValueError::new_err("give an array or a path, not both")),
    };
    let rows = table_rows(thresholds, bpp)?;
    let options = table_encoding(raster.len(), wavelet, &rows)?;
    let rule = split_rule(rule)?;
    let table = py.detach(|| {
        let encoded = encode_raster(&raster, &options)?;
        lod::paper_table(&raster, &encoded, &rows, rule, runs)
    });
    let table = table.map_err(codec_error)?;
    serde_json::to_string(&table).map_err(|e| CodecError::new_err(e.to_string()))
}
