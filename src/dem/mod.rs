//! Reading and writing DEM files.
//!
//! Readers: single-band GeoTIFF ([`DemFormat::GeoTiff`]), 8/16-bit grayscale PNG
//! ([`DemFormat::Png`]), Mapbox Terrain-RGB PNG ([`DemFormat::TerrainRgb`]), SRTM `.hgt`
//! ([`DemFormat::Hgt`]) and ESRI ASCII grids ([`DemFormat::Asc`]). [`read_dem`] picks the
//! format from the file's first bytes, then from its extension.
//!
//! Writers: GeoTIFF, grayscale PNG and ESRI ASCII grid, chosen by [`write_dem`] from the
//! extension and always written atomically (see [`crate::atomic::write_atomic`]).
//!
//! Streaming, for rasters larger than memory: [`RowBands`] reads a DEM by bands of rows
//! (a GeoTIFF from the strips or tiles the band touches only), and
//! [`TiledGeoTiffWriter`] writes a tiled GeoTIFF by bands (one row of tiles in memory) or
//! by blocks of whole tiles.

mod asc;
mod bands;
mod gdal_metadata;
mod geotiff;
mod hgt;
mod png;
mod side_files;
mod terrain_rgb;
mod tiff_chunks;
mod tiled_writer;

pub use bands::{DemInfo, RowBands, BLOCK_WIDTH};
pub use tiled_writer::TiledGeoTiffWriter;

use std::fs::File;
use std::io::{self, BufRead, BufReader};
use std::path::{Path, PathBuf};

use wavemesh_codec::{Limits, Raster, SampleType, Samples};

use crate::atomic::write_atomic;

/// The CRS as GeoKeys and back: the EPSG code a GeoKey directory names, and the
/// GeoKeys of a WKT that names its EPSG code (used by the Python package's `crs=`).
pub use side_files::{epsg_code, keys_from_wkt};

/// Everything that can go wrong reading or writing a DEM file, split by cause.
#[derive(Debug, thiserror::Error)]
pub enum DemError {
    /// The file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// The file's format could not be recognised from its first bytes or its extension.
    #[error(
        "{}: unknown DEM format; expected a GeoTIFF, a PNG, an SRTM .hgt or an ESRI ASCII .asc file",
        path.display()
    )]
    UnknownFormat {
        /// The file involved.
        path: PathBuf,
    },
    /// The file is valid but uses a feature, layout or sample type this crate does not handle.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// The file does not follow its format (bad header, truncated data, bad tokens...).
    #[error("malformed file: {0}")]
    Malformed(String),
    /// The raster is larger than [`ReadOptions::max_samples`] allows.
    #[error(
        "raster of {width} x {height} = {} samples exceeds the limit of {limit} samples",
        u128::from(*width) * u128::from(*height)
    )]
    TooLarge {
        /// Width the file claims.
        width: u64,
        /// Height the file claims.
        height: u64,
        /// The configured limit on `width × height`.
        limit: u64,
    },
    /// Reading the raster and the work after it would take more than
    /// [`ReadOptions::max_memory`] bytes.
    #[error(
        "raster of {width} x {height} {sample_type} samples needs about {needed} bytes of \
         memory, more than the limit of {limit} bytes"
    )]
    OverMemory {
        /// Width the file claims.
        width: u64,
        /// Height the file claims.
        height: u64,
        /// The sample type the memory was counted for.
        sample_type: &'static str,
        /// Bytes the raster and the caller's work on it need.
        needed: u128,
        /// The configured limit.
        limit: u64,
    },
    /// The file's samples went through lossy compression (JPEG...): reading them back is
    /// not exact, so a "lossless" encoding would only be exact against this reader.
    #[error("{0}")]
    LossyInput(String),
    /// The raster handed to a writer is inconsistent (sample count ≠ width × height).
    #[error("invalid raster: {0}")]
    InvalidRaster(String),
    /// A band of rows and what the reader keeps beside it (one row of TIFF chunks, or the
    /// whole raster for formats read whole) exceed [`ReadOptions::max_samples`] or
    /// [`ReadOptions::max_memory`].
    #[error(
        "a band of {rows} rows of {width} samples, plus the {kept} samples the reader keeps \
         (one row of chunks), needs {needed} {unit}, more than the limit of {limit} {unit}"
    )]
    BandOverLimit {
        /// Columns of the band.
        width: u64,
        /// Rows of the band.
        rows: u64,
        /// Samples the reader holds besides the band.
        kept: u64,
        /// Samples or bytes needed.
        needed: u128,
        /// The configured limit.
        limit: u64,
        /// `samples` or `bytes`.
        unit: &'static str,
    },
    /// A window asked for that is empty or not inside the raster.
    #[error(
        "window {}x{} at ({}, {}) asked for, but the raster is {width}x{height}",
        window.2, window.3, window.0, window.1
    )]
    WindowOutOfRange {
        /// The window: x, y, width, height.
        window: (usize, usize, usize, usize),
        /// Columns of the raster.
        width: usize,
        /// Rows of the raster.
        height: usize,
    },
}

