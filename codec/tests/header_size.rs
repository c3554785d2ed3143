//! Version-2 headers are small: at most 40 bytes without georeferencing, at most 80 with
//! an EPSG-coded CRS and a north-up geotransform.

use wavemesh_codec::{encode, EncodeOptions, Georef, Quality, Raster, SampleType, Samples};

/// A smooth terrain of `width × height` samples of `sample_type` around `base`.
fn terrain(width: usize, height: usize, sample_type: SampleType, base: f64) -> Raster {
    let values: Vec<f64> = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            base + 300.0 * (x * 0.05).sin() * (y * 0.03).cos() + 7.0 * (x * 1.3 + y).sin()
        })
        .collect();
    Raster::new(width, height, Samples::from_f64(sample_type, &values)).unwrap()
}

/// EPSG:4326 as GDAL writes it (with the keys that only restate the code).
fn gdal_epsg4326() -> Georef {
    Georef {
        geotransform: [
            -84.41375,
            1.0 / 1200.0,
            0.0,
            36.73291666666667,
            0.0,
            -1.0 / 1200.0,
        ],
        geo_key_directory: vec![
            1, 1, 0, 6, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326, 2049, 34737, 7, 0, 2054, 0,
            1, 9102, 2057, 34736, 1, 1,
        ],
        geo_double_params: vec![298.257223563, 6378137.0],
        geo_ascii_params: "WGS 84|".into(),
    }
}

/// (name, raster, options) of every kind of stream: integer and float rasters (f32 off
/// any grid), lossless, 9/7 cut at a rate and max-error, small and larger (sizes take
/// 1 or 2 bytes, payload lengths 2 or 3). The sizes show with `--nocapture`.
fn cases() -> Vec<(String, Raster, EncodeOptions)> {
    let mut cases = Vec::new();
    for (w, h) in [(120, 91), (128, 128), (700, 500)] {
        for (t, base) in [
            (SampleType::I16, 500.0),
            (SampleType::U16, 30000.0),
            (SampleType::F32, 12.25),
            (SampleType::F32, 2345.678),
        ] {
            let r = terrain(w, h, t, base);
            for (name, opts) in [
                ("lossless", EncodeOptions::new(Quality::Lossless, None)),
                (
                    "9/7 at 0.25 bpp",
                    EncodeOptions::new(Quality::Lossless, Some((w * h / 32) as u64)),
                ),
                (
                    "max-error 2",
                    EncodeOptions::new(Quality::MaxError(2.0), None),
                ),
            ] {
                let name = format!("{w}x{h} {} around {base} {name}", t.name());
                cases.push((name, r.clone(), opts));
            }
        }
    }
    cases
}

/// Encodes every case with `georef` and checks its header against `limit` bytes.
fn check_sizes(georef: Option<Georef>, limit: usize) {
    let mut over = Vec::new();
    for (name, mut raster, options) in cases() {
        raster.georef = georef.clone();
        let encoded = encode(&raster, &options).unwrap();
        eprintln!("{name}: header {} bytes", encoded.header_len);
        if encoded.header_len > limit {
            over.push(format!("{name}: {} bytes", encoded.header_len));
        }
    }
    assert!(over.is_empty(), "headers above {limit} bytes: {over:?}");
}

#[test]
fn headers_without_georeferencing_take_at_most_40_bytes() {
    check_sizes(None, 40);
}

#[test]
fn headers_with_an_epsg_crs_take_at_most_80_bytes() {
    check_sizes(Some(gdal_epsg4326()), 80);
}
