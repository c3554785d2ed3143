//! Grayscale PNG DEMs: 8-bit (u8) and 16-bit (u16) grayscale, plus 8-bit palette PNGs
//! whose palette is pure grey (read as u8 grey levels). Writing produces 8- or 16-bit
//! grayscale; PNG holds neither nodata nor georeferencing, so both are dropped.

use std::io::{BufRead, Seek};
use std::path::Path;

use ::png::{BitDepth, ColorType, DecodingError, Transformations};
use wavemesh_codec::{Raster, SampleType, Samples};

use super::{checked_sample_count, make_raster, read_error, DemError, ReadOptions};

/// A decoded PNG frame, without any colour transformation applied.
pub(super) struct DecodedPng {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Colour type as stored.
    pub color_type: ColorType,
    /// Bits per channel as stored.
    pub bit_depth: BitDepth,
    /// Rows of pixels, each `line_size` bytes, 16-bit channels big-endian.
    pub data: Vec<u8>,
    /// The PLTE chunk (RGB triples), if any.
    pub palette: Option<Vec<u8>>,
}

impl DecodedPng {
    /// Short description such as "8-bit Rgba", for messages.
    pub fn describe(&self) -> String {
        format!("{}-bit {:?}", self.bit_depth as u8, self.color_type)
    }
}

/// Maps a `png` decoding error to a [`DemError`].
fn png_error(path: &Path, e: DecodingError) -> DemError {
    match e {
        DecodingError::IoError(e) => read_error(path, e),
        DecodingError::LimitsExceeded => {
            DemError::Malformed("PNG needs more memory than its dimensions justify".into())
        }
        other => DemError::Malformed(format!("invalid PNG: {other}")),
    }
}

/// Decodes the first frame of a PNG, checking its size against `options.max_samples`
/// before allocating the pixel buffer.
pub(super) fn decode<R: BufRead + Seek>(
    reader: R,
    path: &Path,
    options: &ReadOptions,
) -> Result<DecodedPng, DemError> {
    let err = |e| png_error(path, e);
    let mut decoder = ::png::Decoder::new(reader);
    decoder.set_transformations(Transformations::IDENTITY);
    let header = decoder.read_header_info().map_err(err)?;
    let (width, height) = (header.width, header.height);
    // What the pixels become: Terrain-RGB heights are f32, 16-bit grey u16, else u8.
    let sample_type = if options.terrain_rgb {
        SampleType::F32
    } else if header.bit_depth == BitDepth::Sixteen {
        SampleType::U16
    } else {
        SampleType::U8
    };
    checked_sample_count(u64::from(width), u64::from(height), sample_type, options)?;
    let mut reader = decoder.read_info().map_err(err)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| DemError::TooLarge {
            width: u64::from(width),
            height: u64::from(height),
            limit: options.max_samples,
        })?;
    let mut data = vec![0; size];
    let frame = reader.next_frame(&mut data).map_err(err)?;
    data.truncate(frame.buffer_size());
    let palette = reader.info().palette.as_ref().map(|p| p.to_vec());
    Ok(DecodedPng {
        width: width as usize,
        height: height as usize,
        color_type: frame.color_type,
        bit_depth: frame.bit_depth,
        data,
        palette,
    })
}

/// Reads a grayscale (or grey-palette) PNG.
pub(super) fn read<R: BufRead + Seek>(
    reader: R,
    path: &Path,
    options: &ReadOptions,
) -> Result<Raster, DemError> {
    let png = decode(reader, path, options)?;
    let samples = match (png.color_type, png.bit_depth) {
        (ColorType::Grayscale, BitDepth::Eight) => Samples::U8(png.data),
        (ColorType::Grayscale, BitDepth::Sixteen) => Samples::U16(
            png.data
                .chunks_exact(2)
                .map(|b| u16::from_be_bytes([b[0], b[1]]))
                .collect(),
        ),
        (ColorType::Indexed, BitDepth::Eight) => {
            Samples::U8(grey_palette_lookup(&png.data, png.palette.as_deref())?)
        }
        (ColorType::Rgb | ColorType::Rgba, _) => {
            return Err(DemError::Unsupported(format!(
                "{} PNG; expected 8- or 16-bit grayscale (use --terrain-rgb to decode a Mapbox \
                 Terrain-RGB tile)",
                png.describe()
            )))
        }
        _ => {
            return Err(DemError::Unsupported(format!(
                "{} PNG; expected 8- or 16-bit grayscale, or an 8-bit palette of pure greys",
                png.describe()
            )))
        }
    };
    make_raster(png.width, png.height, samples)
}

