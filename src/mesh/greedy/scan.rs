//! Reading a triangle's samples: the grid samples on or inside it, row span by row
//! span, against the plane through its corners — its worst sample (the next vertex to
//! insert), its squared error (what a data-dependent flip compares), or whether it is
//! within a tolerance. Spans are found exactly and without a division per row
//! ([`for_each_span`]: corners sorted by row, the long side against the two short
//! ones); a span of valid samples is read as a flat slice (`row_worst`,
//! `row_errors`); only rows that meet nodata are read sample by sample. Heights may
//! be stored as `f32` ([`Height`]); errors are always computed in `f64`.

use super::triangulation::{orient, Vertex};

/// A stored height: `f64`, or `f32` when every valid height is exactly an `f32` (the
/// same values in half the memory; every error is still computed in `f64`).
pub trait Height: Copy + Into<f64> + Send + Sync {}

impl<T: Copy + Into<f64> + Send + Sync> Height for T {}

/// Sides of a grid shared with a neighbouring grid (a part of a larger one): their
/// samples are fitted beforehand, the same on both sides, so they are never candidates.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SharedSides {
    /// Column 0.
    pub first_column: bool,
    /// The last column.
    pub last_column: bool,
    /// Row 0.
    pub first_row: bool,
    /// The last row.
    pub last_row: bool,
}

/// The heights a greedy mesh approximates.
#[derive(Debug, Clone, Copy)]
pub struct Grid<'a, H: Height = f64> {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height` heights, row-major (any value at nodata samples).
    pub heights: &'a [H],
    /// Valid samples: bit `s % 64` of word `s / 64` (a `BitVec<u64, Lsb0>`'s words).
    pub valid: &'a [u64],
    /// Whether every sample is valid (rows then need no check).
    no_nodata: bool,
    /// Columns whose samples may be candidates (all but shared sides), first and last.
    candidate_columns: (i64, i64),
    /// Rows whose samples may be candidates, first and last.
    candidate_rows: (i64, i64),
}

impl<'a, H: Height> Grid<'a, H> {
    /// The grid of `width × height` `heights` whose valid samples `valid` marks (at
    /// least `width × height` bits).
    pub fn new(width: usize, height: usize, heights: &'a [H], valid: &'a [u64]) -> Grid<'a, H> {
        let n = width * height;
        let (whole, rest) = (n / 64, n % 64);
        let no_nodata = valid.len() * 64 >= n
            && valid[..whole].iter().all(|&w| w == u64::MAX)
            && (rest == 0 || valid[whole] & ((1 << rest) - 1) == (1 << rest) - 1);
        Grid {
            width,
            height,
            heights,
            valid,
            no_nodata,
            candidate_columns: (0, width as i64 - 1),
            candidate_rows: (0, height as i64 - 1),
        }
    }

    /// The grid whose `shared` sides hold no candidates.
    pub fn with_shared_sides(mut self, shared: SharedSides) -> Grid<'a, H> {
        let (w, h) = (self.width as i64, self.height as i64);
        self.candidate_columns = (
            i64::from(shared.first_column),
            w - 1 - i64::from(shared.last_column),
        );
        self.candidate_rows = (
            i64::from(shared.first_row),
            h - 1 - i64::from(shared.last_row),
        );
        self
    }

    /// Whether every sample is valid.
    pub fn has_no_nodata(&self) -> bool {
        self.no_nodata
    }

    /// Whether sample `s` may be inserted (it is not on a shared side).
    #[inline]
    pub fn may_be_candidate(&self, s: usize) -> bool {
        let (x, y) = ((s % self.width) as i64, (s / self.width) as i64);
        let (columns, rows) = (self.candidate_columns, self.candidate_rows);
        (columns.0..=columns.1).contains(&x) && (rows.0..=rows.1).contains(&y)
    }

    /// Whether a sample among the eight around sample `s` is nodata.
    pub fn next_to_nodata(&self, s: usize) -> bool {
        let (x, y) = ((s % self.width) as i64, (s / self.width) as i64);
        self.nodata_around(y, x, x)
    }

    /// Whether sample `s` is valid.
    #[inline]
    pub fn is_valid(&self, s: usize) -> bool {
        (self.valid[s >> 6] >> (s & 63)) & 1 == 1
    }

    /// Whether samples `first..=last` are all valid.
    #[inline]
    fn all_valid(&self, first: usize, last: usize) -> bool {
        if self.no_nodata {
            return true;
        }
        let (w0, w1) = (first >> 6, last >> 6);
        let head = u64::MAX << (first & 63);
        let tail = u64::MAX >> (63 - (last & 63));
        if w0 == w1 {
            return self.valid[w0] & head & tail == head & tail;
        }
        self.valid[w0] & head == head
            && self.valid[w0 + 1..w1].iter().all(|&w| w == u64::MAX)
            && self.valid[w1] & tail == tail
    }

    /// Whether samples `first..=last` are all nodata.
    #[inline]
    fn none_valid(&self, first: usize, last: usize) -> bool {
        let (w0, w1) = (first >> 6, last >> 6);
        let head = u64::MAX << (first & 63);
        let tail = u64::MAX >> (63 - (last & 63));
        if w0 == w1 {
            return self.valid[w0] & head & tail == 0;
        }
        self.valid[w0] & head == 0
            && self.valid[w0 + 1..w1].iter().all(|&w| w == 0)
            && self.valid[w1] & tail == 0
    }

    /// Calls `run(start, end)` for each maximal run of valid samples in `first..=last`
    /// (found a word of 64 samples at a time).
    fn for_each_valid_run(&self, first: usize, last: usize, mut run: impl FnMut(usize, usize)) {
        let mut from = first;
        while let Some(start) = self.next_with(from, last, true) {
            let end = self.next_with(start, last, false).map_or(last, |s| s - 1);
            run(start, end);
            from = end + 1;
        }
    }

    /// The first sample of `from..=last` that is valid (`valid`) or nodata.
    fn next_with(&self, from: usize, last: usize, valid: bool) -> Option<usize> {
        if from > last {
            return None;
        }
        let flip = if valid { 0 } else { u64::MAX };
        let mut word = from >> 6;
        let mut bits = (self.valid[word] ^ flip) & (u64::MAX << (from & 63));
        loop {
            if bits != 0 {
                let s = (word << 6) + bits.trailing_zeros() as usize;
                return (s <= last).then_some(s);
            }
            word += 1;
            if word << 6 > last {
                return None;
            }
            bits = self.valid[word] ^ flip;
        }
    }

    /// Whether a sample of row `y`'s columns `lo..=hi` may have nodata among its eight
    /// neighbours (some sample around them is nodata).
    fn nodata_around(&self, y: i64, lo: i64, hi: i64) -> bool {
        let (w, h) = (self.width as i64, self.height as i64);
        let (x0, x1) = ((lo - 1).max(0) as usize, (hi + 1).min(w - 1) as usize);
        ((y - 1).max(0)..=(y + 1).min(h - 1)).any(|r| {
            let row = r as usize * self.width;
            !self.all_valid(row + x0, row + x1)
        })
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
            self.heights[s].into()
        } else {
            0.0
        }
    }
}

