//! GIS metadata end to end: a GeoTIFF made here with GDAL's tags (GeoKeys, GDAL_NODATA,
//! GDAL_METADATA with scale, offset, description, units and free items) goes through
//! `encode` and `decode` to GeoTIFF, ESRI ASCII grid and PNG, and every item arrives —
//! in the GeoTIFF's tags, the `.prj`, the `.pgw` and the `.png.aux.xml`. When Debian's
//! GDAL is installed, `gdalinfo -json` must see the same; without it that test says
//! SKIPPED where `cargo test` shows it.

use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::Command;

mod support;

use support::{json, s, scratch, stdout};
use tiff::encoder::{colortype, TiffEncoder};
use tiff::tags::Tag;
use wavemesh::dem::{read_dem, ReadOptions};

const GDAL_METADATA: &str = r#"<GDALMetadata>
  <Item name="DTED_VerticalDatum">E08</Item>
  <Item name="PLACE">Z&#252;rich</Item>
  <Item name="SOURCE" domain="PROVENANCE">Copernicus &amp; "friends"</Item>
  <Item name="OFFSET" sample="0" role="offset">100</Item>
  <Item name="SCALE" sample="0" role="scale">0.1</Item>
  <Item name="DESCRIPTION" sample="0" role="description">elevation</Item>
  <Item name="UNITTYPE" sample="0" role="unittype">m</Item>
  <Item name="QUALITY" sample="0">good</Item>
</GDALMetadata>"#;

/// EPSG:4326 with the keys GDAL writes beside the code.
const GEO_KEYS: [u16; 32] = [
    1, 1, 0, 7, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326, 2049, 34737, 7, 0, 2054, 0, 1,
    9102, 2057, 34736, 1, 1, 2059, 34736, 1, 0,
];

/// A 40×30 u16 GeoTIFF with every tag above, written as `dir/source.tif`.
fn source_tif(dir: &Path) -> PathBuf {
    let path = dir.join("source.tif");
    let (w, h) = (40u32, 30u32);
    let data: Vec<u16> = (0..w * h)
        .map(|i| 5000 + ((i % w) * 37 + (i / w) * 11) as u16)
        .collect();
    let mut encoder = TiffEncoder::new(File::create(&path).unwrap()).unwrap();
    let mut image = encoder.new_image::<colortype::Gray16>(w, h).unwrap();
    let dir = image.encoder();
    dir.write_tag(Tag::ModelPixelScaleTag, &[0.5f64, 0.25, 0.0][..])
        .unwrap();
    dir.write_tag(
        Tag::ModelTiepointTag,
        &[0.0f64, 0.0, 0.0, 11.0, 47.5, 0.0][..],
    )
    .unwrap();
    dir.write_tag(Tag::GeoKeyDirectoryTag, &GEO_KEYS[..])
        .unwrap();
    dir.write_tag(Tag::GeoDoubleParamsTag, &[298.257223563f64, 6378137.0][..])
        .unwrap();
    dir.write_tag(Tag::GeoAsciiParamsTag, "WGS 84|").unwrap();
    dir.write_tag(Tag::GdalNodata, "0").unwrap();
    dir.write_tag(Tag::Unknown(42112), GDAL_METADATA).unwrap();
    image.write_data(&data).unwrap();
    path
}

/// Encodes the source GeoTIFF into `dir` and decodes it to `dir/output`; returns the
/// `.ezw` and the output paths.
fn round_trip(dir: &Path, output: &str) -> (PathBuf, PathBuf) {
    let ezw = dir.join("metadata.ezw");
    let out = dir.join(output);
    stdout(&["encode", s(&source_tif(dir)), "-o", s(&ezw)]);
    stdout(&["decode", s(&ezw), "-o", s(&out)]);
    (ezw, out)
}

#[test]
fn geotiff_metadata_survives_encode_and_decode() {
    let dir = scratch("gis_metadata");
    let (ezw, out) = round_trip(dir.path(), "decoded.tif");
    let source = read_dem(&dir.path().join("source.tif"), &ReadOptions::default()).unwrap();
    let m = &source.metadata;
    assert_eq!((m.scale, m.offset), (Some(0.1), Some(100.0)));
    assert_eq!(m.description.as_deref(), Some("elevation"));
    assert_eq!(m.unit_type.as_deref(), Some("m"));
    assert_eq!(m.items.len(), 4, "{:?}", m.items);
    assert_eq!(m.items[1].value, "Zürich");
    let decoded = read_dem(&out, &ReadOptions::default()).unwrap();
    assert_eq!(&decoded.metadata, m);
    assert_eq!(decoded.nodata, Some(0.0));
    assert_eq!(decoded.samples, source.samples);
    let georef = decoded.georef.unwrap();
    assert_eq!(georef.geotransform, [11.0, 0.5, 0.0, 47.5, 0.0, -0.25]);
    assert!(georef.geo_key_directory.ends_with(&[2048, 0, 1, 4326]));

    let info = json(&["info", s(&ezw), "--json"]);
    assert_eq!(info["format_version"], 2);
    assert_eq!(info["metadata"]["scale"], 0.1);
    assert_eq!(info["metadata"]["offset"], 100.0);
    assert_eq!(info["metadata"]["unit_type"], "m");
    assert_eq!(info["metadata"]["items"][0]["name"], "DTED_VerticalDatum");
    assert_eq!(info["metadata"]["items"][0]["value"], "E08");
    assert!(info["header_bytes"].as_u64().unwrap() > 0);
}

