//! The data-dependent flips of the greedy mesher: a resolving flip during insertion
//! towards a tolerance (a triangle over it swaps a side instead of taking a vertex when
//! both triangles the flip makes are within it), and error-lowering flips after the
//! last insertion. Both read as few samples as they can: a flip is dropped at the first
//! row that rules it out, and an edge whose two triangles did not change since it was
//! last weighed is not weighed again.

use super::scan::{assess, assess_within, error_at, errors, errors_within, Height};
use super::triangulation::{orient, prefetch, prev, Vertex, NONE};
use super::{GreedyMesher, GridMesh};

/// Clock value of "never": edges not weighed yet, triangles not flipped yet.
const NEVER: u32 = 0;

/// [`FlipState::kinds`] bit: the triangle covers nodata (left out, never flipped).
const VOID: u8 = 1;
/// [`FlipState::kinds`] bit: the triangle held no sample but its corners when assessed.
const EMPTY: u8 = 2;

/// How many half-edges ahead the error-lowering passes prefetch (see
/// [`GreedyMesher::prefetch_far_side`]).
const PREFETCH_AHEAD: usize = 16;

/// What the error-lowering passes remember between edges.
struct FlipState {
    /// Each triangle's [`VOID`] and [`EMPTY`] bits, from its assessment before the
    /// passes (a byte a triangle: the passes' test of an edge's far triangle reads
    /// this dense array instead of the assessments).
    kinds: Vec<u8>,
    /// Each triangle's largest error and sum of squared errors (NaN: not read yet).
    errors: Vec<(f64, f64)>,
    /// Flips made so far: the clock.
    clock: u32,
    /// Clock of the flip that last rewrote each triangle.
    changed: Vec<u32>,
    /// Clock when each half-edge was last weighed.
    weighed: Vec<u32>,
}

