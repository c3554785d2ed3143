//! Per-node summaries computed once beside the significance map: which nodes touch a
//! nodata sample, and how far each node's cell, drawn as two triangles or as a fan from
//! its centre, misses the heights it covers.
//!
//! Nodes are those of [`wavemesh_codec::significance`]: node `(m, i, j)` is the cell with
//! corner samples `i·2^m ..= (i+1)·2^m` by `j·2^m ..= (j+1)·2^m`, clipped to the grid.

use std::sync::{Arc, OnceLock};

use bitvec::prelude::*;
use wavemesh_codec::significance::nodes_along;

#[cfg(test)]
use super::rasterise::rasterise_triangle;

/// The closed sample range `(x0, y0, x1, y1)` of node `(level, i, j)` on a
/// `width × height` grid.
#[inline]
pub fn node_bounds(
    width: usize,
    height: usize,
    level: u32,
    i: usize,
    j: usize,
) -> (usize, usize, usize, usize) {
    let x0 = i << level;
    let y0 = j << level;
    (
        x0,
        y0,
        ((i + 1) << level).min(width - 1),
        ((j + 1) << level).min(height - 1),
    )
}

/// Which diagonal splits a cell into its two triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Diagonal {
    /// From the top-left corner to the bottom-right one.
    Falling,
    /// From the top-right corner to the bottom-left one.
    Rising,
}

/// Heights of a grid with the helpers the mesher needs.
#[derive(Debug, Clone, Copy)]
pub struct Heights<'a> {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height` heights, row-major (any value at nodata samples).
    pub values: &'a [f64],
}

