//! The tile index: for every tile, where its stream lies and its rate–distortion ladder,
//! so a reader can plan every range it fetches from the header and the index alone.

use std::io;

use super::blocks::BlockGrid;
use super::{ByteSource, TileGrid};
use crate::container::{
    error_from_u16, error_to_u16, logical_len, unframe, write_varint, Header, Reader,
    MAX_HEADER_LEN,
};
use crate::error::CodecError;

/// One tile's entry in the index. Offsets count from the start of the tile's stream.
#[derive(Debug, Clone, PartialEq)]
pub struct TileEntry {
    /// Bytes of the tile's stream in the file.
    pub len: u64,
    /// Bytes of its header and nodata mask: the shortest prefix that decodes.
    pub head_len: u64,
    /// Estimated sum of squared errors of a decode of the head alone.
    pub initial_error: f64,
    /// Per pass: the prefix length through which it decodes, and the estimated sum of
    /// squared errors after it.
    pub passes: Vec<(u64, f64)>,
}

impl TileEntry {
    /// The tile's rate–distortion points: the head, each pass, and the whole stream
    /// (error 0 when the file is lossless, else that of the last pass).
    pub fn points(&self, lossless: bool) -> Vec<(u64, f64)> {
        let mut points = vec![(self.head_len, self.initial_error)];
        points.extend(self.passes.iter().copied());
        let last = points.last().expect("the head").1;
        points.push((self.len, if lossless { 0.0 } else { last }));
        points
    }

    /// [`points`](Self::points) with the passes between them modelled: inside each
    /// segment of at least 16 bytes whose later error is above 0, a point at every
    /// sixteenth of its bytes (rounded down), the error falling by the same factor at
    /// each. A pass codes the decisions that lower the error most first,
    /// so its error falls fastest at its start: an allocation that stops tiles inside
    /// passes comes closer to what a decode gets than along straight lines.
    pub fn modelled_points(&self, lossless: bool) -> Vec<(u64, f64)> {
        let points = self.points(lossless);
        let mut modelled = Vec::with_capacity(points.len() * MODEL_STEPS as usize);
        modelled.push(points[0]);
        for pair in points.windows(2) {
            let ((from, e0), (to, e1)) = (pair[0], pair[1]);
            if e1 > 0.0 && e0 > e1 && to - from >= MODEL_STEPS {
                modelled.extend((1..MODEL_STEPS).map(|k| {
                    let t = k as f64 / MODEL_STEPS as f64;
                    (from + (to - from) * k / MODEL_STEPS, e0 * (e1 / e0).powf(t))
                }));
            }
            modelled.push(pair[1]);
        }
        modelled
    }
}

/// Parts a pass is cut into by [`TileEntry::modelled_points`].
const MODEL_STEPS: u64 = 16;

/// Serialises the index (before framing). Compact (files whose tiles have the tile
/// layout): per tile, varints `len`, `head_len`, the initial error's code (see
/// [`error_code`]), the pass count, then per pass the growth of its end over the previous
/// one (the first over `head_len`) and how much its code is below the previous one's.
/// Before it: the initial error and each pass's error as u16s on the ladder's log scale.
pub(crate) fn write_index(entries: &[TileEntry], compact: bool) -> Vec<u8> {
    let mut out = Vec::with_capacity(entries.len() * 32);
    for entry in entries {
        write_varint(&mut out, entry.len);
        write_varint(&mut out, entry.head_len);
        let mut code = error_code(entry.initial_error);
        match compact {
            true => write_varint(&mut out, code),
            false => out.extend_from_slice(&error_to_u16(entry.initial_error).to_le_bytes()),
        }
        write_varint(&mut out, entry.passes.len() as u64);
        let mut previous = entry.head_len;
        for &(end, error) in &entry.passes {
            write_varint(&mut out, end - previous);
            previous = end;
            if compact {
                let drop = code.saturating_sub(error_code(error));
                write_varint(&mut out, drop);
                code -= drop;
            } else {
                out.extend_from_slice(&error_to_u16(error).to_le_bytes());
            }
        }
    }
    out
}

