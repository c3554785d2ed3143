//! Single-band GeoTIFF reading and writing (through the `tiff` crate).
//!
//! Reads u8, u16, i16, i32 and f32 samples, stripped or tiled, with any compression the
//! `tiff` crate decodes (none, LZW, Deflate, PackBits). Georeferencing is kept:
//! ModelPixelScale + ModelTiepoint or ModelTransformation become a GDAL geotransform
//! (shifted by half a pixel for `PixelIsPoint` rasters, as GDAL does), the three GeoKey
//! tags are carried raw, GDAL_NODATA becomes the nodata value, and GDAL_METADATA (tag
//! 42112: scale, offset, description, units, items) the raster's metadata.
//!
//! Writes the same five sample types, Deflate-compressed (with the horizontal predictor
//! for integers), with the georeferencing, nodata and GDAL_METADATA tags.

use std::io::{Cursor, Read, Seek, Write};
use std::path::Path;

use tiff::decoder::Decoder;
use tiff::encoder::colortype::{self, ColorType};
use tiff::encoder::{Compression, DeflateLevel, DirectoryEncoder, TiffEncoder, TiffKind};
use tiff::tags::{Predictor, Tag};
use tiff::TiffError;
use wavemesh_codec::{geokey, Georef, Metadata, Raster, SampleType, Samples};

use super::tiff_chunks::ChunkReader;
use super::{
    checked_sample_count, gdal_metadata, make_raster, read_error, DemError, DemInfo, ReadOptions,
};

/// TIFF `PhotometricInterpretation` value `WhiteIsZero`.
const WHITE_IS_ZERO: u16 = 0;

/// Maps a `tiff` error met while reading `path` to a [`DemError`].
pub(super) fn tiff_error(path: &Path, e: TiffError) -> DemError {
    match e {
        TiffError::IoError(e) => read_error(path, e),
        TiffError::UnsupportedError(e) => DemError::Unsupported(format!("TIFF: {e}")),
        TiffError::LimitsExceeded => DemError::Malformed(
            "a TIFF tag or strip is larger than the image dimensions allow".into(),
        ),
        other => DemError::Malformed(format!("invalid TIFF: {other}")),
    }
}

/// Opens a single-band TIFF/GeoTIFF: everything but its samples, and the chunk decoder
/// that reads them (nothing is decoded or allocated for samples yet).
pub(super) fn open<R: Read + Seek>(
    reader: R,
    path: &Path,
    options: &ReadOptions,
) -> Result<(DemInfo, ChunkReader<R>), DemError> {
    let err = |e| tiff_error(path, e);
    let mut decoder = Decoder::new(reader).map_err(err)?;
    let (width, height) = decoder.dimensions().map_err(err)?;
    let sample_type = sample_type(&mut decoder, path)?;
    if width == 0 || height == 0 {
        return Err(DemError::Malformed(format!(
            "raster is {width} x {height}; expected a positive width and height"
        )));
    }
    check_compression(&mut decoder, path, options)?;
    let info = DemInfo {
        width: width as usize,
        height: height as usize,
        sample_type,
        georef: read_georef(&mut decoder, path)?,
        nodata: read_nodata(&mut decoder, path)?,
        metadata: read_metadata(&mut decoder, path)?,
    };
    Ok((info, ChunkReader::new(decoder, path, sample_type)?))
}

/// Reads a single-band TIFF/GeoTIFF whole, after checking its size against `options`.
pub(super) fn read<R: Read + Seek>(
    reader: R,
    path: &Path,
    options: &ReadOptions,
) -> Result<Raster, DemError> {
    let (info, mut chunks) = open(reader, path, options)?;
    let (width, height) = (info.width, info.height);
    checked_sample_count(width as u64, height as u64, info.sample_type, options)?;
    let mut raster = make_raster(width, height, chunks.read_rows(0, height)?)?;
    raster.nodata = info.nodata;
    raster.georef = info.georef;
    raster.metadata = info.metadata;
    Ok(raster)
}

