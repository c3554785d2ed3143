//! SRTM `.hgt` tiles: a headerless square of big-endian `i16` heights, row 0 = north,
//! voids = -32768. The side comes from the file length (`n² × 2` bytes); the
//! georeferencing comes from a `[NS]dd[EW]ddd` file name (south-west corner of the tile).

use std::io::Read;
use std::path::Path;

use wavemesh_codec::{Georef, Raster, SampleType, Samples};

use super::{checked_sample_count, make_raster, read_error, DemError, ReadOptions};

/// SRTM void value.
const VOID: i16 = -32768;

/// GeoKeys for EPSG:4326: GTModelType = geographic, GTRasterType = pixel-is-area,
/// GeographicType = 4326.
const EPSG_4326_KEYS: [u16; 16] = [
    1, 1, 0, 3, // version 1.1.0, 3 keys
    1024, 0, 1, 2, // GTModelTypeGeoKey = ModelTypeGeographic
    1025, 0, 1, 1, // GTRasterTypeGeoKey = RasterPixelIsArea
    2048, 0, 1, 4326, // GeographicTypeGeoKey = WGS 84
];

/// The side `n` of a square tile of `len` bytes, if `len == n² × 2` with `n ≥ 2`.
fn side_from_len(len: u64) -> Option<u64> {
    if len & 1 != 0 {
        return None;
    }
    let cells = len / 2;
    let mut n = (cells as f64).sqrt() as u64;
    // Correct the floating-point estimate.
    while n.saturating_mul(n) > cells {
        n -= 1;
    }
    while (n + 1).saturating_mul(n + 1) <= cells {
        n += 1;
    }
    (n >= 2 && n * n == cells).then_some(n)
}

/// South-west corner `(lat, lon)` from a file name starting with `[NS]dd[EW]ddd`.
fn corner_from_name(path: &Path) -> Option<(i32, i32)> {
    let name = path.file_name()?.to_str()?.as_bytes();
    let name = name.get(..7)?;
    let digits = |s: &[u8]| -> Option<i32> {
        s.iter().try_fold(0i32, |acc, &c| {
            c.is_ascii_digit().then(|| acc * 10 + i32::from(c - b'0'))
        })
    };
    let lat = digits(&name[1..3])?;
    let lon = digits(&name[4..7])?;
    let lat = match name[0].to_ascii_uppercase() {
        b'N' => lat,
        b'S' => -lat,
        _ => return None,
    };
    let lon = match name[3].to_ascii_uppercase() {
        b'E' => lon,
        b'W' => -lon,
        _ => return None,
    };
    ((-90..90).contains(&lat) && (-180..=180).contains(&lon)).then_some((lat, lon))
}

/// Pixel-is-area georeferencing of an `n × n` tile whose south-west cell centre is at
/// (`lat`, `lon`).
fn georef(lat: i32, lon: i32, n: u64) -> Georef {
    let step = 1.0 / (n - 1) as f64;
    Georef {
        geotransform: [
            f64::from(lon) - 0.5 * step,
            step,
            0.0,
            f64::from(lat + 1) + 0.5 * step,
            0.0,
            -step,
        ],
        geo_key_directory: EPSG_4326_KEYS.to_vec(),
        geo_double_params: Vec::new(),
        geo_ascii_params: String::new(),
    }
}

/// Reads an `.hgt` tile of `len` bytes.
pub(super) fn read<R: Read>(
    mut reader: R,
    len: u64,
    path: &Path,
    options: &ReadOptions,
) -> Result<Raster, DemError> {
    let n = side_from_len(len).ok_or_else(|| {
        DemError::Malformed(format!(
            "an .hgt tile is n x n big-endian i16 samples (2,884,802 bytes for SRTM3 1201 x 1201, \
             25,934,402 for SRTM1 3601 x 3601); {len} bytes is not 2·n² for any n >= 2"
        ))
    })?;
    let count = checked_sample_count(n, n, SampleType::I16, options)?;
    let mut bytes = vec![0; count * 2];
    reader
        .read_exact(&mut bytes)
        .map_err(|e| read_error(path, e))?;
    let samples = bytes
        .chunks_exact(2)
        .map(|b| i16::from_be_bytes([b[0], b[1]]))
        .collect();
    let mut raster = make_raster(n as usize, n as usize, Samples::I16(samples))?;
    raster.nodata = Some(f64::from(VOID));
    raster.georef = corner_from_name(path).map(|(lat, lon)| georef(lat, lon, n));
    Ok(raster)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn read_bytes(bytes: &[u8], name: &str) -> Result<Raster, DemError> {
        read(
            Cursor::new(bytes.to_vec()),
            bytes.len() as u64,
            Path::new(name),
            &ReadOptions::default(),
        )
    }

    #[test]
    fn side_from_length() {
        assert_eq!(side_from_len(1201 * 1201 * 2), Some(1201));
        assert_eq!(side_from_len(3601 * 3601 * 2), Some(3601));
        assert_eq!(side_from_len(8), Some(2));
        assert_eq!(side_from_len(2), None);
        assert_eq!(side_from_len(0), None);
        assert_eq!(side_from_len(1201 * 1201 * 2 + 2), None);
        assert_eq!(side_from_len(19), None);
        assert_eq!(side_from_len(u64::MAX - 1), None);
    }

    #[test]
    fn corner_from_file_name() {
        assert_eq!(
            corner_from_name(Path::new("/a/N57E011.hgt")),
            Some((57, 11))
        );
        assert_eq!(corner_from_name(Path::new("s09w078.HGT")), Some((-9, -78)));
        assert_eq!(
            corner_from_name(Path::new("N27E086.SRTMGL1.hgt")),
            Some((27, 86))
        );
        assert_eq!(corner_from_name(Path::new("tile.hgt")), None);
        assert_eq!(corner_from_name(Path::new("N5E011.hgt")), None);
        assert_eq!(corner_from_name(Path::new("N95E011.hgt")), None);
    }

    #[test]
    fn reads_big_endian_with_georef() {
        let values: [i16; 9] = [1, -2, 300, -32768, 0, 32767, 5, 6, 7];
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
        let r = read_bytes(&bytes, "S01W002.hgt").unwrap();
        assert_eq!((r.width, r.height), (3, 3));
        assert_eq!(r.samples, Samples::I16(values.to_vec()));
        assert_eq!(r.nodata, Some(-32768.0));
        let g = r.georef.unwrap();
        assert_eq!(g.geotransform, [-2.25, 0.5, 0.0, 0.25, 0.0, -0.5]);
        assert_eq!(g.geo_key_directory, EPSG_4326_KEYS.to_vec());
        assert!(read_bytes(&bytes, "dem.hgt").unwrap().georef.is_none());
    }

    #[test]
    fn wrong_length_names_expected_sizes() {
        let err = read_bytes(&[0; 10], "N00E000.hgt").unwrap_err().to_string();
        assert!(
            err.contains("2,884,802") && err.contains("10 bytes"),
            "{err}"
        );
    }

    #[test]
    fn short_read_and_limit_are_errors() {
        // Claimed length larger than the data actually available.
        let r = read(
            Cursor::new(vec![0; 6]),
            8,
            Path::new("x.hgt"),
            &ReadOptions::default(),
        );
        assert!(matches!(r, Err(DemError::Malformed(_))));
        let small = ReadOptions {
            max_samples: 3,
            ..ReadOptions::default()
        };
        let r = read(Cursor::new(vec![0; 8]), 8, Path::new("x.hgt"), &small);
        assert!(matches!(r, Err(DemError::TooLarge { .. })));
    }
}