impl Heights<'_> {
    #[inline]
    fn at(&self, x: usize, y: usize) -> f64 {
        self.values[y * self.width + x]
    }

    /// Height at (x, y) of cell `(x0, y0, x1, y1)` drawn as two triangles split along
    /// `diagonal` (x, y inside the cell).
    #[inline]
    pub fn interpolate(
        &self,
        (x0, y0, x1, y1): (usize, usize, usize, usize),
        diagonal: Diagonal,
        x: usize,
        y: usize,
    ) -> f64 {
        let (tl, tr) = (self.at(x0, y0), self.at(x1, y0));
        let (bl, br) = (self.at(x0, y1), self.at(x1, y1));
        let u = (x - x0) as f64 / (x1 - x0) as f64;
        let v = (y - y0) as f64 / (y1 - y0) as f64;
        match diagonal {
            Diagonal::Falling if u >= v => tl + u * (tr - tl) + v * (br - tr),
            Diagonal::Falling => tl + v * (bl - tl) + u * (br - bl),
            Diagonal::Rising if u + v <= 1.0 => tl + u * (tr - tl) + v * (bl - tl),
            Diagonal::Rising => br + (1.0 - u) * (bl - br) + (1.0 - v) * (tr - br),
        }
    }

    /// The diagonal of cell `bounds` whose mean of end heights is closer to the height
    /// of the cell's centre sample (the falling one on a tie): the diagonal that follows
    /// a ridge or a valley rather than cutting across it.
    #[inline]
    pub fn diagonal(&self, bounds: (usize, usize, usize, usize)) -> Diagonal {
        let (x0, y0, x1, y1) = bounds;
        let h = self.at((x0 + x1) / 2, (y0 + y1) / 2);
        let falling = (0.5 * (self.at(x0, y0) + self.at(x1, y1)) - h).abs();
        let rising = (0.5 * (self.at(x1, y0) + self.at(x0, y1)) - h).abs();
        if rising < falling {
            Diagonal::Rising
        } else {
            Diagonal::Falling
        }
    }

    /// Reference for [`Heights::node_errors`]: for cell `bounds` of quadtree level `level`
    /// drawn as a fan of triangles from its centre sample, one rasterisation per triangle:
    /// per side (top, right, bottom, left), the largest |height −
    /// interpolation| over the samples of that side's triangle, without and with a vertex
    /// at the side's midpoint (infinite where the side has none). `None` when the cell is
    /// too thin to have a centre strictly inside.
    #[cfg(test)]
    fn fan_side_errors(
        &self,
        bounds: (usize, usize, usize, usize),
        level: u32,
    ) -> Option<[[f64; 2]; 4]> {
        let (x0, y0, x1, y1) = bounds;
        if x1 - x0 < 2 || y1 - y0 < 2 {
            return None;
        }
        let half = 1usize << level.saturating_sub(1);
        let (cx, cy) = ((x0 + x1) / 2, (y0 + y1) / 2);
        let point = |x: usize, y: usize| (x, y, self.at(x, y));
        let centre = point(cx, cy);
        let ring = [point(x0, y0), point(x1, y0), point(x1, y1), point(x0, y1)];
        let mid = [
            (x0 + half < x1).then(|| point(x0 + half, y0)),
            (y0 + half < y1).then(|| point(x1, y0 + half)),
            (x0 + half < x1).then(|| point(x0 + half, y1)),
            (y0 + half < y1).then(|| point(x0, y0 + half)),
        ];
        let worst = |triangles: &[[(usize, usize, f64); 3]]| {
            let mut worst = 0.0f64;
            for &t in triangles {
                rasterise_triangle(self.width, t, |s, z| {
                    worst = worst.max((z - self.values[s]).abs())
                });
            }
            worst
        };
        let mut out = [[f64::INFINITY; 2]; 4];
        for k in 0..4 {
            let (a, b) = (ring[k], ring[(k + 1) % 4]);
            out[k][0] = worst(&[[centre, a, b]]);
            if let Some(m) = mid[k] {
                out[k][1] = worst(&[[centre, a, m], [centre, m, b]]);
            }
        }
        Some(out)
    }

    /// Reference for [`Heights::node_errors`]: the largest |height − two-triangle
    /// interpolation| over the samples of cell `bounds`.
    #[cfg(test)]
    fn cell_error(&self, bounds: (usize, usize, usize, usize), diagonal: Diagonal) -> f64 {
        self.cell_errors(bounds, diagonal).0
    }

    /// Largest and summed squared |height − two-triangle interpolation| over the samples
    /// of cell `bounds`.
    #[cfg(test)]
    fn cell_errors(&self, bounds: (usize, usize, usize, usize), diagonal: Diagonal) -> (f64, f64) {
        let (x0, y0, x1, y1) = bounds;
        let (mut worst, mut squares) = (0.0f64, 0.0f64);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let e = self.interpolate(bounds, diagonal, x, y) - self.at(x, y);
                worst = worst.max(e.abs());
                squares += e * e;
            }
        }
        (worst, squares)
    }

    /// Everything the error pyramid keeps for cell `bounds` of quadtree level `level`, in
    /// one pass over its samples: per diagonal (falling, rising) the largest and the summed
    /// squared error of the two-triangle drawing; and, for cells at least two samples wide
    /// and high, per side of the fan from the centre sample (top, right, bottom, left) the
    /// largest error of that side's triangle without and with a vertex at the side's
    /// midpoint (infinite where the side has none).
    pub fn node_errors(&self, bounds: (usize, usize, usize, usize), level: u32) -> CellErrors {
        let (x0, y0, x1, y1) = bounds;
        let (tl, tr) = (self.at(x0, y0), self.at(x1, y0));
        let (bl, br) = (self.at(x0, y1), self.at(x1, y1));
        let (inv_w, inv_h) = (1.0 / (x1 - x0) as f64, 1.0 / (y1 - y0) as f64);
        let mut two = [0.0f64; 2];
        let mut squares = [0.0f64; 2];
        let fan_ok = x1 - x0 >= 2 && y1 - y0 >= 2;
        let mut fan = [[0.0f64; 2]; 4];
        // Fan geometry, relative to the centre C, in integers.
        let half = 1i64 << level.saturating_sub(1);
        let (cx, cy) = (((x0 + x1) / 2) as i64, ((y0 + y1) / 2) as i64);
        let hc = self.at(cx as usize, cy as usize);
        let (ix0, iy0, ix1, iy1) = (x0 as i64, y0 as i64, x1 as i64, y1 as i64);
        let corner = [
            (ix0, iy0, tl),
            (ix1, iy0, tr),
            (ix1, iy1, br),
            (ix0, iy1, bl),
        ];
        let mid_x = (ix0 + half < ix1).then_some(ix0 + half);
        let mid_y = (iy0 + half < iy1).then_some(iy0 + half);
        let at = |x: i64, y: i64| (x, y, self.at(x as usize, y as usize));
        let midpoint = [
            mid_x.map(|x| at(x, iy0)),
            mid_y.map(|y| at(ix1, y)),
            mid_x.map(|x| at(x, iy1)),
            mid_y.map(|y| at(ix0, y)),
        ];
        if !fan_ok {
            fan = [[f64::INFINITY; 2]; 4];
        }
        for (s, m) in midpoint.iter().enumerate() {
            if m.is_none() {
                fan[s][1] = f64::INFINITY;
            }
        }
        // (p − C) × (q − C): positive when q is counter-clockwise of p (grid frame).
        let cross = |(px, py): (i64, i64), (qx, qy): (i64, i64)| px * qy - py * qx;
        // The height at `p` of the plane through C, a and b.
        let plane = |p: (i64, i64), a: (i64, i64, f64), b: (i64, i64, f64)| {
            let (da, db) = ((a.0 - cx, a.1 - cy), (b.0 - cx, b.1 - cy));
            let area = cross(da, db) as f64;
            let wa = cross(p, db) as f64;
            let wb = cross(da, p) as f64;
            hc + (wa * (a.2 - hc) + wb * (b.2 - hc)) / area
        };
        for y in y0..=y1 {
            let v = (y - y0) as f64 * inv_h;
            let row = &self.values[y * self.width + x0..=y * self.width + x1];
            for (x, &h) in (x0..=x1).zip(row) {
                let u = (x - x0) as f64 * inv_w;
                let falling = if u >= v {
                    tl + u * (tr - tl) + v * (br - tr)
                } else {
                    tl + v * (bl - tl) + u * (br - bl)
                };
                let rising = if u + v <= 1.0 {
                    tl + u * (tr - tl) + v * (bl - tl)
                } else {
                    br + (1.0 - u) * (bl - br) + (1.0 - v) * (tr - br)
                };
                for (k, z) in [falling, rising].into_iter().enumerate() {
                    let e = z - h;
                    two[k] = two[k].max(e.abs());
                    squares[k] += e * e;
                }
                if !fan_ok {
                    continue;
                }
                let p = (x as i64 - cx, y as i64 - cy);
                // The wedge between the rays to corner s and corner s + 1.
                let s = (0..4)
                    .find(|&s| {
                        let (a, b) = (corner[s], corner[(s + 1) % 4]);
                        cross((a.0 - cx, a.1 - cy), p) >= 0 && cross(p, (b.0 - cx, b.1 - cy)) >= 0
                    })
                    .unwrap_or(0);
                let (a, b) = (corner[s], corner[(s + 1) % 4]);
                let e = (plane(p, a, b) - h).abs();
                fan[s][0] = fan[s][0].max(e);
                if let Some(m) = midpoint[s] {
                    let dm = (m.0 - cx, m.1 - cy);
                    let z = if cross(p, dm) >= 0 {
                        plane(p, a, m)
                    } else {
                        plane(p, m, b)
                    };
                    fan[s][1] = fan[s][1].max((z - h).abs());
                }
            }
        }
        CellErrors {
            two,
            two_squares: squares,
            fan: fan_ok.then_some(fan),
        }
    }
}

