//! Decoding the tiles a window touches and placing them in the output.

use super::{TiledLayout, Window};
use crate::container::Header;
use crate::error::CodecError;
use crate::pipeline::{Damage, DecodeOptions, Decoded};
use crate::raster::{Raster, SampleType, Samples};

/// Decodes one tile's stream (its allocated prefix), on the calling thread.
pub(super) fn tile(bytes: &[u8], options: &DecodeOptions) -> Result<Decoded, CodecError> {
    let single = (*options)
        .with_max_bytes(None)
        .with_threads(1)
        .with_significance_map(false);
    crate::progress::observe(|_| {}, || crate::pipeline::decode(bytes, &single))
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

    /// Places tile `k`'s decode (of `fetched` bytes). A tile whose bytes end before its
    /// header does is missing (the file is truncated); any other failure is damage,
    /// reported by tile number, and an error when `strict`. Either way the tile keeps
    /// the fill value and the other tiles decode.
    pub(super) fn place(
        &mut self,
        k: usize,
        layout: &TiledLayout,
        fetched: u64,
        result: Result<Decoded, CodecError>,
        strict: bool,
    ) -> Result<(), CodecError> {
        let start = layout.offsets[k];
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
                self.complete &= decoded.complete && fetched == layout.entries[k].len;
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