/// One side of a triangle walked down its rows from its upper end: its column on each
/// row is an exact fraction whose floor is kept as quotient and remainder and stepped by
/// adding, so no row divides.
#[derive(Debug, Clone, Copy)]
struct SideWalk {
    quotient: i64,
    remainder: i64,
    divisor: i64,
    step_quotient: i64,
    step_remainder: i64,
}

/// `(⌊n / d⌋, n mod d)` for `d > 0`, dividing only when `|n| ≥ d`, in 32 bits when
/// both fit (a grid's coordinate differences do; the 64-bit division is slower).
#[inline]
fn floor_div_rem(n: i64, d: i64) -> (i64, i64) {
    if (0..d).contains(&n) {
        (0, n)
    } else if (-d..0).contains(&n) {
        (-1, n + d)
    } else if let (Ok(n), Ok(d)) = (i32::try_from(n), i32::try_from(d)) {
        (n.div_euclid(d).into(), n.rem_euclid(d).into())
    } else {
        (n.div_euclid(d), n.rem_euclid(d))
    }
}

impl SideWalk {
    /// The walk from `upper` down to `lower` (on a lower row), starting on `upper`'s row.
    #[inline]
    fn new(upper: (i64, i64), lower: (i64, i64)) -> SideWalk {
        let divisor = lower.1 - upper.1;
        let (step_quotient, step_remainder) = floor_div_rem(lower.0 - upper.0, divisor);
        SideWalk {
            quotient: upper.0,
            remainder: 0,
            divisor,
            step_quotient,
            step_remainder,
        }
    }

    /// The first column on or right of the side on the current row.
    #[inline]
    fn ceil(&self) -> i64 {
        self.quotient + i64::from(self.remainder > 0)
    }

    /// The last column on or left of the side on the current row.
    #[inline]
    fn floor(&self) -> i64 {
        self.quotient
    }

    /// Moves to the next row.
    #[inline]
    fn step(&mut self) {
        self.quotient += self.step_quotient;
        self.remainder += self.step_remainder;
        if self.remainder >= self.divisor {
            self.remainder -= self.divisor;
            self.quotient += 1;
        }
    }
}

/// Calls `row(y, lo, hi)` for every row `y` of the counter-clockwise triangle `p` with
/// samples `lo..=hi` inside or on it, top to bottom, until `row` returns `false`. The
/// corners sorted by row, the long side (top to bottom) bounds one end of every row and
/// the two short sides the other, the upper one down to the middle corner's row. One
/// loop calls `row` (one call site, so each reader's row body is inlined into it and
/// its running state kept in registers).
#[inline(always)]
pub fn for_each_span(p: [(i64, i64); 3], mut row: impl FnMut(i64, i64, i64) -> bool) {
    let [mut top, mut middle, mut bottom] = p;
    if top.1 > middle.1 {
        std::mem::swap(&mut top, &mut middle);
    }
    if middle.1 > bottom.1 {
        std::mem::swap(&mut middle, &mut bottom);
    }
    if top.1 > middle.1 {
        std::mem::swap(&mut top, &mut middle);
    }
    // Rows grow downwards: a positive orientation puts the middle corner left of the long side.
    let middle_left = orient(top, bottom, middle) > 0;
    let mut long = SideWalk::new(top, bottom);
    // The upper short side down to the middle corner's row (to the last row with a
    // horizontal bottom side), then the lower one; with a horizontal top, the lower one.
    let (mut short, switch) = if middle.1 > top.1 {
        let switch = if bottom.1 > middle.1 {
            middle.1
        } else {
            i64::MAX
        };
        (SideWalk::new(top, middle), switch)
    } else {
        (SideWalk::new(middle, bottom), i64::MAX)
    };
    for y in top.1..=bottom.1 {
        if y == switch {
            short = SideWalk::new(middle, bottom);
        }
        let (lo, hi) = match middle_left {
            true => (short.ceil(), long.floor()),
            false => (long.ceil(), short.floor()),
        };
        if lo <= hi && !row(y, lo, hi) {
            return;
        }
        short.step();
        long.step();
    }
}

/// The plane through a triangle's corners: its height at column `x` of row `y` is
/// `row_start(y, x) + gx·k` at column `x + k`.
#[derive(Debug, Clone, Copy)]
struct Plane {
    origin: (i64, i64),
    z0: f64,
    gx: f64,
    gy: f64,
}

impl Plane {
    /// The plane through the corners `p` (counter-clockwise) at heights `z`.
    #[inline]
    fn new(p: [(i64, i64); 3], z: [f64; 3]) -> Plane {
        let [a, b, c] = p;
        let area = ((b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)) as f64;
        let (db, dc) = (z[1] - z[0], z[2] - z[0]);
        let inverse = 1.0 / area;
        Plane {
            origin: a,
            z0: z[0],
            gx: (db * (c.1 - a.1) as f64 - dc * (b.1 - a.1) as f64) * inverse,
            gy: (dc * (b.0 - a.0) as f64 - db * (c.0 - a.0) as f64) * inverse,
        }
    }

    /// The plane through the corners `v` (counter-clockwise).
    #[inline]
    fn through(v: [Vertex; 3]) -> Plane {
        Plane::new(v.map(Vertex::point), v.map(|v| v.z))
    }