/// A squared error on the compact index's log scale: `round(log2(1 + e) · 32)`, 1/32 of
/// a bit (≈ 0.09 dB) a step.
fn error_code(squared_error: f64) -> u64 {
    ((1.0 + squared_error.max(0.0)).log2() * 32.0).round() as u64
}

/// Inverse of [`error_code`] (to its precision).
fn error_of_code(code: u64) -> f64 {
    (code as f64 / 32.0).exp2() - 1.0
}

/// Largest error code a compact index may hold (that of an error of 2^2048).
const MAX_ERROR_CODE: u64 = 2048 * 32;

/// Parses an index of `count` entries (`compact`: see [`write_index`]); every offset
/// must lie inside its tile.
pub(crate) fn parse_index(
    bytes: &[u8],
    count: usize,
    compact: bool,
) -> Result<Vec<TileEntry>, CodecError> {
    let bad = |what: &str| CodecError::InvalidHeader(format!("tile index: {what}"));
    let mut r = Reader {
        data: bytes,
        pos: 0,
    };
    let mut entries = Vec::with_capacity(count.min(bytes.len() / MIN_ENTRY_BYTES));
    let field = |r: &mut Reader| r.varint().map_err(|_| bad("ends early"));
    let old_error = |r: &mut Reader| r.u16().map(error_from_u16).map_err(|_| bad("ends early"));
    for _ in 0..count {
        let len = field(&mut r)?;
        let head_len = field(&mut r)?;
        let mut code = if compact { field(&mut r)? } else { 0 };
        if code > MAX_ERROR_CODE {
            return Err(bad("an error beyond any raster's"));
        }
        let initial_error = match compact {
            true => error_of_code(code),
            false => old_error(&mut r)?,
        };
        let pass_count = field(&mut r)?;
        if head_len > len || pass_count > 64 {
            return Err(bad("a tile's head or pass count"));
        }
        let mut passes = Vec::with_capacity(pass_count as usize);
        let mut end = head_len;
        for _ in 0..pass_count {
            end = end
                .checked_add(field(&mut r)?)
                .filter(|&e| e <= len)
                .ok_or_else(|| bad("a pass ends past its tile"))?;
            let error = if compact {
                code = code
                    .checked_sub(field(&mut r)?)
                    .ok_or_else(|| bad("an error below zero"))?;
                error_of_code(code)
            } else {
                old_error(&mut r)?
            };
            passes.push((end, error));
        }
        entries.push(TileEntry {
            len,
            head_len,
            initial_error,
            passes,
        });
    }
    if r.pos != bytes.len() {
        return Err(bad("trailing bytes"));
    }
    Ok(entries)
}

/// The first entry of each tile of `grid` and the entry count: one entry a tile, or with
/// code blocks of `code_block` a head and one per block of what the tile codes.
fn tile_entries(grid: &TileGrid, code_block: Option<u32>) -> Vec<usize> {
    let mut starts = Vec::with_capacity(grid.count() + 1);
    let mut next = 0usize;
    for k in 0..grid.count() {
        starts.push(next);
        let tile = grid.coded(k);
        let blocks = code_block
            .and_then(|side| BlockGrid::new(tile.width, tile.height, side as usize, 0))
            .map_or(0, |blocks| blocks.count());
        next = next.saturating_add(1 + blocks);
    }
    starts.push(next);
    starts
}

/// Fewest bytes an index entry takes (four varints of the compact form).
const MIN_ENTRY_BYTES: usize = 4;