impl<H: Height> GreedyMesher<'_, H> {
    /// Flips a side of triangle `t` (over `tolerance`) when both triangles the flip
    /// makes are within `tolerance`: the tolerance met there without a new vertex.
    pub(super) fn resolving_flip(&mut self, t: u32, tolerance: f64) -> bool {
        if self.assessments[t as usize].touches_void {
            return false;
        }
        for e in 3 * t..3 * t + 3 {
            let Some(q) = self.tin.quad_vertices(e) else {
                continue;
            };
            let [a, b, c, d] = q.map(Vertex::point);
            if orient(c, a, d) <= 0 || orient(d, b, c) <= 0 {
                continue;
            }
            let (first, second) = ([q[2], q[0], q[3]], [q[3], q[1], q[2]]);
            let f = self.tin.twins[e as usize];
            // The worst samples of the two triangles are the likeliest to stay over.
            let stays_over = |s: u32| {
                let (x, y) = self.sample_point(s);
                let error = error_at(&self.grid, first, (x, y))
                    .or_else(|| error_at(&self.grid, second, (x, y)));
                error.is_some_and(|error| error > tolerance)
            };
            let neighbour = &self.assessments[(f / 3) as usize];
            if neighbour.touches_void {
                // A triangle the flip makes would cover the same nodata.
                continue;
            }
            if stays_over(self.assessments[t as usize].candidate)
                || (neighbour.error > tolerance && stays_over(neighbour.candidate))
            {
                continue;
            }
            let Some(first) = assess_within(&self.grid, first, tolerance) else {
                continue;
            };
            let Some(second) = assess_within(&self.grid, second, tolerance) else {
                continue;
            };
            self.tin.flip(e);
            self.store(e / 3, first);
            self.store(f / 3, second);
            return true;
        }
        false
    }

    /// (column, row) of sample `s`.
    fn sample_point(&self, s: u32) -> (i64, i64) {
        let s = s as usize;
        ((s % self.grid.width) as i64, (s / self.grid.width) as i64)
    }

    /// Local optimisation after insertion: passes over every interior edge, flipping
    /// it when the other diagonal of its (convex) quadrilateral has a smaller squared
    /// error and a largest error no worse than `limit` (or than the current diagonal's
    /// when `limit` is `None`); stops after a pass without flips or `passes` passes.
    /// An edge whose two triangles are unchanged since it was last weighed is skipped
    /// (it would be refused again). Returns the mesh and the flips made. The flipped
    /// triangles are not assessed again (they cover no nodata, as the quadrilaterals
    /// they come from), so this ends the insertion.
    pub fn optimise_flips(mut self, limit: Option<f64>, passes: usize) -> (GridMesh, usize) {
        if let Some(tolerance) = limit {
            self.covering_flips(tolerance);
        }
        let triangles = self.triangle_count();
        let kind = |a: &super::scan::Assessment| {
            u8::from(a.touches_void) * VOID + u8::from(a.candidate == u32::MAX) * EMPTY
        };
        let mut state = FlipState {
            kinds: self.assessments[..triangles].iter().map(kind).collect(),
            errors: vec![(f64::NAN, 0.0); triangles],
            clock: NEVER + 1,
            changed: vec![NEVER; triangles],
            weighed: vec![NEVER; 3 * triangles],
        };
        let mut flips = 0;
        for pass in 0..passes {
            let before = flips;
            for e in 0..self.tin.corners.len() as u32 {
                // Later passes weigh only the edges near a flip.
                if pass == 0 {
                    self.prefetch_far_side(e as usize, &state);
                }
                if self.try_improving_flip(e, limit, &mut state) {
                    flips += 1;
                }
            }
            if flips == before {
                break;
            }
        }
        (self.mesh(), flips)
    }

    /// Flips edges between two triangles left out over nodata when a triangle the flip
    /// makes covers no nodata, has a corner no triangle of the mesh covers yet, and both
    /// are within `tolerance`, until no such flip is left: a valid vertex whose every
    /// triangle held nodata gets covered (by a triangle of valid corners across the
    /// chord of two of its neighbours). Returns the flips made. Each flip covers a
    /// vertex, so the passes end.
    pub(super) fn covering_flips(&mut self, tolerance: f64) -> usize {
        // Triangles of the mesh at each vertex, and the triangles left out.
        let mut covering = vec![0u32; self.tin.points.len()];
        let mut left_out = Vec::new();
        for t in 0..self.triangle_count() as u32 {
            match self.assessments[t as usize].touches_void {
                true => left_out.push(t),
                false => self
                    .tin
                    .triangle(t)
                    .iter()
                    .for_each(|&v| covering[v as usize] += 1),
            }
        }
        let mut flips = 0;
        loop {
            let before = flips;
            for e in left_out.iter().flat_map(|&t| 3 * t..3 * t + 3) {
                flips += usize::from(self.try_covering_flip(e, tolerance, &mut covering));
            }
            if flips == before {
                return flips;
            }
        }
    }

    /// Flips the edge of `e` when [`GreedyMesher::covering_flips`] would (`covering`:
    /// the triangles of the mesh at each vertex, kept up to date).
    fn try_covering_flip(&mut self, e: u32, tolerance: f64, covering: &mut [u32]) -> bool {
        let f = self.tin.twins[e as usize];
        if f == NONE || f < e {
            return false;
        }
        let left_out = |t: u32| self.assessments[t as usize].touches_void;
        if !left_out(e / 3) || !left_out(f / 3) {
            return false;
        }
        let Some([a, b, c, d]) = self.tin.quad(e) else {
            return false;
        };
        let point = |v: u32| self.tin.points[v as usize];
        if orient(point(c).point(), point(a).point(), point(d).point()) <= 0
            || orient(point(d).point(), point(b).point(), point(c).point()) <= 0
        {
            return false;
        }
        let (first, second) = ([c, a, d], [d, b, c]);
        let made = [first, second].map(|t| assess(&self.grid, t.map(point)));
        let strands = |t: [u32; 3]| t.iter().any(|&v| covering[v as usize] == 0);
        let covers = |k: usize, t| !made[k].touches_void && strands(t);
        let within = made.iter().all(|m| m.error <= tolerance);
        if !within || !(covers(0, first) || covers(1, second)) {
            return false;
        }
        self.tin.flip(e);
        for (k, t) in [first, second].into_iter().enumerate() {
            if !made[k].touches_void {
                t.iter().for_each(|&v| covering[v as usize] += 1);
            }
        }
        self.store(e / 3, made[0]);
        self.store(f / 3, made[1]);
        true
    }

    /// Asks for what weighing edges ahead of `e` will read at random: the far triangle's
    /// corners and errors [`PREFETCH_AHEAD`] half-edges ahead, its far corner's point
    /// and the near corners' points half as far (the passes wait on those loads), for
    /// the edges that are weighed (those whose twin comes after them).
    #[inline(always)]
    fn prefetch_far_side(&self, e: usize, state: &FlipState) {
        let (corners, twins) = (&self.tin.corners, &self.tin.twins);
        let ahead = e + PREFETCH_AHEAD;
        if ahead >= twins.len() {
            return;
        }
        let f = twins[ahead] as usize;
        if f != NONE as usize && f > ahead {
            prefetch(corners, prev(f as u32) as usize);
            prefetch(&state.errors, f / 3);
        }
        let near = e + PREFETCH_AHEAD / 2;
        let f = twins[near] as usize;
        if f != NONE as usize && f > near {
            prefetch(&self.tin.points, corners[prev(f as u32) as usize] as usize);
        }
        prefetch(&self.tin.points, corners[near] as usize);
    }

    /// Flips the edge of `e` when [`GreedyMesher::optimise_flips`] would.
    fn try_improving_flip(&mut self, e: u32, limit: Option<f64>, state: &mut FlipState) -> bool {
        let f = self.tin.twins[e as usize];
        if f == NONE || f < e {
            return false;
        }
        let (t1, t2) = ((e / 3) as usize, (f / 3) as usize);
        let last = state.weighed[e as usize];
        if last != NEVER && state.changed[t1] <= last && state.changed[t2] <= last {
            return false;
        }
        state.weighed[e as usize] = state.clock;
        let (first, second) = (state.kinds[t1], state.kinds[t2]);
        if (first | second) & VOID != 0 {
            return false;
        }
        let unflipped = state.changed[t1] == NEVER && state.changed[t2] == NEVER;
        if unflipped && first & second & EMPTY != 0 {
            // Neither triangle holds a sample but its corners (as assessed during
            // insertion): nor does the quadrilateral, and either diagonal is exact.
            return false;
        }
        let q = self.tin.quad_vertices(e).expect("interior");
        let [a, b, c, d] = q.map(Vertex::point);
        if orient(c, a, d) <= 0 || orient(d, b, c) <= 0 {
            return false;
        }
        if !holds_a_sample_inside([a, d, b, c]) {
            // Every sample of the quadrilateral is on its outline: either diagonal
            // interpolates them the same.
            return false;
        }
        let [va, vb, vc, vd] = q;
        for (t, p) in [(t1, [va, vb, vc]), (t2, [vb, va, vd])] {
            if state.errors[t].0.is_nan() {
                state.errors[t] = errors(&self.grid, p);
            }
        }
        let (now1, now2) = (state.errors[t1], state.errors[t2]);
        let allowed = limit.unwrap_or(now1.0.max(now2.0));
        let sum_limit = (now1.1 + now2.1) * (1.0 - 1e-12);
        let Some(new1) = errors_within(&self.grid, [vc, va, vd], allowed, sum_limit) else {
            return false;
        };
        let Some(new2) = errors_within(&self.grid, [vd, vb, vc], allowed, sum_limit - new1.1)
        else {
            return false;
        };
        self.tin.flip(e);
        state.errors[t1] = new1;
        state.errors[t2] = new2;
        state.clock += 1;
        state.changed[t1] = state.clock;
        state.changed[t2] = state.clock;
        true
    }
}

