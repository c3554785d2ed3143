//! The in-memory elevation raster the codec encodes and decodes.
//!
//! A [`Raster`] is a single-band grid of typed samples in row-major order (row 0 first),
//! with an optional nodata value, optional georeferencing and GIS metadata (GDAL scale,
//! offset, band description, units, free items) that the container carries through.

use crate::error::CodecError;

/// The numeric type of a raster's samples, as stored in the source file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SampleType {
    /// Unsigned 8-bit integers.
    U8,
    /// Unsigned 16-bit integers.
    U16,
    /// Signed 16-bit integers (SRTM).
    I16,
    /// Signed 32-bit integers.
    I32,
    /// IEEE 754 single-precision floats.
    F32,
}

impl SampleType {
    /// Stable one-byte code used in the container header.
    pub fn code(self) -> u8 {
        match self {
            SampleType::U8 => 1,
            SampleType::U16 => 2,
            SampleType::I16 => 3,
            SampleType::I32 => 4,
            SampleType::F32 => 5,
        }
    }

    /// Inverse of [`SampleType::code`].
    pub fn from_code(code: u8) -> Option<SampleType> {
        Some(match code {
            1 => SampleType::U8,
            2 => SampleType::U16,
            3 => SampleType::I16,
            4 => SampleType::I32,
            5 => SampleType::F32,
            _ => return None,
        })
    }

    /// Size of one sample in bytes.
    pub fn bytes(self) -> usize {
        match self {
            SampleType::U8 => 1,
            SampleType::U16 | SampleType::I16 => 2,
            SampleType::I32 | SampleType::F32 => 4,
        }
    }

    /// Whether the type holds integers (exactly representable in an `i64`).
    pub fn is_integer(self) -> bool {
        self != SampleType::F32
    }

    /// Short lower-case name (`u8`, `u16`, `i16`, `i32`, `f32`).
    pub fn name(self) -> &'static str {
        match self {
            SampleType::U8 => "u8",
            SampleType::U16 => "u16",
            SampleType::I16 => "i16",
            SampleType::I32 => "i32",
            SampleType::F32 => "f32",
        }
    }

    /// Smallest and largest value the type can hold.
    pub fn value_range(self) -> (f64, f64) {
        match self {
            SampleType::U8 => (0.0, u8::MAX as f64),
            SampleType::U16 => (0.0, u16::MAX as f64),
            SampleType::I16 => (i16::MIN as f64, i16::MAX as f64),
            SampleType::I32 => (i32::MIN as f64, i32::MAX as f64),
            SampleType::F32 => (f32::MIN as f64, f32::MAX as f64),
        }
    }
}

/// Sample storage, one variant per [`SampleType`], row-major.
#[derive(Debug, Clone, PartialEq)]
pub enum Samples {
    /// Unsigned 8-bit samples.
    U8(Vec<u8>),
    /// Unsigned 16-bit samples.
    U16(Vec<u16>),
    /// Signed 16-bit samples.
    I16(Vec<i16>),
    /// Signed 32-bit samples.
    I32(Vec<i32>),
    /// Single-precision float samples.
    F32(Vec<f32>),
}

