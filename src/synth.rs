//! Synthetic terrain for tests and benchmarks of large DEMs: fractal (fBm) value noise,
//! deterministic for a seed and computed sample by sample, so a DEM of any size is
//! written as a GeoTIFF strip by strip (or row of tiles by row of tiles) in memory
//! bounded by one strip (one row of tiles).

use std::path::Path;

use wavemesh_codec::{geokey, Georef, Metadata, Raster, SampleType, Samples};

use crate::dem::{DemError, DemInfo, TiledGeoTiffWriter};

/// Fractal terrain: `octaves` layers of smoothly interpolated lattice noise, each of
/// half the wavelength and `persistence` times the amplitude of the one before.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FractalTerrain {
    /// Seed of the lattice values: the same seed gives the same terrain.
    pub seed: u64,
    /// Layers of noise.
    pub octaves: u32,
    /// Wavelength of the first layer, in samples.
    pub wavelength: f64,
    /// Amplitude ratio from one layer to the next.
    pub persistence: f64,
    /// Height of the mean surface, metres.
    pub base: f64,
    /// Amplitude of the first layer, metres.
    pub relief: f64,
}

impl FractalTerrain {
    /// Mountainous terrain (heights of about 100–2900 m) for `seed`.
    pub fn new(seed: u64) -> FractalTerrain {
        FractalTerrain {
            seed,
            octaves: 11,
            wavelength: 1024.0,
            persistence: 0.5,
            base: 1500.0,
            relief: 1400.0,
        }
    }

    /// Height (metres) at sample position (`x`, `y`).
    pub fn height(&self, x: f64, y: f64) -> f64 {
        let mut sum = 0.0;
        let mut amplitude = self.relief;
        let mut frequency = 1.0 / self.wavelength;
        for octave in 0..self.octaves {
            sum += amplitude * value_noise(x * frequency, y * frequency, self.layer_seed(octave));
            amplitude *= self.persistence;
            frequency *= 2.0;
        }
        self.base + sum
    }

    /// Row `y` of a raster, as whole metres in `out` (one `i16` a column): the same
    /// values as [`FractalTerrain::height`], a layer at a time along the row so each
    /// lattice value is computed once per row.
    pub fn row_i16(&self, y: usize, out: &mut [i16]) {
        let mut row = vec![self.base; out.len()];
        let mut amplitude = self.relief;
        let mut frequency = 1.0 / self.wavelength;
        for octave in 0..self.octaves {
            let layer = Layer {
                seed: self.layer_seed(octave),
                frequency,
                amplitude,
            };
            layer.add_to_row(y as f64, &mut row);
            amplitude *= self.persistence;
            frequency *= 2.0;
        }
        for (sample, h) in out.iter_mut().zip(row) {
            *sample = h
                .round()
                .clamp(f64::from(i16::MIN + 1), f64::from(i16::MAX)) as i16;
        }
    }

    fn layer_seed(&self, octave: u32) -> u64 {
        self.seed ^ u64::from(octave).wrapping_mul(0x9E37_79B9_7F4A_7C15)
    }
}

/// One octave of the noise.
struct Layer {
    seed: u64,
    frequency: f64,
    amplitude: f64,
}

impl Layer {
    /// Adds this layer along row `y` to `row` (sample `x` at column `x`), fetching the
    /// four lattice values of a cell once for all the samples inside it.
    fn add_to_row(&self, y: f64, row: &mut [f64]) {
        let fy = (y * self.frequency).floor();
        let iy = fy as i64;
        let v = fade(y * self.frequency - fy);
        let mut cell = i64::MIN;
        let (mut top, mut bottom) = ((0.0, 0.0), (0.0, 0.0));
        for (x, h) in row.iter_mut().enumerate() {
            let px = x as f64 * self.frequency;
            let fx = px.floor();
            if fx as i64 != cell {
                cell = fx as i64;
                top = (
                    lattice(cell, iy, self.seed),
                    lattice(cell + 1, iy, self.seed),
                );
                bottom = (
                    lattice(cell, iy + 1, self.seed),
                    lattice(cell + 1, iy + 1, self.seed),
                );
            }
            let u = fade(px - fx);
            let noise = lerp(lerp(top.0, top.1, u), lerp(bottom.0, bottom.1, u), v);
            *h += self.amplitude * noise;
        }
    }
}