    /// Height at `(x, y)`.
    #[inline]
    fn at(&self, x: i64, y: i64) -> f64 {
        self.z0 + self.gx * (x - self.origin.0) as f64 + self.gy * (y - self.origin.1) as f64
    }
}

/// Calls `visit(sample, z)` for every grid sample on or inside the counter-clockwise
/// triangle `p` whose corners have heights `z`, with `z` the plane's height there.
#[inline]
pub fn scan(width: usize, p: [(i64, i64); 3], z: [f64; 3], mut visit: impl FnMut(usize, f64)) {
    let plane = Plane::new(p, z);
    for_each_span(p, |y, lo, hi| {
        let (row, start) = (y as usize * width, plane.at(lo, y));
        for k in 0..=(hi - lo) {
            visit(row + (lo + k) as usize, start + plane.gx * k as f64);
        }
        true
    });
}

/// `|start + gx·k − heights[k]|`: the error at column `k` of a row.
#[inline]
fn row_error(start: f64, gx: f64, k: f64, h: impl Height) -> f64 {
    (start + gx * k - h.into()).abs()
}

/// Largest [`row_error`] over a row.
#[inline]
fn row_max_error<H: Height>(heights: &[H], start: f64, gx: f64) -> f64 {
    let error = |k: f64, h: H| row_error(start, gx, k, h);
    let mut lanes = [0.0f64; 4];
    let mut k = 0.0;
    let chunks = heights.chunks_exact(4);
    let tail = chunks.remainder();
    for chunk in chunks {
        for j in 0..4 {
            let e = error(k + j as f64, chunk[j]);
            lanes[j] = if e > lanes[j] { e } else { lanes[j] };
        }
        k += 4.0;
    }
    for (j, &h) in tail.iter().enumerate() {
        let e = error(k + j as f64, h);
        lanes[j] = if e > lanes[j] { e } else { lanes[j] };
    }
    lanes[0].max(lanes[1]).max(lanes[2].max(lanes[3]))
}

/// Rows shorter than this are read in one scalar pass (most rows of a fine mesh's
/// triangles are a few samples long); longer ones by the 4-lane kernel and a search.
const SHORT_ROW: usize = 8;

/// Largest [`row_error`] over a row and the first column reaching it, when that error
/// is above `floor` (a long row's column is searched only then: most rows of a large
/// triangle do not beat the worst of the rows read before them).
#[inline]
fn row_worst<H: Height>(heights: &[H], start: f64, gx: f64, floor: f64) -> Option<(f64, usize)> {
    if heights.len() < SHORT_ROW {
        let (mut max, mut at) = (-1.0, 0);
        for (k, &h) in heights.iter().enumerate() {
            let e = row_error(start, gx, k as f64, h);
            if e > max {
                (max, at) = (e, k);
            }
        }
        let max = max.max(0.0);
        return (max > floor).then_some((max, at));
    }
    let max = row_max_error(heights, start, gx);
    if max <= floor {
        return None;
    }
    let at = heights
        .iter()
        .enumerate()
        .position(|(k, &h)| row_error(start, gx, k as f64, h) == max)
        .unwrap_or(0);
    Some((max, at))
}

/// Largest error and sum of squared errors of `start + gx·k` against a row. Rows of
/// fewer than 4 samples (most, in a fine mesh) are summed in one lane, left to right:
/// the same bits as the four lanes give them (their other lanes add exact zeros).
#[inline]
fn row_errors<H: Height>(heights: &[H], start: f64, gx: f64) -> (f64, f64) {
    if heights.len() < 4 {
        let (mut max, mut sum) = (0.0f64, 0.0f64);
        for (k, &h) in heights.iter().enumerate() {
            let e = start + gx * k as f64 - h.into();
            max = if e.abs() > max { e.abs() } else { max };
            sum += e * e;
        }
        return (max, sum);
    }
    let (mut max, mut sum) = ([0.0f64; 4], [0.0f64; 4]);
    let mut k = 0.0;
    let chunks = heights.chunks_exact(4);
    let tail = chunks.remainder();
    for chunk in chunks {
        for j in 0..4 {
            let e = start + gx * (k + j as f64) - chunk[j].into();
            max[j] = if e.abs() > max[j] { e.abs() } else { max[j] };
            sum[j] += e * e;
        }
        k += 4.0;
    }
    for (j, &h) in tail.iter().enumerate() {
        let e = start + gx * (k + j as f64) - h.into();
        max[j] = if e.abs() > max[j] { e.abs() } else { max[j] };
        sum[j] += e * e;
    }
    (
        max[0].max(max[1]).max(max[2].max(max[3])),
        (sum[0] + sum[1]) + (sum[2] + sum[3]),
    )
}

/// What splitting a triangle would gain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Assessment {
    /// Largest error over its valid samples; infinite when it covers nodata and valid
    /// samples that are not its corners (it must split until nodata is cut out); 0 when
    /// nothing inside can be inserted.
    pub error: f64,
    /// The sample to insert next (meaningful when `error > 0`; for an infinite error,
    /// `u32::MAX` until [`nodata_candidate`] chooses it).
    pub candidate: u32,
    /// Whether it covers a nodata sample (such triangles are left out of the mesh).
    pub touches_void: bool,
}

/// The worst sample of the triangle with corners `v` (counter-clockwise).
pub fn assess<H: Height>(grid: &Grid<H>, v: [Vertex; 3]) -> Assessment {
    let p = v.map(Vertex::point);
    if holds_only_its_corners(p) {
        return Assessment {
            error: 0.0,
            candidate: u32::MAX,
            touches_void: p.iter().any(|&q| !grid.is_valid(grid.sample(q))),
        };
    }
    if grid.no_nodata && twice_area(p) == 2 {
        return assess_midpoint(grid, v);
    }
    assess_within(grid, v, f64::INFINITY).unwrap_or_else(|| assess_with_nodata(grid, v))
}