impl DemError {
    /// Prefixes the message of path-less variants with `path`.
    fn in_file(self, path: &Path) -> DemError {
        match self {
            DemError::Unsupported(m) => DemError::Unsupported(format!("{}: {m}", path.display())),
            DemError::Malformed(m) => DemError::Malformed(format!("{}: {m}", path.display())),
            other => other,
        }
    }
}

/// Turns an I/O error while reading `path` into a [`DemError`]: an unexpected end of file
/// becomes [`DemError::Malformed`] (the file is truncated), anything else [`DemError::Io`].
fn read_error(path: &Path, source: io::Error) -> DemError {
    if source.kind() == io::ErrorKind::UnexpectedEof {
        DemError::Malformed("file ends before the data is complete (truncated?)".into())
    } else {
        DemError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// Memory the caller will need per sample after reading, besides the raster itself.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WorkMemory {
    /// Bytes a sample for integer rasters.
    pub integer: u64,
    /// Bytes a sample for floating-point rasters.
    pub float: u64,
}

/// Options for [`read_dem`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadOptions {
    /// Decode RGB(A) PNGs as Mapbox Terrain-RGB (`h = -10000 + (R·65536 + G·256 + B)·0.1`).
    pub terrain_rgb: bool,
    /// Largest accepted `width × height`; checked before any sample buffer is allocated.
    pub max_samples: u64,
    /// Largest memory (bytes) the raster plus `work` may take: `width × height ×
    /// (sample bytes + work bytes)`, checked from the declared size before any sample
    /// buffer is allocated (a small compressed file can declare a huge raster).
    pub max_memory: u64,
    /// What the caller allocates per sample once the raster is read (0 to just read).
    pub work: WorkMemory,
    /// Accept samples that went through lossy compression (JPEG-in-TIFF...).
    pub accept_lossy: bool,
}

impl Default for ReadOptions {
    fn default() -> ReadOptions {
        ReadOptions {
            terrain_rgb: false,
            max_samples: Limits::DEFAULT.max_samples,
            max_memory: Limits::DEFAULT.max_memory,
            work: WorkMemory::default(),
            accept_lossy: false,
        }
    }
}

/// Checks claimed dimensions against `options.max_samples` and, for samples of
/// `sample_type`, the memory against `options.max_memory`; returns the sample count.
fn checked_sample_count(
    width: u64,
    height: u64,
    sample_type: SampleType,
    options: &ReadOptions,
) -> Result<usize, DemError> {
    if width == 0 || height == 0 {
        return Err(DemError::Malformed(format!(
            "raster is {width} x {height}; expected a positive width and height"
        )));
    }
    let too_large = DemError::TooLarge {
        width,
        height,
        limit: options.max_samples,
    };
    let count = match width.checked_mul(height) {
        Some(n) if n <= options.max_samples => usize::try_from(n).map_err(|_| too_large)?,
        _ => return Err(too_large),
    };
    let work = match sample_type {
        SampleType::F32 => options.work.float,
        _ => options.work.integer,
    };
    let needed = count as u128 * (sample_type.bytes() as u128 + u128::from(work));
    if needed > u128::from(options.max_memory) {
        return Err(DemError::OverMemory {
            width,
            height,
            sample_type: sample_type.name(),
            needed,
            limit: options.max_memory,
        });
    }
    Ok(count)
}

/// Builds a raster from decoded samples whose count the reader has already checked.
fn make_raster(width: usize, height: usize, samples: Samples) -> Result<Raster, DemError> {
    Raster::new(width, height, samples).map_err(|e| DemError::Malformed(e.to_string()))
}