/// The quintic fade: 0 → 0, 1 → 1, with zero first and second derivatives at both.
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// A well-mixed 64-bit hash (SplitMix64's finaliser).
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The lattice value at (`ix`, `iy`) for `seed`, in [-1, 1].
fn lattice(ix: i64, iy: i64, seed: u64) -> f64 {
    let h = mix(seed ^ mix((ix as u64) ^ mix(iy as u64).rotate_left(17)));
    (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// Value noise at (`x`, `y`): the four surrounding lattice values blended with a
/// quintic fade, so the surface is smooth (C2) between lattice points.
fn value_noise(x: f64, y: f64, seed: u64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let (u, v) = (fade(x - fx), fade(y - fy));
    let top = lerp(lattice(ix, iy, seed), lattice(ix + 1, iy, seed), u);
    let bottom = lerp(lattice(ix, iy + 1, seed), lattice(ix + 1, iy + 1, seed), u);
    lerp(top, bottom, v)
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// Rows a strip of the written GeoTIFF holds.
const ROWS_PER_STRIP: u32 = 16;

/// Pixel size of the written GeoTIFF, metres.
const PIXEL_METRES: f64 = 10.0;

/// Where the written GeoTIFFs lie: UTM zone 32N (EPSG:32632, PixelIsArea), 10 m pixels,
/// the top-left corner at 500 000 E, 5 000 000 N.
pub fn utm32_georef() -> Georef {
    #[rustfmt::skip]
    let keys = vec![
        1, 1, 0, 3,
        geokey::MODEL_TYPE, 0, 1, geokey::MODEL_PROJECTED,
        geokey::RASTER_TYPE, 0, 1, 1,
        geokey::PROJECTED_TYPE, 0, 1, 32632,
    ];
    Georef {
        geotransform: [
            500_000.0,
            PIXEL_METRES,
            0.0,
            5_000_000.0,
            0.0,
            -PIXEL_METRES,
        ],
        geo_key_directory: keys,
        geo_double_params: Vec::new(),
        geo_ascii_params: String::new(),
    }
}

/// Writes `terrain` as a `width × height` i16 GeoTIFF at `path` in `tile × tile` tiles
/// (Deflate, BigTIFF when it may pass 4 GiB; georeferenced by [`utm32_georef`]), one row
/// of tiles in memory at a time, atomically.
pub fn write_tiled_geotiff(
    path: &Path,
    width: u32,
    height: u32,
    terrain: &FractalTerrain,
    tile: u32,
) -> Result<(), DemError> {
    let info = terrain_info(width, height);
    let writer = TiledGeoTiffWriter::create(path, &info, tile)?;
    write_bands(writer, &info, tile as usize, terrain)
}

/// Writes `terrain` as a `width × height` i16 GeoTIFF at `path` in strips of
/// `ROWS_PER_STRIP` rows, otherwise as [`write_tiled_geotiff`]: one strip in memory at a
/// time, atomically.
pub fn write_geotiff(
    path: &Path,
    width: u32,
    height: u32,
    terrain: &FractalTerrain,
) -> Result<(), DemError> {
    let info = terrain_info(width, height);
    let writer = TiledGeoTiffWriter::create_striped(path, &info, ROWS_PER_STRIP)?;
    write_bands(writer, &info, ROWS_PER_STRIP as usize, terrain)
}

/// What the written GeoTIFFs hold besides their samples.
fn terrain_info(width: u32, height: u32) -> DemInfo {
    DemInfo {
        width: width as usize,
        height: height as usize,
        sample_type: SampleType::I16,
        nodata: None,
        georef: Some(utm32_georef()),
        metadata: Metadata::default(),
    }
}

/// Feeds `writer` bands of `rows` rows of `terrain`, then finishes it.
fn write_bands(
    mut writer: TiledGeoTiffWriter,
    info: &DemInfo,
    rows: usize,
    terrain: &FractalTerrain,
) -> Result<(), DemError> {
    let (width, height) = (info.width, info.height);
    for y0 in (0..height).step_by(rows) {
        let rows = rows.min(height - y0);
        let mut band = vec![0i16; width * rows];
        for (y, row) in (y0..).zip(band.chunks_exact_mut(width)) {
            terrain.row_i16(y, row);
        }
        let band = Raster::new(width, rows, Samples::I16(band))
            .map_err(|e| DemError::InvalidRaster(e.to_string()))?;
        writer.write_rows(y0, &band)?;
    }
    writer.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_terrain_other_seed_other_terrain() {
        let a = FractalTerrain::new(7);
        let b = FractalTerrain::new(8);
        let mut row_a = vec![0; 300];
        let mut row_again = vec![0; 300];
        let mut row_b = vec![0; 300];
        a.row_i16(123, &mut row_a);
        a.row_i16(123, &mut row_again);
        b.row_i16(123, &mut row_b);
        assert_eq!(row_a, row_again);
        assert_ne!(row_a, row_b);
    }

    #[test]
    fn rows_equal_the_height_function() {
        let t = FractalTerrain::new(3);
        let mut row = vec![0; 2500];
        for y in [0, 1, 777, 2049] {
            t.row_i16(y, &mut row);
            for (x, &h) in row.iter().enumerate() {
                let expected = t.height(x as f64, y as f64).round() as i16;
                assert!((h - expected).abs() <= 1, "({x}, {y}): {h} vs {expected}");
            }
        }
    }

    #[test]
    fn terrain_is_smooth_and_has_relief() {
        let t = FractalTerrain::new(1);
        let mut row = vec![0; 4096];
        t.row_i16(2000, &mut row);
        let (lo, hi) = (row.iter().min().unwrap(), row.iter().max().unwrap());
        assert!(hi - lo > 300, "relief {lo}..{hi}");
        let steepest = row.windows(2).map(|w| (w[1] - w[0]).abs()).max().unwrap();
        assert!(steepest < 100, "a 10 m pixel step of {steepest} m");
    }

    #[test]
    fn noise_is_continuous_across_lattice_lines() {
        for seed in [0, 5, 99] {
            for x in [0.0, 1.0, 17.0, -3.0] {
                let left = value_noise(x - 1e-9, 0.37, seed);
                let right = value_noise(x + 1e-9, 0.37, seed);
                assert!((left - right).abs() < 1e-6, "seed {seed} x {x}");
                assert!((-1.0..=1.0).contains(&left));
            }
        }
    }
}
