//! Tiled files: lossless round trips, windows, budgets, threads, truncation and damage.

use std::io;

use wavemesh_codec::tiles::TiledLayout;
use wavemesh_codec::{
    decode, decode_window, decode_windows, encode, ByteSource, DecodeOptions, EncodeOptions,
    Quality, Raster, Samples, Window,
};

/// A smooth terrain with a ridge and some noise, `width × height` i16.
fn terrain(width: usize, height: usize) -> Raster {
    let samples = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            let ridge = 300.0 * (-((x - 0.7 * y - 20.0) / 25.0).powi(2)).exp();
            let noise = ((i as u64).wrapping_mul(2654435761) % 7) as f64;
            (500.0 + 2.0 * x - 1.5 * y + ridge + noise) as i16
        })
        .collect();
    Raster::new(width, height, Samples::I16(samples)).unwrap()
}

fn tiled(tile: u32, quality: Quality, budget: Option<u64>) -> EncodeOptions {
    EncodeOptions::new(quality, budget)
        .with_tile_size(Some(tile))
        .with_threads(1)
}

fn squared_error(a: &Raster, b: &Raster) -> f64 {
    (0..a.len())
        .map(|i| (a.samples.get_f64(i) - b.samples.get_f64(i)).powi(2))
        .sum()
}

/// The squared error of `raster` encoded in `tile`-sample tiles cut at `budget` bytes
/// (checked to fit it), decoded.
fn cut_at_budget_error(raster: &Raster, tile: u32, budget: u64) -> f64 {
    let cut = encode(raster, &tiled(tile, Quality::Lossless, Some(budget))).unwrap();
    assert!(cut.bytes.len() as u64 <= budget);
    let decoded = decode(&cut.bytes, &DecodeOptions::default()).unwrap();
    squared_error(raster, &decoded.raster)
}

#[test]
fn lossless_tiles_round_trip_bit_exactly_whatever_the_threads() {
    let mut raster = terrain(203, 150);
    raster.nodata = Some(-32768.0);
    if let Samples::I16(v) = &mut raster.samples {
        v[1000..1100].fill(-32768);
    }
    let one = encode(&raster, &tiled(64, Quality::Lossless, None)).unwrap();
    let two = encode(&raster, &tiled(64, Quality::Lossless, None).with_threads(2)).unwrap();
    assert_eq!(one.bytes, two.bytes, "the bytes depend on the thread count");
    let tiling = one.header.tiling.expect("a tiled file");
    // 203 = 4 tiles of 51 (the last 50), 150 = 3 tiles of 50.
    assert_eq!((tiling.tile_width, tiling.tile_height), (51, 50));
    let decoded = decode(&one.bytes, &DecodeOptions::default()).unwrap();
    assert!(decoded.complete);
    assert_eq!(decoded.raster, raster);
}

#[test]
fn float_tiles_with_nan_voids_round_trip() {
    let base = terrain(130, 70);
    let values = (0..base.len())
        .map(|i| {
            let v = base.samples.get_f64(i) as f32 * 0.37 + 0.001;
            if (i / 130) % 9 == 0 && i % 130 > 60 {
                f32::NAN
            } else {
                v
            }
        })
        .collect();
    let raster = Raster::new(130, 70, Samples::F32(values)).unwrap();
    let encoded = encode(&raster, &tiled(40, Quality::Lossless, None)).unwrap();
    let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    for i in 0..raster.len() {
        let (a, b) = (raster.samples.get_f64(i), decoded.raster.samples.get_f64(i));
        assert!(
            a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
            "sample {i}"
        );
    }
}

#[test]
fn small_rasters_stay_one_stream() {
    let raster = terrain(64, 64);
    let encoded = encode(&raster, &tiled(64, Quality::Lossless, None)).unwrap();
    assert!(encoded.header.tiling.is_none());
}