/// [`assess`] of a triangle of twice-area 2 on a grid without nodata, in O(1): by Pick's
/// theorem (2 = 2 · inside + on the outline − 2) it holds one sample besides its
/// corners, the midpoint of its one side whose column and row differences are both even.
/// The error is computed as [`read_within`] computes it (the same `f64`, to the bit).
fn assess_midpoint<H: Height>(grid: &Grid<H>, v: [Vertex; 3]) -> Assessment {
    let p = v.map(Vertex::point);
    let even = |(a, b): &((i64, i64), (i64, i64))| (a.0 - b.0) % 2 == 0 && (a.1 - b.1) % 2 == 0;
    let sides = [(p[0], p[1]), (p[1], p[2]), (p[2], p[0])];
    let (a, b) = sides.into_iter().find(even).unwrap_or(sides[0]);
    let (x, y) = ((a.0 + b.0) / 2, (a.1 + b.1) / 2);
    let (columns, rows) = (grid.candidate_columns, grid.candidate_rows);
    if !(columns.0..=columns.1).contains(&x) || !(rows.0..=rows.1).contains(&y) {
        return Assessment {
            error: 0.0,
            candidate: u32::MAX,
            touches_void: false,
        };
    }
    let (s, plane) = (grid.sample((x, y)), Plane::through(v));
    let (error, _) =
        row_worst(&grid.heights[s..=s], plane.at(x, y), plane.gx, -1.0).unwrap_or((0.0, 0));
    Assessment {
        error,
        candidate: s as u32,
        touches_void: false,
    }
}

/// [`assess`], unless the triangle with corners `v` is on a grid with nodata, covers
/// none, and is large or `cutting` (made by a split over nodata; then whatever its
/// size, if it holds a sample besides its corners): `None`, its heights need not be read
/// yet. Its validity is read first, a word of 64 samples at a time: one that meets
/// nodata must split wherever its error, and one that does not may be rewritten by the
/// splits over nodata before its error is ever asked for (rectangle-sized triangles
/// over a void's collar at a coarse tolerance, small ones around holes).
pub fn assess_unless_valid<H: Height>(
    grid: &Grid<H>,
    v: [Vertex; 3],
    cutting: bool,
) -> Option<Assessment> {
    let p = v.map(Vertex::point);
    let checked_first = if cutting { 2 } else { CHECKED_FIRST };
    if grid.no_nodata || twice_area(p) < checked_first {
        return Some(assess(grid, v));
    }
    meets_nodata(grid, p).then(|| assess_with_nodata(grid, v))
}

/// [`assess`] of a triangle found to cover no nodata by [`assess_unless_valid`] (its
/// validity is not read again).
pub fn assess_valid<H: Height>(grid: &Grid<H>, v: [Vertex; 3]) -> Assessment {
    read_within(grid, v, f64::INFINITY, false).unwrap_or_else(|| assess(grid, v))
}

/// Triangles at least this large (twice the area, in samples) on a grid with nodata
/// have their validity read before their heights ([`assess_unless_valid`]), and any
/// holding a sample besides its corners while nodata is cut out.
const CHECKED_FIRST: i64 = 1024;

/// Twice the area of the counter-clockwise triangle `p`.
#[inline]
fn twice_area(p: [(i64, i64); 3]) -> i64 {
    (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0)
}

/// Whether the triangle `p` covers a nodata sample (its rows' validity read a word of 64
/// samples at a time, no height read).
fn meets_nodata<H: Height>(grid: &Grid<H>, p: [(i64, i64); 3]) -> bool {
    let mut meets = false;
    for_each_span(p, |y, lo, hi| {
        let row = y as usize * grid.width;
        meets = !grid.all_valid(row + lo as usize, row + hi as usize);
        !meets
    });
    meets
}

/// Whether no grid sample but its corners lies on or inside the counter-clockwise
/// triangle `p`: by Pick's theorem (twice the area = 2 · inside + on the outline − 2,
/// the outline holding the 3 corners at least), exactly when twice its area is 1.
#[inline]
fn holds_only_its_corners(p: [(i64, i64); 3]) -> bool {
    twice_area(p) == 1
}

/// [`assess`] of a triangle whose samples are all valid and within `limit` of it (read
/// up to the first row that is not); `None` when it meets nodata or goes over. Samples
/// on the grid's shared sides are not read (fitted beforehand, never candidates).
#[inline]
pub fn assess_within<H: Height>(grid: &Grid<H>, v: [Vertex; 3], limit: f64) -> Option<Assessment> {
    read_within(grid, v, limit, true)
}

/// [`assess_within`]; rows' validity is read only when `check_validity`.
#[inline]
fn read_within<H: Height>(
    grid: &Grid<H>,
    v: [Vertex; 3],
    limit: f64,
    check_validity: bool,
) -> Option<Assessment> {
    let (p, plane) = (v.map(Vertex::point), Plane::through(v));
    let (mut error, mut candidate) = (-1.0f64, u32::MAX);
    let mut within = true;
    let check_validity = check_validity && !grid.no_nodata;
    for_each_span(p, |y, lo, hi| {
        let row = y as usize * grid.width;
        if check_validity && !grid.all_valid(row + lo as usize, row + hi as usize) {
            within = false;
            return false;
        }
        let Some((lo, hi)) = insertable_run(grid, p, y, lo, hi) else {
            return true;
        };
        {
            let first = row + lo as usize;
            let heights = &grid.heights[first..=row + hi as usize];
            if let Some((max, at)) = row_worst(heights, plane.at(lo, y), plane.gx, error) {
                (error, candidate) = (max, (first + at) as u32);
            }
        }
        within = error <= limit;
        within
    });
    within.then_some(Assessment {
        error: error.max(0.0),
        candidate,
        touches_void: false,
    })
}

/// The samples of row `y`'s span `lo..=hi` of the triangle `p` that may be inserted:
/// not on a shared side, not a corner (corners lie at the ends of their rows' spans);
/// `None` when none.
#[inline]
fn insertable_run<H: Height>(
    grid: &Grid<H>,
    p: [(i64, i64); 3],
    y: i64,
    lo: i64,
    hi: i64,
) -> Option<(i64, i64)> {
    let (columns, rows) = (grid.candidate_columns, grid.candidate_rows);
    if y < rows.0 || y > rows.1 {
        // A shared row: fitted beforehand, within any tolerance asked for.
        return None;
    }
    let (lo, hi) = (lo.max(columns.0), hi.min(columns.1));
    let (lo, hi) = if p.iter().any(|q| q.1 == y) {
        (
            lo + i64::from(p.contains(&(lo, y))),
            hi - i64::from(p.contains(&(hi, y))),
        )
    } else {
        (lo, hi)
    };
    (lo <= hi).then_some((lo, hi))
}

