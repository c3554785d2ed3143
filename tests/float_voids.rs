//! Issue 8 item 3: lossless floats off any value grid with large NaN areas. The shared
//! float DEM (`srtm3_utm32_f32`) as it is and with NaN over 55 % and 79 % of its grid in
//! the shapes of coasts, bays and lakes (a smooth random field cut at a quantile: long
//! waves for a smooth coast, shorter ones for a ragged one), and with its sea flooded
//! (NaN wherever the heights are at or below the level that leaves 79 %: every sample of
//! the sea), coded bit-exactly and set against what GDAL's lossless float settings make
//! of the same raster (`gdal_translate`, when it is on `PATH`): GeoTIFF ZSTD level 19
//! with the floating-point predictor (`PREDICTOR=3`) in 256² and 512² tiles, and
//! LERC_ZSTD with `MAX_Z_ERROR=0` in 512² tiles. Today wavemesh is the smallest in all six
//! cases, 0.5 % under LERC_ZSTD on the ragged coast at 79 % (79559 against 79924 bytes;
//! 83404, +4.4 %, before residual lengths went by exponent; printed with
//! `--nocapture`); the test holds every case within 5 % of the best, against
//! regressions.

mod support;

use std::path::Path;
use std::process::Command;

use wavemesh::dem::{read_dem, write_dem, ReadOptions};
use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, Samples};

/// A smooth field of a few dozen waves (wavelengths `shortest`–`longest` samples, fixed
/// seed).
fn field(width: usize, height: usize, (shortest, longest): (f64, f64)) -> Vec<f64> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let waves: Vec<(f64, f64, f64, f64)> = (0..40)
        .map(|_| {
            let wavelength = shortest * (longest / shortest).powf(uniform());
            let angle = uniform() * std::f64::consts::TAU;
            let k = std::f64::consts::TAU / wavelength;
            (
                k * angle.cos(),
                k * angle.sin(),
                uniform() * 6.3,
                wavelength.powf(0.9),
            )
        })
        .collect();
    (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            waves
                .iter()
                .map(|&(kx, ky, phase, amplitude)| amplitude * (kx * x + ky * y + phase).sin())
                .sum()
        })
        .collect()
}

/// The raster's own heights as the field: flooding it leaves the land above a level.
fn heights(raster: &Raster) -> Vec<f64> {
    (0..raster.len())
        .map(|i| raster.samples.get_f64(i))
        .collect()
}

/// `raster` with NaN where `field` is at or below the level that leaves `fraction` of
/// the grid NaN (its own voids included; more where many samples share that level); as
/// it is for 0.
fn flooded(raster: &Raster, field: &[f64], fraction: f64) -> Raster {
    if fraction == 0.0 {
        return raster.clone();
    }
    let mut sorted: Vec<f64> = (0..raster.len())
        .filter(|&i| raster.is_valid(i))
        .map(|i| field[i])
        .collect();
    sorted.sort_by(f64::total_cmp);
    let own = raster.len() - sorted.len();
    let extra = ((fraction * raster.len() as f64) as usize).saturating_sub(own);
    let level = sorted[extra.min(sorted.len() - 1)];
    let Samples::F32(values) = &raster.samples else {
        panic!("a float DEM")
    };
    let values = values
        .iter()
        .zip(field)
        .map(|(&v, &f)| if f <= level { f32::NAN } else { v })
        .collect();
    let mut out = Raster::new(raster.width, raster.height, Samples::F32(values)).unwrap();
    out.nodata = raster.nodata;
    out.georef = raster.georef.clone();
    out
}

