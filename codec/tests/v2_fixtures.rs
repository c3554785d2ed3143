//! Version-2 `.ezw` files made by the first version-2 coder ([`Coder::V1`]: the context
//! models before the header's "coder 2" bit, commit 6eaf062) must decode forever to
//! exactly what that coder's decoder made of them, whole and as prefixes.
//!
//! `fixtures/v2/NAME.ezw` is the file and `NAME.decoded` its decoded samples, raw
//! little-endian (f32 as their bits); `NAME.prefixN.decoded` is the decode of its first
//! N bytes. The files are 32 × 24 synthetic terrain (a sine relief with noise).

use wavemesh_codec::format::Coder;
use wavemesh_codec::{decode, DecodeOptions, Decoded, Mode, Samples, Wavelet};

mod support;

use support::raw;

fn fixture(name: &str) -> Vec<u8> {
    support::fixture("v2", name)
}

/// Fixture `NAME.ezw` decoded within `budget` bytes: undamaged, to the samples of
/// `RECORDED.decoded`. The decode, for the caller's checks of its header.
fn decodes_as_recorded(name: &str, budget: Option<u64>, recorded: &str) -> Decoded {
    let options = DecodeOptions::default().with_max_bytes(budget);
    let out = decode(&fixture(&format!("{name}.ezw")), &options).unwrap();
    assert!(out.damage.is_none(), "{name} damage");
    assert_eq!(
        raw(&out.raster.samples),
        fixture(&format!("{recorded}.decoded")),
        "{name} at {budget:?}"
    );
    out
}

#[test]
fn every_v2_fixture_decodes_to_its_recorded_samples() {
    for (name, mode) in [
        ("i16_nodata_georef_lossless", Mode::Lossless),
        ("i16_97_200_bytes", Mode::Lossy),
        ("u16_max_error_2", Mode::MaxError),
        ("f32_nan_lossless", Mode::Lossless),
        ("f32_grid_lossless", Mode::Lossless),
    ] {
        let file = fixture(&format!("{name}.ezw"));
        assert_eq!(u16::from_le_bytes([file[8], file[9]]), 2, "{name} version");
        let decoded = decode(&file, &DecodeOptions::default()).unwrap();
        assert_eq!((decoded.raster.width, decoded.raster.height), (32, 24));
        assert_eq!(decoded.header.mode, mode, "{name} mode");
        assert_eq!(decoded.header.coder, Coder::V1, "{name} coder");
        assert!(decoded.complete, "{name} complete");
        assert!(decoded.damage.is_none(), "{name} damage");
        assert_eq!(
            raw(&decoded.raster.samples),
            fixture(&format!("{name}.decoded")),
            "{name} samples"
        );
    }
}

#[test]
fn a_v2_prefix_decodes_to_its_recorded_samples() {
    let file = fixture("i16_nodata_georef_lossless.ezw");
    let options = DecodeOptions::default().with_max_bytes(Some(300));
    let decoded = decode(&file, &options).unwrap();
    assert!(!decoded.complete);
    assert_eq!(
        raw(&decoded.raster.samples),
        fixture("i16_nodata_georef_lossless.prefix300.decoded")
    );
    // The prefix is a coarser DEM, not the whole one.
    assert_ne!(
        fixture("i16_nodata_georef_lossless.prefix300.decoded"),
        fixture("i16_nodata_georef_lossless.decoded")
    );
}

#[test]
fn v2_nodata_and_georeferencing_survive() {
    let decoded = decode(
        &fixture("i16_nodata_georef_lossless.ezw"),
        &DecodeOptions::default(),
    )
    .unwrap();
    assert_eq!(decoded.raster.nodata, Some(-32768.0));
    let georef = decoded.raster.georef.expect("georeferenced");
    assert_eq!(georef.geotransform[0], 11.0);
    assert_eq!(georef.geotransform[1], 1.0 / 1200.0);
    let voids = match &decoded.raster.samples {
        Samples::I16(v) => v.iter().filter(|&&x| x == -32768).count(),
        other => panic!("{other:?}"),
    };
    assert_eq!(voids, 40);
    let nan = decode(&fixture("f32_nan_lossless.ezw"), &DecodeOptions::default()).unwrap();
    assert!(nan.raster.nodata.is_some_and(f64::is_nan));
}

