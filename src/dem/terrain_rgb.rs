//! Mapbox Terrain-RGB PNG tiles: heights packed in the colour channels as
//! `h = -10000 + (R·65536 + G·256 + B) · 0.1` metres, decoded in `f64` and stored as `f32`.
//! The alpha channel, when present, is ignored.

use std::io::{BufRead, Seek};
use std::path::Path;

use ::png::{BitDepth, ColorType};
use wavemesh_codec::{Raster, Samples};

use super::png::decode;
use super::{make_raster, DemError, ReadOptions};

/// Decodes one Terrain-RGB pixel to metres.
pub(super) fn height(r: u8, g: u8, b: u8) -> f32 {
    let code = u32::from(r) * 65536 + u32::from(g) * 256 + u32::from(b);
    (-10000.0 + f64::from(code) * 0.1) as f32
}

/// Reads an 8-bit RGB or RGBA Terrain-RGB PNG as `f32` metres.
pub(super) fn read<R: BufRead + Seek>(
    reader: R,
    path: &Path,
    options: &ReadOptions,
) -> Result<Raster, DemError> {
    let png = decode(reader, path, options)?;
    let channels = match (png.color_type, png.bit_depth) {
        (ColorType::Rgb, BitDepth::Eight) => 3,
        (ColorType::Rgba, BitDepth::Eight) => 4,
        _ => {
            return Err(DemError::Unsupported(format!(
                "{} PNG; Terrain-RGB expects 8-bit RGB or RGBA",
                png.describe()
            )))
        }
    };
    let heights = png
        .data
        .chunks_exact(channels)
        .map(|p| height(p[0], p[1], p[2]))
        .collect();
    make_raster(png.width, png.height, Samples::F32(heights))
}

#[cfg(test)]
mod tests {
    use super::super::png::raw_png;
    use super::*;
    use std::io::Cursor;

    fn read_bytes(bytes: Vec<u8>, max_samples: u64) -> Result<Raster, DemError> {
        let options = ReadOptions {
            terrain_rgb: true,
            max_samples,
            ..ReadOptions::default()
        };
        read(Cursor::new(bytes), Path::new("t.png"), &options)
    }

    #[test]
    fn decodes_the_formula() {
        assert_eq!(height(1, 134, 160), 0.0);
        assert_eq!(height(0, 0, 0), -10000.0);
        assert_eq!(height(1, 135, 5), 10.1);
        assert_eq!(height(255, 255, 255), (-10000.0 + 16777215.0 * 0.1) as f32);
    }

    #[test]
    fn reads_rgb_and_rgba() {
        let rgb = raw_png(
            2,
            1,
            ColorType::Rgb,
            BitDepth::Eight,
            None,
            &[1, 134, 160, 1, 138, 136],
        );
        let r = read_bytes(rgb, 1 << 20).unwrap();
        assert_eq!(r.samples, Samples::F32(vec![0.0, 100.0]));
        let rgba = raw_png(
            1,
            2,
            ColorType::Rgba,
            BitDepth::Eight,
            None,
            &[1, 134, 160, 255, 0, 0, 0, 0],
        );
        let r = read_bytes(rgba, 1 << 20).unwrap();
        assert_eq!((r.width, r.height), (1, 2));
        assert_eq!(r.samples, Samples::F32(vec![0.0, -10000.0]));
        assert_eq!(r.nodata, None);
    }

    #[test]
    fn refuses_grayscale_16_bit_rgb_and_oversized() {
        let gray = raw_png(1, 1, ColorType::Grayscale, BitDepth::Eight, None, &[5]);
        assert!(matches!(
            read_bytes(gray, 100),
            Err(DemError::Unsupported(_))
        ));
        let rgb16 = raw_png(1, 1, ColorType::Rgb, BitDepth::Sixteen, None, &[0; 6]);
        assert!(matches!(
            read_bytes(rgb16, 100),
            Err(DemError::Unsupported(_))
        ));
        let big = raw_png(4, 4, ColorType::Rgb, BitDepth::Eight, None, &[0; 48]);
        assert!(matches!(
            read_bytes(big, 15),
            Err(DemError::TooLarge { .. })
        ));
    }
}