/// Reads the GDAL_METADATA tag (42112): scale, offset, description, units and items.
fn read_metadata<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
) -> Result<Metadata, DemError> {
    let tag = Tag::Unknown(gdal_metadata::GDAL_METADATA_TAG);
    let Some(value) = decoder.find_tag(tag).map_err(|e| tiff_error(path, e))? else {
        return Ok(Metadata::default());
    };
    let xml = value
        .into_string()
        .map_err(|_| DemError::Malformed("GDAL_METADATA tag must hold ASCII text".into()))?;
    gdal_metadata::parse(&xml)
}

/// TIFF `Compression` values whose decoded samples differ from what was written.
const LOSSY_COMPRESSIONS: [(u16, &str); 4] = [
    (6, "old-style JPEG"),
    (7, "JPEG"),
    (34892, "lossy JPEG"),
    (50001, "WebP"),
];

/// Refuses lossy-compressed samples unless `options.accept_lossy`: different JPEG
/// decoders reconstruct them ±1 differently, so "lossless" would hold only against ours.
fn check_compression<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
    options: &ReadOptions,
) -> Result<(), DemError> {
    let compression = decoder
        .find_tag_unsigned::<u16>(Tag::Compression)
        .map_err(|e| tiff_error(path, e))?;
    let lossy = LOSSY_COMPRESSIONS
        .iter()
        .find(|(code, _)| Some(*code) == compression);
    match lossy {
        Some((_, name)) if !options.accept_lossy => Err(DemError::LossyInput(format!(
            "the TIFF's samples are {name}-compressed (lossy): decoders disagree on them by \
             ±1, so no encoding of them can be bit-exact against another reader's"
        ))),
        _ => Ok(()),
    }
}

/// The sample type from the colour type and SampleFormat tag, refusing what is not a
/// single band of u8, u16, i16, i32 or f32.
fn sample_type<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
) -> Result<SampleType, DemError> {
    let err = |e| tiff_error(path, e);
    const SUPPORTED: &str = "supported: single-band u8, u16, i16, i32 or f32";
    let bits = match decoder.colortype().map_err(err)? {
        tiff::ColorType::Gray(bits) => bits,
        tiff::ColorType::Multiband { num_samples, .. } => {
            return Err(DemError::Unsupported(format!(
                "TIFF has {num_samples} bands; {SUPPORTED}"
            )))
        }
        other => {
            return Err(DemError::Unsupported(format!(
                "TIFF holds {other:?} colour pixels; {SUPPORTED}"
            )))
        }
    };
    let photometric = decoder
        .find_tag_unsigned::<u16>(Tag::PhotometricInterpretation)
        .map_err(err)?;
    if photometric == Some(WHITE_IS_ZERO) {
        return Err(DemError::Unsupported(
            "TIFF with WhiteIsZero photometric interpretation (inverted values); expected BlackIsZero"
                .into(),
        ));
    }
    let format = decoder
        .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
        .map_err(err)?
        .and_then(|v| v.first().copied())
        .unwrap_or(1);
    Ok(match (format, bits) {
        (1, 8) => SampleType::U8,
        (1, 16) => SampleType::U16,
        (2, 16) => SampleType::I16,
        (2, 32) => SampleType::I32,
        (3, 32) => SampleType::F32,
        _ => {
            let kind = match format {
                1 => "unsigned integer",
                2 => "signed integer",
                3 => "floating-point",
                _ => "untyped",
            };
            return Err(DemError::Unsupported(format!(
                "TIFF holds {bits}-bit {kind} samples; {SUPPORTED}"
            )));
        }
    })
}

/// Reads a tag of DOUBLE values, `None` when absent.
fn f64_tag<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    tag: Tag,
    path: &Path,
) -> Result<Option<Vec<f64>>, DemError> {
    match decoder.find_tag(tag).map_err(|e| tiff_error(path, e))? {
        None => Ok(None),
        Some(value) => value
            .into_f64_vec()
            .map(Some)
            .map_err(|_| DemError::Malformed(format!("TIFF tag {tag:?} must hold DOUBLE values"))),
    }
}

