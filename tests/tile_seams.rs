//! Tile seams on the shared DEMs: at 0.25 bpp with 256-sample tiles, the RMSE of the
//! samples along tile borders against the interior's, and the whole-DEM PSNR against an
//! untiled encode. Issue 9 asks for 10 % and 0.2 dB. Tiles overlapping by two samples
//! (the decoder drops them) meet the first on every DEM checked here (0.75–1.05, printed
//! with `--nocapture`; 1.83 on sthelens_10m without the overlap); the second is not met
//! by independent tiles (0.33–0.73 dB: each tile codes its own coarse levels, as JPEG
//! 2000's tiles do, and pays ~55 bytes of header, checksum and index), so their PSNR
//! bound checked is today's with a margin, against regressions. Code blocks under one
//! transform (`--block 256`) meet both (below).

mod support;

use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh::metrics::compare;
use wavemesh_codec::{decode, encode, DecodeOptions, EncodeOptions, Quality, Raster, TileGrid};

/// Squared errors and counts of the valid samples on tile borders (the first and last
/// row and column of every tile, where a neighbour tile begins) and inside tiles.
fn seam_errors(
    original: &Raster,
    decoded: impl Fn(usize) -> f64,
    grid: &TileGrid,
) -> [(f64, usize); 2] {
    let mut sums = [(0.0, 0); 2];
    for y in 0..original.height {
        for x in 0..original.width {
            let i = y * original.width + x;
            if !original.is_valid(i) {
                continue;
            }
            let (tx, ty) = (x % grid.tile_width, y % grid.tile_height);
            let border_x =
                (tx == 0 && x > 0) || (tx == grid.tile_width - 1 && x + 1 < original.width);
            let border_y =
                (ty == 0 && y > 0) || (ty == grid.tile_height - 1 && y + 1 < original.height);
            let slot = usize::from(!(border_x || border_y));
            let e = original.samples.get_f64(i) - decoded(i);
            sums[slot].0 += e * e;
            sums[slot].1 += 1;
        }
    }
    sums
}

/// The shared DEMs the seams are measured on (none, with a notice, when absent).
fn seam_dems(test: &str) -> Vec<(&'static str, Raster)> {
    let Some(dir) = support::shared_dem(test) else {
        return Vec::new();
    };
    [
        "srtm3_n57e011",
        "sthelens_10m",
        "alps_montblanc",
        "srtm3_utm32_f32",
    ]
    .into_iter()
    .map(|name| {
        let path = dir.join(name).join(format!("{name}.tif"));
        (name, read_dem(&path, &ReadOptions::default()).unwrap())
    })
    .collect()
}

fn rmse((sum, n): (f64, usize)) -> f64 {
    (sum / n.max(1) as f64).sqrt()
}

#[test]
fn tile_seams_on_shared_dems() {
    for (name, raster) in seam_dems("tile_seams_on_shared_dems") {
        let budget = (0.25 * raster.len() as f64 / 8.0) as u64;
        let options = |tile: Option<u32>| {
            EncodeOptions::new(Quality::Lossless, Some(budget)).with_tile_size(tile)
        };
        let tiled = encode(&raster, &options(Some(256))).unwrap();
        let whole = encode(&raster, &options(None)).unwrap();
        let grid = TileGrid::balanced(raster.width, raster.height, 256).unwrap();
        let tiled_out = decode(&tiled.bytes, &DecodeOptions::default())
            .unwrap()
            .raster;
        let whole_out = decode(&whole.bytes, &DecodeOptions::default())
            .unwrap()
            .raster;
        let [border, interior] = seam_errors(&raster, |i| tiled_out.samples.get_f64(i), &grid);
        let all = (border.0 + interior.0, border.1 + interior.1);
        let [wb, wi] = seam_errors(&raster, |i| whole_out.samples.get_f64(i), &grid);
        let untiled = (wb.0 + wi.0, wb.1 + wi.1);
        eprintln!(
            "{name}: border RMSE {:.3} / interior {:.3} = {:.3}; PSNR loss {:.3} dB (untiled border/interior {:.3})",
            rmse(border),
            rmse(interior),
            rmse(border) / rmse(interior),
            20.0 * (rmse(all) / rmse(untiled)).log10(),
            rmse(wb) / rmse(wi),
        );
        assert!(rmse(border) <= 1.1 * rmse(interior), "{name}: border RMSE");
        assert!(
            rmse(all) <= 1.1 * rmse(untiled),
            "{name}: PSNR loss over 0.83 dB"
        );
    }
}

