//! Files whose tiles are cut into code blocks (`EncodeOptions::code_block`, `encode
//! --block`): lossless means bit-exact across tiles and blocks, a window decodes to the
//! very samples of the whole decode while reading only its blocks, a budget shares bytes
//! over every block, the bytes do not depend on the threads, and truncated or damaged
//! files decode what is left and say where the damage is.

use std::io;

use wavemesh::synth::FractalTerrain;
use wavemesh_codec::format::verify;
use wavemesh_codec::tiles::ByteSource;
use wavemesh_codec::{
    decode, decode_window, DecodeOptions, EncodeOptions, Quality, Raster, Samples, Wavelet, Window,
};

/// A fractal terrain of `width × height` whole metres (i16), with a void disc when
/// `voids` (nodata -32768).
fn terrain(width: usize, height: usize, voids: bool) -> Raster {
    let land = FractalTerrain::new(11);
    let mut samples = vec![0i16; width * height];
    for (y, row) in samples.chunks_mut(width).enumerate() {
        land.row_i16(y, row);
    }
    if voids {
        for (i, s) in samples.iter_mut().enumerate() {
            let (dx, dy) = ((i % width) as f64 - 150.0, (i / width) as f64 - 120.0);
            if dx * dx + dy * dy < 60.0 * 60.0 {
                *s = -32768;
            }
        }
    }
    let mut raster = Raster::new(width, height, Samples::I16(samples)).unwrap();
    raster.nodata = voids.then_some(-32768.0);
    raster
}

/// The same terrain as floats off any grid (tenths of a millimetre of noise), NaN in
/// the voids.
fn float_terrain(width: usize, height: usize) -> Raster {
    let ints = terrain(width, height, true);
    let floats = (0..ints.len())
        .map(|i| match ints.is_valid(i) {
            true => ints.samples.get_f64(i) as f32 + ((i * 7919) % 1000) as f32 * 1.3e-4,
            false => f32::NAN,
        })
        .collect();
    Raster::new(width, height, Samples::F32(floats)).unwrap()
}

/// Blocks of 64 in tiles of at most 256: a 600 × 420 raster has 3 × 2 tiles.
fn blocked(options: EncodeOptions) -> EncodeOptions {
    options.with_tile_size(Some(256)).with_code_block(Some(64))
}

fn same_samples(a: &Raster, b: &Raster) -> bool {
    (a.width, a.height) == (b.width, b.height)
        && (0..a.len()).all(|i| a.samples.get_f64(i).to_bits() == b.samples.get_f64(i).to_bits())
}

#[test]
fn lossless_code_blocks_are_bit_exact_across_tiles() {
    for raster in [terrain(600, 420, true), float_terrain(600, 420)] {
        let encoded = wavemesh_codec::encode(&raster, &blocked(EncodeOptions::lossless())).unwrap();
        let tiling = encoded.header.tiling.expect("a tiled file");
        assert_eq!(tiling.code_block, Some(64));
        let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
        assert!(decoded.complete);
        assert!(
            same_samples(&decoded.raster, &raster),
            "{:?}",
            raster.sample_type()
        );
    }
}

/// A byte source counting what it hands out.
struct Counted<'a> {
    data: &'a [u8],
    read: u64,
}

impl ByteSource for Counted<'_> {
    fn read_at(&mut self, offset: u64, len: usize) -> io::Result<Vec<u8>> {
        let bytes = (&self.data[..]).read_at(offset, len)?;
        self.read += bytes.len() as u64;
        Ok(bytes)
    }
}

#[test]
fn a_window_decodes_to_the_samples_of_the_whole_decode() {
    let raster = terrain(600, 420, true);
    let cases = [
        ("5/3 lossless", EncodeOptions::lossless()),
        ("9/7 at 0.5 bpp", EncodeOptions::budget(600 * 420 / 16)),
        (
            "5/3 max error 2",
            EncodeOptions::new(Quality::MaxError(2.0), None),
        ),
    ];
    for (name, options) in cases {
        let bytes = wavemesh_codec::encode(&raster, &blocked(options))
            .unwrap()
            .bytes;
        for max_bytes in [None, Some(bytes.len() as u64 / 3)] {
            let options = DecodeOptions::default().with_max_bytes(max_bytes);
            let whole = decode(&bytes, &options).unwrap().raster;
            // Inside one block, across a block border, across a tile border, a corner.
            for (x, y, width, height) in [
                (70, 70, 40, 40),
                (100, 30, 60, 80),
                (230, 200, 60, 100),
                (590, 410, 10, 10),
            ] {
                let window = Window {
                    x,
                    y,
                    width,
                    height,
                };
                let mut source = Counted {
                    data: &bytes,
                    read: 0,
                };
                let part = decode_window(&mut source, Some(window), &options).unwrap();
                let expected = whole.crop(x, y, width, height);
                assert!(
                    same_samples(&part.raster, &expected),
                    "{name}, {max_bytes:?} bytes: window {window:?}"
                );
                // Past the first read of the header (64 KiB, or the file).
                let probe = bytes.len().min(1 << 16) as u64;
                assert!(
                    source.read - probe < bytes.len() as u64 / 2,
                    "{name}: window {window:?} read {} of {} bytes",
                    source.read,
                    bytes.len()
                );
            }
        }
    }
}

