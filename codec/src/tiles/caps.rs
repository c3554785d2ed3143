//! How far each tile of a budget encode is coded before the cut: a share of the budget
//! estimated from the tile's samples, so a detailed tile is not coded twice and a flat
//! one not far past what the cut keeps. The cut itself does not depend on the caps
//! ([`super::cut_to_budget`] codes a starved tile again), so they only trade time.

use crate::raster::{Raster, Samples};

use super::float_detail::FloatDetail;
use super::{TileGrid, Window};

/// Histogram bins of ⌊log2 g⌋ for a sample's gradient g, from 2^-64 to 2^63.
const BINS: usize = 128;

/// Bin of 2^0 in a [`TileDetail`].
const BIN_OF_ONE: i64 = 64;

/// A tile's first cap in shares of the budget (by detail, or by area for a raster
/// without detail). Caps of 4 shares by area coded sthelens_10m's four tiles to 4 times
/// what the cut kept; the cut is the same whatever the caps, so they only trade coding
/// past the cut against coding a tile twice.
const CAP_SHARES: f64 = 1.5;

/// How far above a budget the lossless file's estimate ([`lossless_may_fit`]) may be
/// for a budget encode to try it: the estimate is within 0.87–1.34 times the lossless
/// files of the development set's DEMs, integer and float.
const LOSSLESS_TRY: f64 = 1.5;

/// A tile's samples counted by ⌊log2⌋ of their gradient |Δx| + |Δy| (to the valid left
/// and upper neighbours inside the tile; zero gradients are not counted), on one row in
/// [`TileDetail::ROW_STEP`]: what [`budget_caps`] shares a budget by. Float samples are
/// counted too by what their lossless file's value step needs.
#[derive(Debug, Clone, PartialEq)]
pub struct TileDetail {
    gradients: [u64; BINS],
    floats: Option<FloatDetail>,
}

impl Default for TileDetail {
    fn default() -> Self {
        TileDetail {
            gradients: [0; BINS],
            floats: None,
        }
    }
}

impl TileDetail {
    /// Rows of a tile from one row read to the next ([`TileDetail::rows`]).
    pub const ROW_STEP: usize = 8;

    /// The detail of `raster`'s samples in `window` (a tile's coded samples).
    pub fn of(raster: &Raster, window: &Window) -> TileDetail {
        let mut detail = TileDetail::default();
        for y in TileDetail::rows(window) {
            let (above, row) = ((y - 1) * raster.width, y * raster.width);
            detail.add(raster, (above, row), window.x..window.x + window.width);
        }
        detail
    }

    /// The rows of `window` whose gradients are counted (each against the row above).
    pub fn rows(window: &Window) -> impl Iterator<Item = usize> {
        (window.y + 1..window.y + window.height).step_by(TileDetail::ROW_STEP)
    }

    /// Adds the gradients of row 1 of `rows` (against its row 0) in `columns`: a raster
    /// of the two rows of the DEM that end at a row of [`TileDetail::rows`].
    pub fn add_row(&mut self, rows: &Raster, columns: std::ops::Range<usize>) {
        self.add(rows, (0, rows.width), columns);
    }

    /// Adds the gradients in `columns` of the row starting at sample `starts.1` of
    /// `raster`, against the row starting at `starts.0`.
    fn add(&mut self, raster: &Raster, starts: (usize, usize), columns: std::ops::Range<usize>) {
        let (above, row) = (
            read_row(raster, starts.0 + columns.start..starts.0 + columns.end),
            read_row(raster, starts.1 + columns.start..starts.1 + columns.end),
        );
        let mut left = f64::NAN;
        for (&value, &up) in row.iter().zip(&above) {
            let gradient = distance(value, left) + distance(value, up);
            if gradient > 0.0 && gradient.is_finite() {
                self.gradients[bin_of(gradient)] += 1;
            }
            left = value;
        }
        if matches!(raster.samples, Samples::F32(_)) {
            let floats = self.floats.get_or_insert_with(FloatDetail::default);
            for &value in row.iter().filter(|v| !v.is_nan()) {
                floats.add(value as f32);
            }
        }
    }