/// A tiled file's header and index, read from the start of a file: all a reader needs to
/// plan which bytes to fetch.
#[derive(Debug, Clone)]
pub struct TiledLayout {
    /// The file's header (describing the whole raster).
    pub header: Header,
    /// Bytes of the header.
    pub header_len: u64,
    /// The tiles.
    pub grid: TileGrid,
    /// The index entries in file order: one per tile, row-major, or with code blocks
    /// per tile its head's and then its blocks' (row-major).
    pub entries: Vec<TileEntry>,
    /// File offset of each entry's stream.
    pub offsets: Vec<u64>,
    /// First entry of each tile, then the entry count: tile `k`'s entries are
    /// `tile_entries[k]..tile_entries[k + 1]`.
    pub tile_entries: Vec<usize>,
}

impl TiledLayout {
    /// Reads the header and, for a tiled file, the index: `Ok(None)` for a single
    /// stream. Refuses an index larger than `max_index_bytes`.
    pub fn read(
        source: &mut impl ByteSource,
        max_index_bytes: u64,
    ) -> Result<Option<TiledLayout>, CodecError> {
        let (header, header_len) = read_header(source)?;
        let Some(tiling) = header.tiling else {
            return Ok(None);
        };
        let grid = TileGrid {
            width: header.width as usize,
            height: header.height as usize,
            tile_width: tiling.tile_width as usize,
            tile_height: tiling.tile_height as usize,
            overlap: tiling.overlap as usize,
        };
        // Every entry takes at least 4 bytes; a forged count cannot allocate beyond that.
        let index_holds = |count: usize| {
            let least = (count as u64).saturating_mul(MIN_ENTRY_BYTES as u64);
            match logical_len(tiling.index_len).is_some_and(|len| len >= least) {
                true => Ok(()),
                false => Err(CodecError::InvalidHeader(format!(
                    "a tile index of {} bytes for {count} entries",
                    tiling.index_len
                ))),
            }
        };
        index_holds(grid.count())?;
        if tiling.index_len > max_index_bytes {
            return Err(CodecError::LimitExceeded {
                what: "tile index bytes",
                needed: tiling.index_len,
                limit: max_index_bytes,
            });
        }
        let framed = source
            .read_at(header_len as u64, tiling.index_len as usize)
            .map_err(read_error)?;
        let index = unframe(&framed, tiling.index_len as usize);
        if let Some(at) = index.damaged_at {
            return Err(CodecError::Damaged {
                section: "tile index",
                offset: header_len as u64 + at as u64,
            });
        }
        if !index.complete {
            return Err(CodecError::TruncatedHeader(
                "file ends inside the tile index",
            ));
        }
        // Only now, with the index's bytes at hand, is the tile count known to be small.
        let tile_entries = tile_entries(&grid, tiling.code_block);
        let count = *tile_entries.last().expect("a start");
        index_holds(count)?;
        let entries = parse_index(&index.bytes, count, tiling.compact_tiles)?;
        let mut offsets = Vec::with_capacity(count);
        let mut offset = header_len as u64 + tiling.index_len;
        for entry in &entries {
            offsets.push(offset);
            offset = offset
                .checked_add(entry.len)
                .filter(|&end| end <= crate::container::MAX_FILE_LEN)
                .ok_or_else(|| {
                    CodecError::InvalidHeader("tile lengths run past any file".into())
                })?;
        }
        Ok(Some(TiledLayout {
            header,
            header_len: header_len as u64,
            grid,
            entries,
            offsets,
            tile_entries,
        }))
    }

    /// Side of the code blocks the tiles are cut into, if they are.
    pub fn code_block(&self) -> Option<usize> {
        self.header
            .tiling
            .and_then(|t| t.code_block)
            .map(|side| side as usize)
    }

    /// Whether the tiles' streams have the tile layout (see [`Header::parse_tile`]).
    pub fn compact_tiles(&self) -> bool {
        self.header.tiling.is_some_and(|t| t.compact_tiles)
    }

    /// Length of the file the header and index describe.
    pub fn file_len(&self) -> u64 {
        self.offsets.last().map_or(0, |&o| o) + self.entries.last().map_or(0, |e| e.len)
    }