/// [`assess`] for a triangle that meets nodata: while it holds valid samples besides
/// its corners it must split (infinite error), else nothing in it can be inserted
/// (error 0). Its rows' validity is read a word of 64 samples at a time, up to the
/// first insertable valid sample once nodata is seen. The sample it splits at is
/// chosen only when it is split ([`nodata_candidate`]; candidate `u32::MAX` until
/// then): most such triangles are rewritten by other splits before (alps_srtm_voids
/// at E = 50: 21593 assessed so, 8941 split).
fn assess_with_nodata<H: Height>(grid: &Grid<H>, v: [Vertex; 3]) -> Assessment {
    let p = v.map(Vertex::point);
    let (mut voids, mut insertable) = (false, false);
    for_each_span(p, |y, lo, hi| {
        let row = y as usize * grid.width;
        voids = voids || !grid.all_valid(row + lo as usize, row + hi as usize);
        if let (false, Some((a, b))) = (insertable, insertable_run(grid, p, y, lo, hi)) {
            insertable = grid
                .next_with(row + a as usize, row + b as usize, true)
                .is_some();
        }
        !(voids && insertable)
    });
    if !voids {
        // Every span valid (the caller found one that was not): read as usual.
        if let Some(assessment) = assess_within(grid, v, f64::INFINITY) {
            return assessment;
        }
    }
    Assessment {
        error: if insertable { f64::INFINITY } else { 0.0 },
        candidate: u32::MAX,
        touches_void: true,
    }
}

/// The sample a triangle over nodata holding insertable valid samples (infinite
/// error, see `assess_with_nodata`) splits at, read row span by row span (sample by
/// sample only where a span mixes valid samples and nodata): the one farthest towards
/// its nodata (along the line from its valid samples' centroid to its nodata
/// samples'), preferably one next to nodata: beyond a chord of a void's outline, the
/// corner of the valid samples' hull farthest out; over a hole, a sample on its rim.
/// So nodata is cut out with few vertices (srtm3_utm32_f32's NaN collar at E = 50:
/// 611 triangles, against 1776 when the first valid sample next to nodata in scan
/// order split). Samples on shared sides are never candidates.
pub fn nodata_candidate<H: Height>(grid: &Grid<H>, v: [Vertex; 3]) -> u32 {
    let p = v.map(Vertex::point);
    let (mut voids, mut insertable) = (Centroid::default(), Centroid::default());
    for_each_span(p, |y, lo, hi| {
        let row = y as usize * grid.width;
        let (first, last) = (row + lo as usize, row + hi as usize);
        if grid.all_valid(first, last) {
            if let Some((a, b)) = insertable_run(grid, p, y, lo, hi) {
                insertable.add_run(y, a, b);
            }
        } else if grid.none_valid(first, last) {
            voids.add_run(y, lo, hi);
        } else {
            let runs = insertable_run(grid, p, y, lo, hi);
            voids.add_run(y, lo, hi);
            grid.for_each_valid_run(first, last, |start, end| {
                let (x0, x1) = ((start - row) as i64, (end - row) as i64);
                voids.remove_run(y, x0, x1);
                if let Some((a, b)) = runs {
                    if x0.max(a) <= x1.min(b) {
                        insertable.add_run(y, x0.max(a), x1.min(b));
                    }
                }
            });
        }
        true
    });
    farthest_towards(grid, p, insertable.point(), voids.point())
}

/// The insertable valid sample of the triangle `p` reaching farthest along the line
/// `from → to`, preferring one with nodata among its eight neighbours (the first in
/// scan order of those reaching as far). A span of valid samples with no nodata around
/// it is settled at its end.
fn farthest_towards<H: Height>(
    grid: &Grid<H>,
    p: [(i64, i64); 3],
    from: (f64, f64),
    to: (f64, f64),
) -> u32 {
    let reach = |x: i64, y: i64| {
        (x as f64 - from.0) * (to.0 - from.0) + (y as f64 - from.1) * (to.1 - from.1)
    };
    // Reach is monotone along a row: rising (to the right) or not.
    let rising = to.0 > from.0;
    let mut farthest = (f64::NEG_INFINITY, u32::MAX);
    let mut on_rim = (f64::NEG_INFINITY, u32::MAX);
    for_each_span(p, |y, lo, hi| {
        let Some((a, b)) = insertable_run(grid, p, y, lo, hi) else {
            return true;
        };
        let row = y as usize * grid.width;
        let (first, last) = (row + lo as usize, row + hi as usize);
        let mut visit = |x0: i64, x1: i64, rim: bool| {
            let best = first_farthest(x0, x1, |x| reach(x, y), rising);
            if reach(best, y) > farthest.0 {
                farthest = (reach(best, y), (row as i64 + best) as u32);
            }
            let next_to_nodata = |x: i64| grid.next_to_nodata(row + x as usize);
            if let Some(x) = rim
                .then(|| first_on_rim(x0, x1, |x| reach(x, y), rising, next_to_nodata))
                .flatten()
            {
                if reach(x, y) > on_rim.0 {
                    on_rim = (reach(x, y), (row as i64 + x) as u32);
                }
            }
        };
        if grid.all_valid(first, last) && !grid.nodata_around(y, lo, hi) {
            visit(a, b, false);
            return true;
        }
        grid.for_each_valid_run(first, last, |start, end| {
            let (x0, x1) = (((start - row) as i64).max(a), ((end - row) as i64).min(b));
            if x0 <= x1 {
                visit(x0, x1, true);
            }
        });
        true
    });
    if on_rim.1 != u32::MAX {
        on_rim.1
    } else {
        farthest.1
    }
}

/// The first column of `x0..=x1` where `reach` (monotone: non-decreasing when
/// `rising`, else non-increasing) is largest.
fn first_farthest(x0: i64, x1: i64, reach: impl Fn(i64) -> f64, rising: bool) -> i64 {
    if !rising {
        return x0;
    }
    let mut x = x1;
    while x > x0 && reach(x - 1) == reach(x1) {
        x -= 1;
    }
    x
}