/// A DEM file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DemFormat {
    /// TIFF / GeoTIFF, single band (`.tif`, `.tiff`).
    GeoTiff,
    /// 8- or 16-bit grayscale PNG (`.png`).
    Png,
    /// Mapbox Terrain-RGB PNG, selected by [`ReadOptions::terrain_rgb`].
    TerrainRgb,
    /// SRTM `.hgt` tile: big-endian `i16`, square, no header.
    Hgt,
    /// ESRI ASCII grid (`.asc`).
    Asc,
}

impl DemFormat {
    /// Human-readable name of the format.
    pub fn name(self) -> &'static str {
        match self {
            DemFormat::GeoTiff => "GeoTIFF",
            DemFormat::Png => "grayscale PNG",
            DemFormat::TerrainRgb => "Terrain-RGB PNG",
            DemFormat::Hgt => "SRTM .hgt",
            DemFormat::Asc => "ESRI ASCII grid",
        }
    }
}

const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
const TIFF_SIGNATURES: [&[u8]; 4] = [b"II*\0", b"MM\0*", b"II+\0", b"MM\0+"];

/// Lower-cased extension of `path`, empty when there is none.
fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// Decides the format of `path` from its first bytes (magic numbers: TIFF, PNG, an ESRI
/// ASCII header keyword), then from its extension (`.hgt` has no magic).
///
/// With `options.terrain_rgb` the file must be a PNG, read as [`DemFormat::TerrainRgb`].
pub fn detect_format(
    path: &Path,
    first_bytes: &[u8],
    options: &ReadOptions,
) -> Result<DemFormat, DemError> {
    let ext = extension(path);
    let format = if TIFF_SIGNATURES.iter().any(|s| first_bytes.starts_with(s)) {
        DemFormat::GeoTiff
    } else if first_bytes.starts_with(PNG_SIGNATURE) {
        DemFormat::Png
    } else if asc::looks_like_header(first_bytes) || ext == "asc" {
        DemFormat::Asc
    } else if ext == "hgt" {
        DemFormat::Hgt
    } else if matches!(ext.as_str(), "tif" | "tiff" | "png") {
        return Err(DemError::Malformed(format!(
            "{}: the .{ext} extension promises a {} file but it does not start with its signature",
            path.display(),
            if ext == "png" { "PNG" } else { "TIFF" }
        )));
    } else {
        return Err(DemError::UnknownFormat {
            path: path.to_path_buf(),
        });
    };
    match (format, options.terrain_rgb) {
        (DemFormat::Png, true) => Ok(DemFormat::TerrainRgb),
        (other, true) => Err(DemError::Unsupported(format!(
            "{}: Terrain-RGB decoding needs an RGB PNG, but this is a {}",
            path.display(),
            other.name()
        ))),
        (other, false) => Ok(other),
    }
}

/// Reads a DEM file, choosing the format with [`detect_format`].
///
/// The raster size is checked against `options.max_samples` before sample buffers are
/// allocated. Errors name the file; no input makes this panic.
pub fn read_dem(path: &Path, options: &ReadOptions) -> Result<Raster, DemError> {
    let (reader, len, format) = open_detected(path, options)?;
    let result = match format {
        DemFormat::GeoTiff => geotiff::read(reader, path, options),
        DemFormat::Png => png::read(reader, path, options),
        DemFormat::TerrainRgb => terrain_rgb::read(reader, path, options),
        DemFormat::Hgt => hgt::read(reader, len, path, options),
        DemFormat::Asc => asc::read(reader, path, options),
    };
    result.map_err(|e| e.in_file(path))
}

/// A DEM file opened for reading.
type SourceFile = BufReader<File>;

/// Opens `path` and detects its format: the buffered file, its length and the format.
fn open_detected(
    path: &Path,
    options: &ReadOptions,
) -> Result<(SourceFile, u64, DemFormat), DemError> {
    let file = File::open(path).map_err(|e| read_error(path, e))?;
    let len = file.metadata().map_err(|e| read_error(path, e))?.len();
    let mut reader = BufReader::new(file);
    let head = reader.fill_buf().map_err(|e| read_error(path, e))?.to_vec();
    let format = detect_format(path, &head, options)?;
    Ok((reader, len, format))
}

/// Writes `raster` to `path` atomically, in the format given by the extension:
/// `.tif`/`.tiff` (GeoTIFF), `.png` (grayscale PNG) or `.asc` (ESRI ASCII grid); GeoTIFF
/// to `-` (standard output), a device or a FIFO without an extension.
///
/// Rasters a format cannot hold (float or negative samples in PNG, a rotated
/// geotransform in `.asc`) are refused with [`DemError::Unsupported`] before anything is
/// written.
pub fn write_dem(path: &Path, raster: &Raster) -> Result<(), DemError> {
    write_by_extension(path, raster).map_err(|e| e.in_file(path))
}

