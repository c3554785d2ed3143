//! Side files GIS tools read beside rasters whose format cannot say where they lie: the
//! `.prj` (CRS as WKT) beside an ESRI ASCII grid, and the world file (`.pgw`) and GDAL
//! PAM file (`.png.aux.xml`: CRS, nodata, scale/offset, metadata) beside a PNG.
//!
//! Side files are written atomically, and only beside a regular file (not beside
//! `/dev/stdout` or a pipe).

use std::io::Read;
use std::path::{Path, PathBuf};

use wavemesh_codec::{geokey, Georef, Raster};

use super::{gdal_metadata, read_error, DemError};
use crate::atomic::write_atomic;

/// Largest `.prj` read (a WKT is a few kilobytes).
const MAX_PRJ_BYTES: u64 = 1 << 20;

/// The EPSG code of the CRS `georef`'s GeoKeys name (projected first), if any.
pub fn epsg_code(georef: &Georef) -> Option<u16> {
    let dir = &georef.geo_key_directory;
    [geokey::PROJECTED_TYPE, geokey::GEOGRAPHIC_TYPE]
        .into_iter()
        .find_map(|id| geokey::value(dir, id).filter(|code| (1024..32767).contains(code)))
}

/// The raster's CRS as WKT: the text its source gave, or the EPSG definition of its
/// GeoKeys' code (from the `crs-definitions` tables); `None` when neither is known.
pub(super) fn crs_wkt(raster: &Raster) -> Option<String> {
    if let Some(wkt) = &raster.metadata.crs_wkt {
        return Some(wkt.clone());
    }
    let code = epsg_code(raster.georef.as_ref()?)?;
    crs_definitions::from_code(code).map(|def| def.wkt.to_string())
}

/// The code of the `AUTHORITY["EPSG", code]` that is a direct child of a WKT 1 text's
/// top-level node; nested ones (of its datum, base CRS or units) do not name the CRS.
fn top_level_epsg(text: &str) -> Option<u16> {
    let (mut depth, mut quoted) = (0usize, false);
    let at = text.char_indices().find_map(|(at, c)| {
        match c {
            '"' => quoted = !quoted,
            '[' if !quoted => depth += 1,
            ']' if !quoted => depth = depth.saturating_sub(1),
            ',' if !quoted && depth == 1 => {
                let next = text[at + 1..].trim_start();
                if next.starts_with("AUTHORITY[") {
                    return Some(text.len() - next.len());
                }
            }
            _ => {}
        }
        None
    })?;
    let rest = &text[at..];
    let inner = rest[10..rest.find(']')?].replace('"', "");
    let (authority, code) = inner.split_once(',')?;
    (authority.trim() == "EPSG").then(|| code.trim().parse::<u16>().ok())?
}

/// The GeoKey directory of a WKT whose top-level `AUTHORITY["EPSG", code]` names its CRS,
/// so a GeoTIFF written from it carries the CRS.
pub fn keys_from_wkt(wkt: &str) -> Vec<u16> {
    let text = wkt.trim();
    let projected = text.starts_with("PROJCS");
    if !(projected || text.starts_with("GEOGCS")) {
        return Vec::new();
    }
    let code = top_level_epsg(text);
    let Some(code) = code.filter(|c| (1024..32767).contains(c)) else {
        return Vec::new();
    };
    let (model, key) = if projected {
        (geokey::MODEL_PROJECTED, geokey::PROJECTED_TYPE)
    } else {
        (geokey::MODEL_GEOGRAPHIC, geokey::GEOGRAPHIC_TYPE)
    };
    #[rustfmt::skip]
    let keys = vec![
        1, 1, 0, 3,
        geokey::MODEL_TYPE, 0, 1, model,
        geokey::RASTER_TYPE, 0, 1, 1,
        key, 0, 1, code,
    ];
    keys
}