    /// The bytes of the tile's lossless file, the counted rows standing for all: one
    /// bit a bit of gradient above the value step (the unit for integer samples), and
    /// for floats off any grid the bits of their exact residuals.
    pub fn lossless_estimate(&self) -> f64 {
        let (step, residual_bits) = self
            .floats
            .as_ref()
            .map_or((1.0, 0.0), FloatDetail::step_and_residual_bits);
        (self.bits_above(step.log2()) + residual_bits) * TileDetail::ROW_STEP as f64 / 8.0
    }

    /// Bits of the gradients at and above `plane` (a gradient in bin b has b − plane + 1).
    fn bits_above(&self, plane: f64) -> f64 {
        self.gradients
            .iter()
            .enumerate()
            .map(|(bin, &count)| {
                let above = (bin as i64 - BIN_OF_ONE) as f64 - plane + 1.0;
                count as f64 * above.max(0.0)
            })
            .sum()
    }
}

/// Each tile's cap for a `budget`-byte encode on `grid`, the tiles' `details` in grid
/// order: one and a half times the share of the budget its detail predicts, and 4 KiB.
/// The share is the tile's bits of gradient above a threshold common to every tile (as
/// bit-plane coding cuts every tile at about the same plane), the threshold the highest
/// plane where the raster's bits reach the budget. Without any detail, shares by area.
pub fn budget_caps(details: &[TileDetail], grid: &TileGrid, budget: u64) -> Vec<u64> {
    let Some(bits) = bits_at_budget(details, budget) else {
        let samples = (grid.width * grid.height) as u64;
        return (0..grid.count())
            .map(|k| area_cap(budget, &grid.coded(k), samples))
            .collect();
    };
    let total: f64 = bits.iter().sum();
    bits.iter().map(|b| cap_of(budget, b / total)).collect()
}

/// Whether a lossless file estimated at `estimate` bytes (the sum of its tiles'
/// [`TileDetail::lossless_estimate`]) may fit in `budget` bytes: at most
/// one and a half times the budget: the estimate is within 0.87–1.34 times the lossless
/// files of the development set.
pub fn lossless_may_fit(estimate: f64, budget: u64) -> bool {
    estimate <= LOSSLESS_TRY * budget as f64
}

/// A tile's cap for a `budget`-byte encode of a `samples`-sample raster when the other
/// tiles' detail is not at hand (a tile encoded on its own): its share by area, as
/// [`budget_caps`] gives it.
pub fn area_cap(budget: u64, tile: &Window, samples: u64) -> u64 {
    cap_of(budget, (tile.width * tile.height) as f64 / samples as f64)
}

/// The cap of a tile given `share` of `budget`: [`CAP_SHARES`] times it, and 4 KiB.
fn cap_of(budget: u64, share: f64) -> u64 {
    (CAP_SHARES * budget as f64 * share) as u64 + 4096
}

/// Each tile's bits above the highest threshold plane where the tiles' bits together
/// reach `budget` bytes (the lowest plane if they never do); `None` when no tile has
/// any detail.
fn bits_at_budget(details: &[TileDetail], budget: u64) -> Option<Vec<f64>> {
    let at =
        |plane: i64| -> Vec<f64> { details.iter().map(|d| d.bits_above(plane as f64)).collect() };
    let target = 8.0 * budget as f64;
    let lowest = -BIN_OF_ONE;
    let plane = (lowest..BINS as i64 - BIN_OF_ONE)
        .rev()
        .find(|&p| at(p).iter().sum::<f64>() >= target)
        .unwrap_or(lowest);
    let bits = at(plane);
    (bits.iter().sum::<f64>() > 0.0).then_some(bits)
}

