//! Error metrics between an original DEM and a reconstruction, as defined project-wide:
//! R = max − min of the original valid samples; RMSE over valid samples;
//! PSNR = 20·log10(R / RMSE) dB; max error in data units.

use serde::Serialize;
use wavemesh_codec::Raster;

/// Distortion of a reconstruction against its original.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Distortion {
    /// Valid samples compared (valid in the original).
    pub valid_samples: u64,
    /// Samples valid in the original but nodata in the reconstruction, or the reverse.
    pub nodata_mismatches: u64,
    /// Max − min of the original's valid samples.
    pub range: f64,
    /// Root mean squared error, data units.
    pub rmse: f64,
    /// Peak signal-to-noise ratio in dB (`inf` when identical).
    pub psnr_db: f64,
    /// Largest absolute error, data units.
    pub max_error: f64,
    /// Whether every sample is bit-identical (nodata positions included).
    pub identical: bool,
}

/// Why two rasters cannot be compared.
#[derive(Debug, thiserror::Error)]
#[error("cannot compare a {0}x{1} raster with a {2}x{3} one")]
pub struct SizeMismatch(pub usize, pub usize, pub usize, pub usize);

/// Compares `decoded` with `original` sample by sample.
pub fn compare(original: &Raster, decoded: &Raster) -> Result<Distortion, SizeMismatch> {
    if original.width != decoded.width || original.height != decoded.height {
        return Err(SizeMismatch(
            original.width,
            original.height,
            decoded.width,
            decoded.height,
        ));
    }
    let mut valid_samples = 0u64;
    let mut nodata_mismatches = 0u64;
    let mut sum_sq = 0.0f64;
    let mut max_error = 0.0f64;
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut identical = original.samples.sample_type() == decoded.samples.sample_type();
    for i in 0..original.len() {
        let a = original.samples.get_f64(i);
        let b = decoded.samples.get_f64(i);
        if identical && a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan()) {
            identical = false;
        }
        let valid_a = original.is_valid(i);
        let valid_b = decoded.is_valid(i);
        if valid_a != valid_b {
            nodata_mismatches += 1;
        }
        if !valid_a {
            continue;
        }
        valid_samples += 1;
        lo = lo.min(a);
        hi = hi.max(a);
        if valid_b {
            let e = (a - b).abs();
            sum_sq += e * e;
            max_error = max_error.max(e);
        }
    }
    let range = if valid_samples > 0 { hi - lo } else { 0.0 };
    let rmse = if valid_samples > 0 {
        (sum_sq / valid_samples as f64).sqrt()
    } else {
        0.0
    };
    Ok(Distortion {
        valid_samples,
        nodata_mismatches,
        range,
        rmse,
        psnr_db: psnr(range, rmse),
        max_error,
        identical,
    })
}

/// PSNR in dB from range and RMSE (`inf` for zero error).
pub fn psnr(range: f64, rmse: f64) -> f64 {
    if rmse == 0.0 {
        f64::INFINITY
    } else {
        20.0 * (range / rmse).log10()
    }
}

/// Bits per sample of `bytes` over a `width × height` raster.
pub fn bits_per_sample(bytes: u64, width: usize, height: usize) -> f64 {
    bytes as f64 * 8.0 / (width as f64 * height as f64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use wavemesh_codec::Samples;

    #[test]
    fn known_values() {
        let a = Raster::new(4, 1, Samples::I16(vec![0, 10, 20, 100])).unwrap();
        let b = Raster::new(4, 1, Samples::I16(vec![1, 10, 17, 100])).unwrap();
        let d = compare(&a, &b).unwrap();
        assert_eq!(d.range, 100.0);
        assert_eq!(d.max_error, 3.0);
        assert!((d.rmse - (10.0f64 / 4.0).sqrt()).abs() < 1e-12);
        assert!((d.psnr_db - 20.0 * (100.0 / d.rmse).log10()).abs() < 1e-9);
        assert!(!d.identical);
        assert!(compare(&a, &a).unwrap().identical);
        assert_eq!(compare(&a, &a).unwrap().psnr_db, f64::INFINITY);
    }

    #[test]
    fn nodata_is_excluded_and_mismatches_counted() {
        let mut a = Raster::new(3, 1, Samples::I16(vec![5, -32768, 9])).unwrap();
        a.nodata = Some(-32768.0);
        let mut b = Raster::new(3, 1, Samples::I16(vec![5, -32768, -32768])).unwrap();
        b.nodata = Some(-32768.0);
        let d = compare(&a, &b).unwrap();
        assert_eq!(d.valid_samples, 2);
        assert_eq!(d.nodata_mismatches, 1);
        assert_eq!(d.range, 4.0);
    }

    #[test]
    fn size_mismatch_is_an_error() {
        let a = Raster::new(2, 1, Samples::U8(vec![1, 2])).unwrap();
        let b = Raster::new(1, 2, Samples::U8(vec![1, 2])).unwrap();
        assert!(compare(&a, &b).is_err());
    }
}
