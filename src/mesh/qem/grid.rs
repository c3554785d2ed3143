//! The height map as triangles: every cell split along one diagonal (the flag map's
//! diagonal bit), the valid triangles around a sample, and orientation seen from above.

use bitvec::prelude::*;

use super::flags::{Diagonal, FlagMap};

/// The heights of a `width × height` grid and which samples are valid.
#[derive(Debug, Clone, Copy)]
pub struct Grid<'a> {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Every sample's height (nodata samples hold anything).
    pub heights: &'a [f64],
    /// Valid samples.
    pub valid: &'a BitSlice<u64, Lsb0>,
}

/// Why a height grid cannot be meshed (by QEM or the variable-resolution model).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// Fewer than two samples along a side.
    #[error("a {width}x{height} grid is too small to mesh (2x2 at least)")]
    TooSmall {
        /// Samples per row.
        width: usize,
        /// Rows.
        height: usize,
    },
    /// The heights and validity do not match the grid's size.
    #[error("{0} heights or validity flags for a grid of {1} samples")]
    SizeMismatch(usize, usize),
    /// A valid sample holds NaN or an infinity.
    #[error("sample {0} is valid but not finite")]
    NotFinite(usize),
    /// A grid this large overflows the mesher's 32-bit indices.
    #[error("{0} samples are more than the mesher's 32-bit indices hold")]
    TooLarge(usize),
}

impl Grid<'_> {
    /// Checks that the grid can be meshed: 2 × 2 samples at least, heights and validity
    /// of its size, every valid height finite, fewer than `max_samples` samples.
    pub fn check(&self, max_samples: usize) -> Result<(), GridError> {
        let n = self.len();
        if self.width < 2 || self.height < 2 {
            return Err(GridError::TooSmall {
                width: self.width,
                height: self.height,
            });
        }
        if self.heights.len() != n || self.valid.len() != n {
            return Err(GridError::SizeMismatch(self.heights.len(), n));
        }
        if n >= max_samples {
            return Err(GridError::TooLarge(n));
        }
        match (0..n).find(|&s| self.valid[s] && !self.heights[s].is_finite()) {
            Some(s) => Err(GridError::NotFinite(s)),
            None => Ok(()),
        }
    }

    /// Samples of the grid.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Whether the grid has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// `(column, row, height)` of sample `s`.
    pub fn point(&self, s: u32) -> [f64; 3] {
        let s = s as usize;
        [
            (s % self.width) as f64,
            (s / self.width) as f64,
            self.heights[s],
        ]
    }

    /// Whether all three corners of a triangle are valid.
    pub fn is_valid_triangle(&self, t: [u32; 3]) -> bool {
        t.iter().all(|&s| self.valid[s as usize])
    }

    /// The diagonal the paper's rule picks for the cell at top-left sample `s`: the one
    /// joining the two corners closer in height; a cell with one void corner takes the
    /// diagonal that leaves its other three a valid triangle.
    pub fn choose_diagonal(&self, s: usize) -> Diagonal {
        let [tl, tr, bl, br] = [s, s + 1, s + self.width, s + self.width + 1];
        let void = |c: usize| !self.valid[c];
        match [void(tl), void(tr), void(bl), void(br)] {
            [true, false, false, false] | [false, false, false, true] => Diagonal::Rising,
            [false, true, false, false] | [false, false, true, false] => Diagonal::Falling,
            _ => {
                let falling = (self.heights[tl] - self.heights[br]).abs();
                let rising = (self.heights[tr] - self.heights[bl]).abs();
                if rising < falling {
                    Diagonal::Rising
                } else {
                    Diagonal::Falling
                }
            }
        }
    }

    /// A flag map with every cell's diagonal chosen, no sample merged.
    pub fn flag_map(&self) -> FlagMap {
        let mut flags = FlagMap::new(self.width, self.height);
        for y in 0..self.height.saturating_sub(1) {
            for x in 0..self.width - 1 {
                let s = y * self.width + x;
                flags.set_diagonal(s, self.choose_diagonal(s));
            }
        }
        flags
    }

    /// The two triangles of the cell at top-left sample `s`, counter-clockwise seen
    /// from above in (column, row).
    pub fn cell_triangles(&self, s: usize, diagonal: Diagonal) -> [[u32; 3]; 2] {
        let [tl, tr, bl, br] = [s, s + 1, s + self.width, s + self.width + 1].map(|c| c as u32);
        match diagonal {
            Diagonal::Falling => [[tl, tr, br], [tl, br, bl]],
            Diagonal::Rising => [[tl, tr, bl], [tr, br, bl]],
        }
    }

    /// The 8 neighbours of sample `s` in [`NEIGHBOUR_STEPS`] order, `None` where outside
    /// the grid or void.
    pub fn neighbours(&self, s: usize) -> [Option<u32>; 8] {
        let (x, y) = ((s % self.width) as i64, (s / self.width) as i64);
        NEIGHBOUR_STEPS.map(|(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            let inside = nx >= 0 && ny >= 0 && nx < self.width as i64 && ny < self.height as i64;
            let t = (ny * self.width as i64 + nx) as usize;
            (inside && self.valid[t]).then_some(t as u32)
        })
    }

    /// Calls `visit(u, w)` for every grid triangle `(s, u, w)` (counter-clockwise) of the
    /// cells around sample `s`, as indices into [`NEIGHBOUR_STEPS`]; the caller skips
    /// those with a void or outside corner.
    pub fn triangles_around(&self, flags: &FlagMap, s: usize, mut visit: impl FnMut(usize, usize)) {
        let (x, y) = (s % self.width, s / self.width);
        // Cells north-west, north-east, south-west and south-east of s.
        let cells = [
            (x > 0 && y > 0).then(|| s - self.width - 1),
            (x + 1 < self.width && y > 0).then(|| s - self.width),
            (x > 0 && y + 1 < self.height).then(|| s - 1),
            (x + 1 < self.width && y + 1 < self.height).then_some(s),
        ];
        for (quadrant, cell) in cells.into_iter().enumerate() {
            let Some(cell) = cell else {
                continue;
            };
            let rising = usize::from(flags.diagonal(cell) == Diagonal::Rising);
            for &(u, w) in CORNER_TRIANGLES[quadrant][rising] {
                visit(u, w);
            }
        }
    }
}