/// `raster`'s samples `range` as `f64`, NaN where not valid (one typed loop).
fn read_row(raster: &Raster, range: std::ops::Range<usize>) -> Vec<f64> {
    let mut row = Vec::with_capacity(range.len());
    match &raster.samples {
        Samples::U8(v) => row.extend(v[range].iter().map(|&x| f64::from(x))),
        Samples::U16(v) => row.extend(v[range].iter().map(|&x| f64::from(x))),
        Samples::I16(v) => row.extend(v[range].iter().map(|&x| f64::from(x))),
        Samples::I32(v) => row.extend(v[range].iter().map(|&x| f64::from(x))),
        Samples::F32(v) => row.extend(v[range].iter().map(|&x| f64::from(x))),
    }
    if let Some(nodata) = raster.nodata {
        row.iter_mut()
            .filter(|value| **value == nodata)
            .for_each(|value| *value = f64::NAN);
    }
    row
}

/// |a − b|, or 0 when either is NaN (not valid, or no neighbour).
fn distance(a: f64, b: f64) -> f64 {
    let d = (a - b).abs();
    if d.is_nan() {
        0.0
    } else {
        d
    }
}

/// The histogram bin of a positive finite `gradient`: ⌊log2⌋ (its binary exponent),
/// clamped to the bins.
fn bin_of(gradient: f64) -> usize {
    let plane = ((gradient.to_bits() >> 52) & 0x7ff) as i64 - 1023;
    (plane + BIN_OF_ONE).clamp(0, BINS as i64 - 1) as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::SampleType;

    fn raster(width: usize, height: usize, value: impl Fn(usize, usize) -> f64) -> Raster {
        let values: Vec<f64> = (0..width * height)
            .map(|i| value(i % width, i / width))
            .collect();
        Raster::new(width, height, Samples::from_f64(SampleType::I16, &values)).unwrap()
    }

    /// A 100 × 40 raster's grid of two 50-column tiles.
    fn two_tiles() -> TileGrid {
        TileGrid {
            width: 100,
            height: 40,
            tile_width: 50,
            tile_height: 40,
            overlap: 0,
        }
    }

    fn details(r: &Raster, grid: &TileGrid) -> Vec<TileDetail> {
        (0..grid.count())
            .map(|k| TileDetail::of(r, &grid.coded(k)))
            .collect()
    }

    #[test]
    fn a_detailed_tile_gets_the_larger_cap() {
        // Left half flat sea, right half noisy hills.
        let r = raster(100, 40, |x, y| {
            if x < 50 {
                0.0
            } else {
                ((x * 7919 + y * 104729) % 97) as f64
            }
        });
        let grid = two_tiles();
        let caps = budget_caps(&details(&r, &grid), &grid, 2000);
        assert_eq!(caps, vec![4096, 3000 + 4096]);
    }

    #[test]
    fn tiles_of_equal_detail_get_equal_caps_and_a_flat_raster_caps_by_area() {
        let grid = two_tiles();
        let ramp = raster(100, 40, |x, y| (x + 3 * y) as f64);
        let flat = raster(100, 40, |_, _| 5.0);
        for r in [ramp, flat] {
            assert_eq!(
                budget_caps(&details(&r, &grid), &grid, 2000),
                vec![1500 + 4096; 2]
            );
        }
    }

    #[test]
    fn nodata_makes_no_gradient() {
        // Every valid sample's left and upper neighbours are nodata.
        let mut r = raster(8, 2, |x, y| {
            if (x + y) % 2 == 0 {
                -32768.0
            } else {
                10.0 * y as f64
            }
        });
        let window = Window {
            x: 0,
            y: 0,
            width: 8,
            height: 2,
        };
        assert_ne!(TileDetail::of(&r, &window), TileDetail::default());
        r.nodata = Some(-32768.0);
        assert_eq!(TileDetail::of(&r, &window), TileDetail::default());
    }

    #[test]
    fn bits_count_the_planes_at_and_above_the_threshold() {
        let mut h = TileDetail::default();
        h.gradients[bin_of(5.0)] = 3; // ⌊log2 5⌋ = 2
        assert_eq!([0.75, 1.0, 7.99, 8.0].map(bin_of), [63, 64, 66, 67]);
        assert_eq!(h.bits_above(0.0), 9.0);
        assert_eq!(h.bits_above(2.0), 3.0);
        assert_eq!(h.bits_above(3.0), 0.0);
        assert_eq!(h.bits_above(-2.0), 15.0);
        assert_eq!(h.bits_above(0.5), 7.5);
    }
}