/// Whether [`write_dem`] writes `path` as a GeoTIFF (by its extension).
pub fn is_geotiff_path(path: &Path) -> bool {
    matches!(output_extension(path).as_str(), "tif" | "tiff")
}

/// [`write_dem`] without the file name in the error messages.
fn write_by_extension(path: &Path, raster: &Raster) -> Result<(), DemError> {
    check_raster(raster)?;
    let io_error = |source| DemError::Io {
        path: path.to_path_buf(),
        source,
    };
    match output_extension(path).as_str() {
        "tif" | "tiff" => {
            let bytes = geotiff::encode(raster)?;
            write_atomic(path, |w| w.write_all(&bytes)).map_err(io_error)
        }
        "png" => {
            let bytes = png::encode(raster)?;
            write_atomic(path, |w| w.write_all(&bytes)).map_err(io_error)?;
            side_files::write_png_side_files(path, raster)
        }
        "asc" => {
            asc::check_writable(raster)?;
            write_atomic(path, |w| asc::write(raster, w)).map_err(io_error)?;
            side_files::write_prj(path, raster)
        }
        other => Err(DemError::Unsupported(format!(
            "cannot write '.{other}' files; expected a .tif, .tiff, .png or .asc extension"
        ))),
    }
}

/// The extension that picks the output format: a stream without one (`-`, a device, a
/// FIFO) gets GeoTIFF, the format that carries everything.
fn output_extension(path: &Path) -> String {
    let ext = extension(path);
    let is_stream = crate::atomic::destination(path).is_ok_and(|d| d.is_stream());
    if ext.is_empty() && is_stream {
        "tif".into()
    } else {
        ext
    }
}

