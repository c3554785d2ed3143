//! Decoding the tiles a window touches and placing them in the output.

use std::collections::VecDeque;

use super::workers::{Task, Workers};
use super::{ByteSource, TiledLayout, Window};
use crate::container::{logical_offset, Header};
use crate::error::CodecError;
use crate::ezw::PassRecord;
use crate::pipeline::{Damage, DecodeOptions, Decoded};
use crate::raster::{Raster, SampleType, Samples};

/// Decodes one tile's stream, as many of its bytes as `bytes` holds (`compact`: in the
/// tile layout, as [`TiledLayout::compact_tiles`] says, else a single-stream file), on
/// the calling thread; `options`' byte limit, threads and significance map are ignored.
/// `passes` are the tile's index entry's (prefix length, error) per pass, or empty: its
/// stream holds no ladder, and with one a 9/7 tile of 1- or 2-byte samples decodes in
/// less memory (the ladder says which planes the prefix reaches).
pub fn decode_tile(
    bytes: &[u8],
    compact: bool,
    passes: &[(u64, f64)],
    options: &DecodeOptions,
) -> Result<Decoded, CodecError> {
    let single = (*options)
        .with_max_bytes(None)
        .with_threads(1)
        .with_significance_map(false);
    let (mut header, header_len) = match compact {
        true => Header::parse_tile(bytes)?,
        false => Header::parse(bytes)?,
    };
    if header.passes.is_empty() {
        header.passes = ladder_of(&header, header_len, passes);
    }
    crate::progress::observe(
        |_| {},
        || crate::pipeline::decode_parsed(bytes, header, header_len, &single),
    )
}

/// A tile's ladder from its index entry's passes (prefix lengths from the tile's start):
/// pass `k` is plane `top − k`, and ends at that prefix's payload byte.
fn ladder_of(header: &Header, header_len: usize, passes: &[(u64, f64)]) -> Vec<PassRecord> {
    let Some(top) = header.top_plane.map(u32::from) else {
        return Vec::new();
    };
    let payload_start = header_len as u64 + u64::from(header.mask_len);
    passes
        .iter()
        .zip(0..=top)
        .map(|(&(end, squared_error), k)| PassRecord {
            plane: top - k,
            end_byte: logical_offset(end.saturating_sub(payload_start)),
            squared_error,
        })
        .collect()
}

/// A tile's decode: what [`decode_tile`] returned for it.
type TileDecode = Result<Decoded, CodecError>;

/// The file's tiles in the order the windows place them, each decoded on the workers
/// ahead of its turn: with several threads, one tile more started and not yet taken than
/// there are threads (one thread decodes each tile when it is taken), so a thread
/// finishing a window's last tiles goes on with the next window's first ones, and memory
/// holds a tile's decoders per thread and at most one decoded tile waiting, not a row.
pub(super) struct TilesAhead<'a, S: ByteSource> {
    source: &'a mut S,
    layout: &'a TiledLayout,
    /// Bytes each tile's decode reads.
    lengths: &'a [u64],
    options: DecodeOptions,
    workers: &'a Workers,
    /// Tile indices in placing order.
    order: Vec<usize>,
    /// Tiles of `order` started so far.
    started: usize,
    /// Started and not yet taken: tile, bytes read, its decode.
    running: VecDeque<(usize, u64, Task<TileDecode>)>,
}

impl<'a, S: ByteSource> TilesAhead<'a, S> {
    /// Decodes the tiles of `order`, reading `lengths[k]` bytes of tile `k` from `source`.
    pub(super) fn new(
        (source, layout, lengths): (&'a mut S, &'a TiledLayout, &'a [u64]),
        options: &DecodeOptions,
        workers: &'a Workers,
        order: Vec<usize>,
    ) -> Self {
        TilesAhead {
            source,
            layout,
            lengths,
            options: *options,
            workers,
            order,
            started: 0,
            running: VecDeque::new(),
        }
    }

    /// The next tile in order: its index, the bytes read and its decode. An error when
    /// the source fails; called past the last tile it panics.
    pub(super) fn next(&mut self) -> Result<(usize, u64, TileDecode), CodecError> {
        let threads = self.workers.count();
        let ahead = if threads > 1 { threads + 1 } else { 1 };
        while self.started < self.order.len() && self.running.len() < ahead {
            let k = self.order[self.started];
            let bytes = self
                .source
                .read_at(self.layout.offsets[k], self.lengths[k] as usize)
                .map_err(|e| CodecError::Read(e.to_string()))?;
            let options = self.options;
            let fetched = bytes.len() as u64;
            let compact = self.layout.compact_tiles();
            let passes = self.layout.entries[k].passes.clone();
            let task = self
                .workers
                .spawn(move || decode_tile(&bytes, compact, &passes, &options));
            self.running.push_back((k, fetched, task));
            self.started += 1;
        }
        let (k, fetched, task) = self.running.pop_front().expect("a tile left to take");
        Ok((k, fetched, task.wait()))
    }
}

/// The window being filled, and what the tiles placed so far say about the decode.
pub(super) struct Output {
    raster: Raster,
    window: Window,
    passes: Option<u32>,
    complete: bool,
    bytes_used: u64,
    damage: Option<Damage>,
}

impl Output {
    /// A window of `header`'s raster, every sample at the fill value until a tile lands.
    pub(super) fn new(header: &Header, window: Window) -> Output {
        let samples = Samples::filled(
            header.sample_type,
            fill_value(header),
            window.width * window.height,
        );
        Output {
            raster: Raster::new(window.width, window.height, samples).expect("sized to the window"),
            window,
            passes: None,
            complete: true,
            bytes_used: 0,
            damage: None,
        }
    }