/// For every node of levels `1..=levels`, the diagonal [`Heights::diagonal`] picks, one
/// bit a node: a triangulation reads one bit a cell instead of five heights far apart
/// (a cache miss each on a large grid). A level is computed on its first look-up and
/// kept, so coarse meshes never pay for the fine levels.
#[derive(Debug)]
pub struct DiagonalPyramid<'a> {
    heights: Heights<'a>,
    /// Index `m − 1` for level `m`.
    levels: Vec<OnceLock<DiagonalLevel>>,
}

/// One level of a [`DiagonalPyramid`].
#[derive(Debug)]
struct DiagonalLevel {
    /// Nodes per row.
    width: usize,
    /// Bit `k % 64` of word `k / 64` set when node `k` is cut along its rising diagonal.
    rising: Vec<u64>,
}

impl<'a> DiagonalPyramid<'a> {
    /// The diagonals of the nodes of `heights` up to level `levels` (none computed yet).
    pub fn new(heights: Heights<'a>, levels: u32) -> DiagonalPyramid<'a> {
        DiagonalPyramid {
            heights,
            levels: (1..=levels).map(|_| OnceLock::new()).collect(),
        }
    }

    /// The diagonal of node `(level, i, j)`, `level ≥ 1`.
    #[inline]
    pub fn diagonal(&self, level: u32, i: usize, j: usize) -> Diagonal {
        let nodes = self.levels[level as usize - 1].get_or_init(|| self.compute(level));
        let k = j * nodes.width + i;
        if nodes.rising[k / 64] >> (k % 64) & 1 != 0 {
            Diagonal::Rising
        } else {
            Diagonal::Falling
        }
    }

    fn compute(&self, level: u32) -> DiagonalLevel {
        let (w, h) = (self.heights.width, self.heights.height);
        let (nw, nh) = (nodes_along(w, level), nodes_along(h, level));
        let mut rising = vec![0u64; (nw * nh).div_ceil(64)];
        for j in 0..nh {
            for i in 0..nw {
                let bounds = node_bounds(w, h, level, i, j);
                if self.heights.diagonal(bounds) == Diagonal::Rising {
                    let k = j * nw + i;
                    rising[k / 64] |= 1 << (k % 64);
                }
            }
        }
        DiagonalLevel { width: nw, rising }
    }
}

/// Which samples are valid, as the partitions built on a [`VoidPyramid`] keep it (a
/// shared handle: cloning it copies no bits). It tells which corners of a grid cell its
/// triangles may use.
#[derive(Debug, Clone)]
pub struct SampleValidity {
    width: usize,
    valid: Arc<BitVec<u64, Lsb0>>,
}

impl SampleValidity {
    /// The valid corners of grid cell (`i`, `j`): bit 0 top-left, 1 top-right,
    /// 2 bottom-right, 3 bottom-left (the cell's ring order).
    #[inline]
    pub fn cell_corners(&self, i: usize, j: usize) -> u8 {
        let top = j * self.width + i;
        let bottom = top + self.width;
        let bit = |s: usize| u8::from(self.valid[s]);
        bit(top) | bit(top + 1) << 1 | bit(bottom + 1) << 2 | bit(bottom) << 3
    }
}

/// For every node, whether its closed sample range holds a nodata sample: such nodes
/// always split. A void grid cell (level 0) with three valid corners is meshed as the
/// one triangle of those corners; one with fewer is left out of the mesh.
#[derive(Debug, Clone)]
pub struct VoidPyramid {
    width: usize,
    height: usize,
    /// Index `m` for level `m` (0 = grid cells).
    levels: Vec<BitVec<u64, Lsb0>>,
    /// The validity of every sample.
    validity: SampleValidity,
}

impl VoidPyramid {
    /// Builds the pyramid up to `levels` from the validity of every sample; `None` when
    /// every sample is valid.
    pub fn new(
        width: usize,
        height: usize,
        levels: u32,
        valid: &BitSlice<u64, Lsb0>,
    ) -> Option<VoidPyramid> {
        if valid.all() {
            return None;
        }
        let (cw, ch) = (nodes_along(width, 0), nodes_along(height, 0));
        let mut cells = bitvec![u64, Lsb0; 0; cw * ch];
        for y in 0..ch {
            for x in 0..cw {
                let s = y * width + x;
                let void = !(valid[s] && valid[s + 1] && valid[s + width] && valid[s + width + 1]);
                cells.set(y * cw + x, void);
            }
        }
        let mut pyramid = vec![cells];
        for m in 1..=levels {
            let (nw, nh) = (nodes_along(width, m), nodes_along(height, m));
            let (cw, ch) = (nodes_along(width, m - 1), nodes_along(height, m - 1));
            let children = &pyramid[m as usize - 1];
            let mut nodes = bitvec![u64, Lsb0; 0; nw * nh];
            for cy in 0..ch {
                for cx in 0..cw {
                    if children[cy * cw + cx] {
                        nodes.set((cy / 2) * nw + cx / 2, true);
                    }
                }
            }
            pyramid.push(nodes);
        }
        Some(VoidPyramid {
            width,
            height,
            levels: pyramid,
            validity: SampleValidity {
                width,
                valid: Arc::new(valid.to_bitvec()),
            },
        })
    }