/// Maps palette indices to grey levels, refusing palettes with any coloured entry.
fn grey_palette_lookup(indices: &[u8], palette: Option<&[u8]>) -> Result<Vec<u8>, DemError> {
    let palette =
        palette.ok_or_else(|| DemError::Malformed("palette PNG without a PLTE chunk".into()))?;
    let greys: Vec<u8> = palette
        .chunks_exact(3)
        .map(|rgb| {
            if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
                Ok(rgb[0])
            } else {
                Err(DemError::Unsupported(format!(
                    "palette PNG with colour entry ({}, {}, {}); only a pure grey palette can be \
                     read as heights",
                    rgb[0], rgb[1], rgb[2]
                )))
            }
        })
        .collect::<Result<_, _>>()?;
    indices
        .iter()
        .map(|&i| {
            greys.get(usize::from(i)).copied().ok_or_else(|| {
                DemError::Malformed(format!(
                    "palette index {i} is beyond the {}-entry palette",
                    greys.len()
                ))
            })
        })
        .collect()
}

/// Encodes `raster` as an 8-bit (u8) or 16-bit (u16, and i16/i32 within 0..=65535)
/// grayscale PNG.
pub(super) fn encode(raster: &Raster) -> Result<Vec<u8>, DemError> {
    const NO_FIT: &str = "values outside 0..65535 do not fit PNG16; write .tif or .asc";
    let (depth, bytes): (BitDepth, Vec<u8>) = match &raster.samples {
        Samples::U8(v) => (BitDepth::Eight, v.clone()),
        Samples::U16(v) => (
            BitDepth::Sixteen,
            v.iter().flat_map(|x| x.to_be_bytes()).collect(),
        ),
        Samples::I16(v) => (
            BitDepth::Sixteen,
            to_png16(v.iter().map(|&x| i64::from(x)), NO_FIT)?,
        ),
        Samples::I32(v) => (
            BitDepth::Sixteen,
            to_png16(v.iter().map(|&x| i64::from(x)), NO_FIT)?,
        ),
        Samples::F32(_) => {
            return Err(DemError::Unsupported(
                "f32 samples do not fit a grayscale PNG; write .tif or .asc".into(),
            ))
        }
    };
    let too_big = || {
        DemError::Unsupported(format!(
            "{} x {} raster exceeds the PNG size limit",
            raster.width, raster.height
        ))
    };
    let width = u32::try_from(raster.width).map_err(|_| too_big())?;
    let height = u32::try_from(raster.height).map_err(|_| too_big())?;
    let mut out = Vec::new();
    let mut encoder = ::png::Encoder::new(&mut out, width, height);
    encoder.set_color(ColorType::Grayscale);
    encoder.set_depth(depth);
    let encode_err = |e: ::png::EncodingError| DemError::Unsupported(format!("PNG encoder: {e}"));
    let mut writer = encoder.write_header().map_err(encode_err)?;
    writer.write_image_data(&bytes).map_err(encode_err)?;
    writer.finish().map_err(encode_err)?;
    Ok(out)
}

/// Big-endian 16-bit bytes of `values`, which must all lie in 0..=65535.
fn to_png16(values: impl Iterator<Item = i64>, no_fit: &str) -> Result<Vec<u8>, DemError> {
    let mut out = Vec::new();
    for v in values {
        let v = u16::try_from(v).map_err(|_| DemError::Unsupported(no_fit.into()))?;
        out.extend(v.to_be_bytes());
    }
    Ok(out)
}

