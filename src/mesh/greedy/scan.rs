//! Reading a triangle's samples: the grid samples on or inside it, row span by row
//! span, against the plane through its corners — its worst sample (the next vertex to
//! insert) and its squared error (what a data-dependent flip compares).

/// The heights a greedy mesh approximates.
#[derive(Debug, Clone, Copy)]
pub struct Grid<'a> {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height` heights, row-major (any value at nodata samples).
    pub heights: &'a [f64],
    /// Valid samples: bit `s % 64` of word `s / 64` (a `BitVec<u64, Lsb0>`'s words).
    pub valid: &'a [u64],
}

impl Grid<'_> {
    /// Whether sample `s` is valid.
    #[inline]
    pub fn is_valid(&self, s: usize) -> bool {
        (self.valid[s >> 6] >> (s & 63)) & 1 == 1
    }

    /// Sample index of `(x, y)`.
    #[inline]
    pub fn sample(&self, (x, y): (i64, i64)) -> usize {
        y as usize * self.width + x as usize
    }

    /// Height a vertex at `(x, y)` takes: the sample's, 0 at nodata (such vertices only
    /// touch triangles that are dropped).
    #[inline]
    pub fn vertex_height(&self, p: (i64, i64)) -> f64 {
        let s = self.sample(p);
        if self.is_valid(s) {
            self.heights[s]
        } else {
            0.0
        }
    }
}

/// `⌊n / d⌋` for `d > 0`.
#[inline]
fn floor_div(n: i64, d: i64) -> i64 {
    n.div_euclid(d)
}

/// The columns `[lo, hi]` of row `y` where `A·x + B(y) ≥ 0` for each edge of the
/// counter-clockwise triangle `p` (empty when `lo > hi`).
#[inline]
fn row_span(p: &[(i64, i64); 3], y: i64, mut lo: i64, mut hi: i64) -> (i64, i64) {
    for k in 0..3 {
        let (a, b) = (p[k], p[(k + 1) % 3]);
        // orient(a, b, (x, y)) = slope·x + offset.
        let slope = a.1 - b.1;
        let offset = (b.0 - a.0) * (y - a.1) + (b.1 - a.1) * a.0;
        match slope.signum() {
            1 => lo = lo.max(-floor_div(offset, slope)),
            -1 => hi = hi.min(floor_div(offset, -slope)),
            _ if offset < 0 => return (1, 0),
            _ => {}
        }
    }
    (lo, hi)
}

/// Calls `visit(sample, z)` for every grid sample on or inside the counter-clockwise
/// triangle `p` whose corners have heights `z`, with `z` the plane's height there.
#[inline]
pub fn scan(width: usize, p: [(i64, i64); 3], z: [f64; 3], mut visit: impl FnMut(usize, f64)) {
    let [a, b, c] = p;
    let area = ((b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)) as f64;
    let (db, dc) = (z[1] - z[0], z[2] - z[0]);
    let gx = (db * (c.1 - a.1) as f64 - dc * (b.1 - a.1) as f64) / area;
    let gy = (dc * (b.0 - a.0) as f64 - db * (c.0 - a.0) as f64) / area;
    let (min_x, max_x) = (a.0.min(b.0).min(c.0), a.0.max(b.0).max(c.0));
    let (min_y, max_y) = (a.1.min(b.1).min(c.1), a.1.max(b.1).max(c.1));
    for y in min_y..=max_y {
        let (lo, hi) = row_span(&p, y, min_x, max_x);
        if lo > hi {
            continue;
        }
        let row = y as usize * width;
        let mut zx = z[0] + gx * (lo - a.0) as f64 + gy * (y - a.1) as f64;
        for x in lo..=hi {
            visit(row + x as usize, zx);
            zx += gx;
        }
    }
}

/// What splitting a triangle would gain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assessment {
    /// Largest error over its valid samples; infinite when it covers nodata and valid
    /// samples that are not its corners (it must split until nodata is cut out); 0 when
    /// nothing inside can be inserted.
    pub error: f64,
    /// The sample to insert next (meaningful when `error > 0`).
    pub candidate: u32,
    /// Whether it covers a nodata sample (such triangles are left out of the mesh).
    pub touches_void: bool,
}

