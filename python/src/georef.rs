//! Georeferencing between Python and the codec: a GDAL geotransform and a CRS given as
//! an EPSG code or WKT become a [`Georef`] as the command line stores it (GeoKeys naming
//! the EPSG code; WKT kept as text besides), and back.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use wavemesh::dem::{epsg_code, keys_from_wkt};
use wavemesh_codec::{Georef, Metadata, Raster};

/// The GeoKeys of EPSG code `code`, from its definition (geographic or projected).
fn keys_of_epsg(code: i64) -> PyResult<Vec<u16>> {
    let definition = u16::try_from(code)
        .ok()
        .and_then(crs_definitions::from_code)
        .ok_or_else(|| PyValueError::new_err(format!("unknown EPSG code {code}")))?;
    let keys = keys_from_wkt(definition.wkt);
    if keys.is_empty() {
        return Err(PyValueError::new_err(format!(
            "EPSG:{code} is neither a geographic nor a projected CRS; give its WKT instead"
        )));
    }
    Ok(keys)
}

/// The GeoKeys of a CRS, and the WKT to keep beside them: an EPSG code our tables know
/// becomes keys alone; otherwise the WKT is kept as given (and becomes keys when it names
/// its EPSG code), so a CRS object whose code is unknown here still travels.
fn crs_keys(epsg: Option<i64>, wkt: Option<String>) -> PyResult<(Vec<u16>, Option<String>)> {
    if wkt.as_deref().is_some_and(|text| text.trim().is_empty()) {
        return Err(PyValueError::new_err("crs is an empty string"));
    }
    match (epsg.map(keys_of_epsg), wkt) {
        (Some(Ok(keys)), _) => Ok((keys, None)),
        (Some(Err(unknown)), None) => Err(unknown),
        (Some(Err(_)) | None, Some(text)) => Ok((keys_from_wkt(&text), Some(text))),
        (None, None) => Ok((Vec::new(), None)),
    }
}

/// Places `raster` with a GDAL `geotransform` and a CRS given as an `epsg` code and/or
/// `wkt` text (see [`georef_of`]).
pub fn set_georef(
    raster: &mut Raster,
    geotransform: Option<[f64; 6]>,
    epsg: Option<i64>,
    wkt: Option<String>,
) -> PyResult<()> {
    let (georef, crs_wkt) = georef_of(geotransform, epsg, wkt)?;
    if georef.is_some() {
        raster.metadata.crs_wkt = crs_wkt;
        raster.georef = georef;
    }
    Ok(())
}

/// The georeferencing of a GDAL `geotransform` and a CRS given as an `epsg` code and/or
/// `wkt` text (see [`crs_keys`]), and the WKT to keep in the metadata beside it.
pub fn georef_of(
    geotransform: Option<[f64; 6]>,
    epsg: Option<i64>,
    wkt: Option<String>,
) -> PyResult<(Option<Georef>, Option<String>)> {
    let has_crs = epsg.is_some() || wkt.is_some();
    let (keys, crs_wkt) = crs_keys(epsg, wkt)?;
    let Some(geotransform) = geotransform else {
        if has_crs {
            return Err(PyValueError::new_err(
                "a CRS without a transform places nothing: give transform= too",
            ));
        }
        return Ok((None, None));
    };
    if geotransform.iter().any(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "transform must hold finite numbers, got {geotransform:?}"
        )));
    }
    let georef = Georef {
        geotransform,
        geo_key_directory: keys,
        ..Georef::default()
    };
    Ok((Some(georef), crs_wkt))
}

/// Puts the georeferencing and GIS metadata of a stream into `out`: `geotransform` (GDAL
/// order), `crs_epsg`, `crs_wkt` (the WKT the source gave, else the EPSG definition),
/// `scale`, `offset`, `description`, `unit_type` and `metadata_items`.
pub fn add_georef(
    out: &Bound<'_, PyDict>,
    georef: Option<&Georef>,
    metadata: &Metadata,
) -> PyResult<()> {
    let epsg = georef.and_then(epsg_code);
    let wkt = metadata.crs_wkt.clone().or_else(|| {
        epsg.and_then(crs_definitions::from_code)
            .map(|definition| definition.wkt.to_string())
    });
    out.set_item("geotransform", georef.map(|g| g.geotransform))?;
    out.set_item("crs_epsg", epsg)?;
    out.set_item("crs_wkt", wkt)?;
    out.set_item("scale", metadata.scale)?;
    out.set_item("offset", metadata.offset)?;
    out.set_item("description", metadata.description.clone())?;
    out.set_item("unit_type", metadata.unit_type.clone())?;
    let items = PyList::empty(out.py());
    for item in &metadata.items {
        let entry = PyDict::new(out.py());
        entry.set_item("name", &item.name)?;
        entry.set_item("value", &item.value)?;
        entry.set_item("domain", &item.domain)?;
        entry.set_item("band", item.band)?;
        items.append(entry)?;
    }
    out.set_item("metadata_items", items)
}