/// Test helper: encodes raw pixel bytes with the given colour type and depth.
#[cfg(test)]
pub(super) fn raw_png(
    w: u32,
    h: u32,
    color: ColorType,
    depth: BitDepth,
    palette: Option<Vec<u8>>,
    data: &[u8],
) -> Vec<u8> {
    let mut out = Vec::new();
    let mut e = ::png::Encoder::new(&mut out, w, h);
    e.set_color(color);
    e.set_depth(depth);
    if let Some(p) = palette {
        e.set_palette(p);
    }
    let mut wr = e.write_header().unwrap();
    wr.write_image_data(data).unwrap();
    wr.finish().unwrap();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn read_bytes(bytes: Vec<u8>, options: &ReadOptions) -> Result<Raster, DemError> {
        read(Cursor::new(bytes), Path::new("t.png"), options)
    }

    #[test]
    fn round_trips_u8_and_u16() {
        let o = ReadOptions::default();
        let r8 = Raster::new(5, 3, Samples::U8((0..15).map(|i| i * 17).collect())).unwrap();
        assert_eq!(read_bytes(encode(&r8).unwrap(), &o).unwrap(), r8);
        let r16 = Raster::new(3, 5, Samples::U16((0..15).map(|i| i * 4369).collect())).unwrap();
        assert_eq!(read_bytes(encode(&r16).unwrap(), &o).unwrap(), r16);
    }

    #[test]
    fn signed_in_range_becomes_u16_and_out_of_range_is_refused() {
        let o = ReadOptions::default();
        let ok = Raster::new(2, 2, Samples::I32(vec![0, 1, 65535, 300])).unwrap();
        let back = read_bytes(encode(&ok).unwrap(), &o).unwrap();
        assert_eq!(back.samples, Samples::U16(vec![0, 1, 65535, 300]));
        let ok16 = Raster::new(2, 1, Samples::I16(vec![0, 32767])).unwrap();
        assert_eq!(
            read_bytes(encode(&ok16).unwrap(), &o).unwrap().samples,
            Samples::U16(vec![0, 32767])
        );
        for bad in [Samples::I16(vec![-1, 0]), Samples::I32(vec![65536, 0])] {
            let r = Raster::new(2, 1, bad).unwrap();
            let err = encode(&r).unwrap_err().to_string();
            assert!(err.contains("0..65535"), "{err}");
        }
        let f = Raster::new(1, 1, Samples::F32(vec![1.0])).unwrap();
        assert!(matches!(encode(&f), Err(DemError::Unsupported(_))));
    }

    #[test]
    fn grey_palette_is_read_as_u8() {
        let palette: Vec<u8> = (0..4u8).flat_map(|i| [i * 80; 3]).collect();
        let png = raw_png(
            4,
            1,
            ColorType::Indexed,
            BitDepth::Eight,
            Some(palette),
            &[3, 2, 1, 0],
        );
        let r = read_bytes(png, &ReadOptions::default()).unwrap();
        assert_eq!(r.samples, Samples::U8(vec![240, 160, 80, 0]));
    }

    #[test]
    fn colour_palette_and_bad_index_are_refused() {
        let palette = vec![0, 0, 0, 255, 0, 0];
        let png = raw_png(
            2,
            1,
            ColorType::Indexed,
            BitDepth::Eight,
            Some(palette),
            &[0, 1],
        );
        let err = read_bytes(png, &ReadOptions::default()).unwrap_err();
        assert!(matches!(err, DemError::Unsupported(_)), "{err}");
        assert!(matches!(
            grey_palette_lookup(&[0, 5], Some(&[9, 9, 9])),
            Err(DemError::Malformed(_))
        ));
    }

    #[test]
    fn rgb_without_terrain_rgb_suggests_the_flag() {
        let png = raw_png(1, 1, ColorType::Rgb, BitDepth::Eight, None, &[1, 2, 3]);
        let err = read_bytes(png, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("--terrain-rgb"), "{err}");
        let ga = raw_png(
            1,
            1,
            ColorType::GrayscaleAlpha,
            BitDepth::Eight,
            None,
            &[1, 2],
        );
        let err = read_bytes(ga, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("grayscale"), "{err}");
    }

    #[test]
    fn truncated_and_oversized_are_errors() {
        let r = Raster::new(
            64,
            64,
            Samples::U16((0..4096).map(|i| i as u16 * 13).collect()),
        )
        .unwrap();
        let bytes = encode(&r).unwrap();
        for cut in [0, 8, 20, 40, bytes.len() / 2, bytes.len() - 5] {
            assert!(
                read_bytes(bytes[..cut].to_vec(), &ReadOptions::default()).is_err(),
                "{cut}"
            );
        }
        let small = ReadOptions {
            max_samples: 4095,
            ..ReadOptions::default()
        };
        assert!(matches!(
            read_bytes(bytes, &small),
            Err(DemError::TooLarge { .. })
        ));
    }

    #[test]
    fn absurd_header_dimensions_are_refused() {
        // A PNG whose IHDR claims 1,000,000 x 1,000,000 pixels (checked before allocating).
        let mut ihdr = Vec::new();
        ihdr.extend(1_000_000u32.to_be_bytes());
        ihdr.extend(1_000_000u32.to_be_bytes());
        ihdr.extend([16, 0, 0, 0, 0]);
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        png.extend(13u32.to_be_bytes());
        let mut chunk = b"IHDR".to_vec();
        chunk.extend(&ihdr);
        png.extend(&chunk);
        png.extend(crc32(&chunk).to_be_bytes());
        assert!(matches!(
            read_bytes(png, &ReadOptions::default()),
            Err(DemError::TooLarge { .. })
        ));
    }

    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }
}