/// Steps to the 8 neighbours: north-west, north, north-east, west, east, south-west,
/// south, south-east.
pub const NEIGHBOUR_STEPS: [(i64, i64); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// The indices of [`NEIGHBOUR_STEPS`] that are 4-neighbours.
pub const AXIS_NEIGHBOURS: [usize; 4] = [1, 3, 4, 6];

const NW: usize = 0;
const N: usize = 1;
const NE: usize = 2;
const W: usize = 3;
const E: usize = 4;
const SW: usize = 5;
const S: usize = 6;
const SE: usize = 7;

/// For the cell in each quadrant around a sample (north-west, north-east, south-west,
/// south-east) and its diagonal (falling, rising): the far corners of its triangles
/// that hold the sample, counter-clockwise.
const CORNER_TRIANGLES: [[&[(usize, usize)]; 2]; 4] = [
    [&[(NW, N), (W, NW)], &[(W, N)]],
    [&[(N, E)], &[(N, NE), (NE, E)]],
    [&[(S, W)], &[(SW, W), (S, SW)]],
    [&[(E, SE), (SE, S)], &[(E, S)]],
];

/// Twice the signed area of triangle `a b c` seen from above in (column, row): positive
/// when counter-clockwise.
pub fn orient(width: usize, a: u32, b: u32, c: u32) -> i64 {
    let xy = |s: u32| ((s as usize % width) as i64, (s as usize / width) as i64);
    let ((ax, ay), (bx, by), (cx, cy)) = (xy(a), xy(b), xy(c));
    (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid<'a>(heights: &'a [f64], valid: &'a BitVec<u64, Lsb0>) -> Grid<'a> {
        Grid {
            width: 3,
            height: 3,
            heights,
            valid,
        }
    }

    #[test]
    fn cell_triangles_wind_counter_clockwise() {
        let heights = [0.0; 9];
        let valid = bitvec![u64, Lsb0; 1; 9];
        let g = grid(&heights, &valid);
        for diagonal in [Diagonal::Falling, Diagonal::Rising] {
            for t in g.cell_triangles(4, diagonal) {
                assert_eq!(orient(3, t[0], t[1], t[2]), 1, "{diagonal:?} {t:?}");
            }
        }
    }

    #[test]
    fn the_diagonal_joins_the_closer_corners_and_avoids_a_void() {
        let mut heights = [0.0; 9];
        heights[1] = 5.0; // cell 0: tl 0, tr 5, bl 0, br 0 -> rising is |5 - 0|, falling 0
        let mut valid = bitvec![u64, Lsb0; 1; 9];
        assert_eq!(grid(&heights, &valid).choose_diagonal(0), Diagonal::Falling);
        heights[4] = 9.0; // falling |0 - 9| against rising |5 - 0|
        assert_eq!(grid(&heights, &valid).choose_diagonal(0), Diagonal::Rising);
        valid.set(3, false); // bottom-left void: the falling diagonal keeps tl, tr, br
        assert_eq!(grid(&heights, &valid).choose_diagonal(0), Diagonal::Falling);
    }

    #[test]
    fn a_centre_sample_has_its_cells_triangles_and_voids_take_theirs() {
        let heights = [0.0; 9];
        let mut valid = bitvec![u64, Lsb0; 1; 9];
        let around = |g: &Grid| {
            let neighbours = g.neighbours(4);
            let mut out = Vec::new();
            g.triangles_around(&g.flag_map(), 4, |u, w| {
                if let (Some(u), Some(w)) = (neighbours[u], neighbours[w]) {
                    out.push([4, u, w]);
                }
            });
            out.sort();
            out
        };
        let g = grid(&heights, &valid);
        let all = around(&g);
        assert_eq!(all.len(), 6);
        assert!(all.iter().all(|t| orient(3, t[0], t[1], t[2]) > 0));
        // Every triangle of the four cells that holds the centre, once.
        let flags = g.flag_map();
        let mut expected: Vec<[u32; 3]> = [0, 1, 3, 4]
            .iter()
            .flat_map(|&cell| g.cell_triangles(cell, flags.diagonal(cell)))
            .filter_map(|t| {
                let k = t.iter().position(|&c| c == 4)?;
                Some([t[k], t[(k + 1) % 3], t[(k + 2) % 3]])
            })
            .collect();
        expected.sort();
        assert_eq!(all, expected);
        valid.set(0, false);
        let g = grid(&heights, &valid);
        assert_eq!(g.neighbours(4)[0], None);
        assert_eq!(around(&g).len(), 5);
    }
}