#[test]
fn a_window_decodes_like_the_same_part_of_the_whole() {
    let raster = terrain(200, 180);
    let encoded = encode(&raster, &tiled(64, Quality::Lossless, None)).unwrap();
    let whole = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    let window = Window {
        x: 50,
        y: 61,
        width: 90,
        height: 40,
    };
    for budget in [None, Some(encoded.bytes.len() as u64 / 5)] {
        let options = DecodeOptions::default().with_max_bytes(budget);
        let all = decode(&encoded.bytes, &options).unwrap();
        let part = decode_window(&mut &encoded.bytes[..], Some(window), &options).unwrap();
        assert_eq!(part.raster.samples, all.raster.crop(50, 61, 90, 40).samples);
    }
    assert_eq!(whole.raster, raster);
}

#[test]
fn windows_decode_one_after_the_other_as_each_alone() {
    let raster = terrain(200, 180);
    // Overlapping, repeated, one sample, the whole raster; tiled and single streams.
    let windows = [
        (0, 0, 64, 64),
        (50, 61, 90, 40),
        (50, 61, 90, 40),
        (199, 179, 1, 1),
    ]
    .map(|(x, y, width, height)| Window {
        x,
        y,
        width,
        height,
    });
    let whole = Window {
        x: 0,
        y: 0,
        width: 200,
        height: 180,
    };
    for tile in [64, 1024] {
        let encoded = encode(&raster, &tiled(tile, Quality::Lossless, None)).unwrap();
        for (threads, budget) in [
            (1, None),
            (2, None),
            (3, Some(encoded.bytes.len() as u64 / 4)),
        ] {
            let options = DecodeOptions::default()
                .with_threads(threads)
                .with_max_bytes(budget);
            let (mut before_output, mut delivered) = (0, Vec::new());
            let windows = [&windows[..], &[whole]].concat();
            decode_windows(
                &mut &encoded.bytes[..],
                &windows,
                &options,
                &mut || before_output += 1,
                &mut |w, d| {
                    delivered.push((w, d));
                    true
                },
            )
            .unwrap();
            assert_eq!(
                (before_output, delivered.len()),
                (windows.len(), windows.len())
            );
            for (w, d) in delivered {
                if budget.is_none() {
                    let part = raster.crop(w.x, w.y, w.width, w.height);
                    assert_eq!(d.raster.samples, part.samples, "lossless");
                }
                let alone = decode_window(&mut &encoded.bytes[..], Some(w), &options).unwrap();
                assert_eq!(
                    d.raster, alone.raster,
                    "tile {tile}, {threads} threads, {w:?}"
                );
                assert_eq!(
                    (d.passes_decoded, d.complete, d.bytes_used),
                    (alone.passes_decoded, alone.complete, alone.bytes_used)
                );
            }
        }
        // `deliver` saying no stops the decode.
        let mut delivered = 0;
        decode_windows(
            &mut &encoded.bytes[..],
            &windows,
            &DecodeOptions::default().with_threads(2),
            &mut || {},
            &mut |_, _| {
                delivered += 1;
                false
            },
        )
        .unwrap();
        assert_eq!(delivered, 1);
    }
}

/// A source that counts the bytes it hands out.
struct Counting<'a> {
    data: &'a [u8],
    read: u64,
}

impl ByteSource for Counting<'_> {
    fn read_at(&mut self, offset: u64, len: usize) -> io::Result<Vec<u8>> {
        let bytes = (&mut self.data).read_at(offset, len)?;
        self.read += bytes.len() as u64;
        Ok(bytes)
    }
}

#[test]
fn a_window_reads_only_the_tiles_it_touches() {
    let raster = terrain(256, 256);
    let encoded = encode(&raster, &tiled(64, Quality::Lossless, None)).unwrap();
    let layout = TiledLayout::read(&mut &encoded.bytes[..], u64::MAX)
        .unwrap()
        .unwrap();
    let mut source = Counting {
        data: &encoded.bytes,
        read: 0,
    };
    let window = Window {
        x: 70,
        y: 10,
        width: 50,
        height: 40,
    };
    let part = decode_window(&mut source, Some(window), &DecodeOptions::default()).unwrap();
    assert_eq!(part.raster.samples, raster.crop(70, 10, 50, 40).samples);
    // The window lies in tile 1 (x 64–127, y 0–63): the header read (up to 64 KiB, the
    // whole small file), the index, and that tile again.
    let tile = layout.entries[1].len;
    assert!(
        source.read <= encoded.bytes.len() as u64 + layout.head_len() + tile,
        "read {} bytes",
        source.read
    );
    let mut big = Counting {
        data: &encoded.bytes,
        read: 0,
    };
    decode_window(&mut big, None, &DecodeOptions::default()).unwrap();
    assert!(source.read < big.read);
}