/// Reads the georeferencing tags; `None` when the file has none of them.
fn read_georef<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
) -> Result<Option<Georef>, DemError> {
    let err = |e| tiff_error(path, e);
    let scale = f64_tag(decoder, Tag::ModelPixelScaleTag, path)?;
    let tiepoints = f64_tag(decoder, Tag::ModelTiepointTag, path)?;
    let transform = f64_tag(decoder, Tag::ModelTransformationTag, path)?;
    let keys = match decoder.find_tag(Tag::GeoKeyDirectoryTag).map_err(err)? {
        None => None,
        Some(v) => Some(v.into_u16_vec().map_err(|_| {
            DemError::Malformed("GeoKeyDirectoryTag must hold SHORT values".into())
        })?),
    };
    let doubles = f64_tag(decoder, Tag::GeoDoubleParamsTag, path)?;
    let ascii =
        match decoder.find_tag(Tag::GeoAsciiParamsTag).map_err(err)? {
            None => None,
            Some(v) => Some(v.into_string().map_err(|_| {
                DemError::Malformed("GeoAsciiParamsTag must hold ASCII text".into())
            })?),
        };
    if scale.is_none()
        && tiepoints.is_none()
        && transform.is_none()
        && keys.is_none()
        && doubles.is_none()
        && ascii.is_none()
    {
        return Ok(None);
    }
    let keys = keys.unwrap_or_default();
    let mut gt = [0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let mut from_tags = true;
    match (transform, scale, tiepoints) {
        (Some(m), _, _) => {
            if m.len() != 16 {
                return Err(DemError::Malformed(format!(
                    "ModelTransformationTag holds {} values; expected 16",
                    m.len()
                )));
            }
            gt = [m[3], m[0], m[1], m[7], m[4], m[5]];
        }
        (None, Some(s), Some(t)) => {
            if s.len() < 2 || t.len() < 6 {
                return Err(DemError::Malformed(format!(
                    "ModelPixelScaleTag holds {} values and ModelTiepointTag {}; expected at least 2 and 6",
                    s.len(),
                    t.len()
                )));
            }
            // First tie point (I, J, K, X, Y, Z) maps raster (I, J) to model (X, Y).
            gt = [
                t[3] - t[0] * s[0],
                s[0],
                0.0,
                t[4] + t[1] * s[1],
                0.0,
                -s[1],
            ];
        }
        (None, None, Some(t)) if t.len() > 6 => {
            return Err(DemError::Unsupported(format!(
                "GeoTIFF georeferenced by {} tie points (GCPs) without a pixel scale; \
                 expected ModelPixelScale + ModelTiepoint or ModelTransformation",
                t.len() / 6
            )))
        }
        _ => from_tags = false,
    }
    if from_tags && geokey::value(&keys, geokey::RASTER_TYPE) == Some(geokey::PIXEL_IS_POINT) {
        gt[0] -= 0.5 * (gt[1] + gt[2]);
        gt[3] -= 0.5 * (gt[4] + gt[5]);
    }
    Ok(Some(Georef {
        geotransform: gt,
        geo_key_directory: keys,
        geo_double_params: doubles.unwrap_or_default(),
        geo_ascii_params: ascii.unwrap_or_default(),
    }))
}

/// Reads GDAL_NODATA (ASCII, e.g. `-32768` or `nan`).
fn read_nodata<R: Read + Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
) -> Result<Option<f64>, DemError> {
    let Some(value) = decoder
        .find_tag(Tag::GdalNodata)
        .map_err(|e| tiff_error(path, e))?
    else {
        return Ok(None);
    };
    let text = value
        .into_string()
        .map_err(|_| DemError::Malformed("GDAL_NODATA tag must hold ASCII text".into()))?;
    parse_nodata(&text).map(Some)
}

