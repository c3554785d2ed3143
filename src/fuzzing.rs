//! Fuzzing harness for the DEM readers: the check behind the `read_*` `cargo fuzz` targets
//! in `fuzz/`, kept here so the same function replays every saved crash input on stable
//! (`tests/fuzz_regressions.rs`).
//!
//! The readers are private to [`crate::dem`] and read from files, so the harness writes
//! the bytes to a temporary file (in [`std::env::temp_dir`]; point `TMPDIR` at a RAM disk
//! such as `/dev/shm` for speed) with the format's extension and calls
//! [`read_dem`] on it.

use std::io::Write;

use crate::dem::{read_dem, DemFormat, ReadOptions, WorkMemory};

/// The largest raster the harness lets a reader allocate.
pub const FUZZ_MAX_SAMPLES: u64 = 1 << 20;

/// The memory budget the harness gives a read: binding before the sample limit for
/// 16- and 32-bit samples, so both checks are fuzzed.
pub const FUZZ_MAX_MEMORY: u64 = 3 << 20;

/// The working memory per sample the harness declares beside the raster.
const FUZZ_WORK: WorkMemory = WorkMemory {
    integer: 1,
    float: 2,
};

/// Reads `data` as a DEM file of `format`; must never panic.
///
/// The file gets the format's extension (`.tif`, `.png`, `.hgt`, `.asc`; Terrain-RGB is a
/// `.png` read with [`ReadOptions::terrain_rgb`]); `.hgt` files are named after a tile
/// (`N36W084…`, `S01E180…` or no tile, chosen by the data's length) so the georeferencing
/// from the name is exercised too. Format detection looks at the magic bytes first, so a
/// `.png` input starting with a TIFF signature is read as a TIFF: every reader is reachable
/// from every target, which is fine.
///
/// Options: `max_samples` = [`FUZZ_MAX_SAMPLES`], `max_memory` = [`FUZZ_MAX_MEMORY`].
/// An `Ok` raster must be consistent: positive sides, `width × height` samples, within
/// both limits, and a Terrain-RGB read gives `f32` samples.
#[doc(hidden)]
pub fn read_arbitrary(data: &[u8], format: DemFormat) {
    let (prefix, suffix) = match format {
        DemFormat::GeoTiff => ("fuzz", ".tif"),
        DemFormat::Png | DemFormat::TerrainRgb => ("fuzz", ".png"),
        DemFormat::Asc => ("fuzz", ".asc"),
        DemFormat::Hgt => (["N36W084", "S01E180", "fuzz"][data.len() % 3], ".hgt"),
    };
    let mut file = tempfile::Builder::new()
        .prefix(prefix)
        .suffix(suffix)
        .tempfile()
        .expect("create a temporary file");
    file.write_all(data).expect("write the temporary file");
    file.flush().expect("flush the temporary file");
    let options = ReadOptions {
        terrain_rgb: format == DemFormat::TerrainRgb,
        max_samples: FUZZ_MAX_SAMPLES,
        max_memory: FUZZ_MAX_MEMORY,
        work: FUZZ_WORK,
        // Fuzz every decoder the readers reach, the lossy ones too.
        accept_lossy: true,
    };
    let Ok(raster) = read_dem(file.path(), &options) else {
        return;
    };
    assert!(
        raster.width > 0 && raster.height > 0,
        "{} x {} raster",
        raster.width,
        raster.height
    );
    assert_eq!(
        raster.samples.len(),
        raster.width * raster.height,
        "{} x {} raster holds {} samples",
        raster.width,
        raster.height,
        raster.samples.len()
    );
    assert!(
        raster.samples.len() as u64 <= FUZZ_MAX_SAMPLES,
        "{} samples read past the limit of {FUZZ_MAX_SAMPLES}",
        raster.samples.len()
    );
    let work = match raster.sample_type() {
        wavemesh_codec::SampleType::F32 => FUZZ_WORK.float,
        _ => FUZZ_WORK.integer,
    };
    let bytes = raster.samples.len() as u64 * (raster.sample_type().bytes() as u64 + work);
    assert!(
        bytes <= FUZZ_MAX_MEMORY,
        "{bytes} bytes read past the memory limit of {FUZZ_MAX_MEMORY}"
    );
    if format == DemFormat::TerrainRgb {
        assert_eq!(
            raster.sample_type(),
            wavemesh_codec::SampleType::F32,
            "Terrain-RGB gives f32 heights"
        );
    }
}
