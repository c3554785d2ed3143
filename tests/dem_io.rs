//! The DEM readers and writers on real files: the shared development DEMs in
//! `../shared/dem` (checked against its `manifest.json`, skipped when absent) and the
//! samples in `samples/`.

mod support;

use std::collections::HashSet;
use std::fs;
use std::path::Path;

use serde_json::Value;
use wavemesh::dem::{detect_format, read_dem, write_dem, DemFormat, ReadOptions};
use wavemesh_codec::{Raster, SampleType, Samples};

/// The GeoKeys name the manifest's EPSG code (geographic or projected) and the pixel
/// size is the manifest's ground resolution (3 arc-seconds, or metres), north-up.
fn check_crs_and_pixel_size(name: &str, g: &wavemesh_codec::Georef, ds: &Value) {
    let crs = ds["crs"].as_str().unwrap();
    // "EPSG:4326", or "EPSG:4326 (nominal; ...)".
    let code = crs.split_whitespace().next().unwrap();
    let code: u16 = code.strip_prefix("EPSG:").unwrap().parse().unwrap();
    let (key, pixel) = if code == 4326 {
        // 3 arc-seconds (alps_srtm_voids stores it rounded to 0.000833333).
        assert_eq!(g.geo_ascii_params, "WGS 84|");
        assert_eq!(g.geo_double_params, vec![298.257223563, 6378137.0]);
        (2048, 1.0 / 1200.0)
    } else {
        let metres = ds["ground_resolution"].as_str().unwrap();
        let metres: f64 = metres.trim_end_matches(" m").parse().unwrap();
        (3072, metres)
    };
    let keys = &g.geo_key_directory;
    assert!(
        keys.chunks(4).any(|k| k == [key, 0, 1, code]),
        "{name} keys {keys:?}"
    );
    let gt = g.geotransform;
    let tolerance = 1e-9 * pixel.max(1.0);
    assert!((gt[1] - pixel).abs() < tolerance, "{name} pixel width");
    assert!((gt[5] + pixel).abs() < tolerance, "{name} pixel height");
    assert_eq!((gt[2], gt[4]), (0.0, 0.0));
}

/// The manifest's datasets.
fn datasets(dir: &Path) -> Vec<Value> {
    let text = fs::read_to_string(dir.join("manifest.json")).expect("read manifest.json");
    let manifest: Value = serde_json::from_str(&text).expect("parse manifest.json");
    manifest["datasets"]
        .as_array()
        .expect("datasets array")
        .clone()
}