#[test]
fn budgets_spend_bytes_where_they_buy_the_most() {
    let raster = terrain(256, 200);
    let file = encode(&raster, &tiled(64, Quality::Lossless, None)).unwrap();
    let mut previous = f64::INFINITY;
    for fraction in [10, 5, 3, 2] {
        let budget = file.bytes.len() as u64 / fraction;
        let options = DecodeOptions::default().with_max_bytes(Some(budget));
        let decoded = decode(&file.bytes, &options).unwrap();
        assert!(
            decoded.bytes_used <= budget,
            "{} > {budget}",
            decoded.bytes_used
        );
        let error = squared_error(&raster, &decoded.raster);
        assert!(
            error <= previous,
            "more bytes, more error: {error} > {previous}"
        );
        previous = error;
        // An encode cut at the same budget fits it and decodes about as well.
        let cut_error = cut_at_budget_error(&raster, 64, budget);
        assert!(cut_error <= 1.5 * error + 1.0, "{cut_error} vs {error}");
    }
}

/// One rough tile among flat ones: under a budget it needs many times its share, more
/// than the encoder first codes a tile to; the cut must still match a decode of the
/// complete file at the same budget.
#[test]
fn a_tile_needing_many_times_its_share_is_not_starved_by_its_cap() {
    let (width, height) = (512, 512);
    let samples = (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            if x < 128 && y < 128 {
                ((i as u64).wrapping_mul(2654435761) % 4000) as i16 - 2000
            } else {
                100
            }
        })
        .collect();
    let raster = Raster::new(width, height, Samples::I16(samples)).unwrap();
    let budget = (width * height / 8) as u64;
    let full = encode(&raster, &tiled(128, Quality::Lossless, Some(8 * budget))).unwrap();
    let at_budget = DecodeOptions::default().with_max_bytes(Some(budget));
    let full_error = squared_error(&raster, &decode(&full.bytes, &at_budget).unwrap().raster);
    let cut_error = cut_at_budget_error(&raster, 128, budget);
    assert!(
        cut_error <= 1.05 * full_error,
        "cut at the budget: {cut_error}, the whole file decoded at it: {full_error}"
    );
}

#[test]
fn a_truncated_file_decodes_the_tiles_it_holds() {
    let raster = terrain(200, 130);
    let file = encode(&raster, &tiled(64, Quality::Lossless, None)).unwrap();
    let layout = TiledLayout::read(&mut &file.bytes[..], u64::MAX)
        .unwrap()
        .unwrap();
    // Cut inside tile 5: tiles 0–4 whole, 5 partly, the rest missing.
    let cut = (layout.offsets[5] + layout.entries[5].len / 2) as usize;
    let decoded = decode(&file.bytes[..cut], &DecodeOptions::default()).unwrap();
    assert!(!decoded.complete);
    let first = layout.grid.tile(0);
    assert_eq!(
        decoded
            .raster
            .crop(first.x, first.y, first.width, first.height)
            .samples,
        raster
            .crop(first.x, first.y, first.width, first.height)
            .samples
    );
}

#[test]
fn a_damaged_tile_is_reported_by_number_and_the_others_decode() {
    let raster = terrain(200, 130);
    let mut file = encode(&raster, &tiled(64, Quality::Lossless, None))
        .unwrap()
        .bytes;
    let layout = TiledLayout::read(&mut &file[..], u64::MAX)
        .unwrap()
        .unwrap();
    let at = (layout.offsets[3] + layout.entries[3].head_len + 10) as usize;
    file[at] ^= 0x40;
    let decoded = decode(&file, &DecodeOptions::default()).unwrap();
    let damage = decoded.damage.expect("damage found");
    assert_eq!(damage.tile, Some(3));
    for k in [0, 1, 2, 4, 5] {
        let t = layout.grid.tile(k);
        assert_eq!(
            decoded.raster.crop(t.x, t.y, t.width, t.height).samples,
            raster.crop(t.x, t.y, t.width, t.height).samples,
            "tile {k}"
        );
    }
    let strict = DecodeOptions::default().with_strict(true);
    assert!(decode(&file, &strict).is_err());
}