/// Parses a GDAL nodata string; NaN spellings such as `nan`, `-nan` and `NaN` are accepted.
fn parse_nodata(text: &str) -> Result<f64, DemError> {
    let t = text.trim();
    if t.trim_start_matches(['-', '+']).eq_ignore_ascii_case("nan") {
        return Ok(f64::NAN);
    }
    t.parse::<f64>().map_err(|_| {
        DemError::Malformed(format!(
            "GDAL_NODATA holds '{t}'; expected a number or 'nan'"
        ))
    })
}

/// Formats a nodata value the way GDAL writes and reads it.
fn format_nodata(value: f64, sample_type: SampleType) -> String {
    if value.is_nan() {
        "nan".to_string()
    } else if sample_type.is_integer() && value.fract() == 0.0 && value.abs() < 1e18 {
        format!("{}", value as i64)
    } else {
        format!("{value}")
    }
}

/// Encodes `raster` as a single-band GeoTIFF in memory.
pub(super) fn encode(raster: &Raster) -> Result<Vec<u8>, DemError> {
    let too_big = || {
        DemError::Unsupported(format!(
            "{} x {} raster is too large for a classic TIFF (4 GiB)",
            raster.width, raster.height
        ))
    };
    let width = u32::try_from(raster.width).map_err(|_| too_big())?;
    let height = u32::try_from(raster.height).map_err(|_| too_big())?;
    let bytes = (raster.samples.len() as u64) * raster.sample_type().bytes() as u64;
    // Leave room for tags and for incompressible strips.
    if bytes > u64::from(u32::MAX) - (64 << 20) {
        return Err(too_big());
    }
    let tags = GeoTags::new(&DemInfo::of(raster))?;
    let mut out = Cursor::new(Vec::new());
    let result = match &raster.samples {
        Samples::U8(v) => write_image::<colortype::Gray8>(&mut out, width, height, v, &tags),
        Samples::U16(v) => write_image::<colortype::Gray16>(&mut out, width, height, v, &tags),
        Samples::I16(v) => write_image::<colortype::GrayI16>(&mut out, width, height, v, &tags),
        Samples::I32(v) => write_image::<colortype::GrayI32>(&mut out, width, height, v, &tags),
        Samples::F32(v) => write_image::<colortype::Gray32Float>(&mut out, width, height, v, &tags),
    };
    result.map_err(|e| DemError::Unsupported(format!("TIFF encoder: {e}")))?;
    Ok(out.into_inner())
}

/// Georeferencing, nodata and metadata tags ready to write.
pub(super) struct GeoTags {
    /// ModelPixelScale + ModelTiepoint, for north-up rasters.
    scale_tiepoint: Option<([f64; 3], [f64; 6])>,
    /// ModelTransformation, for rotated or flipped rasters.
    transformation: Option<[f64; 16]>,
    keys: Vec<u16>,
    doubles: Vec<f64>,
    ascii: String,
    nodata: Option<String>,
    /// GDAL_METADATA XML, when the raster has metadata.
    metadata: Option<String>,
}

impl GeoTags {
    /// The tags for a raster described by `info`.
    pub(super) fn new(info: &DemInfo) -> Result<GeoTags, DemError> {
        let nodata = info.nodata.map(|v| format_nodata(v, info.sample_type));
        let metadata = gdal_metadata::to_tiff_xml(&info.metadata);
        let Some(georef) = &info.georef else {
            return Ok(GeoTags {
                scale_tiepoint: None,
                transformation: None,
                keys: Vec::new(),
                doubles: Vec::new(),
                ascii: String::new(),
                nodata,
                metadata,
            });
        };
        if !georef.geo_ascii_params.is_ascii() || georef.geo_ascii_params.contains('\0') {
            return Err(DemError::Unsupported(
                "GeoAsciiParams must be ASCII text without NUL bytes to be written to TIFF".into(),
            ));
        }
        let mut gt = georef.geotransform;
        if geokey::value(&georef.geo_key_directory, geokey::RASTER_TYPE)
            == Some(geokey::PIXEL_IS_POINT)
        {
            gt[0] += 0.5 * (gt[1] + gt[2]);
            gt[3] += 0.5 * (gt[4] + gt[5]);
        }
        let north_up = gt[2] == 0.0 && gt[4] == 0.0 && gt[1] > 0.0 && gt[5] < 0.0;
        let (scale_tiepoint, transformation) = if north_up {
            (
                Some(([gt[1], -gt[5], 0.0], [0.0, 0.0, 0.0, gt[0], gt[3], 0.0])),
                None,
            )
        } else {
            #[rustfmt::skip]
            let m = [
                gt[1], gt[2], 0.0, gt[0],
                gt[4], gt[5], 0.0, gt[3],
                0.0, 0.0, 0.0, 0.0,
                0.0, 0.0, 0.0, 1.0,
            ];
            (None, Some(m))
        };
        Ok(GeoTags {
            scale_tiepoint,
            transformation,
            keys: georef.geo_key_directory.clone(),
            doubles: georef.geo_double_params.clone(),
            ascii: georef.geo_ascii_params.clone(),
            nodata,
            metadata,
        })
    }