    /// Places tile `k`'s decode (`whole`: of all its bytes). A tile whose bytes end before its
    /// header does is missing (the file is truncated); any other failure is damage,
    /// reported by tile number, and an error when `strict`. Either way the tile keeps
    /// the fill value and the other tiles decode.
    pub(super) fn place(
        &mut self,
        k: usize,
        layout: &TiledLayout,
        whole: bool,
        result: Result<Decoded, CodecError>,
        strict: bool,
    ) -> Result<(), CodecError> {
        let start = layout.offsets[layout.tile_entries[k]];
        let area = layout.grid.coded(k);
        let misfit = |d: &Decoded| {
            (d.raster.width, d.raster.height, d.raster.sample_type())
                != (area.width, area.height, self.raster.sample_type())
        };
        let result = match result {
            Ok(d) if misfit(&d) => Err(CodecError::InvalidHeader(format!(
                "tile {k} is {}x{} {}, not {}x{} {}",
                d.raster.width,
                d.raster.height,
                d.raster.sample_type().name(),
                area.width,
                area.height,
                self.raster.sample_type().name()
            ))),
            other => other,
        };
        match result {
            Ok(decoded) => {
                let part = layout
                    .grid
                    .tile(k)
                    .intersection(&self.window)
                    .expect("a tile the window touches");
                let from = (part.x - area.x, part.y - area.y, part.width, part.height);
                let (x, y) = (part.x - self.window.x, part.y - self.window.y);
                self.raster.paste_part(x, y, &decoded.raster, from);
                self.passes = Some(
                    self.passes
                        .map_or(decoded.passes_decoded, |p| p.min(decoded.passes_decoded)),
                );
                self.complete &= decoded.complete && whole;
                self.bytes_used += decoded.bytes_used;
                if let Some(d) = decoded.damage {
                    self.note(Damage {
                        section: d.section,
                        offset: start + d.offset,
                        tile: Some(k as u32),
                    });
                }
            }
            Err(CodecError::TruncatedHeader(_)) => {
                self.complete = false;
                self.passes = Some(0);
            }
            Err(CodecError::Damaged { section, offset }) if strict => {
                return Err(CodecError::Damaged {
                    section,
                    offset: start + offset,
                });
            }
            Err(_) if strict => {
                return Err(CodecError::Damaged {
                    section: "tile header",
                    offset: start,
                });
            }
            Err(_) => {
                self.complete = false;
                self.passes = Some(0);
                self.note(Damage {
                    section: "tile header",
                    offset: start,
                    tile: Some(k as u32),
                });
            }
        }
        Ok(())
    }

    fn note(&mut self, damage: Damage) {
        if self.damage.is_none_or(|d| damage.offset < d.offset) {
            self.damage = Some(damage);
        }
    }

    /// The decode: the window's samples, with the file's nodata, metadata and
    /// georeferencing moved to the window's corner.
    pub(super) fn finish(mut self, layout: &TiledLayout) -> Decoded {
        let header = &layout.header;
        self.raster.nodata = header.nodata;
        self.raster.metadata = header.metadata.clone();
        self.raster.georef = header.georef.clone().map(|mut georef| {
            let gt = &mut georef.geotransform;
            let (x, y) = (self.window.x as f64, self.window.y as f64);
            gt[0] += x * gt[1] + y * gt[2];
            gt[3] += x * gt[4] + y * gt[5];
            georef
        });
        Decoded {
            raster: self.raster,
            header: header.clone(),
            passes_decoded: self.passes.unwrap_or(0),
            complete: self.complete,
            bytes_used: layout.head_len() + self.bytes_used,
            damage: self.damage,
            significance: None,
        }
    }
}

/// What a sample no tile could give holds: the nodata value (NaN for floats without one
/// or whose nodata has no f32 value), else the middle of the valid range.
fn fill_value(header: &Header) -> f64 {
    match header.nodata {
        Some(nd) if header.sample_type != SampleType::F32 || f64::from(nd as f32) == nd => nd,
        _ if header.sample_type == SampleType::F32 => f64::NAN,
        _ => ((header.valid_range.0 + header.valid_range.1) / 2.0).round(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::EncodeOptions;
    use crate::tiles::encode_tile;

    /// The ladder a tile's index entry gives its stream is the one the same stream
    /// has as a file: the same planes, ending at the same payload bytes.
    #[test]
    fn a_tile_ladder_from_its_index_entry_is_the_streams() {
        let values: Vec<f64> = (0..90 * 70)
            .map(|i| {
                let (x, y) = ((i % 90) as f64, (i / 90) as f64);
                300.0 + 80.0 * (x / 9.0).sin() * (y / 13.0).cos() + (i * 7919 % 13) as f64
            })
            .collect();
        let raster = Raster::new(90, 70, Samples::from_f64(SampleType::I16, &values)).unwrap();
        for options in [EncodeOptions::budget(1500), EncodeOptions::lossless()] {
            // A tile is coded whole when not given a cap: so is the file here.
            let whole = options.clone().with_budget_bytes(None);
            let file = crate::pipeline::encode(&raster, &whole).unwrap();
            let tile = encode_tile(&raster, &options, None).unwrap();
            let (header, header_len) = Header::parse_tile(&tile.bytes).unwrap();
            let ladder = ladder_of(&header, header_len, &tile.summary.entry.passes);
            assert!(ladder.len() > 3, "{} passes", ladder.len());
            let planes_and_ends = |passes: &[PassRecord]| -> Vec<(u32, u64)> {
                passes.iter().map(|p| (p.plane, p.end_byte)).collect()
            };
            assert_eq!(
                planes_and_ends(&ladder),
                planes_and_ends(&file.header.passes)
            );
        }
    }
}