/// Files of coder 2 (before its models started trained, commit 4cea2bc) and of coder 3
/// (before the propagation scan, commit 8f9cbe0), made from the decoded
/// `i16_nodata_georef_lossless` fixture: lossless, and 9/7 cut at about 200 bytes.
#[test]
fn coder_2_and_3_fixtures_decode_to_their_recorded_samples() {
    // The lossless files must give back the samples they were made from.
    let source = "i16_nodata_georef_lossless";
    for (name, coder, samples) in [
        ("coder2_i16_lossless", Coder::V2, source),
        (
            "coder2_i16_97_200_bytes",
            Coder::V2,
            "coder2_i16_97_200_bytes",
        ),
        ("coder3_i16_lossless", Coder::V3, source),
        (
            "coder3_i16_97_199_bytes",
            Coder::V3,
            "coder3_i16_97_199_bytes",
        ),
    ] {
        let decoded = decodes_as_recorded(name, None, samples);
        assert_eq!(decoded.header.coder, coder, "{name} coder");
    }
}

#[test]
fn new_files_say_coder_4_and_decode_exactly() {
    let file = fixture("i16_nodata_georef_lossless.ezw");
    let old = decode(&file, &DecodeOptions::default()).unwrap();
    let options = wavemesh_codec::EncodeOptions::new(wavemesh_codec::Quality::Lossless, None);
    let new = wavemesh_codec::encode(&old.raster, &options).unwrap();
    let redecoded = decode(&new.bytes, &DecodeOptions::default()).unwrap();
    assert_eq!(redecoded.header.coder, Coder::V4);
    assert_eq!(redecoded.raster, old.raster);
    assert_ne!(new.bytes, file, "coder 4 makes other bytes");
}

/// A lossless float file of coder 4 written before flag 16 (commit ba84cf1: residual
/// lengths modelled by the residual before), the samples of `f32_nan_lossless`, decodes
/// to them; a new file of the same samples says flag 16 and decodes to them too.
#[test]
fn float_residuals_of_both_length_models_decode_exactly() {
    let decoded = fixture("f32_nan_lossless.decoded");
    let file = fixture("coder4_f32_nan_lossless.ezw");
    let old = decode(&file, &DecodeOptions::default()).unwrap();
    assert_eq!(old.header.coder, Coder::V4);
    assert!(old.header.residual_len > 0 && !old.header.residuals_by_exponent);
    assert_eq!(raw(&old.raster.samples), decoded);
    let options = wavemesh_codec::EncodeOptions::new(wavemesh_codec::Quality::Lossless, None);
    let new = wavemesh_codec::encode(&old.raster, &options).unwrap();
    let redecoded = decode(&new.bytes, &DecodeOptions::default()).unwrap();
    assert!(redecoded.header.residuals_by_exponent);
    assert_eq!(raw(&redecoded.raster.samples), decoded);
}

/// Tiled files written before tiles overlapped (commit 0603092: no overlap field, flag 9
/// clear), 120 × 90 synthetic terrain in 6 tiles of 40 × 45, decode to what that
/// decoder made of them: lossless whole and at a 1500-byte budget, and a 9/7 file cut
/// at 2 bpp. (The budget's decode is re-recorded since budgets are allocated over
/// modelled passes, `TileEntry::modelled_points`: RMSE against the lossless decode 1.660
/// before, 1.633 after.)
#[test]
fn tiled_files_without_overlap_decode_to_their_recorded_samples() {
    let cases = [
        ("tiled_i16_lossless", None, "tiled_i16_lossless"),
        (
            "tiled_i16_lossless",
            Some(1500),
            "tiled_i16_lossless.prefix1500",
        ),
        ("tiled_i16_97_2bpp", None, "tiled_i16_97_2bpp"),
    ];
    tiled_fixtures_decode(&cases, (40, 45, 0));
}

/// Each tiled fixture `(file, budget, decoded)` decodes at that budget to the recorded
/// samples, its tiles and overlap as given.
fn tiled_fixtures_decode(cases: &[(&str, Option<u64>, &str)], grid: (u32, u32, u32)) {
    for &(name, budget, decoded) in cases {
        let out = decodes_as_recorded(name, budget, decoded);
        let tiling = out.header.tiling.expect("a tiled file");
        assert_eq!(
            (tiling.tile_width, tiling.tile_height, tiling.overlap),
            grid
        );
    }
}

