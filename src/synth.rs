//! Synthetic terrain for tests and benchmarks of large DEMs: fractal (fBm) value noise,
//! deterministic for a seed and computed sample by sample, so a DEM of any size is
//! written as a GeoTIFF strip by strip in memory bounded by one strip.

use std::io::{self, Seek, Write};
use std::path::Path;

use tiff::encoder::{colortype, Compression, DeflateLevel, TiffEncoder, TiffKind};
use tiff::encoder::{TiffKindBig, TiffKindStandard};
use tiff::tags::Tag;
use wavemesh_codec::geokey;

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

/// Writes `terrain` as a `width × height` i16 GeoTIFF at `path` (Deflate, strips of
/// [`ROWS_PER_STRIP`] rows, BigTIFF when the samples pass 2 GiB; UTM zone 32N with
/// 10 m pixels), one strip in memory at a time, atomically.
pub fn write_geotiff(
    path: &Path,
    width: u32,
    height: u32,
    terrain: &FractalTerrain,
) -> io::Result<()> {
    crate::atomic::write_atomic_seekable(path, |file| {
        let big = u64::from(width) * u64::from(height) * 2 > (2u64 << 30);
        let result = if big {
            write_strips(
                TiffEncoder::<_, TiffKindBig>::new_big(file),
                width,
                height,
                terrain,
            )
        } else {
            write_strips(
                TiffEncoder::<_, TiffKindStandard>::new(file),
                width,
                height,
                terrain,
            )
        };
        result.map_err(io::Error::other)
    })
}

/// The strips and georeferencing tags of [`write_geotiff`].
fn write_strips<W: Write + Seek, K: TiffKind>(
    encoder: tiff::TiffResult<TiffEncoder<W, K>>,
    width: u32,
    height: u32,
    terrain: &FractalTerrain,
) -> tiff::TiffResult<()> {
    let mut encoder = encoder?.with_compression(Compression::Deflate(DeflateLevel::Fast));
    let mut image = encoder.new_image::<colortype::GrayI16>(width, height)?;
    image.rows_per_strip(ROWS_PER_STRIP)?;
    let tags = image.encoder();
    tags.write_tag(
        Tag::ModelPixelScaleTag,
        &[PIXEL_METRES, PIXEL_METRES, 0.0][..],
    )?;
    let origin = [0.0, 0.0, 0.0, 500_000.0, 5_000_000.0, 0.0];
    tags.write_tag(Tag::ModelTiepointTag, &origin[..])?;
    // Projected, PixelIsArea, EPSG:32632 (UTM zone 32N).
    #[rustfmt::skip]
    let keys: [u16; 16] = [
        1, 1, 0, 3,
        geokey::MODEL_TYPE, 0, 1, geokey::MODEL_PROJECTED,
        geokey::RASTER_TYPE, 0, 1, 1,
        geokey::PROJECTED_TYPE, 0, 1, 32632,
    ];
    tags.write_tag(Tag::GeoKeyDirectoryTag, &keys[..])?;
    let mut strip = vec![0i16; width as usize * ROWS_PER_STRIP as usize];
    let mut y = 0usize;
    while image.next_strip_sample_count() > 0 {
        let samples = image.next_strip_sample_count() as usize;
        for row in strip[..samples].chunks_exact_mut(width as usize) {
            terrain.row_i16(y, row);
            y += 1;
        }
        image.write_strip(&strip[..samples])?;
    }
    image.finish()
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