/// The worst sample of the triangle with corners `p` (counter-clockwise).
pub fn assess(grid: &Grid, p: [(i64, i64); 3]) -> Assessment {
    let corners = p.map(|q| grid.sample(q));
    let z = p.map(|q| grid.vertex_height(q));
    let (mut error, mut candidate) = (0.0f64, u32::MAX);
    let (mut touches_void, mut inner_valid) = (false, u32::MAX);
    let mut edge_of_void = u32::MAX;
    let mut previous_void = false;
    scan(grid.width, p, z, |s, zs| {
        if !grid.is_valid(s) {
            touches_void = true;
            if !previous_void && inner_valid.wrapping_add(1) == s as u32 {
                edge_of_void = inner_valid;
            }
            previous_void = true;
            return;
        }
        let was_void = std::mem::replace(&mut previous_void, false);
        let e = (zs - grid.heights[s]).abs();
        // Corners are exact up to rounding; they are checked only when they would win.
        if (e > error || candidate == u32::MAX || touches_void) && !corners.contains(&s) {
            inner_valid = s as u32;
            if was_void && edge_of_void == u32::MAX {
                edge_of_void = s as u32;
            }
            if e > error || candidate == u32::MAX {
                error = e;
                candidate = s as u32;
            }
        }
    });
    if touches_void {
        if inner_valid == u32::MAX {
            return Assessment {
                error: 0.0,
                candidate: u32::MAX,
                touches_void,
            };
        }
        let pick = if edge_of_void != u32::MAX {
            edge_of_void
        } else {
            inner_valid
        };
        return Assessment {
            error: f64::INFINITY,
            candidate: pick,
            touches_void,
        };
    }
    Assessment {
        error,
        candidate,
        touches_void,
    }
}

/// Largest error and sum of squared errors over the valid samples of the triangle `p`
/// (counter-clockwise).
pub fn errors(grid: &Grid, p: [(i64, i64); 3]) -> (f64, f64) {
    let z = p.map(|q| grid.vertex_height(q));
    let (mut max, mut sum) = (0.0f64, 0.0);
    scan(grid.width, p, z, |s, zs| {
        if grid.is_valid(s) {
            let e = zs - grid.heights[s];
            max = max.max(e.abs());
            sum += e * e;
        }
    });
    (max, sum)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::rasterise::rasterise_triangle;
    use bitvec::prelude::*;

    fn grid<'a>(w: usize, h: usize, heights: &'a [f64], valid: &'a BitVec<u64, Lsb0>) -> Grid<'a> {
        Grid {
            width: w,
            height: h,
            heights,
            valid: valid.as_raw_slice(),
        }
    }

    #[test]
    fn scan_visits_what_the_reference_rasteriser_does() {
        let triangles = [
            [(0, 0), (7, 2), (3, 9)],
            [(1, 1), (9, 1), (9, 9)],
            [(0, 9), (2, 0), (9, 5)],
            [(4, 4), (5, 4), (4, 5)],
        ];
        for p in triangles {
            let z = [1.0, -2.0, 5.5];
            let mut ours = Vec::new();
            scan(10, p, z, |s, zs| ours.push((s, zs)));
            let mut reference = Vec::new();
            let corners = [0, 1, 2].map(|k| (p[k].0 as usize, p[k].1 as usize, z[k]));
            rasterise_triangle(10, corners, |s, zs| reference.push((s, zs)));
            ours.sort_by_key(|a| a.0);
            reference.sort_by_key(|a| a.0);
            assert_eq!(ours.len(), reference.len(), "{p:?}");
            for (o, r) in ours.iter().zip(&reference) {
                assert_eq!(o.0, r.0);
                assert!((o.1 - r.1).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn assess_finds_the_worst_sample() {
        let (w, h) = (5, 5);
        let mut heights = vec![0.0; w * h];
        heights[2 * w + 1] = 3.0;
        heights[w + 1] = -1.0;
        let valid = bitvec![u64, Lsb0; 1; w * h];
        let a = assess(&grid(w, h, &heights, &valid), [(0, 0), (4, 0), (0, 4)]);
        assert_eq!(a.candidate as usize, 2 * w + 1);
        assert_eq!(a.error, 3.0);
        assert!(!a.touches_void);
    }

    #[test]
    fn nodata_forces_a_split_until_only_corners_are_valid() {
        let (w, h) = (5, 5);
        let heights = vec![1.0; w * h];
        let mut valid = bitvec![u64, Lsb0; 1; w * h];
        valid.set(w + 2, false);
        let g = grid(w, h, &heights, &valid);
        let a = assess(&g, [(0, 0), (4, 0), (0, 4)]);
        assert!(a.touches_void && a.error.is_infinite());
        assert!(g.is_valid(a.candidate as usize));
        // Nodata at a corner, nothing else inside: nothing to insert.
        let small = assess(&g, [(2, 1), (3, 1), (2, 2)]);
        assert!(small.touches_void);
        assert_eq!(small.error, 0.0);
    }

    #[test]
    fn the_errors_of_a_plane_are_zero() {
        let (w, h) = (6, 6);
        let heights: Vec<f64> = (0..w * h)
            .map(|s| (s % w) as f64 * 2.0 + (s / w) as f64)
            .collect();
        let valid = bitvec![u64, Lsb0; 1; w * h];
        let g = grid(w, h, &heights, &valid);
        let (max, sum) = errors(&g, [(0, 0), (5, 0), (5, 5)]);
        assert!(max < 1e-9 && sum < 1e-18);
    }
}