/// f32 files in the layout before the valid range moved to the ladder and the
/// correction step could be implied (commit 8f9cbe0, coder 3): 9/7 max-error streams
/// with corrections (NaN voids; on a 0.1 grid) and a 9/7 stream cut at 2 bpp.
#[test]
fn f32_fixtures_of_the_range_in_header_layout_decode_to_their_recorded_samples() {
    for (name, mode, correction_step) in [
        ("f32_nan_max_error_2", Mode::MaxError, 3.996),
        ("f32_grid_max_error_0.25", Mode::MaxError, 0.4995),
        ("f32_nan_97_2bpp", Mode::Lossy, 0.0),
    ] {
        let decoded = decode(&fixture(&format!("{name}.ezw")), &DecodeOptions::default()).unwrap();
        assert_eq!(decoded.header.mode, mode, "{name} mode");
        assert_eq!(decoded.header.correction_step, correction_step, "{name}");
        let (min, max) = decoded.header.valid_range;
        assert!(min.is_finite() && min < max, "{name} range {min} .. {max}");
        assert!(decoded.complete && decoded.damage.is_none(), "{name}");
        assert_eq!(
            raw(&decoded.raster.samples),
            fixture(&format!("{name}.decoded")),
            "{name} samples"
        );
    }
}

/// Tiled files written before tiles had compact headers (commit 732b23a: overlapping
/// tiles, each a whole single-stream file with magic, size and ladder), from the same
/// 120 × 90 terrain in 6 tiles of 40 × 30: lossless whole and at a 1500-byte budget, and
/// a 9/7 file cut at 2 bpp.
#[test]
fn tiled_files_of_whole_tile_streams_decode_to_their_recorded_samples() {
    let cases = [
        ("tiled_overlap_i16_lossless", None, "tiled_i16_lossless"),
        (
            "tiled_overlap_i16_lossless",
            Some(1500),
            "tiled_overlap_i16_lossless.prefix1500",
        ),
        (
            "tiled_overlap_i16_97_2bpp",
            None,
            "tiled_overlap_i16_97_2bpp",
        ),
    ];
    tiled_fixtures_decode(&cases, (40, 30, 2));
}

/// Files whose tiles are cut into code blocks (flag 15, first written by commit
/// aa04d6a's encoder, as of the overlapping tiles and joined slivers of the same stop),
/// from the same 120 × 90 terrain: lossless in one tile of 64² blocks, whole (the terrain
/// itself) and at a 1500-byte budget, and a 9/7 file cut at 2 bpp in four tiles of one
/// block each, overlapping by two samples.
#[test]
fn code_block_files_decode_to_their_recorded_samples() {
    let cases = [
        ("blocks_i16_lossless", None, "tiled_i16_lossless", (120, 90)),
        (
            "blocks_i16_lossless",
            Some(1500),
            "blocks_i16_lossless.prefix1500",
            (120, 90),
        ),
        ("blocks_i16_97_2bpp", None, "blocks_i16_97_2bpp", (64, 64)),
    ];
    for (name, budget, decoded, tile) in cases {
        let out = decodes_as_recorded(name, budget, decoded);
        let tiling = out.header.tiling.expect("a tiled file");
        assert_eq!((tiling.tile_width, tiling.tile_height), tile, "{name}");
        assert_eq!(tiling.code_block, Some(64), "{name}");
    }
}

/// A 13/11 file (wavelet code 3, first written by this stop's encoder): the 120 × 90
/// terrain of the code-block fixtures, lossless in one stream, whole and at 1500 bytes.
#[test]
fn a_13_11_file_decodes_to_its_recorded_samples() {
    let name = "int1311_i16_lossless";
    let whole = decodes_as_recorded(name, None, "tiled_i16_lossless");
    assert_eq!(whole.header.wavelet, Wavelet::Int1311);
    assert!(whole.complete);
    let prefix = decodes_as_recorded(name, Some(1500), "int1311_i16_lossless.prefix1500");
    assert!(!prefix.complete);
}