/// The first column of `x0..=x1` where `reach` (monotone as in [`first_farthest`]) is
/// largest among those `on_rim`, walking from the far end; `None` when none is.
fn first_on_rim(
    x0: i64,
    x1: i64,
    reach: impl Fn(i64) -> f64,
    rising: bool,
    on_rim: impl Fn(i64) -> bool,
) -> Option<i64> {
    if !rising {
        return (x0..=x1).find(|&x| on_rim(x));
    }
    let mut best = (x0..=x1).rev().find(|&x| on_rim(x))?;
    let most = reach(best);
    let mut x = best;
    while x > x0 && reach(x - 1) == most {
        x -= 1;
        if on_rim(x) {
            best = x;
        }
    }
    Some(best)
}

/// A running sum of sample positions.
#[derive(Debug, Default, Clone, Copy)]
struct Centroid {
    count: u64,
    x: u64,
    y: u64,
}

impl Centroid {
    /// Adds the samples of row `y`'s columns `a..=b`.
    #[inline]
    fn add_run(&mut self, y: i64, a: i64, b: i64) {
        let n = (b - a + 1) as u64;
        self.count += n;
        self.x += (a + b) as u64 * n / 2;
        self.y += y as u64 * n;
    }

    /// Takes out the samples of row `y`'s columns `a..=b` (added before).
    #[inline]
    fn remove_run(&mut self, y: i64, a: i64, b: i64) {
        let n = (b - a + 1) as u64;
        self.count -= n;
        self.x -= (a + b) as u64 * n / 2;
        self.y -= y as u64 * n;
    }

    /// The mean (column, row) of the samples added (at least one).
    fn point(&self) -> (f64, f64) {
        let n = self.count as f64;
        (self.x as f64 / n, self.y as f64 / n)
    }
}

/// Largest error and sum of squared errors over the valid samples of the triangle `v`
/// (counter-clockwise).
pub fn errors<H: Height>(grid: &Grid<H>, v: [Vertex; 3]) -> (f64, f64) {
    errors_within(grid, v, f64::INFINITY, f64::INFINITY).unwrap_or((f64::INFINITY, 0.0))
}

/// [`errors`], or `None` as soon as the largest error is over `max_limit` or the sum
/// reaches `sum_limit` (the rest of the triangle is then not read).
#[inline]
pub fn errors_within<H: Height>(
    grid: &Grid<H>,
    v: [Vertex; 3],
    max_limit: f64,
    sum_limit: f64,
) -> Option<(f64, f64)> {
    let (p, plane) = (v.map(Vertex::point), Plane::through(v));
    let (mut max, mut sum) = (0.0f64, 0.0);
    let mut within = true;
    for_each_span(p, |y, lo, hi| {
        let row = y as usize * grid.width;
        let (first, last) = (row + lo as usize, row + hi as usize);
        let start = plane.at(lo, y);
        let (row_max, row_sum) = if grid.no_nodata || grid.all_valid(first, last) {
            row_errors(&grid.heights[first..=last], start, plane.gx)
        } else {
            valid_row_errors(grid, first, last, start, plane.gx)
        };
        max = max.max(row_max);
        sum += row_sum;
        within = max <= max_limit && sum < sum_limit;
        within
    });
    within.then_some((max, sum))
}

/// [`row_errors`] over the valid samples of `first..=last` only.
fn valid_row_errors<H: Height>(
    grid: &Grid<H>,
    first: usize,
    last: usize,
    start: f64,
    gx: f64,
) -> (f64, f64) {
    let (mut max, mut sum) = (0.0f64, 0.0);
    for s in (first..=last).filter(|&s| grid.is_valid(s)) {
        let e = start + gx * (s - first) as f64 - grid.heights[s].into();
        max = max.max(e.abs());
        sum += e * e;
    }
    (max, sum)
}