/// Checks that a raster handed to a writer is self-consistent.
fn check_raster(raster: &Raster) -> Result<(), DemError> {
    let expected = raster.width.checked_mul(raster.height);
    if raster.width == 0 || raster.height == 0 || expected != Some(raster.samples.len()) {
        return Err(DemError::InvalidRaster(format!(
            "{} x {} raster holds {} samples; expected width x height, both positive",
            raster.width,
            raster.height,
            raster.samples.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use wavemesh_codec::Georef;

    fn opts() -> ReadOptions {
        ReadOptions::default()
    }

    #[test]
    fn default_options() {
        let o = ReadOptions::default();
        assert!(!o.terrain_rgb);
        assert_eq!(o.max_samples, 1 << 31);
    }

    #[test]
    fn detects_by_magic_then_extension() {
        let p = Path::new;
        let d = |path: &str, head: &[u8]| detect_format(p(path), head, &opts());
        assert_eq!(d("x.bin", b"II*\0rest").unwrap(), DemFormat::GeoTiff);
        assert_eq!(d("x.png", b"MM\0*").unwrap(), DemFormat::GeoTiff);
        assert_eq!(d("x", PNG_SIGNATURE).unwrap(), DemFormat::Png);
        assert_eq!(d("x.dat", b"NCOLS 3\nNROWS 2\n").unwrap(), DemFormat::Asc);
        assert_eq!(d("x.asc", b"").unwrap(), DemFormat::Asc);
        assert_eq!(d("N57E011.HGT", &[0, 1, 0, 2]).unwrap(), DemFormat::Hgt);
        assert!(matches!(
            d("x.tif", b"GIF89a"),
            Err(DemError::Malformed(m)) if m.contains("TIFF")
        ));
        assert!(matches!(
            d("x.dat", b"hello"),
            Err(DemError::UnknownFormat { .. })
        ));
        let trgb = ReadOptions {
            terrain_rgb: true,
            ..opts()
        };
        assert_eq!(
            detect_format(p("t.png"), PNG_SIGNATURE, &trgb).unwrap(),
            DemFormat::TerrainRgb
        );
        assert!(matches!(
            detect_format(p("t.tif"), b"II*\0", &trgb),
            Err(DemError::Unsupported(_))
        ));
    }

    #[test]
    fn sample_count_limits() {
        let small = ReadOptions {
            max_samples: 100,
            ..opts()
        };
        assert_eq!(
            checked_sample_count(10, 10, SampleType::I16, &small).unwrap(),
            100
        );
        assert!(matches!(
            checked_sample_count(10, 11, SampleType::I16, &small),
            Err(DemError::TooLarge { .. })
        ));
        assert!(matches!(
            checked_sample_count(u64::MAX, u64::MAX, SampleType::I16, &opts()),
            Err(DemError::TooLarge { .. })
        ));
        assert!(matches!(
            checked_sample_count(0, 5, SampleType::I16, &opts()),
            Err(DemError::Malformed(_))
        ));
        let msg = checked_sample_count(1 << 20, 1 << 20, SampleType::I16, &opts())
            .unwrap_err()
            .to_string();
        assert!(msg.contains("1099511627776 samples"), "{msg}");
    }

    #[test]
    fn memory_limit_counts_the_sample_type_and_the_work() {
        let budget = ReadOptions {
            max_memory: 1000,
            work: WorkMemory {
                integer: 8,
                float: 36,
            },
            ..opts()
        };
        // 10 × 10 i16: 100 × (2 + 8) = 1000 bytes fits; f32: 100 × (4 + 36) does not.
        assert_eq!(
            checked_sample_count(10, 10, SampleType::I16, &budget).unwrap(),
            100
        );
        let err = checked_sample_count(10, 10, SampleType::F32, &budget).unwrap_err();
        assert!(
            matches!(
                err,
                DemError::OverMemory {
                    needed: 4000,
                    limit: 1000,
                    ..
                }
            ),
            "{err}"
        );
        // 40000 × 40000 i16 (a 320 KB sparse GeoTIFF can declare it) is refused by default.
        assert!(matches!(
            checked_sample_count(40000, 40000, SampleType::I16, &opts()),
            Err(DemError::OverMemory { .. })
        ));
    }

    fn sample_raster() -> Raster {
        let mut r = Raster::new(3, 2, Samples::I16(vec![-5, 0, 7, 300, -32768, 12])).unwrap();
        r.nodata = Some(-32768.0);
        r.georef = Some(Georef {
            geotransform: [10.0, 0.5, 0.0, 20.0, 0.0, -0.5],
            ..Georef::default()
        });
        r
    }

    #[test]
    fn write_and_read_each_extension() {
        let dir = tempfile::tempdir().unwrap();
        let r = sample_raster();
        for name in ["a.tif", "a.TIFF", "a.asc"] {
            let path = dir.path().join(name);
            write_dem(&path, &r).unwrap();
            let back = read_dem(&path, &opts()).unwrap();
            assert_eq!(back.samples.to_f64(), r.samples.to_f64(), "{name}");
            assert_eq!(back.nodata, r.nodata, "{name}");
            assert_eq!(
                back.georef.unwrap().geotransform,
                r.georef.as_ref().unwrap().geotransform
            );
        }
        // Negative values do not fit a PNG: refused, and nothing is left behind.
        let png = dir.path().join("a.png");
        let err = write_dem(&png, &r).unwrap_err();
        assert!(matches!(err, DemError::Unsupported(_)), "{err}");
        assert!(err.to_string().contains("a.png"), "{err}");
        assert!(!png.exists());
    }

    #[test]
    fn write_rejects_unknown_extension_and_bad_raster() {
        let dir = tempfile::tempdir().unwrap();
        let r = sample_raster();
        let err = write_dem(&dir.path().join("a.jpg"), &r).unwrap_err();
        assert!(
            err.to_string().contains(".tif, .tiff, .png or .asc"),
            "{err}"
        );
        let mut bad = r.clone();
        bad.width = 4;
        assert!(matches!(
            write_dem(&dir.path().join("a.tif"), &bad),
            Err(DemError::InvalidRaster(_))
        ));
        let err = write_dem(dir.path(), &r).unwrap_err();
        assert!(matches!(
            err,
            DemError::Unsupported(_) | DemError::Io { .. }
        ));
    }

    #[test]
    fn read_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.tif");
        let err = read_dem(&missing, &opts()).unwrap_err();
        assert!(matches!(err, DemError::Io { .. }));
        assert!(err.to_string().contains("missing.tif"));

        let truncated = dir.path().join("t.tif");
        let mut bytes = geotiff::encode(&sample_raster()).unwrap();
        bytes.truncate(bytes.len() / 2);
        std::fs::write(&truncated, &bytes).unwrap();
        let err = read_dem(&truncated, &opts()).unwrap_err();
        assert!(err.to_string().contains("t.tif"), "{err}");
    }
}