impl Samples {
    /// The type of the stored samples.
    pub fn sample_type(&self) -> SampleType {
        match self {
            Samples::U8(_) => SampleType::U8,
            Samples::U16(_) => SampleType::U16,
            Samples::I16(_) => SampleType::I16,
            Samples::I32(_) => SampleType::I32,
            Samples::F32(_) => SampleType::F32,
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            Samples::U8(v) => v.len(),
            Samples::U16(v) => v.len(),
            Samples::I16(v) => v.len(),
            Samples::I32(v) => v.len(),
            Samples::F32(v) => v.len(),
        }
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sample `index` widened to `f64` (exact for every supported type).
    pub fn get_f64(&self, index: usize) -> f64 {
        match self {
            Samples::U8(v) => v[index] as f64,
            Samples::U16(v) => v[index] as f64,
            Samples::I16(v) => v[index] as f64,
            Samples::I32(v) => v[index] as f64,
            Samples::F32(v) => v[index] as f64,
        }
    }

    /// `f(i, v)` for every sample `i` widened to `v: f64`, in order, collected: one typed
    /// loop instead of a type dispatch per sample.
    pub(crate) fn map_f64<U>(&self, mut f: impl FnMut(usize, f64) -> U) -> Vec<U> {
        match self {
            Samples::U8(v) => v.iter().enumerate().map(|(i, &x)| f(i, x as f64)).collect(),
            Samples::U16(v) => v.iter().enumerate().map(|(i, &x)| f(i, x as f64)).collect(),
            Samples::I16(v) => v.iter().enumerate().map(|(i, &x)| f(i, x as f64)).collect(),
            Samples::I32(v) => v.iter().enumerate().map(|(i, &x)| f(i, x as f64)).collect(),
            Samples::F32(v) => v.iter().enumerate().map(|(i, &x)| f(i, x as f64)).collect(),
        }
    }

    /// Folds `f(acc, i, v)` over every sample `i` widened to `v: f64`, in order.
    pub(crate) fn fold_f64<A>(&self, init: A, mut f: impl FnMut(A, usize, f64) -> A) -> A {
        match self {
            Samples::U8(v) => v
                .iter()
                .enumerate()
                .fold(init, |a, (i, &x)| f(a, i, x as f64)),
            Samples::U16(v) => v
                .iter()
                .enumerate()
                .fold(init, |a, (i, &x)| f(a, i, x as f64)),
            Samples::I16(v) => v
                .iter()
                .enumerate()
                .fold(init, |a, (i, &x)| f(a, i, x as f64)),
            Samples::I32(v) => v
                .iter()
                .enumerate()
                .fold(init, |a, (i, &x)| f(a, i, x as f64)),
            Samples::F32(v) => v
                .iter()
                .enumerate()
                .fold(init, |a, (i, &x)| f(a, i, x as f64)),
        }
    }

    /// `len` samples of `sample_type`, all `value` (rounded and clamped like
    /// [`Samples::from_f64`]).
    pub fn filled(sample_type: SampleType, value: f64, len: usize) -> Samples {
        match Samples::from_f64(sample_type, &[value]) {
            Samples::U8(v) => Samples::U8(vec![v[0]; len]),
            Samples::U16(v) => Samples::U16(vec![v[0]; len]),
            Samples::I16(v) => Samples::I16(vec![v[0]; len]),
            Samples::I32(v) => Samples::I32(vec![v[0]; len]),
            Samples::F32(v) => Samples::F32(vec![v[0]; len]),
        }
    }

    /// All samples widened to `f64`.
    pub fn to_f64(&self) -> Vec<f64> {
        (0..self.len()).map(|i| self.get_f64(i)).collect()
    }

    /// Builds samples of type `sample_type` from `f64` values, rounding and clamping
    /// integers to the type's range (floats are narrowed with `as f32`).
    pub fn from_f64(sample_type: SampleType, values: &[f64]) -> Samples {
        fn int<T>(values: &[f64], lo: f64, hi: f64, cast: fn(f64) -> T) -> Vec<T> {
            values
                .iter()
                .map(|&v| {
                    cast(if v.is_nan() {
                        0.0
                    } else {
                        v.round().clamp(lo, hi)
                    })
                })
                .collect()
        }
        let (lo, hi) = sample_type.value_range();
        match sample_type {
            SampleType::U8 => Samples::U8(int(values, lo, hi, |v| v as u8)),
            SampleType::U16 => Samples::U16(int(values, lo, hi, |v| v as u16)),
            SampleType::I16 => Samples::I16(int(values, lo, hi, |v| v as i16)),
            SampleType::I32 => Samples::I32(int(values, lo, hi, |v| v as i32)),
            SampleType::F32 => Samples::F32(values.iter().map(|&v| v as f32).collect()),
        }
    }
}

/// Georeferencing carried from a GeoTIFF source to the decoded output, byte for byte.
///
/// The codec does not interpret it beyond storing it; `geotransform` follows GDAL's
/// convention: `x = gt[0] + col·gt[1] + row·gt[2]`, `y = gt[3] + col·gt[4] + row·gt[5]`
/// for the top-left corner of pixel (col, row).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Georef {
    /// GDAL-style affine geotransform.
    pub geotransform: [f64; 6],
    /// GeoTIFF GeoKeyDirectoryTag (34735) values, empty when absent.
    pub geo_key_directory: Vec<u16>,
    /// GeoTIFF GeoDoubleParamsTag (34736) values.
    pub geo_double_params: Vec<f64>,
    /// GeoTIFF GeoAsciiParamsTag (34737) text.
    pub geo_ascii_params: String,
}