    /// Whether node `(level, i, j)` touches a nodata sample.
    #[inline]
    pub fn is_void(&self, level: u32, i: usize, j: usize) -> bool {
        let nw = nodes_along(self.width, level);
        self.levels[level as usize][j * nw + i]
    }

    /// The validity of every sample, for the partitions built on this pyramid.
    pub fn validity(&self) -> &SampleValidity {
        &self.validity
    }

    /// Grid size the pyramid describes.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

/// A cell's errors in every shape, from [`Heights::node_errors`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellErrors {
    /// Largest error of the two triangles along the falling and the rising diagonal.
    pub two: [f64; 2],
    /// Summed squared errors of the same.
    pub two_squares: [f64; 2],
    /// Per side of the fan, largest error without and with the side's midpoint; `None`
    /// for cells too thin to have a centre strictly inside.
    pub fan: Option<[[f64; 2]; 4]>,
}

/// How a leaf cell is cut into triangles (before its hanging vertices are added).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// Two triangles split along a diagonal.
    Two(Diagonal),
    /// Four triangles fanned from the cell's centre sample (cells at least two samples
    /// wide and high).
    Fan,
}

/// For every node of levels `1..=levels`, how far its cell misses the heights it covers
/// when drawn as two triangles (along the better diagonal) and as a fan from its centre:
/// a node within a tolerance `E` in either shape needs no split.
#[derive(Debug, Clone)]
pub struct ErrorPyramid {
    width: usize,
    /// Index `m − 1` for level `m`: per node, the errors of its shapes.
    levels: Vec<Vec<NodeErrors>>,
}