    /// Writes the tags into the image directory `dir`.
    pub(super) fn write<W: Write + Seek, K: TiffKind>(
        &self,
        dir: &mut DirectoryEncoder<'_, W, K>,
    ) -> tiff::TiffResult<()> {
        if let Some((scale, tiepoint)) = &self.scale_tiepoint {
            dir.write_tag(Tag::ModelPixelScaleTag, &scale[..])?;
            dir.write_tag(Tag::ModelTiepointTag, &tiepoint[..])?;
        }
        if let Some(m) = &self.transformation {
            dir.write_tag(Tag::ModelTransformationTag, &m[..])?;
        }
        if !self.keys.is_empty() {
            dir.write_tag(Tag::GeoKeyDirectoryTag, &self.keys[..])?;
        }
        if !self.doubles.is_empty() {
            dir.write_tag(Tag::GeoDoubleParamsTag, &self.doubles[..])?;
        }
        if !self.ascii.is_empty() {
            dir.write_tag(Tag::GeoAsciiParamsTag, self.ascii.as_str())?;
        }
        if let Some(nodata) = &self.nodata {
            dir.write_tag(Tag::GdalNodata, nodata.as_str())?;
        }
        if let Some(xml) = &self.metadata {
            let tag = Tag::Unknown(gdal_metadata::GDAL_METADATA_TAG);
            dir.write_tag(tag, xml.as_str())?;
        }
        Ok(())
    }
}