/// PSNR of `decoded` against `original` (the project's definition).
fn psnr(original: &Raster, decoded: &Raster) -> f64 {
    compare(original, decoded).unwrap().psnr_db
}

/// Issue 9's 0.2 dB: 256-sample code blocks under one transform per tile of up to 2048
/// (`encode --block 256 --tile 2048`), every block's stream cut by one allocation, at
/// 0.25 bpp, against one stream. Today's figures (printed with `--nocapture`): 0.02–0.16
/// dB lost (256² tiles: 0.33–0.73), borders within 1.0–1.05 of the interior.
#[test]
fn code_blocks_under_one_transform_on_shared_dems() {
    for (name, raster) in seam_dems("code_blocks_under_one_transform_on_shared_dems") {
        let budget = (0.25 * raster.len() as f64 / 8.0) as u64;
        let options = EncodeOptions::new(Quality::Lossless, Some(budget));
        let coded = |options: &EncodeOptions| {
            let encoded = encode(&raster, options).unwrap();
            assert!(encoded.bytes.len() as u64 <= budget);
            decode(&encoded.bytes, &DecodeOptions::default())
                .unwrap()
                .raster
        };
        let one_stream = psnr(&raster, &coded(&options.clone().with_tile_size(None)));
        let blocked = options
            .with_tile_size(Some(2048))
            .with_code_block(Some(256));
        let out = coded(&blocked);
        let grid = TileGrid {
            tile_width: 256,
            tile_height: 256,
            overlap: 0,
            ..TileGrid::balanced(raster.width, raster.height, 256).unwrap()
        };
        let [border, interior] = seam_errors(&raster, |i| out.samples.get_f64(i), &grid);
        let lost = one_stream - psnr(&raster, &out);
        eprintln!(
            "{name}: one stream {one_stream:.3} dB; 256-sample code blocks {lost:.3} dB lost, border RMSE / interior {:.3}",
            rmse(border) / rmse(interior),
        );
        assert!(lost < 0.2, "{name}: blocks lose {lost:.3} dB");
        assert!(rmse(border) <= 1.1 * rmse(interior), "{name}: border RMSE");
    }
}

/// Lossless 5/3 code blocks rebuild every sample exactly, for ≤ 2.5 % more bytes than one
/// stream (256² tiles: 3.0–4.0 % larger files, `encode --tile 256` against `--tile 0`).
#[test]
fn lossless_code_blocks_are_exact() {
    let Some(dir) = support::shared_dem("lossless_code_blocks_are_exact") else {
        return;
    };
    for name in ["srtm3_n57e011", "alps_montblanc"] {
        let path = dir.join(name).join(format!("{name}.tif"));
        let raster = read_dem(&path, &ReadOptions::default()).unwrap();
        let size = |options: EncodeOptions| {
            let encoded = encode(&raster, &options).unwrap();
            let out = decode(&encoded.bytes, &DecodeOptions::default()).unwrap();
            let exact = compare(&raster, &out.raster).unwrap().identical;
            assert!(exact, "{name}: {options:?} is not exact");
            encoded.bytes.len()
        };
        let one = size(EncodeOptions::lossless().with_tile_size(None));
        let blocks = size(EncodeOptions::lossless().with_code_block(Some(256)));
        let over = 100.0 * (blocks as f64 / one as f64 - 1.0);
        eprintln!("{name}: lossless 256-sample code blocks {blocks} bytes, +{over:.2} % over one stream ({one})");
        assert!(over < 2.5, "{name}: +{over:.2} %");
    }
}