/// Whether a grid sample lies strictly inside the convex counter-clockwise
/// quadrilateral `q` (Pick's theorem: twice the area minus the samples on the outline,
/// plus 2, is twice the count of samples inside).
fn holds_a_sample_inside(q: [(i64, i64); 4]) -> bool {
    let twice_area = orient(q[0], q[1], q[2]) + orient(q[0], q[2], q[3]);
    let on_outline: i64 = (0..4)
        .map(|k| {
            let (p, r) = (q[k], q[(k + 1) % 4]);
            gcd((p.0 - r.0).unsigned_abs(), (p.1 - r.1).unsigned_abs()) as i64
        })
        .sum();
    twice_area - on_outline + 2 > 0
}

/// Greatest common divisor (binary: no division).
fn gcd(mut a: u64, mut b: u64) -> u64 {
    if a == 0 || b == 0 {
        return a | b;
    }
    let shift = (a | b).trailing_zeros();
    a >>= a.trailing_zeros();
    while b != 0 {
        b >>= b.trailing_zeros();
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        b -= a;
    }
    a << shift
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gcd_of_small_numbers() {
        assert_eq!(gcd(12, 18), 6);
        assert_eq!(gcd(0, 7), 7);
        assert_eq!(gcd(7, 0), 7);
        assert_eq!(gcd(1, 1), 1);
        assert_eq!(gcd(64, 48), 16);
    }

    #[test]
    fn samples_inside_a_quadrilateral_are_counted_by_picks_theorem() {
        // A unit square holds none; a 2 × 2 square holds its centre.
        assert!(!holds_a_sample_inside([(0, 0), (1, 0), (1, 1), (0, 1)]));
        assert!(holds_a_sample_inside([(0, 0), (2, 0), (2, 2), (0, 2)]));
        // A long thin strip along a row holds none, a kite around (1, 1) holds it.
        assert!(!holds_a_sample_inside([(0, 0), (9, 0), (9, 1), (0, 1)]));
        assert!(holds_a_sample_inside([(1, 0), (2, 1), (1, 2), (0, 1)]));
    }
}
