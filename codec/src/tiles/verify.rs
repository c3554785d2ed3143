//! Checking every checksum of a tiled file: the index, then each tile's header and
//! sections, each tile reported on its own line (and with code blocks, each block).

use super::TiledLayout;
use crate::container::{
    check_frames, logical_len, verify, verify_tile, SectionCheck, Verification, CHUNK,
};
use crate::error::CodecError;

/// Checks a tiled file: one section for the index, then one per tile (its header and all
/// its sections together). Usable bytes are those of the header, the index and every
/// undamaged tile.
pub(crate) fn verify_tiled(data: &[u8]) -> Result<Verification, CodecError> {
    let (header, header_len) = crate::container::Header::parse(data)?;
    let tiling = header.tiling.expect("a tiled header");
    let index_chunks =
        logical_len(tiling.index_len).map_or(0, |l| (l as usize).div_ceil(CHUNK)) as u64;
    let mut index = SectionCheck {
        name: "tile index",
        tile: None,
        offset: header_len as u64,
        framed_len: tiling.index_len,
        chunks: index_chunks,
        verified_chunks: index_chunks,
        damaged_at: None,
        complete: data.len() as u64 >= header_len as u64 + tiling.index_len,
    };
    let layout = match TiledLayout::read(&mut &data[..], u64::MAX) {
        Ok(layout) => layout.expect("a tiled header"),
        Err(CodecError::Damaged { offset, .. }) => {
            index.damaged_at = Some(offset);
            index.verified_chunks = (offset - header_len as u64) / (CHUNK as u64 + 4);
            return Ok(tiled_verification(
                header,
                header_len,
                vec![index],
                0,
                offset,
            ));
        }
        Err(CodecError::TruncatedHeader(_)) => {
            index.verified_chunks = 0;
            return Ok(tiled_verification(
                header,
                header_len,
                vec![index],
                0,
                data.len() as u64,
            ));
        }
        Err(e) => return Err(e),
    };
    let mut sections = vec![index];
    let mut usable = layout.head_len();
    for k in 0..layout.grid.count() {
        let entries = layout.tile_entries[k]..layout.tile_entries[k + 1];
        for e in entries.clone() {
            let (entry, offset) = (&layout.entries[e], layout.offsets[e]);
            let start = (offset as usize).min(data.len());
            let end = (offset.saturating_add(entry.len) as usize).min(data.len());
            let bytes = &data[start..end];
            let check = if e == entries.start {
                let found = match layout.compact_tiles() {
                    true => verify_tile(bytes),
                    false => verify(bytes),
                };
                tile_check(found, bytes.len(), (k as u32, offset, entry.len))
            } else {
                block_check(bytes, (k as u32, offset, entry.len))
            };
            if check.damaged_at.is_none() {
                usable += (end - start) as u64;
            }
            sections.push(check);
        }
    }
    let trailing = (data.len() as u64).saturating_sub(layout.file_len());
    Ok(tiled_verification(
        header, header_len, sections, trailing, usable,
    ))
}

/// The checksums of a code block of tile `tile` (its head byte, then its framed
/// payload) as one section, from its `available` bytes.
fn block_check(available: &[u8], (tile, offset, len): (u32, u64, u64)) -> SectionCheck {
    let framed = len.saturating_sub(1) as usize;
    let found = check_frames(available.get(1..).unwrap_or(&[]), framed);
    let chunks = framed.div_ceil(CHUNK + 4) as u64;
    SectionCheck {
        name: "code block",
        tile: Some(tile),
        offset,
        framed_len: len,
        chunks,
        verified_chunks: match found.complete {
            true => chunks,
            false => (found.data_len / CHUNK) as u64,
        },
        damaged_at: found.damaged_at.map(|at| offset + 1 + at as u64),
        complete: found.complete && available.len() as u64 == len,
    }
}

/// One tile's checksums as one section, from what verifying its `available` bytes
/// `found`: its chunks summed, damaged where its header or first damaged section is.
fn tile_check(
    found: Result<Verification, CodecError>,
    available: usize,
    (tile, offset, len): (u32, u64, u64),
) -> SectionCheck {
    let chunks = (len as usize).div_ceil(CHUNK + 4) as u64;
    let mut check = SectionCheck {
        name: "tile",
        tile: Some(tile),
        offset,
        framed_len: len,
        chunks,
        verified_chunks: 0,
        damaged_at: None,
        complete: false,
    };
    match found {
        Ok(found) => {
            check.verified_chunks = found.sections.iter().map(|s| s.verified_chunks).sum();
            check.chunks = found.sections.iter().map(|s| s.chunks).sum();
            check.damaged_at = found
                .sections
                .iter()
                .filter_map(|s| s.damaged_at)
                .min()
                .map(|at| offset + at);
            check.complete = found.complete() && available as u64 == len;
        }
        Err(CodecError::TruncatedHeader(_)) => {}
        Err(_) => check.damaged_at = Some(offset),
    }
    check
}

fn tiled_verification(
    header: crate::container::Header,
    header_len: usize,
    sections: Vec<SectionCheck>,
    trailing_bytes: u64,
    usable_bytes: u64,
) -> Verification {
    Verification {
        header,
        header_len: header_len as u64,
        sections,
        trailing_bytes,
        usable_bytes,
        usable_passes: None,
    }
}
