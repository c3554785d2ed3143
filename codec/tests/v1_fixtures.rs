//! Version-1 `.ezw` files, made by the version-1 encoder (commit 47a241a), must decode
//! forever to exactly what that encoder's decoder made of them.
//!
//! `fixtures/v1/NAME.ezw` is the file and `NAME.decoded` its decoded samples, raw
//! little-endian (f32 as their bits).

use wavemesh_codec::{decode, DecodeOptions, Mode};

mod support;

use support::raw;

fn fixture(name: &str) -> Vec<u8> {
    support::fixture("v1", name)
}

#[test]
fn every_v1_fixture_decodes_to_its_recorded_samples() {
    for (name, mode, complete) in [
        ("i16_georef_lossless", Mode::Lossless, true),
        ("i16_97_prefix_300_bytes", Mode::Lossy, true),
        ("f32_nan_nodata_lossless", Mode::Lossless, true),
        ("u16_max_error_25", Mode::MaxError, true),
    ] {
        let file = fixture(&format!("{name}.ezw"));
        assert_eq!(u16::from_le_bytes([file[8], file[9]]), 1, "{name} version");
        let decoded = decode(&file, &DecodeOptions::default()).unwrap();
        assert_eq!((decoded.raster.width, decoded.raster.height), (24, 20));
        assert_eq!(decoded.header.mode, mode, "{name} mode");
        assert_eq!(decoded.complete, complete, "{name} complete");
        assert!(decoded.damage.is_none(), "{name} damage");
        assert_eq!(
            raw(&decoded.raster.samples),
            fixture(&format!("{name}.decoded")),
            "{name} samples"
        );
    }
}

#[test]
fn v1_georeferencing_and_nodata_survive() {
    let decoded = decode(
        &fixture("i16_georef_lossless.ezw"),
        &DecodeOptions::default(),
    )
    .unwrap();
    assert_eq!(decoded.raster.nodata, Some(-32768.0));
    let georef = decoded.raster.georef.expect("georeferenced");
    assert_eq!(georef.geotransform[1], 1.0 / 1200.0);
    assert_eq!(georef.geotransform[3], 36.73291666666667);
    assert_eq!(
        georef.geo_key_directory,
        [
            1, 1, 0, 5, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326, 2049, 34737, 7, 0, 2054, 0,
            1, 9102
        ]
    );
    assert_eq!(georef.geo_double_params, [298.257223563, 6378137.0]);
    assert_eq!(georef.geo_ascii_params, "WGS 84|");
    let nan = decode(
        &fixture("f32_nan_nodata_lossless.ezw"),
        &DecodeOptions::default(),
    )
    .unwrap();
    assert!(nan.raster.nodata.is_some_and(f64::is_nan));
}