/// GeoTIFF GeoKey ids and values the project reads and writes, and the lookup of a key
/// in a GeoKeyDirectoryTag ([`Georef::geo_key_directory`]).
pub mod geokey {
    /// `GTModelTypeGeoKey`.
    pub const MODEL_TYPE: u16 = 1024;
    /// `GTRasterTypeGeoKey`.
    pub const RASTER_TYPE: u16 = 1025;
    /// `GeographicTypeGeoKey`: the EPSG code of a geographic CRS.
    pub const GEOGRAPHIC_TYPE: u16 = 2048;
    /// `GeogAngularUnitsGeoKey`.
    pub const ANGULAR_UNITS: u16 = 2054;
    /// `ProjectedCSTypeGeoKey`: the EPSG code of a projected CRS.
    pub const PROJECTED_TYPE: u16 = 3072;
    /// `ModelTypeProjected`.
    pub const MODEL_PROJECTED: u16 = 1;
    /// `ModelTypeGeographic`.
    pub const MODEL_GEOGRAPHIC: u16 = 2;
    /// `RasterPixelIsPoint`: tie points refer to pixel centres, not corners.
    pub const PIXEL_IS_POINT: u16 = 2;
    /// A key value meaning "user-defined", not an EPSG code.
    pub const USER_DEFINED: u16 = 32767;

    /// The value of key `id` held in the directory itself (location 0), if the
    /// directory is well formed enough to hold it.
    pub fn value(directory: &[u16], id: u16) -> Option<u16> {
        let count = usize::from(*directory.get(3)?);
        directory
            .get(4..)?
            .chunks_exact(4)
            .take(count)
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn values_are_found_only_in_well_formed_directories() {
            assert_eq!(value(&[], RASTER_TYPE), None);
            assert_eq!(value(&[1, 1, 0, 5, 1025, 0], RASTER_TYPE), None);
            assert_eq!(value(&[1, 1, 0, 1, 1025, 0, 1, 2], RASTER_TYPE), Some(2));
            // Beyond the declared count, and stored in another tag: not a value.
            assert_eq!(value(&[1, 1, 0, 0, 1025, 0, 1, 2], RASTER_TYPE), None);
            assert_eq!(value(&[1, 1, 0, 1, 1025, 34736, 1, 0], RASTER_TYPE), None);
        }
    }
}

/// One free metadata item, as GDAL keeps them in a GeoTIFF's `GDAL_METADATA` tag
/// (e.g. Copernicus DTED's `DTED_VerticalDatum = E08`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct MetadataItem {
    /// The item's name.
    pub name: String,
    /// Its value, as text.
    pub value: String,
    /// GDAL metadata domain (empty: the default domain).
    pub domain: String,
    /// Whether the item belongs to the band (GDAL `sample="0"`) rather than the dataset.
    pub band: bool,
}

/// What the samples mean, beyond their values: GIS metadata carried from the source to
/// the decoded output. Every field is optional; [`Metadata::is_empty`] when none is set.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Metadata {
    /// GDAL band scale: a value in units is `sample · scale + offset`.
    pub scale: Option<f64>,
    /// GDAL band offset (see `scale`).
    pub offset: Option<f64>,
    /// GDAL band description (its name, e.g. `elevation`).
    pub description: Option<String>,
    /// GDAL band unit type (e.g. `m`, `ft`).
    pub unit_type: Option<String>,
    /// The CRS as WKT text, when the source gave it as text (an `.asc` file's `.prj`)
    /// rather than as GeoTIFF keys.
    pub crs_wkt: Option<String>,
    /// Free items, in the source's order.
    pub items: Vec<MetadataItem>,
}