/// The error at sample `(x, y)` of the plane of triangle `v`, when the sample is on or
/// inside it.
pub fn error_at<H: Height>(grid: &Grid<H>, v: [Vertex; 3], (x, y): (i64, i64)) -> Option<f64> {
    let p = v.map(Vertex::point);
    let inside = (0..3).all(|k| {
        let (a, b) = (p[k], p[(k + 1) % 3]);
        (b.0 - a.0) * (y - a.1) - (b.1 - a.1) * (x - a.0) >= 0
    });
    let s = grid.sample((x, y));
    (inside && grid.is_valid(s))
        .then(|| (Plane::through(v).at(x, y) - grid.heights[s].into()).abs())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::rasterise::rasterise_triangle;
    use bitvec::prelude::*;

    /// The corners `p` with the heights the mesher gives them.
    fn corners(g: &Grid, p: [(i64, i64); 3]) -> [Vertex; 3] {
        p.map(|q| Vertex {
            x: q.0 as i32,
            y: q.1 as i32,
            z: g.vertex_height(q),
        })
    }

    fn grid<'a>(w: usize, h: usize, heights: &'a [f64], valid: &'a BitVec<u64, Lsb0>) -> Grid<'a> {
        Grid::new(w, h, heights, valid.as_raw_slice())
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
    fn short_rows_sum_their_errors_as_the_four_lanes_do() {
        // The four-lane sum of rows of 1 to 3 samples, written out, against row_errors.
        let lanes = |heights: &[f64], start: f64, gx: f64| {
            let (mut max, mut sum) = ([0.0f64; 4], [0.0f64; 4]);
            for (j, &h) in heights.iter().enumerate() {
                let e = start + gx * (0.0 + j as f64) - h;
                max[j] = if e.abs() > max[j] { e.abs() } else { max[j] };
                sum[j] += e * e;
            }
            (
                max[0].max(max[1]).max(max[2].max(max[3])),
                (sum[0] + sum[1]) + (sum[2] + sum[3]),
            )
        };
        let mut state = 99u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 200.0 - 100.0
        };
        for len in 1..4 {
            for _ in 0..2000 {
                let heights: Vec<f64> = (0..len).map(|_| next()).collect();
                let (start, gx) = (next(), next() / 7.0);
                let (ours, theirs) = (row_errors(&heights, start, gx), lanes(&heights, start, gx));
                assert_eq!(ours.0.to_bits(), theirs.0.to_bits(), "{heights:?}");
                assert_eq!(ours.1.to_bits(), theirs.1.to_bits(), "{heights:?}");
            }
        }
    }

    #[test]
    fn a_twice_area_two_triangle_is_assessed_as_its_rows_are_read() {
        // Every counter-clockwise triangle of twice-area 2 on a 9 × 9 lattice, on a whole
        // grid and with the first row and last column shared (never candidates).
        let (w, h) = (9, 9);
        let heights: Vec<f64> = (0..w * h)
            .map(|s| ((s * 7919) % 97) as f64 * 0.37)
            .collect();
        let valid = bitvec![u64, Lsb0; 1; w * h];
        let shared = SharedSides {
            first_row: true,
            last_column: true,
            ..SharedSides::default()
        };
        let points: Vec<(i64, i64)> = (0..w * h)
            .map(|k| ((k % w) as i64, (k / w) as i64))
            .collect();
        let mut checked = 0;
        for g in [
            grid(w, h, &heights, &valid),
            grid(w, h, &heights, &valid).with_shared_sides(shared),
        ] {
            for &a in &points {
                for &b in &points {
                    for &c in &points {
                        if twice_area([a, b, c]) != 2 {
                            continue;
                        }
                        let v = corners(&g, [a, b, c]);
                        let read = read_within(&g, v, f64::INFINITY, true).expect("no nodata");
                        assert_eq!(assess_midpoint(&g, v), read, "{a:?} {b:?} {c:?}");
                        assert_eq!(assess(&g, v), read);
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 1000);
    }

    #[test]
    fn spans_hold_exactly_the_samples_on_or_inside() {
        // Every counter-clockwise triangle of a 7 × 7 lattice: slivers, shallow and
        // steep sides, horizontal sides.
        let points: Vec<(i64, i64)> = (0..49).map(|k| (k % 7, k / 7)).collect();
        let mut checked = 0;
        for (i, &a) in points.iter().enumerate().step_by(3) {
            for &b in &points[i + 1..] {
                for &c in points.iter().step_by(2) {
                    let twice = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
                    if twice <= 0 {
                        continue;
                    }
                    let mut ours = Vec::new();
                    for_each_span([a, b, c], |y, lo, hi| {
                        ours.extend((lo..=hi).map(|x| (x, y)));
                        true
                    });
                    let inside = |&(x, y): &(i64, i64)| {
                        [(a, b), (b, c), (c, a)]
                            .iter()
                            .all(|&(p, q)| (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0) >= 0)
                    };
                    let reference: Vec<(i64, i64)> = (0..7)
                        .flat_map(|y| (0..7).map(move |x| (x, y)))
                        .filter(inside)
                        .collect();
                    ours.sort_by_key(|&(x, y)| (y, x));
                    assert_eq!(ours, reference, "{a:?} {b:?} {c:?}");
                    assert_eq!(holds_only_its_corners([a, b, c]), reference.len() == 3);
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000);
    }

    #[test]
    fn bounded_reads_stop_over_their_limits() {
        let (w, h) = (8, 8);
        let mut heights = vec![0.0; w * h];
        heights[3 * w + 2] = 2.0;
        let valid = bitvec![u64, Lsb0; 1; w * h];
        let g = grid(w, h, &heights, &valid);
        let p = [(0, 0), (7, 0), (0, 7)];
        let v = corners(&g, p);
        assert!(assess_within(&g, v, 1.0).is_none());
        assert_eq!(assess_within(&g, v, 2.0).unwrap().error, 2.0);
        assert!(errors_within(&g, v, 1.0, f64::INFINITY).is_none());
        assert!(errors_within(&g, v, 3.0, 4.0).is_none());
        assert_eq!(errors_within(&g, v, 3.0, 4.5), Some((2.0, 4.0)));
        assert_eq!(error_at(&g, v, (2, 3)), Some(2.0));
        assert_eq!(error_at(&g, v, (6, 6)), None);
    }

    #[test]
    fn rows_meeting_nodata_are_seen_whatever_the_grid_size() {
        for (w, h) in [(8, 8), (13, 5), (70, 3)] {
            let heights = vec![0.0; w * h];
            let mut valid = bitvec![u64, Lsb0; 1; w * h];
            assert!(grid(w, h, &heights, &valid).all_valid(0, w * h - 1));
            valid.set(w * h - 1, false);
            let g = grid(w, h, &heights, &valid);
            assert!(!g.all_valid(0, w * h - 1));
            assert!(g.all_valid(0, w * h - 2));
        }
    }

    #[test]
    fn only_large_triangles_clear_of_nodata_wait_to_be_read() {
        let (w, h) = (64, 64);
        let heights = vec![1.0; w * h];
        let mut valid = bitvec![u64, Lsb0; 1; w * h];
        valid.set(w * h - 1, false);
        let g = grid(w, h, &heights, &valid);
        let clear = corners(&g, [(0, 0), (62, 0), (0, 62)]);
        assert!(assess_unless_valid(&g, clear, false).is_none());
        let over = corners(&g, [(63, 0), (63, 63), (0, 63)]);
        assert_eq!(assess_unless_valid(&g, over, false), Some(assess(&g, over)));
        assert!(assess(&g, over).touches_void);
        let small = corners(&g, [(0, 0), (8, 0), (0, 8)]);
        assert_eq!(
            assess_unless_valid(&g, small, false),
            Some(assess(&g, small))
        );
        let whole = bitvec![u64, Lsb0; 1; w * h];
        let g = grid(w, h, &heights, &whole);
        assert_eq!(
            assess_unless_valid(&g, clear, false),
            Some(assess(&g, clear))
        );
    }

    #[test]
    fn assess_finds_the_worst_sample() {
        let (w, h) = (5, 5);
        let mut heights = vec![0.0; w * h];
        heights[2 * w + 1] = 3.0;
        heights[w + 1] = -1.0;
        let valid = bitvec![u64, Lsb0; 1; w * h];
        let g = grid(w, h, &heights, &valid);
        let a = assess(&g, corners(&g, [(0, 0), (4, 0), (0, 4)]));
        assert_eq!(a.candidate as usize, 2 * w + 1);
        assert_eq!(a.error, 3.0);
        assert!(!a.touches_void);
    }

    #[test]
    fn assess_matches_a_sample_by_sample_reading() {
        // Integer heights (ties between rows and within long rows), large and small
        // triangles: the worst error to the bit and the first sample reaching it.
        let (w, h) = (48, 40);
        let mut state = 7u64;
        let mut next = |n: u64| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) % n
        };
        let heights: Vec<f64> = (0..w * h).map(|_| next(9) as f64).collect();
        let valid = bitvec![u64, Lsb0; 1; w * h];
        let g = grid(w, h, &heights, &valid);
        for _ in 0..3000 {
            let mut p = [0; 3].map(|_| (next(w as u64) as i64, next(h as u64) as i64));
            if twice_area(p) < 0 {
                p.swap(1, 2);
            }
            if twice_area(p) < 3 {
                continue;
            }
            let (v, plane) = (
                corners(&g, p),
                Plane::new(p, [0, 1, 2].map(|k| g.vertex_height(p[k]))),
            );
            let (mut worst, mut at) = (-1.0f64, u32::MAX);
            for_each_span(p, |y, lo, hi| {
                if let Some((lo, hi)) = insertable_run(&g, p, y, lo, hi) {
                    for x in lo..=hi {
                        let s = g.sample((x, y));
                        let e = row_error(plane.at(lo, y), plane.gx, (x - lo) as f64, heights[s]);
                        if e > worst {
                            (worst, at) = (e, s as u32);
                        }
                    }
                }
                true
            });
            let a = assess(&g, v);
            assert_eq!(a.error.to_bits(), worst.max(0.0).to_bits(), "{p:?}");
            assert_eq!(a.candidate, at, "{p:?}");
        }
    }

    #[test]
    fn nodata_forces_a_split_until_only_corners_are_valid() {
        let (w, h) = (5, 5);
        let heights = vec![1.0; w * h];
        let mut valid = bitvec![u64, Lsb0; 1; w * h];
        valid.set(w + 2, false);
        let g = grid(w, h, &heights, &valid);
        let v = corners(&g, [(0, 0), (4, 0), (0, 4)]);
        let a = assess(&g, v);
        assert!(a.touches_void && a.error.is_infinite());
        assert!(g.is_valid(nodata_candidate(&g, v) as usize));
        // Nodata at a corner, nothing else inside: nothing to insert.
        let small = assess(&g, corners(&g, [(2, 1), (3, 1), (2, 2)]));
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
        let (max, sum) = errors(&g, corners(&g, [(0, 0), (5, 0), (5, 5)]));
        assert!(max < 1e-9 && sum < 1e-18);
    }

    /// [`assess_with_nodata`]'s candidate sample by sample: the insertable valid
    /// sample reaching farthest from the insertable samples' centroid towards the
    /// nodata's, those next to nodata first, the first in scan order of equals.
    fn reference_candidate(g: &Grid, p: [(i64, i64); 3]) -> u32 {
        let corners = p.map(|q| g.sample(q));
        let (mut valid, mut void) = (Vec::new(), Vec::new());
        scan(g.width, p, [0.0; 3], |s, _| match g.is_valid(s) {
            false => void.push(s),
            true if !corners.contains(&s) && g.may_be_candidate(s) => valid.push(s),
            true => {}
        });
        let centre = |samples: &[usize]| {
            let n = samples.len() as f64;
            let x: usize = samples.iter().map(|s| s % g.width).sum();
            let y: usize = samples.iter().map(|s| s / g.width).sum();
            (x as f64 / n, y as f64 / n)
        };
        let (from, to) = (centre(&valid), centre(&void));
        let reach = |s: usize| {
            let (x, y) = ((s % g.width) as f64, (s / g.width) as f64);
            (x - from.0) * (to.0 - from.0) + (y - from.1) * (to.1 - from.1)
        };
        let best = |samples: Vec<usize>| {
            let mut best: Option<usize> = None;
            for s in samples {
                if best.is_none_or(|b| reach(s) > reach(b)) {
                    best = Some(s);
                }
            }
            best
        };
        let rim: Vec<usize> = valid
            .iter()
            .copied()
            .filter(|&s| g.next_to_nodata(s))
            .collect();
        best(rim).or_else(|| best(valid)).unwrap() as u32
    }

    #[test]
    fn nodata_candidates_read_by_runs_match_a_sample_by_sample_reading() {
        let (w, h) = (70, 40);
        let heights = vec![0.0; w * h];
        let mut noise = 0x2545_f491_4f6c_dd1du64;
        let mut next = move |n: u64| {
            noise ^= noise << 13;
            noise ^= noise >> 7;
            noise ^= noise << 17;
            noise % n
        };
        let mut checked = 0;
        for round in 0..40 {
            let mut valid = bitvec![u64, Lsb0; 1; w * h];
            let slope = 1 + next(5) as usize;
            for s in 0..w * h {
                let (x, y) = (s % w, s / w);
                let collar = match round % 4 {
                    0 => x < 10 + y / slope,
                    1 => x + y / slope > 60,
                    2 => (x as i64 - 35).pow(2) + (y as i64 - 20).pow(2) < 90,
                    _ => false,
                };
                if collar || next(17) == 0 {
                    valid.set(s, false);
                }
            }
            let shared = SharedSides {
                first_row: round % 3 == 0,
                last_column: round % 5 == 0,
                ..SharedSides::default()
            };
            let g = grid(w, h, &heights, &valid).with_shared_sides(shared);
            for _ in 0..30 {
                let mut p = [0; 3].map(|_| (next(w as u64) as i64, next(h as u64) as i64));
                if orient(p[0], p[1], p[2]) < 0 {
                    p.swap(1, 2);
                }
                if orient(p[0], p[1], p[2]) == 0 || holds_only_its_corners(p) {
                    continue;
                }
                let a = assess_with_nodata(&g, corners(&g, p));
                if a.error.is_infinite() {
                    let candidate = nodata_candidate(&g, corners(&g, p));
                    assert_eq!(candidate, reference_candidate(&g, p), "{p:?}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 300, "{checked}");
    }
}