    /// Bytes before the first tile: header and index.
    pub fn head_len(&self) -> u64 {
        self.offsets
            .first()
            .copied()
            .unwrap_or_else(|| self.file_len())
    }
}

/// Reads and parses the header at the start of `source`, fetching more when it is longer
/// than a first 64 KiB read.
pub fn read_header(source: &mut impl ByteSource) -> Result<(Header, usize), CodecError> {
    let first = source.read_at(0, 1 << 16).map_err(read_error)?;
    match Header::declared_len(&first) {
        Some(len) if len > first.len() && len <= MAX_HEADER_LEN => {
            let whole = source.read_at(0, len).map_err(read_error)?;
            Header::parse(&whole)
        }
        _ => Header::parse(&first),
    }
}

fn read_error(error: io::Error) -> CodecError {
    CodecError::Read(error.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn modelled_points_fall_geometrically_inside_passes() {
        let entry = TileEntry {
            len: 2000,
            head_len: 10,
            initial_error: 4096.0,
            passes: vec![(20, 1024.0), (1620, 16.0)],
        };
        let modelled = entry.modelled_points(true);
        // The head-to-first-pass segment is under 16 bytes; the pass to the lossless end
        // ends at error 0: neither is modelled. The pass of 1600 bytes is, in steps of
        // 100 bytes, its error falling by 2^(-6/16) at each.
        assert_eq!(modelled.len(), 4 + 15);
        assert_eq!(&modelled[..2], &entry.points(true)[..2]);
        for (k, &(end, error)) in modelled[2..17].iter().enumerate() {
            let t = (k + 1) as f64 / 16.0;
            assert_eq!(end, 20 + 100 * (k as u64 + 1));
            assert!((error - 1024.0 * (-6.0 * t).exp2()).abs() < 1e-9, "{error}");
        }
        assert_eq!(&modelled[17..], &entry.points(true)[2..]);
    }

    #[test]
    fn a_compact_index_keeps_errors_to_a_32nd_of_a_bit() {
        let entries = vec![
            TileEntry {
                len: 5000,
                head_len: 19,
                initial_error: 3.7e9,
                passes: vec![(40, 9.1e8), (300, 2.2e8), (301, 2.3e8), (4000, 0.4)],
            },
            TileEntry {
                len: 19,
                head_len: 19,
                initial_error: 0.0,
                passes: Vec::new(),
            },
        ];
        let compact = write_index(&entries, true);
        assert!(compact.len() < write_index(&entries, false).len());
        let parsed = parse_index(&compact, 2, true).unwrap();
        assert_eq!(parsed[1], entries[1]);
        let (first, read) = (&entries[0], &parsed[0]);
        assert_eq!((read.len, read.head_len), (first.len, first.head_len));
        let close = |a: f64, b: f64| ((1.0 + a).log2() - (1.0 + b).log2()).abs() <= 1.0 / 64.0;
        assert!(close(read.initial_error, first.initial_error));
        for (k, (&(end, error), &(read_end, read_error))) in
            first.passes.iter().zip(&read.passes).enumerate()
        {
            assert_eq!(end, read_end);
            // An error above the previous pass's is kept at the previous one.
            let expected = if k == 2 { first.passes[1].1 } else { error };
            assert!(
                close(read_error, expected),
                "pass {k}: {read_error} for {error}"
            );
        }
    }

    #[test]
    fn a_compact_index_refuses_errors_below_zero_and_beyond_any_raster() {
        let mut bytes = Vec::new();
        for v in [100, 10, 5, 1, 20, 6] {
            write_varint(&mut bytes, v);
        }
        assert!(parse_index(&bytes, 1, true).is_err(), "code 5 less 6");
        let mut beyond = Vec::new();
        for v in [100, 10, MAX_ERROR_CODE + 1, 0] {
            write_varint(&mut beyond, v);
        }
        assert!(parse_index(&beyond, 1, true).is_err());
    }
}