#[test]
fn a_budget_is_shared_over_every_block_and_longer_prefixes_are_better() {
    let raster = terrain(600, 420, false);
    let bytes = wavemesh_codec::encode(&raster, &blocked(EncodeOptions::lossless()))
        .unwrap()
        .bytes;
    let mut last = f64::INFINITY;
    for share in [20, 10, 5, 2] {
        let budget = bytes.len() as u64 / share;
        let options = DecodeOptions::default().with_max_bytes(Some(budget));
        let decoded = decode(&bytes, &options).unwrap();
        assert!(
            decoded.bytes_used <= budget,
            "{} > {budget}",
            decoded.bytes_used
        );
        let rmse = wavemesh::metrics::compare(&raster, &decoded.raster)
            .unwrap()
            .rmse;
        assert!(
            rmse < last,
            "1/{share} of the file: RMSE {rmse} after {last}"
        );
        last = rmse;
    }
    // Floats off any grid: their residual section trails each tile's head, read only
    // once every block is whole, so a budget below it still decodes.
    let floats = float_terrain(600, 420);
    let bytes = wavemesh_codec::encode(&floats, &blocked(EncodeOptions::lossless()))
        .unwrap()
        .bytes;
    let options = DecodeOptions::default().with_max_bytes(Some(bytes.len() as u64 / 10));
    let decoded = decode(&bytes, &options).unwrap();
    let rmse = wavemesh::metrics::compare(&floats, &decoded.raster)
        .unwrap()
        .rmse;
    assert!(!decoded.complete && rmse < 10.0, "RMSE {rmse}");
    // A file cut by the encoder's budget decodes whole to its size.
    let budget = 600 * 420 / 32;
    let encoded = wavemesh_codec::encode(&raster, &blocked(EncodeOptions::budget(budget))).unwrap();
    assert!(encoded.bytes.len() as u64 <= budget);
    let decoded = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
    assert!(decoded.complete);
}

#[test]
fn the_bytes_do_not_depend_on_the_threads() {
    let raster = float_terrain(600, 420);
    for options in [EncodeOptions::lossless(), EncodeOptions::budget(20_000)] {
        let with = |threads| {
            let options = blocked(options.clone()).with_threads(threads);
            wavemesh_codec::encode(&raster, &options).unwrap().bytes
        };
        assert_eq!(with(1), with(2));
    }
}

#[test]
fn truncated_and_damaged_files_decode_what_is_left() {
    let raster = terrain(600, 420, true);
    let options = blocked(EncodeOptions::new(Quality::Lossless, None).with_wavelet(Wavelet::Int53));
    let bytes = wavemesh_codec::encode(&raster, &options).unwrap().bytes;
    let whole = decode(&bytes, &DecodeOptions::default()).unwrap();
    // Cut anywhere past the index: an image, not an error, and not complete.
    for cut in [bytes.len() / 3, bytes.len() / 2, bytes.len() - 7] {
        let decoded = decode(&bytes[..cut], &DecodeOptions::default()).unwrap();
        assert!(!decoded.complete, "cut at {cut}");
        assert_eq!(decoded.raster.len(), raster.len());
    }
    // A flipped byte in the middle of the file: reported with its tile, the rest exact.
    let mut damaged = bytes.clone();
    let at = bytes.len() / 2;
    damaged[at] ^= 0x5a;
    let decoded = decode(&damaged, &DecodeOptions::default()).unwrap();
    let damage = decoded.damage.expect("the damage is reported");
    assert!(
        damage.tile.is_some() && damage.offset <= at as u64,
        "{damage:?}"
    );
    let report = verify(&damaged).unwrap();
    assert!(report.damaged());
    let bad: Vec<_> = report
        .sections
        .iter()
        .filter(|s| s.damaged_at.is_some())
        .collect();
    assert_eq!(bad.len(), 1, "{bad:?}");
    assert_eq!(bad[0].name, "code block");
    let tile = bad[0].tile.expect("its tile") as usize;
    let grid = wavemesh_codec::TileGrid {
        width: 600,
        height: 420,
        tile_width: 256,
        tile_height: 256,
        overlap: 0,
    };
    // Every tile but the damaged one decodes exactly as before.
    for k in (0..grid.count()).filter(|&k| k != tile) {
        let w = grid.tile(k);
        let part = |r: &Raster| r.crop(w.x, w.y, w.width, w.height);
        assert!(
            same_samples(&part(&decoded.raster), &part(&whole.raster)),
            "tile {k}"
        );
    }
    assert!(decode(&damaged, &DecodeOptions::default().with_strict(true)).is_err());
    assert!(!verify(&bytes).unwrap().damaged());
}

#[test]
fn block_sides_must_be_multiples_of_64() {
    let raster = terrain(300, 200, false);
    let options = EncodeOptions::lossless().with_code_block(Some(100));
    let error = wavemesh_codec::encode(&raster, &options).unwrap_err();
    assert!(error.to_string().contains("multiple of 64"), "{error}");
    // A raster within one block stays one stream.
    let small = terrain(60, 50, false);
    let one = wavemesh_codec::encode(&small, &EncodeOptions::lossless().with_code_block(Some(64)));
    assert!(one.unwrap().header.tiling.is_none());
}