/// Writes one image of colour type `C` with the geo tags.
fn write_image<C: ColorType>(
    out: &mut Cursor<Vec<u8>>,
    width: u32,
    height: u32,
    data: &[C::Inner],
    tags: &GeoTags,
) -> tiff::TiffResult<()>
where
    [C::Inner]: tiff::encoder::TiffValue,
{
    let predictor = if C::SAMPLE_FORMAT[0] == tiff::tags::SampleFormat::IEEEFP {
        Predictor::None
    } else {
        Predictor::Horizontal
    };
    let mut encoder = TiffEncoder::new(out)?
        .with_compression(Compression::Deflate(DeflateLevel::Fast))
        .with_predictor(predictor);
    let mut image = encoder.new_image::<C>(width, height)?;
    tags.write(image.encoder())?;
    image.write_data(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_bytes(bytes: Vec<u8>) -> Result<Raster, DemError> {
        read(
            Cursor::new(bytes),
            Path::new("test.tif"),
            &ReadOptions::default(),
        )
    }

    fn round_trip(raster: &Raster) -> Raster {
        let back = read_bytes(encode(raster).unwrap()).unwrap();
        assert_eq!(back.width, raster.width);
        assert_eq!(back.height, raster.height);
        assert_eq!(back.sample_type(), raster.sample_type());
        back
    }

    #[test]
    fn gdal_metadata_round_trips_including_non_ascii_text() {
        let mut r = Raster::new(3, 2, Samples::I16(vec![1, 2, 3, 4, 5, 6])).unwrap();
        r.metadata = Metadata {
            scale: Some(0.25),
            offset: Some(-3.5),
            description: Some("Höhe über NN".into()),
            unit_type: Some("m".into()),
            crs_wkt: None,
            items: vec![wavemesh_codec::MetadataItem {
                name: "DTED_VerticalDatum".into(),
                value: "E08".into(),
                ..Default::default()
            }],
        };
        assert_eq!(round_trip(&r).metadata, r.metadata);
    }

    fn epsg4326() -> Georef {
        Georef {
            geotransform: [
                10.999583333333334,
                1.0 / 1200.0,
                0.0,
                58.000416666666666,
                0.0,
                -1.0 / 1200.0,
            ],
            geo_key_directory: vec![
                1, 1, 0, 4, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326, 2049, 34737, 7, 0,
            ],
            geo_double_params: vec![298.257223563, 6378137.0],
            geo_ascii_params: "WGS 84|".into(),
        }
    }

    #[test]
    fn round_trips_every_type_with_nodata_and_georef() {
        let (w, h) = (7, 5);
        let n = w * h;
        let cases = [
            (
                Samples::U8((0..n).map(|i| (i * 7) as u8).collect()),
                Some(255.0),
            ),
            (
                Samples::U16((0..n).map(|i| (i * 1871) as u16).collect()),
                Some(0.0),
            ),
            (
                Samples::I16((0..n).map(|i| (i as i16 - 17) * 900).collect()),
                Some(-32768.0),
            ),
            (
                Samples::I32((0..n).map(|i| (i as i32 - 3) * 123_456_789).collect()),
                Some(-9999.0),
            ),
            (
                Samples::F32((0..n).map(|i| i as f32 * 0.1 - 1.5).collect()),
                Some(-3.4028235e38),
            ),
            (Samples::U16(vec![7; n]), None),
        ];
        for (samples, nodata) in cases {
            let mut r = Raster::new(w, h, samples).unwrap();
            r.nodata = nodata;
            r.georef = Some(epsg4326());
            let back = round_trip(&r);
            assert_eq!(back, r);
        }
    }

    #[test]
    fn round_trips_nan_and_missing_georef() {
        let mut r = Raster::new(3, 1, Samples::F32(vec![1.5, f32::NAN, -0.25])).unwrap();
        r.nodata = Some(f64::NAN);
        let back = round_trip(&r);
        assert!(back.nodata.unwrap().is_nan());
        assert!(back.georef.is_none());
        let Samples::F32(v) = &back.samples else {
            panic!("type")
        };
        assert_eq!(v[0], 1.5);
        assert!(v[1].is_nan());
        assert_eq!(v[2], -0.25);
    }

    #[test]
    fn rotated_geotransform_uses_model_transformation() {
        let mut r = Raster::new(2, 2, Samples::U8(vec![1, 2, 3, 4])).unwrap();
        r.georef = Some(Georef {
            geotransform: [100.0, 2.0, 0.5, 50.0, 0.25, -2.0],
            ..Georef::default()
        });
        assert_eq!(round_trip(&r), r);
        // South-up (positive y step) also needs the matrix.
        r.georef = Some(Georef {
            geotransform: [100.0, 2.0, 0.0, 50.0, 0.0, 2.0],
            ..Georef::default()
        });
        assert_eq!(round_trip(&r), r);
    }

    #[test]
    fn pixel_is_point_shifts_half_a_pixel() {
        let mut r = Raster::new(2, 2, Samples::U8(vec![1, 2, 3, 4])).unwrap();
        let keys = vec![1, 1, 0, 2, 1024, 0, 1, 2, 1025, 0, 1, 2];
        r.georef = Some(Georef {
            geotransform: [9.5, 1.0, 0.0, 20.5, 0.0, -1.0],
            geo_key_directory: keys,
            ..Georef::default()
        });
        let bytes = encode(&r).unwrap();
        // The file's tie point is the centre of the first pixel...
        let mut decoder = Decoder::new(Cursor::new(bytes.clone())).unwrap();
        let tie = decoder.get_tag_f64_vec(Tag::ModelTiepointTag).unwrap();
        assert_eq!(&tie[3..5], &[10.0, 20.0]);
        // ...and reading shifts it back to the corner.
        assert_eq!(read_bytes(bytes).unwrap(), r);
    }

    #[test]
    fn parses_gdal_nodata_spellings() {
        assert_eq!(parse_nodata("-32768").unwrap(), -32768.0);
        assert_eq!(parse_nodata(" -9999.5 ").unwrap(), -9999.5);
        assert_eq!(parse_nodata("1e+20").unwrap(), 1e20);
        for nan in ["nan", "NaN", "-nan", "+NAN"] {
            assert!(parse_nodata(nan).unwrap().is_nan(), "{nan}");
        }
        assert!(parse_nodata("none").is_err());
        assert_eq!(format_nodata(-32768.0, SampleType::I16), "-32768");
        assert_eq!(format_nodata(-9999.5, SampleType::F32), "-9999.5");
        assert_eq!(format_nodata(f64::NAN, SampleType::F32), "nan");
    }

    #[test]
    fn refuses_too_many_samples_before_decoding() {
        let r = Raster::new(100, 50, Samples::U8(vec![0; 5000])).unwrap();
        let bytes = encode(&r).unwrap();
        let options = ReadOptions {
            max_samples: 4999,
            ..ReadOptions::default()
        };
        let err = read(Cursor::new(bytes), Path::new("x.tif"), &options).unwrap_err();
        assert!(matches!(
            err,
            DemError::TooLarge {
                width: 100,
                height: 50,
                limit: 4999
            }
        ));
    }

    /// A minimal little-endian TIFF with the given tags and no image data.
    fn tiny_tiff(entries: &[(u16, u16, u32, u32)]) -> Vec<u8> {
        let mut b = b"II*\0\x08\0\0\0".to_vec();
        b.extend((entries.len() as u16).to_le_bytes());
        for &(tag, typ, count, value) in entries {
            b.extend(tag.to_le_bytes());
            b.extend(typ.to_le_bytes());
            b.extend(count.to_le_bytes());
            b.extend(value.to_le_bytes());
        }
        b.extend(0u32.to_le_bytes());
        b
    }

    #[test]
    fn absurd_dimensions_are_refused_not_allocated() {
        // 4e9 x 4e9 with a single 1-byte strip.
        let bytes = tiny_tiff(&[
            (256, 4, 1, 4_000_000_000),
            (257, 4, 1, 4_000_000_000),
            (258, 3, 1, 8),
            (262, 3, 1, 1),
            (273, 4, 1, 8),
            (279, 4, 1, 1),
        ]);
        assert!(matches!(read_bytes(bytes), Err(DemError::TooLarge { .. })));
    }

    #[test]
    fn unsupported_layouts_are_named() {
        // RGB 8-bit.
        let rgb = tiny_tiff(&[
            (256, 3, 1, 1),
            (257, 3, 1, 1),
            (258, 3, 1, 8),
            (262, 3, 1, 2),
            (273, 4, 1, 8),
            (277, 3, 1, 3),
            (279, 4, 1, 3),
        ]);
        let err = read_bytes(rgb).unwrap_err().to_string();
        assert!(err.contains("single-band"), "{err}");
        // Two bands.
        let two = tiny_tiff(&[
            (256, 3, 1, 1),
            (257, 3, 1, 1),
            (258, 3, 1, 8),
            (262, 3, 1, 1),
            (273, 4, 1, 8),
            (277, 3, 1, 2),
            (279, 4, 1, 2),
        ]);
        let err = read_bytes(two).unwrap_err().to_string();
        assert!(err.contains("2 bands"), "{err}");
        // 64-bit floats.
        let f64s = tiny_tiff(&[
            (256, 3, 1, 1),
            (257, 3, 1, 1),
            (258, 3, 1, 64),
            (262, 3, 1, 1),
            (273, 4, 1, 8),
            (279, 4, 1, 8),
            (339, 3, 1, 3),
        ]);
        let err = read_bytes(f64s).unwrap_err().to_string();
        assert!(err.contains("64-bit floating-point"), "{err}");
        // Signed 8-bit.
        let i8s = tiny_tiff(&[
            (256, 3, 1, 1),
            (257, 3, 1, 1),
            (258, 3, 1, 8),
            (262, 3, 1, 1),
            (273, 4, 1, 8),
            (279, 4, 1, 1),
            (339, 3, 1, 2),
        ]);
        let err = read_bytes(i8s).unwrap_err().to_string();
        assert!(err.contains("8-bit signed"), "{err}");
    }

    #[test]
    fn truncated_and_garbage_input_is_an_error() {
        let r = Raster::new(64, 64, Samples::I16((0..4096).map(|i| i as i16).collect())).unwrap();
        let bytes = encode(&r).unwrap();
        for cut in [0, 4, 8, 100, bytes.len() / 2, bytes.len() - 1] {
            assert!(read_bytes(bytes[..cut].to_vec()).is_err(), "cut at {cut}");
        }
        assert!(read_bytes(b"II*\0\xff\xff\xff\xff".to_vec()).is_err());
        // Strip data cut off: the IFD is intact but the strip points past the end.
        let b = tiny_tiff(&[
            (256, 3, 1, 4),
            (257, 3, 1, 4),
            (258, 3, 1, 8),
            (262, 3, 1, 1),
            (273, 4, 1, 1000),
            (279, 4, 1, 16),
        ]);
        assert!(read_bytes(b).is_err());
    }

    #[test]
    fn reads_tiled_tiff() {
        // 20 x 18 u8 image in four uncompressed 16 x 16 tiles (edge tiles padded).
        let (w, h, t) = (20u32, 18u32, 16u32);
        let value = |x: u32, y: u32| (x * 7 + y * 3) as u8;
        let mut tiles = Vec::new();
        for ty in 0..2 {
            for tx in 0..2 {
                for y in 0..t {
                    for x in 0..t {
                        let (gx, gy) = (tx * t + x, ty * t + y);
                        tiles.push(if gx < w && gy < h { value(gx, gy) } else { 0 });
                    }
                }
            }
        }
        let n_entries = 10u32;
        let ifd_len = 2 + 12 * n_entries + 4;
        let arrays = 8 + ifd_len; // offsets array, then byte counts array, then tiles
        let data = arrays + 32;
        let offsets: Vec<u32> = (0..4).map(|i| data + i * t * t).collect();
        let mut b = tiny_tiff(&[
            (256, 3, 1, w),
            (257, 3, 1, h),
            (258, 3, 1, 8),
            (259, 3, 1, 1),
            (262, 3, 1, 1),
            (277, 3, 1, 1),
            (322, 3, 1, t),
            (323, 3, 1, t),
            (324, 4, 4, arrays),
            (325, 4, 4, arrays + 16),
        ]);
        assert_eq!(b.len() as u32, arrays);
        for o in &offsets {
            b.extend(o.to_le_bytes());
        }
        for _ in 0..4 {
            b.extend((t * t).to_le_bytes());
        }
        b.extend(&tiles);
        let back = read_bytes(b).unwrap();
        let expected: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).map(move |x| value(x, y)))
            .collect();
        assert_eq!(back.samples, Samples::U8(expected));
    }

    #[test]
    fn reads_lzw_packbits_and_uncompressed() {
        use tiff::encoder::TiffEncoder;
        let data: Vec<u16> = (0..40 * 30).map(|i| (i * 37 % 5000) as u16).collect();
        for compression in [
            Compression::Lzw,
            Compression::Packbits,
            Compression::Uncompressed,
        ] {
            let mut out = Cursor::new(Vec::new());
            TiffEncoder::new(&mut out)
                .unwrap()
                .with_compression(compression)
                .write_image::<colortype::Gray16>(40, 30, &data)
                .unwrap();
            let back = read_bytes(out.into_inner()).unwrap();
            assert_eq!(back.samples, Samples::U16(data.clone()));
            assert_eq!(back.georef, None);
        }
    }
}
