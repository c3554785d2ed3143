//! The version-1 header (fixed-width fields), read so that version-1 files decode
//! forever. `codec/FORMAT.md` ("Version 1 header") gives the byte layout.

use super::{check_levels, read_bands, read_kinds, Header, Reader};
use crate::error::CodecError;
use crate::quantize::ValueMapping;
use crate::raster::{Georef, Metadata};

/// Parses the fields after the header length; `r` ends before the CRC.
pub(super) fn parse_fields(r: &mut Reader) -> Result<Header, CodecError> {
    let width = r.u32()?;
    let height = r.u32()?;
    let (sample_type, wavelet, levels, mode) = read_kinds(r)?;
    check_levels(width, height, levels)?;
    let offset = r.f64()?;
    let step = r.f64()?;
    let max_error = r.f64()?;
    let coefficient_step = r.f64()?;
    let valid_range = (r.f64()?, r.f64()?);
    let has_nodata = r.u8()? != 0;
    let nodata_bits = r.u64()?;
    let nodata = has_nodata.then(|| f64::from_bits(nodata_bits));
    let top_plane = match r.u8()? {
        0xFF => None,
        p => Some(p),
    };
    let band_count = r.u16()? as usize;
    let bands = read_bands(r, wavelet, levels)?;
    if band_count != bands.len() {
        return Err(CodecError::InvalidHeader(format!(
            "{band_count} subbands for {levels} levels"
        )));
    }
    let payload_len = r.u64()?;
    let payload_truncated = match r.u8()? {
        0 => false,
        1 => true,
        _ => return Err(CodecError::InvalidHeader("payload flag".into())),
    };
    let mask_len = r.u32()?;
    let residual_len = r.u32()?;
    let correction_step = r.f64()?;
    let ladder_len = r.u32()?;
    let georef = match r.u8()? {
        0 => None,
        1 => Some(read_georef(r)?),
        _ => return Err(CodecError::InvalidHeader("georeferencing flag".into())),
    };
    Ok(Header {
        width,
        height,
        sample_type,
        wavelet,
        levels,
        mode,
        mapping: ValueMapping { offset, step },
        max_error,
        coefficient_step,
        nodata,
        valid_range,
        coder: crate::ezw::Coder::V1,
        shift_rule: crate::wavelet::ShiftRule::Rounded,
        top_plane,
        bands,
        derived: super::DerivedMemo(None),
        payload_len,
        payload_truncated,
        mask_len,
        residual_len,
        correction_step,
        residuals_by_exponent: false,
        ladder_len,
        passes: Vec::new(),
        georef,
        metadata: Metadata::default(),
        tiling: None,
    })
}

/// The geotransform and the three GeoTIFF key arrays, each list with a u32 count.
fn read_georef(r: &mut Reader) -> Result<Georef, CodecError> {
    let mut geotransform = [0.0; 6];
    for v in &mut geotransform {
        *v = r.f64()?;
    }
    let n = r.count(2)?;
    let geo_key_directory = (0..n).map(|_| r.u16()).collect::<Result<_, _>>()?;
    let n = r.count(8)?;
    let geo_double_params = (0..n).map(|_| r.f64()).collect::<Result<_, _>>()?;
    let n = r.count(1)?;
    let geo_ascii_params = String::from_utf8_lossy(r.bytes(n)?).into_owned();
    Ok(Georef {
        geotransform,
        geo_key_directory,
        geo_double_params,
        geo_ascii_params,
    })
}