impl Metadata {
    /// Whether no field is set.
    pub fn is_empty(&self) -> bool {
        *self == Metadata::default()
    }
}

/// A single-band elevation grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Raster {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// `width × height` samples, row-major.
    pub samples: Samples,
    /// The value marking missing samples (may be NaN for floats), if any.
    pub nodata: Option<f64>,
    /// Optional georeferencing.
    pub georef: Option<Georef>,
    /// GIS metadata (empty when the source had none).
    pub metadata: Metadata,
}

impl Raster {
    /// Creates a raster, checking that the sample count matches the dimensions.
    pub fn new(width: usize, height: usize, samples: Samples) -> Result<Raster, CodecError> {
        let expected = width.checked_mul(height).ok_or(CodecError::Dimensions {
            width: width as u64,
            height: height as u64,
        })?;
        if width == 0 || height == 0 || samples.len() != expected {
            return Err(CodecError::Dimensions {
                width: width as u64,
                height: height as u64,
            });
        }
        Ok(Raster {
            width,
            height,
            samples,
            nodata: None,
            georef: None,
            metadata: Metadata::default(),
        })
    }

    /// The sample type.
    pub fn sample_type(&self) -> SampleType {
        self.samples.sample_type()
    }

    /// Number of samples (`width × height`).
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Whether the raster has no samples (never true for a raster built by [`Raster::new`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether sample `index` is a valid (not nodata, not NaN) sample.
    pub fn is_valid(&self, index: usize) -> bool {
        self.is_valid_value(self.samples.get_f64(index))
    }

    /// Whether a sample of value `v` is valid: not NaN and not the nodata value.
    fn is_valid_value(&self, v: f64) -> bool {
        !v.is_nan() && self.nodata.is_none_or(|nd| v != nd)
    }

    /// The validity mask: `true` for every valid sample.
    pub fn valid_mask(&self) -> Vec<bool> {
        // `is_valid` for every sample, in one typed loop.
        self.samples.map_f64(|_, v| self.is_valid_value(v))
    }

    /// The `width × height` samples whose top-left corner is (`x`, `y`), with this
    /// raster's nodata value and no georeferencing or metadata. Panics if the window
    /// does not lie inside the raster.
    pub fn crop(&self, x: usize, y: usize, width: usize, height: usize) -> Raster {
        assert!(x + width <= self.width && y + height <= self.height);
        fn rows<T: Copy>(v: &[T], stride: usize, x: usize, y: usize, w: usize, h: usize) -> Vec<T> {
            let mut out = Vec::with_capacity(w * h);
            for row in y..y + h {
                out.extend_from_slice(&v[row * stride + x..row * stride + x + w]);
            }
            out
        }
        let s = self.width;
        let samples = match &self.samples {
            Samples::U8(v) => Samples::U8(rows(v, s, x, y, width, height)),
            Samples::U16(v) => Samples::U16(rows(v, s, x, y, width, height)),
            Samples::I16(v) => Samples::I16(rows(v, s, x, y, width, height)),
            Samples::I32(v) => Samples::I32(rows(v, s, x, y, width, height)),
            Samples::F32(v) => Samples::F32(rows(v, s, x, y, width, height)),
        };
        Raster {
            width,
            height,
            samples,
            nodata: self.nodata,
            georef: None,
            metadata: Metadata::default(),
        }
    }

    /// Copies `part`'s samples into this raster with its top-left corner at (`x`, `y`).
    /// Panics if the types differ or `part` does not fit.
    pub fn paste(&mut self, x: usize, y: usize, part: &Raster) {
        self.paste_part(x, y, part, (0, 0, part.width, part.height));
    }

    /// Copies the `(px, py, width, height)` window of `part` into this raster with its
    /// top-left corner at (`x`, `y`), with no copy of the window between. Panics if the
    /// types differ or the window is not inside `part` or does not fit here.
    pub fn paste_part(
        &mut self,
        x: usize,
        y: usize,
        part: &Raster,
        (px, py, w, h): (usize, usize, usize, usize),
    ) {
        assert!(px + w <= part.width && py + h <= part.height);
        assert!(x + w <= self.width && y + h <= self.height);
        // Row k of the window: (start in this raster, start in `part`).
        let (to_stride, from_stride) = (self.width, part.width);
        let starts = (0..h).map(|k| ((y + k) * to_stride + x, (py + k) * from_stride + px));
        fn rows<T: Copy>(
            to: &mut [T],
            from: &[T],
            starts: impl Iterator<Item = (usize, usize)>,
            w: usize,
        ) {
            for (t, f) in starts {
                to[t..t + w].copy_from_slice(&from[f..f + w]);
            }
        }
        match (&mut self.samples, &part.samples) {
            (Samples::U8(to), Samples::U8(from)) => rows(to, from, starts, w),
            (Samples::U16(to), Samples::U16(from)) => rows(to, from, starts, w),
            (Samples::I16(to), Samples::I16(from)) => rows(to, from, starts, w),
            (Samples::I32(to), Samples::I32(from)) => rows(to, from, starts, w),
            (Samples::F32(to), Samples::F32(from)) => rows(to, from, starts, w),
            _ => panic!("pasting samples of another type"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pasting_a_window_equals_pasting_its_crop() {
        let part = Raster::new(5, 4, Samples::I16((0..20).collect())).unwrap();
        let blank = || Raster::new(6, 6, Samples::I16(vec![-1; 36])).unwrap();
        for (px, py, w, h) in [(0, 0, 5, 4), (1, 2, 3, 2), (4, 3, 1, 1), (2, 0, 0, 4)] {
            let (mut direct, mut via_crop) = (blank(), blank());
            direct.paste_part(1, 2, &part, (px, py, w, h));
            via_crop.paste(1, 2, &part.crop(px, py, w, h));
            assert_eq!(direct.samples, via_crop.samples, "{px},{py} {w}x{h}");
        }
    }

    #[test]
    fn sample_type_codes_round_trip() {
        for t in [
            SampleType::U8,
            SampleType::U16,
            SampleType::I16,
            SampleType::I32,
            SampleType::F32,
        ] {
            assert_eq!(SampleType::from_code(t.code()), Some(t));
        }
        assert_eq!(SampleType::from_code(0), None);
        assert_eq!(SampleType::from_code(6), None);
    }

    #[test]
    fn raster_rejects_mismatched_sizes() {
        assert!(Raster::new(3, 2, Samples::U8(vec![0; 5])).is_err());
        assert!(Raster::new(0, 2, Samples::U8(vec![])).is_err());
        assert!(Raster::new(3, 2, Samples::U8(vec![0; 6])).is_ok());
    }

    #[test]
    fn nodata_and_nan_are_invalid() {
        let mut r = Raster::new(3, 1, Samples::F32(vec![1.0, f32::NAN, -9999.0])).unwrap();
        r.nodata = Some(-9999.0);
        assert_eq!(r.valid_mask(), vec![true, false, false]);
    }

    #[test]
    fn crop_then_paste_gives_the_raster_back() {
        let values: Vec<i16> = (0..7 * 5).map(|i| i as i16 * 3 - 40).collect();
        let whole = Raster::new(7, 5, Samples::I16(values)).unwrap();
        let mut rebuilt = Raster::new(7, 5, Samples::I16(vec![0; 35])).unwrap();
        for (x, y, w, h) in [(0, 0, 4, 3), (4, 0, 3, 3), (0, 3, 4, 2), (4, 3, 3, 2)] {
            let part = whole.crop(x, y, w, h);
            assert_eq!(part.samples.get_f64(0), whole.samples.get_f64(y * 7 + x));
            rebuilt.paste(x, y, &part);
        }
        assert_eq!(rebuilt, whole);
    }

    #[test]
    fn from_f64_rounds_and_clamps() {
        let s = Samples::from_f64(SampleType::U8, &[-3.0, 2.6, 300.0]);
        assert_eq!(s, Samples::U8(vec![0, 3, 255]));
    }
}