/// Reads the `.prj` beside `path`, if there is one.
pub(super) fn read_prj(path: &Path) -> Result<Option<String>, DemError> {
    let prj = path.with_extension("prj");
    let file = match std::fs::File::open(&prj) {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(read_error(&prj, e)),
    };
    let mut text = String::new();
    file.take(MAX_PRJ_BYTES)
        .read_to_string(&mut text)
        .map_err(|e| read_error(&prj, e))?;
    Ok(Some(text.trim().to_string()).filter(|t| !t.is_empty()))
}

/// Writes the `.prj` beside an `.asc` at `path` when the CRS is known.
pub(super) fn write_prj(path: &Path, raster: &Raster) -> Result<(), DemError> {
    match crs_wkt(raster) {
        Some(wkt) if is_regular_file(path) => {
            write_side_file(&path.with_extension("prj"), wkt.as_bytes())
        }
        _ => Ok(()),
    }
}

/// Writes the world file (when georeferenced) and the `.aux.xml` (when there is anything
/// to say) beside a PNG at `path`.
pub(super) fn write_png_side_files(path: &Path, raster: &Raster) -> Result<(), DemError> {
    if !is_regular_file(path) {
        return Ok(());
    }
    if let Some(georef) = &raster.georef {
        write_side_file(&path.with_extension("pgw"), world_file(georef).as_bytes())?;
    }
    let srs = crs_wkt(raster);
    if srs.is_some() || raster.nodata.is_some() || !raster.metadata.is_empty() {
        let xml = gdal_metadata::to_pam_xml(raster, srs.as_deref());
        write_side_file(&aux_xml_path(path), xml.as_bytes())?;
    }
    Ok(())
}

/// `x.png` → `x.png.aux.xml`, where GDAL looks for it.
fn aux_xml_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".aux.xml");
    PathBuf::from(name)
}

/// The six lines of a world file: pixel size and rotation terms, then the centre of the
/// top-left pixel.
fn world_file(georef: &Georef) -> String {
    let gt = georef.geotransform;
    let lines = [
        gt[1],
        gt[4],
        gt[2],
        gt[5],
        gt[0] + 0.5 * (gt[1] + gt[2]),
        gt[3] + 0.5 * (gt[4] + gt[5]),
    ];
    lines.iter().map(|v| format!("{v}\n")).collect()
}

fn is_regular_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
}

fn write_side_file(path: &Path, bytes: &[u8]) -> Result<(), DemError> {
    write_atomic(path, |w| w.write_all(bytes)).map_err(|source| DemError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wkt_authority_becomes_geokeys_and_back() {
        let wkt = crs_definitions::from_code(32632).unwrap().wkt;
        let keys = keys_from_wkt(wkt);
        assert_eq!(keys[12..], [3072, 0, 1, 32632]);
        let georef = Georef {
            geo_key_directory: keys,
            ..Georef::default()
        };
        assert_eq!(epsg_code(&georef), Some(32632));
        assert!(keys_from_wkt("PROJCS[\"local\",UNIT[\"m\",1]]").is_empty());
        // A custom projection on WGS 84: its AUTHORITY nodes name the base CRS and the
        // unit (EPSG:4326, EPSG:9001), not the CRS.
        let custom = "PROJCS[\"unknown\",GEOGCS[\"WGS 84\",AUTHORITY[\"EPSG\",\"4326\"]],\
            PROJECTION[\"Transverse_Mercator\"],UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]]]";
        assert!(keys_from_wkt(custom).is_empty());
        assert_eq!(
            keys_from_wkt("GEOGCS[\"x\", AUTHORITY[\"EPSG\",\"4326\"]]")[15],
            4326
        );
    }

    #[test]
    fn world_file_names_the_top_left_pixel_centre() {
        let georef = Georef {
            geotransform: [100.0, 2.0, 0.0, 50.0, 0.0, -2.0],
            ..Georef::default()
        };
        assert_eq!(world_file(&georef), "2\n0\n0\n-2\n101\n49\n");
    }
}
