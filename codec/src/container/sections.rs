//! The sections of a single-stream file as a decoder reads them: where each starts,
//! what its checksums say, and the first damage.
//!
//! File: header | mask | payload | residuals | ladder, each section framed in
//! checksummed chunks. Damage is the first chunk whose checksum fails, or bytes past
//! the end of the file the header describes.

use super::{check_frames, unframe, FrameCheck, Header, Unframed};
use crate::error::CodecError;
use crate::mask::{decode_mask, Mask};
use crate::pipeline::Damage;

/// The sections of a file, read (mask, residuals) or checked in place (payload).
pub(crate) struct StreamSections<'a> {
    /// The decoded nodata mask, when the file has one.
    pub mask: Option<Mask>,
    /// File offset of the payload.
    pub payload_start: usize,
    /// The payload as the file holds it, framed, from its start to the end of the data.
    pub payload_framed: &'a [u8],
    /// What the payload's checksums say.
    pub payload_check: FrameCheck,
    /// The residual section.
    pub residual: Unframed,
    /// File offset of the ladder.
    pub ladder_start: usize,
    /// The first damaged place, if any.
    pub damage: Option<Damage>,
}

impl<'a> StreamSections<'a> {
    /// Reads the sections of `data` (the file, or the prefix `max_bytes` cut) after a
    /// header of `header_len` bytes. A damaged or incomplete nodata mask is an error:
    /// nothing decodes without it; damage elsewhere is noted.
    pub fn read(
        data: &'a [u8],
        header: &Header,
        header_len: usize,
        max_bytes: Option<u64>,
    ) -> Result<StreamSections<'a>, CodecError> {
        let section = |start: usize, len: usize| -> Unframed {
            unframe(data.get(start.min(data.len())..).unwrap_or(&[]), len)
        };
        let mut damage: Option<Damage> = None;
        let mut note_damage = |what: &'static str, offset: usize| {
            if damage.is_none_or(|d| (offset as u64) < d.offset) {
                damage = Some(Damage {
                    section: what,
                    offset: offset as u64,
                    tile: None,
                });
            }
        };
        let mask = read_mask(data, header, header_len)?;
        let payload_start = header_len + header.mask_len as usize;
        let residual_start = payload_start + header.payload_len as usize;
        let ladder_start = residual_start + header.residual_len as usize;
        // The payload is read in place (no copy): its checksums are checked first.
        let payload_framed = data.get(payload_start.min(data.len())..).unwrap_or(&[]);
        let payload_check = check_frames(payload_framed, header.payload_len as usize);
        if let Some(at) = payload_check.damaged_at {
            note_damage("payload", payload_start + at);
        }
        let residual = section(residual_start, header.residual_len as usize);
        if let Some(at) = residual.damaged_at {
            note_damage("residual section", residual_start + at);
        }
        let ladder = section(ladder_start, header.ladder_len as usize);
        if let Some(at) = ladder.damaged_at {
            note_damage("ladder", ladder_start + at);
        }
        let file_end = ladder_start + header.ladder_len as usize;
        if data.len() > file_end && max_bytes.is_none_or(|m| m as usize > file_end) {
            note_damage("trailing bytes", file_end);
        }
        Ok(StreamSections {
            mask,
            payload_start,
            payload_framed,
            payload_check,
            residual,
            ladder_start,
            damage,
        })
    }
}

/// The nodata mask right after the header, `None` when the file has none.
fn read_mask(data: &[u8], header: &Header, header_len: usize) -> Result<Option<Mask>, CodecError> {
    if header.mask_len == 0 {
        return Ok(None);
    }
    let framed = unframe(
        data.get(header_len.min(data.len())..).unwrap_or(&[]),
        header.mask_len as usize,
    );
    if let Some(at) = framed.damaged_at {
        return Err(CodecError::Damaged {
            section: "nodata mask",
            offset: (header_len + at) as u64,
        });
    }
    if !framed.complete {
        return Err(CodecError::TruncatedHeader(
            "file ends inside the nodata mask",
        ));
    }
    let count = header.sample_count() as usize;
    Ok(Some(decode_mask(
        &framed.bytes,
        header.width as usize,
        count,
    )))
}