/// The errors of one node's shapes.
#[derive(Debug, Clone, Copy, PartialEq)]
struct NodeErrors {
    /// Two triangles along the falling and the rising diagonal.
    two: [f32; 2],
    /// Whether the rising diagonal misses by less in the squared sum (the choice when
    /// both are within a tolerance).
    rising_smoother: bool,
    /// Per side of the fan: without and with the side's midpoint.
    fan: [[f32; 2]; 4],
}

impl NodeErrors {
    const VOID: NodeErrors = NodeErrors {
        two: [f32::INFINITY; 2],
        rising_smoother: false,
        fan: [[f32::INFINITY; 2]; 4],
    };

    /// The fan's error with midpoints wherever they help.
    fn fan(&self) -> f32 {
        self.fan.iter().map(|s| s[0].min(s[1])).fold(0.0, f32::max)
    }

    /// The better diagonal's error.
    fn two(&self) -> f32 {
        self.two[0].min(self.two[1])
    }

    /// The better shape's error.
    fn best(&self) -> f32 {
        self.two().min(self.fan())
    }
}

/// `e` rounded up to an `f32`, so that a stored value ≤ E proves the error ≤ E.
fn round_up(e: f64) -> f32 {
    let e32 = e as f32;
    if (e32 as f64) < e {
        e32.next_up()
    } else {
        e32
    }
}

