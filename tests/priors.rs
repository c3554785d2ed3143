//! Coder 3's starting probabilities (`codec/src/ezw/prior_tables.rs`) are what the
//! documented training gives: the first decisions of every model over 256 × 256 crops of
//! the shared DEMs, lossless 5/3 and 9/7. Regenerate the tables after changing the
//! models with `WAVEMESH_WRITE_PRIORS=1 cargo test --release --test priors`.

mod support;

use std::path::Path;

use wavemesh::dem::{read_dem, ReadOptions};
use wavemesh_codec::research::{tally_priors, PriorTally};
use wavemesh_codec::{Raster, Wavelet};

/// The rasters the tables are trained on: the shared DEMs of the first training.
const TRAINING_DEMS: [&str; 8] = [
    "srtm3_n57e011",
    "sthelens_10m",
    "alps_montblanc",
    "grandcanyon_8bit",
    "jacksboro_fault",
    "alps_srtm_voids",
    "srtm3_utm32_f32",
    "fuji_terrainrgb",
];

/// Side of the training crops: the size of small tiles, where priors matter most.
const CROP: usize = 256;

/// Crops of `raster` on a `CROP` grid, those at the right and bottom edges narrower.
fn crops(raster: &Raster) -> Vec<Raster> {
    let mut crops = Vec::new();
    for y in (0..raster.height).step_by(CROP) {
        for x in (0..raster.width).step_by(CROP) {
            let w = CROP.min(raster.width - x);
            let h = CROP.min(raster.height - y);
            let crop = raster.crop(x, y, w, h);
            if (0..crop.len()).any(|i| crop.is_valid(i)) {
                crops.push(crop);
            }
        }
    }
    crops
}

#[test]
fn prior_tables_are_what_the_training_gives() {
    let Some(dir) = support::shared_dem("priors::prior_tables_are_what_the_training_gives") else {
        return;
    };
    let mut tally = PriorTally::new();
    for name in TRAINING_DEMS {
        let path = dir.join(name).join(format!("{name}.tif"));
        if !path.is_file() {
            support::skipped("priors", &format!("{} not found", path.display()));
            return;
        }
        let raster = read_dem(&path, &ReadOptions::default()).unwrap();
        for crop in crops(&raster) {
            for wavelet in [Wavelet::Int53, Wavelet::Cdf97] {
                tally_priors(&crop, wavelet, &mut tally).unwrap();
            }
        }
    }
    let tables = Path::new(env!("CARGO_MANIFEST_DIR")).join("codec/src/ezw/prior_tables.rs");
    let trained = tally.table_source();
    if std::env::var_os("WAVEMESH_WRITE_PRIORS").is_some() {
        std::fs::write(&tables, &trained).unwrap();
    }
    let committed = std::fs::read_to_string(&tables).unwrap();
    assert!(
        committed == trained,
        "{} differs from the training; regenerate it with WAVEMESH_WRITE_PRIORS=1",
        tables.display()
    );
}