fn read(path: &Path) -> Raster {
    read_dem(path, &ReadOptions::default())
        .unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

fn sample_type(dtype: &str) -> SampleType {
    match dtype {
        "uint8" => SampleType::U8,
        "uint16" => SampleType::U16,
        "int16" => SampleType::I16,
        "int32" => SampleType::I32,
        "float32" => SampleType::F32,
        other => panic!("manifest dtype {other}"),
    }
}

/// Bit pattern of a sample, to count distinct values of any type.
fn sample_bits(samples: &Samples, i: usize) -> u64 {
    match samples {
        Samples::F32(v) => u64::from(v[i].to_bits()),
        other => other.get_f64(i).to_bits(),
    }
}

#[test]
fn shared_tifs_match_the_manifest() {
    let Some(dir) = support::shared_dem("dem_io::shared_tifs_match_the_manifest") else {
        return;
    };
    for ds in datasets(&dir) {
        let name = ds["name"].as_str().unwrap();
        let path = dir.join(ds["files"]["tif"].as_str().unwrap());
        let head = fs::read(&path).unwrap();
        assert_eq!(
            detect_format(&path, &head[..16], &ReadOptions::default()).unwrap(),
            DemFormat::GeoTiff
        );
        let r = read(&path);
        assert_eq!(
            r.width as u64,
            ds["width"].as_u64().unwrap(),
            "{name} width"
        );
        assert_eq!(
            r.height as u64,
            ds["height"].as_u64().unwrap(),
            "{name} height"
        );
        assert_eq!(
            r.sample_type(),
            sample_type(ds["dtype"].as_str().unwrap()),
            "{name} type"
        );
        match ds["nodata_value"].as_str() {
            Some("NaN") => assert!(r.nodata.is_some_and(f64::is_nan), "{name} nodata"),
            _ => assert_eq!(r.nodata, ds["nodata_value"].as_f64(), "{name} nodata"),
        }

        let valid: Vec<usize> = (0..r.len()).filter(|&i| r.is_valid(i)).collect();
        let nodata_count = (r.len() - valid.len()) as u64;
        assert_eq!(
            nodata_count,
            ds["nodata_count"].as_u64().unwrap(),
            "{name} voids"
        );
        let values: Vec<f64> = valid.iter().map(|&i| r.samples.get_f64(i)).collect();
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(min, ds["min"].as_f64().unwrap(), "{name} min");
        assert_eq!(max, ds["max"].as_f64().unwrap(), "{name} max");
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        assert!(
            (mean - ds["mean"].as_f64().unwrap()).abs() <= 0.0005 + 1e-9,
            "{name} mean {mean}"
        );
        let distinct: HashSet<u64> = valid.iter().map(|&i| sample_bits(&r.samples, i)).collect();
        assert_eq!(
            distinct.len() as u64,
            ds["distinct_values"].as_u64().unwrap(),
            "{name} distinct values"
        );

        let georeferenced = ds["georeferenced"].as_bool().unwrap();
        assert_eq!(r.georef.is_some(), georeferenced, "{name} georef");
        if let Some(g) = &r.georef {
            check_crs_and_pixel_size(name, g, &ds);
        }
    }
}

#[test]
fn shared_pngs_equal_their_tifs_plus_offset() {
    let Some(dir) = support::shared_dem("dem_io::shared_pngs_equal_their_tifs_plus_offset") else {
        return;
    };
    let mut checked = 0;
    for ds in datasets(&dir) {
        let name = ds["name"].as_str().unwrap();
        let tif = read(&dir.join(ds["files"]["tif"].as_str().unwrap()));
        let offset = ds["png_offset"].as_f64();
        let mut pngs: Vec<(String, f64)> = Vec::new();
        if let (Some(png), Some(offset)) = (ds["files"]["png"].as_str(), offset) {
            pngs.push((png.to_string(), offset));
        }
        // (sthelens_10m's original is its normalised PNG: listed once.)
        // Original grayscale / grey-palette PNGs hold the tif's values unchanged.
        for original in ds["files"]["original"].as_array().unwrap() {
            let original = original.as_str().unwrap();
            let listed = pngs.iter().any(|(p, _)| p == original);
            if original.ends_with(".png") && name != "fuji_terrainrgb" && !listed {
                pngs.push((original.to_string(), 0.0));
            }
        }
        for (png, offset) in pngs {
            let path = dir.join(&png);
            let r = read(&path);
            assert_eq!((r.width, r.height), (tif.width, tif.height), "{png}");
            assert!(
                matches!(r.sample_type(), SampleType::U8 | SampleType::U16),
                "{png}"
            );
            let mismatches = (0..r.len())
                .filter(|&i| r.samples.get_f64(i) != tif.samples.get_f64(i) + offset)
                .count();
            assert_eq!(mismatches, 0, "{png} differs from its tif");
            checked += 1;
        }
    }
    // srtm, sthelens, alps (normalised and original), grandcanyon (normalised and the
    // grey-palette original), jacksboro.
    assert_eq!(checked, 7);
}

#[test]
fn srtm_hgt_equals_its_tif() {
    let Some(dir) = support::shared_dem("dem_io::srtm_hgt_equals_its_tif") else {
        return;
    };
    let hgt_path = dir.join("srtm3_n57e011/N57E011.hgt");
    assert_eq!(
        detect_format(&hgt_path, &[0; 16], &ReadOptions::default()).unwrap(),
        DemFormat::Hgt
    );
    let hgt = read(&hgt_path);
    let tif = read(&dir.join("srtm3_n57e011/srtm3_n57e011.tif"));
    assert_eq!((hgt.width, hgt.height), (1201, 1201));
    assert_eq!(hgt.samples, tif.samples);
    assert_eq!(hgt.nodata, tif.nodata);
    let (h, t) = (hgt.georef.unwrap(), tif.georef.unwrap());
    assert_eq!(h.geotransform, t.geotransform);
    // The .hgt georef carries the three essential keys; GDAL's tif has those and more.
    for key in h.geo_key_directory[4..].chunks(4) {
        assert!(t.geo_key_directory.chunks(4).any(|k| k == key), "{key:?}");
    }
}

#[test]
fn fuji_terrain_rgb_equals_its_tif() {
    let Some(dir) = support::shared_dem("dem_io::fuji_terrain_rgb_equals_its_tif") else {
        return;
    };
    let png = dir.join("fuji_terrainrgb/fuji.png");
    let options = ReadOptions {
        terrain_rgb: true,
        ..ReadOptions::default()
    };
    let rgb = read_dem(&png, &options).unwrap();
    let tif = read(&dir.join("fuji_terrainrgb/fuji_terrainrgb.tif"));
    let (Samples::F32(a), Samples::F32(b)) = (&rgb.samples, &tif.samples) else {
        panic!("fuji should decode to f32");
    };
    assert_eq!((rgb.width, rgb.height), (512, 512));
    let differing = a
        .iter()
        .zip(b)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count();
    assert_eq!(differing, 0, "Terrain-RGB decode differs from the tif");
    // Without the flag the same file is refused with a hint.
    let err = read_dem(&png, &ReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("--terrain-rgb"), "{err}");
}

#[test]
fn shared_dems_survive_write_and_read_back() {
    let Some(dir) = support::shared_dem("dem_io::shared_dems_survive_write_and_read_back") else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    for (tif, formats) in [
        ("alps_srtm_voids/alps_srtm_voids.tif", &["tif", "asc"][..]),
        ("fuji_terrainrgb/fuji_terrainrgb.tif", &["tif", "asc"][..]),
        ("sthelens_10m/sthelens_10m.tif", &["tif", "png"][..]),
        (
            "grandcanyon_8bit/grandcanyon_8bit.tif",
            &["tif", "png", "asc"][..],
        ),
    ] {
        let original = read(&dir.join(tif));
        for ext in formats {
            let path = out.path().join(format!("copy.{ext}"));
            write_dem(&path, &original).unwrap();
            let back = read(&path);
            assert_eq!(
                back.samples.to_f64(),
                original.samples.to_f64(),
                "{tif} .{ext}"
            );
            if *ext == "tif" {
                assert_eq!(back, original, "{tif} .tif");
            } else if *ext == "asc" {
                assert_eq!(back.nodata, original.nodata, "{tif} .asc");
            }
        }
    }
}

#[test]
fn samples_match_what_the_script_claims() {
    let samples = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let clean = read(&samples.join("jacksboro_fault.tif"));
    let voids = read(&samples.join("jacksboro_voids.tif"));
    for r in [&clean, &voids] {
        assert_eq!((r.width, r.height), (403, 344));
        assert_eq!(r.sample_type(), SampleType::I16);
        let g = r.georef.as_ref().expect("georeferenced");
        assert_eq!(
            g.geotransform,
            [
                -84.41375,
                1.0 / 1200.0,
                0.0,
                36.73291666666667,
                0.0,
                -1.0 / 1200.0
            ]
        );
        assert_eq!(
            g.geo_key_directory,
            vec![1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326]
        );
    }
    assert_eq!(clean.nodata, None);
    assert!(clean.valid_mask().iter().all(|&v| v));
    assert_eq!(voids.nodata, Some(-32768.0));
    let void_count = voids.valid_mask().iter().filter(|&&v| !v).count();
    let fraction = void_count as f64 / voids.len() as f64;
    assert!(
        void_count > 0 && (0.025..0.04).contains(&fraction),
        "{void_count}"
    );
    // Outside the voids the heights are untouched.
    for i in 0..clean.len() {
        if voids.is_valid(i) {
            assert_eq!(voids.samples.get_f64(i), clean.samples.get_f64(i));
        }
    }
    // Same heights and placement as the shared copy of the DEM, when it is there.
    if let Some(dir) = support::shared_dem("dem_io::samples_match_what_the_script_claims") {
        let shared = read(&dir.join("jacksboro_fault/jacksboro_fault.tif"));
        assert_eq!(clean.samples, shared.samples);
        assert_eq!(
            clean.georef.unwrap().geotransform,
            shared.georef.unwrap().geotransform
        );
    }
}