impl ErrorPyramid {
    /// Measures every node's cell against `heights` (void nodes get infinite errors).
    pub fn new(heights: Heights<'_>, levels: u32, voids: Option<&VoidPyramid>) -> ErrorPyramid {
        let (width, height) = (heights.width, heights.height);
        let mut pyramid = Vec::with_capacity(levels as usize);
        for m in 1..=levels {
            let (nw, nh) = (nodes_along(width, m), nodes_along(height, m));
            let mut errors = vec![NodeErrors::VOID; nw * nh];
            for j in 0..nh {
                for i in 0..nw {
                    if voids.is_some_and(|v| v.is_void(m, i, j)) {
                        continue;
                    }
                    let bounds = node_bounds(width, height, m, i, j);
                    let e = heights.node_errors(bounds, m);
                    let fan = e.fan.unwrap_or([[f64::INFINITY; 2]; 4]);
                    errors[j * nw + i] = NodeErrors {
                        two: e.two.map(round_up),
                        rising_smoother: e.two_squares[1] < e.two_squares[0],
                        fan: fan.map(|side| side.map(round_up)),
                    };
                }
            }
            pyramid.push(errors);
        }
        ErrorPyramid {
            width,
            levels: pyramid,
        }
    }

    /// The smaller error of node `(level, i, j)`'s two shapes, the fan with midpoints
    /// wherever they help (`level ≥ 1`).
    #[inline]
    pub fn error(&self, level: u32, i: usize, j: usize) -> f32 {
        self.errors(level, i, j).best()
    }

    /// Whether the fan of node `(level, i, j)` needs the midpoint of `side` (index in
    /// [`crate::mesh::cells::Side::ALL`]) to be within `tolerance`.
    pub fn fan_needs_midpoint(
        &self,
        level: u32,
        i: usize,
        j: usize,
        side: usize,
        tolerance: f64,
    ) -> bool {
        f64::from(self.errors(level, i, j).fan[side][0]) > tolerance
    }

    /// The error of node `(level, i, j)` drawn as two triangles along `diagonal`
    /// (`level ≥ 1`; infinite for void nodes).
    #[inline]
    pub fn two_triangle_error(&self, level: u32, i: usize, j: usize, diagonal: Diagonal) -> f32 {
        self.errors(level, i, j).two[match diagonal {
            Diagonal::Falling => 0,
            Diagonal::Rising => 1,
        }]
    }

    #[inline]
    fn errors(&self, level: u32, i: usize, j: usize) -> NodeErrors {
        let nw = nodes_along(self.width, level);
        self.levels[level as usize - 1][j * nw + i]
    }

    /// The cheapest shape of node `(level, i, j)` within `tolerance`: two triangles when
    /// a diagonal is within it (the one with the smaller squared error when both are),
    /// else the fan.
    pub fn shape_within(&self, level: u32, i: usize, j: usize, tolerance: f64) -> Shape {
        let e = self.errors(level, i, j);
        let within = e.two.map(|d| f64::from(d) <= tolerance);
        match within {
            [true, true] if e.rising_smoother => Shape::Two(Diagonal::Rising),
            [true, _] => Shape::Two(Diagonal::Falling),
            [false, true] => Shape::Two(Diagonal::Rising),
            [false, false] => Shape::Fan,
        }
    }