#[test]
fn no_metadata_items_drops_only_the_free_items() {
    let dir = scratch("gis_metadata");
    let source = source_tif(dir.path());
    let (full, bare) = (dir.path().join("full.ezw"), dir.path().join("bare.ezw"));
    stdout(&["encode", s(&source), "-o", s(&full)]);
    stdout(&["encode", s(&source), "-o", s(&bare), "--no-metadata-items"]);
    let out = dir.path().join("bare.tif");
    stdout(&["decode", s(&bare), "-o", s(&out)]);
    let decoded = read_dem(&out, &ReadOptions::default()).unwrap();
    let m = &decoded.metadata;
    assert!(m.items.is_empty(), "{:?}", m.items);
    assert_eq!((m.scale, m.offset), (Some(0.1), Some(100.0)));
    assert_eq!(m.unit_type.as_deref(), Some("m"));
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    assert!(size(&bare) < size(&full));
}

#[test]
fn asc_output_gets_its_prj_and_reads_it_back() {
    let dir = scratch("gis_metadata");
    let (_, out) = round_trip(dir.path(), "decoded.asc");
    let prj = std::fs::read_to_string(out.with_extension("prj")).unwrap();
    assert!(prj.starts_with("GEOGCS[\"WGS 84\"") && prj.ends_with("AUTHORITY[\"EPSG\",\"4326\"]]"));
    let back = read_dem(&out, &ReadOptions::default()).unwrap();
    assert_eq!(back.metadata.crs_wkt.as_deref(), Some(prj.as_str()));
    let keys = back.georef.unwrap().geo_key_directory;
    assert!(keys.ends_with(&[2048, 0, 1, 4326]), "{keys:?}");
}

#[test]
fn png_output_gets_a_world_file_and_aux_xml() {
    let dir = scratch("gis_metadata");
    let (_, out) = round_trip(dir.path(), "decoded.png");
    let world = std::fs::read_to_string(out.with_extension("pgw")).unwrap();
    let lines: Vec<f64> = world.lines().map(|l| l.parse().unwrap()).collect();
    assert_eq!(lines, [0.5, 0.0, 0.0, -0.25, 11.25, 47.375]);
    let aux = std::fs::read_to_string(dir.path().join("decoded.png.aux.xml")).unwrap();
    for needle in [
        "<SRS>GEOGCS[&quot;WGS 84&quot;",
        "<NoDataValue>0</NoDataValue>",
        "<Scale>0.1</Scale>",
        "<Offset>100</Offset>",
        "<UnitType>m</UnitType>",
        "<Description>elevation</Description>",
        "<MDI key=\"DTED_VerticalDatum\">E08</MDI>",
        "<Metadata domain=\"PROVENANCE\">",
        "<MDI key=\"QUALITY\">good</MDI>",
    ] {
        assert!(aux.contains(needle), "{needle} missing from\n{aux}");
    }
}

fn gdalinfo(program: &Path, path: &Path) -> serde_json::Value {
    let out = Command::new(program)
        .args(["-json", "-mdd", "all", s(path)])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn gdalinfo_sees_the_metadata() {
    let test = "gis_metadata::gdalinfo_sees_the_metadata";
    let Some(program) = support::program(test, "gdalinfo", "Debian: gdal-bin") else {
        return;
    };
    let dir = scratch("gis_metadata");
    let (_, tif) = round_trip(dir.path(), "gdal.tif");
    let info = gdalinfo(&program, &tif);
    let band = &info["bands"][0];
    assert_eq!(band["scale"], 0.1);
    assert_eq!(band["offset"], 100.0);
    assert_eq!(band["description"], "elevation");
    assert_eq!(band["unit"], "m");
    assert_eq!(band["metadata"][""]["QUALITY"], "good");
    assert_eq!(info["metadata"][""]["DTED_VerticalDatum"], "E08");
    assert_eq!(info["metadata"][""]["PLACE"], "Zürich");
    assert_eq!(
        info["metadata"]["PROVENANCE"]["SOURCE"],
        "Copernicus & \"friends\""
    );
    assert!(info["coordinateSystem"]["wkt"]
        .as_str()
        .unwrap()
        .contains("4326"));

    let (_, png) = round_trip(dir.path(), "gdal.png");
    let info = gdalinfo(&program, &png);
    assert_eq!(
        info["geoTransform"],
        serde_json::json!([11.0, 0.5, 0.0, 47.5, 0.0, -0.25])
    );
    assert!(info["coordinateSystem"]["wkt"]
        .as_str()
        .unwrap()
        .contains("4326"));
    let band = &info["bands"][0];
    assert_eq!(band["noDataValue"], 0.0);
    assert_eq!(
        (band["scale"].clone(), band["offset"].clone()),
        (0.1.into(), 100.0.into())
    );
    assert_eq!(band["unit"], "m");

    let (_, asc) = round_trip(dir.path(), "gdal.asc");
    let info = gdalinfo(&program, &asc);
    assert!(info["coordinateSystem"]["wkt"]
        .as_str()
        .unwrap()
        .contains("4326"));
}