#[test]
fn every_tile_of_a_max_error_file_has_a_ladder_start() {
    // Large bounds make the cut 9/7 stream with corrections win in some tiles; the
    // index must still hold each tile's initial error, or budgets skip those tiles.
    let raster = terrain(200, 130);
    for e in [4.0, 16.0] {
        let file = encode(&raster, &tiled(64, Quality::MaxError(e), None)).unwrap();
        let layout = TiledLayout::read(&mut &file.bytes[..], u64::MAX)
            .unwrap()
            .unwrap();
        let corrected = layout.offsets.iter().any(|&o| {
            let (header, _) =
                wavemesh_codec::Header::parse_tile(&file.bytes[o as usize..]).unwrap();
            header.correction_step > 0.0
        });
        eprintln!("max error {e}: corrections in some tile: {corrected}");
        for (k, entry) in layout.entries.iter().enumerate() {
            assert!(
                entry.initial_error > 0.0,
                "tile {k} at max error {e}: {entry:?}"
            );
        }
    }
}

/// A budget's cut does not depend on how far the encoder first coded each tile: tiles
/// coded up to the encoder's caps by detail, up to half an even share and 4 KiB each
/// (far below the detailed tiles' caps by detail, so those are coded again where the cut
/// comes near their cap), and whole cut to the same bytes, at rates where the caps stop
/// every tile and where they stop none.
#[test]
fn a_cut_does_not_depend_on_the_tiles_caps() {
    use wavemesh_codec::tiles::{budget_caps, cut_to_budget, encode_tile, RasterInfo, TileDetail};
    use wavemesh_codec::{CodecError, TileGrid};
    let mut raster = terrain(300, 260);
    if let Samples::I16(s) = &mut raster.samples {
        // One rough corner, so one tile needs several times its share.
        for (i, v) in s
            .iter_mut()
            .enumerate()
            .filter(|(i, _)| i % 300 < 100 && i / 300 < 90)
        {
            *v += ((i as u64).wrapping_mul(2654435761) % 900) as i16;
        }
    }
    let grid = TileGrid::balanced(300, 260, 128).unwrap();
    let info = RasterInfo::of(&raster);
    let mut starved_tiles = 0;
    for budget in [1_000, 4_000, 15_000, 40_000] {
        let options = tiled(128, Quality::Lossless, Some(budget));
        let code = |k: usize, cap: Option<u64>| {
            let w = grid.coded(k);
            encode_tile(&raster.crop(w.x, w.y, w.width, w.height), &options, cap)
        };
        let mut recoded = 0;
        let mut recode = |k: usize, cap: u64| {
            recoded += 1;
            code(k, Some(cap))
        };
        let cut = |cap: &dyn Fn(usize) -> Option<u64>, recode: &mut dyn FnMut(usize, u64) -> _| {
            let tiles = (0..grid.count())
                .map(|k| code(k, cap(k)))
                .collect::<Result<_, _>>();
            let cut: Vec<_> =
                cut_to_budget::<CodecError>(tiles.unwrap(), &info, &grid, budget, recode).unwrap();
            cut.into_iter().map(|t| t.bytes).collect::<Vec<_>>()
        };
        let details: Vec<TileDetail> = (0..grid.count())
            .map(|k| TileDetail::of(&raster, &grid.coded(k)))
            .collect();
        let caps = budget_caps(&details, &grid, budget);
        let by_detail = cut(&|k| Some(caps[k]), &mut recode);
        let half_share = budget / grid.count() as u64 / 2 + 4096;
        let starved = cut(&|_| Some(half_share), &mut recode);
        let whole = cut(&|_| None, &mut |_, _| {
            unreachable!("a whole tile is never starved")
        });
        assert_eq!(by_detail, whole, "budget {budget}");
        assert_eq!(
            starved, whole,
            "budget {budget} ({recoded} tiles coded again)"
        );
        starved_tiles += recoded;
    }
    assert!(starved_tiles > 0, "no cap came near a cut");
}