    /// The largest finite two-triangle error of any node: every tolerance at least this
    /// draws every node that is not split by nodata as two triangles, the coarsest mesh
    /// there is (0 for a grid without nodes).
    pub fn top_error(&self) -> f32 {
        self.levels
            .iter()
            .flatten()
            .map(NodeErrors::two)
            .filter(|e| e.is_finite())
            .fold(0.0, f32::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_is_exact_at_corners_and_on_planes() {
        let (w, h) = (5, 4);
        let values: Vec<f64> = (0..w * h)
            .map(|s| 3.0 * (s % w) as f64 - 2.0 * (s / w) as f64 + 7.0)
            .collect();
        let heights = Heights {
            width: w,
            height: h,
            values: &values,
        };
        let bounds = (0, 0, 4, 3);
        for d in [Diagonal::Falling, Diagonal::Rising] {
            assert!(heights.cell_error(bounds, d) < 1e-12);
        }
    }

    #[test]
    fn a_bump_picks_the_diagonal_through_it() {
        // A ridge along the falling diagonal of a 3×3 grid.
        let values = [5.0, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0, 5.0];
        let heights = Heights {
            width: 3,
            height: 3,
            values: &values,
        };
        let bounds = (0, 0, 2, 2);
        assert_eq!(heights.diagonal(bounds), Diagonal::Falling);
        // Along the ridge the error is the edge midpoints' 2.5; across it, the centre's 5.
        assert_eq!(heights.cell_error(bounds, Diagonal::Falling), 2.5);
        assert_eq!(heights.cell_error(bounds, Diagonal::Rising), 5.0);
        // The fan through the centre misses the edge midpoints by 2.5, unless it takes them.
        let fan = heights.node_errors(bounds, 1).fan.unwrap();
        assert!(fan.iter().all(|side| side[0] == 2.5 && side[1] == 0.0));
    }

    #[test]
    fn one_pass_errors_match_the_reference() {
        let (w, h) = (23, 19);
        let mut seed = 7u64;
        let values: Vec<f64> = (0..w * h)
            .map(|_| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 40) as f64 / 1000.0
            })
            .collect();
        let heights = Heights {
            width: w,
            height: h,
            values: &values,
        };
        for level in 1..=4 {
            for j in 0..nodes_along(h, level) {
                for i in 0..nodes_along(w, level) {
                    let bounds = node_bounds(w, h, level, i, j);
                    let fast = heights.node_errors(bounds, level);
                    for (k, d) in [Diagonal::Falling, Diagonal::Rising]
                        .into_iter()
                        .enumerate()
                    {
                        let (max, sq) = heights.cell_errors(bounds, d);
                        assert!((fast.two[k] - max).abs() < 1e-9, "{bounds:?} {d:?}");
                        assert!((fast.two_squares[k] - sq).abs() < 1e-6 * sq.max(1.0));
                    }
                    let reference = heights.fan_side_errors(bounds, level);
                    match (fast.fan, reference) {
                        (None, None) => {}
                        (Some(a), Some(b)) => {
                            // Samples on a ray from the centre belong to one side here and
                            // to both in the reference, with the same height: the fan's
                            // error for every choice of midpoints must agree.
                            for choice in 0..16 {
                                let worst = |e: &[[f64; 2]; 4]| {
                                    (0..4).map(|s| e[s][(choice >> s) & 1]).fold(0.0, f64::max)
                                };
                                let (x, y) = (worst(&a), worst(&b));
                                assert!(
                                    x == y || (x - y).abs() < 1e-9,
                                    "{bounds:?} midpoints {choice:04b}: {x} vs {y}"
                                );
                            }
                        }
                        other => panic!("{bounds:?}: {other:?}"),
                    }
                }
            }
        }
    }

    #[test]
    fn the_diagonal_pyramid_holds_every_nodes_centre_rule_diagonal() {
        let (w, h) = (37, 29);
        let values: Vec<f64> = (0..w * h)
            .map(|s| ((s * 7919) % 101) as f64 + 0.1 * (s % w) as f64)
            .collect();
        let heights = Heights {
            width: w,
            height: h,
            values: &values,
        };
        let pyramid = DiagonalPyramid::new(heights, 4);
        let mut rising = 0;
        for m in 1..=4 {
            for j in 0..nodes_along(h, m) {
                for i in 0..nodes_along(w, m) {
                    let expected = heights.diagonal(node_bounds(w, h, m, i, j));
                    assert_eq!(pyramid.diagonal(m, i, j), expected, "node ({m}, {i}, {j})");
                    rising += usize::from(expected == Diagonal::Rising);
                }
            }
        }
        assert!(rising > 0, "both diagonals occur");
    }

    #[test]
    fn voids_propagate_to_every_ancestor() {
        let (w, h) = (9, 9);
        let mut valid = bitvec![u64, Lsb0; 1; w * h];
        valid.set(4 * w + 6, false);
        let voids = VoidPyramid::new(w, h, 3, &valid).unwrap();
        // The sample (6, 4) is a corner of cells (5..6, 3..4).
        assert!(voids.is_void(0, 5, 3) && voids.is_void(0, 6, 4));
        assert!(!voids.is_void(0, 4, 4));
        assert!(voids.is_void(1, 2, 1) && voids.is_void(1, 3, 2));
        assert!(voids.is_void(3, 0, 0));
        assert!(VoidPyramid::new(w, h, 3, &bitvec![u64, Lsb0; 1; w * h]).is_none());
    }
}