/// What GDAL makes of `tif` with each of the peers' lossless settings: (name, bytes).
fn peers(gdal: &Path, tif: &Path) -> Vec<(&'static str, u64)> {
    const SETTINGS: [(&str, &str); 3] = [
        (
            "GeoTIFF ZSTD+predictor 256²",
            "COMPRESS=ZSTD ZSTD_LEVEL=19 PREDICTOR=3 BLOCKXSIZE=256 BLOCKYSIZE=256",
        ),
        (
            "GeoTIFF ZSTD+predictor 512²",
            "COMPRESS=ZSTD ZSTD_LEVEL=19 PREDICTOR=3 BLOCKXSIZE=512 BLOCKYSIZE=512",
        ),
        (
            "LERC_ZSTD 512²",
            "COMPRESS=LERC_ZSTD MAX_Z_ERROR=0 ZSTD_LEVEL=19 BLOCKXSIZE=512 BLOCKYSIZE=512",
        ),
    ];
    SETTINGS
        .iter()
        .enumerate()
        .map(|(k, &(name, options))| {
            let out = tif.with_extension(format!("peer{k}.tif"));
            let mut command = Command::new(gdal);
            command.args(["-q", "-co", "TILED=YES"]);
            for option in options.split(' ') {
                command.args(["-co", option]);
            }
            let status = command.arg(tif).arg(&out).status().unwrap();
            assert!(status.success(), "gdal_translate {options}");
            (name, std::fs::metadata(&out).unwrap().len())
        })
        .collect()
}

/// Whether every sample of `b` is `a`'s, bit for bit (any NaN for a NaN).
fn bit_exact(a: &Samples, b: &Samples) -> bool {
    let (Samples::F32(a), Samples::F32(b)) = (a, b) else {
        return false;
    };
    a.iter()
        .zip(b)
        .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

#[test]
fn floats_with_large_nan_areas_are_exact_and_compact() {
    let test = "floats_with_large_nan_areas_are_exact_and_compact";
    let Some(dir) = support::shared_dem(test) else {
        return;
    };
    let raster = read_dem(
        &dir.join("srtm3_utm32_f32/srtm3_utm32_f32.tif"),
        &ReadOptions::default(),
    )
    .unwrap();
    let (width, height) = (raster.width, raster.height);
    let cases = [
        ("smooth coast", field(width, height, (150.0, 1500.0)), 0.55),
        ("smooth coast", field(width, height, (150.0, 1500.0)), 0.79),
        ("ragged coast", field(width, height, (40.0, 700.0)), 0.55),
        ("ragged coast", field(width, height, (40.0, 700.0)), 0.79),
        ("sea flooded", heights(&raster), 0.79),
        ("as shared", heights(&raster), 0.0),
    ];
    let gdal = support::program(test, "gdal_translate", "GDAL");
    let scratch = support::scratch("float_voids");
    for (k, (shape, field, fraction)) in cases.iter().enumerate() {
        let masked = flooded(&raster, field, *fraction);
        let nan = (0..masked.len()).filter(|&i| !masked.is_valid(i)).count();
        let encoded = encode(&masked, &EncodeOptions::new(Quality::Lossless, None)).unwrap();
        let decoded = decode(&encoded.bytes, &DecodeOptions::default())
            .unwrap()
            .raster;
        assert!(
            bit_exact(&masked.samples, &decoded.samples),
            "{shape}: not bit-exact"
        );
        let bytes = encoded.bytes.len() as u64;
        let mut line = format!(
            "{shape}, {:.1} % NaN: wavemesh {bytes} bytes",
            100.0 * nan as f64 / masked.len() as f64
        );
        if let Some(gdal) = &gdal {
            let tif = scratch.path().join(format!("masked{k}.tif"));
            write_dem(&tif, &masked).unwrap();
            let peers = peers(gdal, &tif);
            for (name, size) in &peers {
                line += &format!(
                    "; {name} {size} ({:+.1} %)",
                    100.0 * (bytes as f64 / *size as f64 - 1.0)
                );
            }
            let best = peers.iter().map(|p| p.1).min().unwrap();
            assert!(bytes * 100 <= best * 105, "{line}");
        }
        eprintln!("{line}");
    }
}
