//! A triangulation of grid points held as half-edges: triangle `t` owns half-edges
//! `3t`, `3t + 1`, `3t + 2`, half-edge `e` runs from vertex `corners[e]` to the corner of
//! the next half-edge of its triangle, and `twins[e]` is the opposite half-edge across the
//! same edge ([`NONE`] on the rectangle's border). Every triangle winds counter-clockwise
//! in the (column, row) frame. Triangles are never deleted: a split or a flip rewrites
//! slots in place and appends the new ones.

/// No half-edge (the far side of a border edge).
pub const NONE: u32 = u32::MAX;

/// The half-edge after `e` in its triangle.
#[inline]
pub fn next(e: u32) -> u32 {
    if e % 3 == 2 {
        e - 2
    } else {
        e + 1
    }
}

/// The half-edge before `e` in its triangle.
#[inline]
pub fn prev(e: u32) -> u32 {
    if e.is_multiple_of(3) {
        e + 2
    } else {
        e - 1
    }
}

/// Hints the processor to bring `items[i]` into cache (nothing when out of range or
/// not on x86-64): for reads at random that a loop knows ahead of time.
#[inline(always)]
pub fn prefetch<T>(items: &[T], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(item) = items.get(i) {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch only hints the cache (it never faults), of an item in bounds.
        unsafe { _mm_prefetch::<_MM_HINT_T0>((item as *const T).cast()) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (items, i);
}

/// Twice the signed area of `(a, b, c)`: positive when counter-clockwise.
#[inline]
pub fn orient(a: (i64, i64), b: (i64, i64), c: (i64, i64)) -> i64 {
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

/// Whether `d` lies strictly inside the circle through the counter-clockwise `a, b, c`
/// (exact integer arithmetic: `i64` while every offset from `d` is under 2^14, which
/// keeps the determinant under 2^61, else `i128`).
pub fn in_circle(a: (i64, i64), b: (i64, i64), c: (i64, i64), d: (i64, i64)) -> bool {
    let offset = |p: (i64, i64)| (p.0 - d.0, p.1 - d.1);
    let small = |p: (i64, i64)| {
        let o = offset(p);
        o.0.abs() < 1 << 14 && o.1.abs() < 1 << 14
    };
    if small(a) && small(b) && small(c) {
        in_circle_near(a, b, c, d)
    } else {
        let row = |p: (i64, i64)| {
            let (x, y) = offset(p);
            let (x, y) = (i128::from(x), i128::from(y));
            (x, y, x * x + y * y)
        };
        in_circle_determinant([row(a), row(b), row(c)]) > 0
    }
}

/// Grids at most this many samples a side keep every coordinate difference under 2^14,
/// so [`in_circle_near`] applies to any four of their points.
pub const NEAR_SIDE: usize = 1 << 14;

/// [`in_circle`] of points whose offsets from `d` are all under 2^14 (in `i64`, with no
/// range check: the caller knows, e.g. from a grid at most [`NEAR_SIDE`] a side).
#[inline]
pub fn in_circle_near(a: (i64, i64), b: (i64, i64), c: (i64, i64), d: (i64, i64)) -> bool {
    let row = |p: (i64, i64)| {
        let (x, y) = (p.0 - d.0, p.1 - d.1);
        (x, y, x * x + y * y)
    };
    in_circle_determinant([row(a), row(b), row(c)]) > 0
}

/// The in-circle determinant of rows `(x, y, x² + y²)` (offsets from the tested point).
#[inline]
fn in_circle_determinant<T>(rows: [(T, T, T); 3]) -> T
where
    T: Copy + std::ops::Mul<Output = T> + std::ops::Sub<Output = T> + std::ops::Add<Output = T>,
{
    let [(ax, ay, a2), (bx, by, b2), (cx, cy, c2)] = rows;
    ax * (by * c2 - b2 * cy) - ay * (bx * c2 - b2 * cx) + a2 * (bx * cy - by * cx)
}

/// A vertex: its grid column and row, and the height the mesh takes there (kept
/// beside the position so reading a triangle's plane needs no look-up in the grid).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    /// Column.
    pub x: i32,
    /// Row.
    pub y: i32,
    /// Height.
    pub z: f64,
}

impl Vertex {
    /// (column, row).
    #[inline]
    pub fn point(self) -> (i64, i64) {
        (i64::from(self.x), i64::from(self.y))
    }
}

/// Half-edge triangulation of points of a grid.
#[derive(Debug, Clone, Default)]
pub struct Triangulation {
    /// Every vertex.
    pub points: Vec<Vertex>,
    /// The vertex each half-edge starts at.
    pub corners: Vec<u32>,
    /// The opposite half-edge of each half-edge, or [`NONE`].
    pub twins: Vec<u32>,
}

impl Triangulation {
    /// The `width × height` rectangle as two triangles over its four corners, whose
    /// heights `height_at` gives (grids up to 2^31 samples a side).
    pub fn rectangle(
        width: usize,
        height: usize,
        height_at: impl Fn((i64, i64)) -> f64,
    ) -> Triangulation {
        let (w, h) = (width as i64 - 1, height as i64 - 1);
        let mut t = Triangulation::default();
        for (x, y) in [(0, 0), (w, 0), (w, h), (0, h)] {
            t.add_point(x, y, height_at((x, y)));
        }
        // Split along (0, 0)–(w, h): half-edge 2 → 0 of the first meets 0 → 2 of the second.
        t.new_slots(2);
        t.set_triangle(0, [0, 1, 2], [NONE, NONE, NONE]);
        t.set_triangle(1, [0, 2, 3], [NONE, NONE, NONE]);
        t.link(2, 3);
        t
    }

    /// Triangles, including those a split or flip rewrote in place.
    #[inline]
    pub fn triangle_count(&self) -> usize {
        self.corners.len() / 3
    }

    /// The three vertices of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: u32) -> [u32; 3] {
        let e = 3 * t as usize;
        [self.corners[e], self.corners[e + 1], self.corners[e + 2]]
    }

    /// The three corners of triangle `t`.
    #[inline]
    pub fn triangle_vertices(&self, t: u32) -> [Vertex; 3] {
        self.triangle(t).map(|v| self.points[v as usize])
    }

    /// The (column, row) of the three corners of triangle `t`.
    pub fn triangle_points(&self, t: u32) -> [(i64, i64); 3] {
        self.triangle_vertices(t).map(Vertex::point)
    }

    /// Adds vertex `(x, y)` at height `z` and returns its index.
    #[inline]
    pub fn add_point(&mut self, x: i64, y: i64, z: f64) -> u32 {
        let (x, y) = (x as i32, y as i32);
        self.points.push(Vertex { x, y, z });
        (self.points.len() - 1) as u32
    }

    #[inline]
    fn link(&mut self, e: u32, f: u32) {
        if e != NONE {
            self.twins[e as usize] = f;
        }
        if f != NONE {
            self.twins[f as usize] = e;
        }
    }

    /// Appends `count` empty triangle slots; returns the first.
    fn new_slots(&mut self, count: usize) -> u32 {
        let first = self.triangle_count() as u32;
        self.corners.resize(self.corners.len() + 3 * count, NONE);
        self.twins.resize(self.twins.len() + 3 * count, NONE);
        first
    }

    /// Writes triangle slot `t` with `twins` across its three half-edges.
    #[inline]
    fn set_triangle(&mut self, t: u32, corners: [u32; 3], twins: [u32; 3]) {
        let e = 3 * t as usize;
        self.corners[e..e + 3].copy_from_slice(&corners);
        for (k, twin) in twins.into_iter().enumerate() {
            self.link(e as u32 + k as u32, twin);
        }
    }

    /// Splits triangle `t` at vertex `p` inside it into three triangles; returns them
    /// and the half-edges opposite `p` (the old sides, to legalise).
    pub fn split_triangle(&mut self, t: u32, p: u32) -> ([u32; 3], [u32; 3]) {
        let [a, b, c] = self.triangle(t);
        let e = 3 * t;
        let outer = [e, e + 1, e + 2].map(|h| self.twins[h as usize]);
        let t1 = self.new_slots(2);
        let t2 = t1 + 1;
        // t: a→b, b→p, p→a; t1: b→c, c→p, p→b; t2: c→a, a→p, p→c.
        self.set_triangle(t, [a, b, p], [outer[0], 3 * t1 + 2, 3 * t2 + 1]);
        self.set_triangle(t1, [b, c, p], [outer[1], 3 * t2 + 2, e + 1]);
        self.set_triangle(t2, [c, a, p], [outer[2], e + 2, 3 * t1 + 1]);
        ([t, t1, t2], [e, 3 * t1, 3 * t2])
    }

    /// Splits the edge of half-edge `e` at vertex `p` on it: two triangles become four
    /// (one becomes two on the border). Appends the triangles made to `made` and the
    /// half-edges opposite `p` (to legalise) to `opposite` (no allocation a split).
    pub fn split_edge(&mut self, e: u32, p: u32, made: &mut Vec<u32>, opposite: &mut Vec<u32>) {
        let f = self.twins[e as usize];
        let (a, b, c) = (
            self.corners[e as usize],
            self.corners[next(e) as usize],
            self.corners[prev(e) as usize],
        );
        let (x1, x2) = (self.twins[next(e) as usize], self.twins[prev(e) as usize]);
        let t1 = e / 3;
        let n1 = self.new_slots(if f == NONE { 1 } else { 2 });
        if f == NONE {
            // t1: a→p, p→c, c→a; n1: p→b, b→c, c→p.
            self.set_triangle(t1, [a, p, c], [NONE, 3 * n1 + 2, x2]);
            self.set_triangle(n1, [p, b, c], [NONE, x1, 3 * t1 + 1]);
            made.extend_from_slice(&[t1, n1]);
            opposite.extend_from_slice(&[3 * t1 + 2, 3 * n1 + 1]);
            return;
        }
        let d = self.corners[prev(f) as usize];
        let (y1, y2) = (self.twins[next(f) as usize], self.twins[prev(f) as usize]);
        let (t2, n2) = (f / 3, n1 + 1);
        // t2: b→p, p→d, d→b; n2: p→a, a→d, d→p.
        self.set_triangle(t1, [a, p, c], [3 * n2, 3 * n1 + 2, x2]);
        self.set_triangle(n1, [p, b, c], [3 * t2, x1, 3 * t1 + 1]);
        self.set_triangle(t2, [b, p, d], [3 * n1, 3 * n2 + 2, y2]);
        self.set_triangle(n2, [p, a, d], [3 * t1, y1, 3 * t2 + 1]);
        made.extend_from_slice(&[t1, n1, t2, n2]);
        opposite.extend_from_slice(&[3 * t1 + 2, 3 * n1 + 1, 3 * t2 + 2, 3 * n2 + 1]);
    }

    /// The quadrilateral around the edge of `e` (`e` from `a` to `b` in triangle
    /// `(a, b, c)`, its twin in `(b, a, d)`): `[a, b, c, d]`, or `None` on the border.
    #[inline]
    pub fn quad(&self, e: u32) -> Option<[u32; 4]> {
        let f = self.twins[e as usize];
        (f != NONE).then(|| {
            [
                self.corners[e as usize],
                self.corners[next(e) as usize],
                self.corners[prev(e) as usize],
                self.corners[prev(f) as usize],
            ]
        })
    }

    /// [`Triangulation::quad`]'s corners.
    #[inline]
    pub fn quad_vertices(&self, e: u32) -> Option<[Vertex; 4]> {
        Some(self.quad(e)?.map(|v| self.points[v as usize]))
    }

    /// The (column, row) of [`Triangulation::quad`]'s corners.
    #[inline]
    pub fn quad_points(&self, e: u32) -> Option<[(i64, i64); 4]> {
        Some(self.quad_vertices(e)?.map(Vertex::point))
    }

    /// Replaces the diagonal `a–b` of the quadrilateral around `e` by `c–d` (see
    /// [`Triangulation::quad`]); returns the two half-edges of the new triangles opposite
    /// `c` (`a→d` and `d→b`).
    #[inline]
    pub fn flip(&mut self, e: u32) -> [u32; 2] {
        let f = self.twins[e as usize];
        assert!(f != NONE, "an interior edge");
        let corner = |h: u32| self.corners[h as usize];
        let [a, b, c, d] = [corner(e), corner(next(e)), corner(prev(e)), corner(prev(f))];
        let twin = |h: u32| self.twins[h as usize];
        let (x1, x2) = (twin(next(e)), twin(prev(e)));
        let (y1, y2) = (twin(next(f)), twin(prev(f)));
        let (e1, e2) = (3 * (e / 3), 3 * (f / 3));
        // t1: c→a, a→d, d→c; t2: d→b, b→c, c→d. Written at once: the two new
        // triangles' six half-edges, then the four outer ones pointing back.
        let (t1, t2) = (e1 as usize, e2 as usize);
        self.corners[t1..t1 + 3].copy_from_slice(&[c, a, d]);
        self.corners[t2..t2 + 3].copy_from_slice(&[d, b, c]);
        self.twins[t1..t1 + 3].copy_from_slice(&[x2, y1, e2 + 2]);
        self.twins[t2..t2 + 3].copy_from_slice(&[y2, x1, e1 + 2]);
        for (h, outer) in [(e1, x2), (e1 + 1, y1), (e2, y2), (e2 + 1, x1)] {
            if outer != NONE {
                self.twins[outer as usize] = h;
            }
        }
        [e1 + 1, e2]
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Every twin pair runs between the same vertices in opposite directions, every
    /// triangle is counter-clockwise, and the areas add up to the rectangle's.
    pub(crate) fn assert_consistent(t: &Triangulation, width: usize, height: usize) {
        let mut area = 0;
        for tri in 0..t.triangle_count() as u32 {
            let [a, b, c] = t.triangle_points(tri);
            let twice = orient(a, b, c);
            assert!(twice > 0, "triangle {tri} is not counter-clockwise");
            area += twice;
        }
        assert_eq!(area, 2 * (width as i64 - 1) * (height as i64 - 1));
        for e in 0..t.corners.len() as u32 {
            let f = t.twins[e as usize];
            let (from, to) = (t.corners[e as usize], t.corners[next(e) as usize]);
            if f == NONE {
                let (p, q) = (
                    t.points[from as usize].point(),
                    t.points[to as usize].point(),
                );
                let on_border = |k: usize, v: i64| p_k(p, k) == v && p_k(q, k) == v;
                let (w, h) = (width as i64 - 1, height as i64 - 1);
                assert!(on_border(0, 0) || on_border(0, w) || on_border(1, 0) || on_border(1, h));
            } else {
                assert_eq!(t.twins[f as usize], e);
                assert_eq!(t.corners[f as usize], to);
                assert_eq!(t.corners[next(f) as usize], from);
            }
        }
    }

    fn p_k(p: (i64, i64), k: usize) -> i64 {
        if k == 0 {
            p.0
        } else {
            p.1
        }
    }

    #[test]
    fn the_rectangle_is_two_linked_triangles() {
        let t = Triangulation::rectangle(5, 3, |_| 0.0);
        assert_eq!(t.triangle_count(), 2);
        assert_consistent(&t, 5, 3);
    }

    #[test]
    fn splitting_a_triangle_makes_three() {
        let mut t = Triangulation::rectangle(9, 9, |_| 0.0);
        let p = t.add_point(2, 5, 0.0);
        let tri = (0..2).find(|&k| {
            let [a, b, c] = t.triangle_points(k);
            orient(a, b, (2, 5)) > 0 && orient(b, c, (2, 5)) > 0 && orient(c, a, (2, 5)) > 0
        });
        let (made, _) = t.split_triangle(tri.unwrap(), p);
        assert_eq!(made.len(), 3);
        assert_eq!(t.triangle_count(), 4);
        assert_consistent(&t, 9, 9);
    }

    #[test]
    fn splitting_interior_and_border_edges() {
        let mut t = Triangulation::rectangle(9, 9, |_| 0.0);
        // The rectangle's diagonal is its one interior edge.
        let diagonal = (0..6)
            .find(|&e| t.twins[e as usize] != NONE)
            .expect("an interior edge");
        let p = t.add_point(4, 4, 0.0);
        t.split_edge(diagonal, p, &mut Vec::new(), &mut Vec::new());
        assert_eq!(t.triangle_count(), 4);
        assert_consistent(&t, 9, 9);
        let border = (0..t.corners.len() as u32)
            .find(|&e| {
                let (from, to) = (t.corners[e as usize], t.corners[next(e) as usize]);
                t.twins[e as usize] == NONE
                    && t.points[from as usize].y == 8
                    && t.points[to as usize].y == 8
            })
            .unwrap();
        let q = t.add_point(2, 8, 0.0);
        let (mut made, mut opposite) = (Vec::new(), Vec::new());
        t.split_edge(border, q, &mut made, &mut opposite);
        assert_eq!((made.len(), opposite.len()), (2, 2));
        assert_eq!(t.triangle_count(), 5);
        assert_consistent(&t, 9, 9);
    }

    #[test]
    fn flipping_swaps_the_diagonal() {
        let mut t = Triangulation::rectangle(3, 3, |_| 0.0);
        let e = (0..6).find(|&e| t.twins[e as usize] != NONE).unwrap();
        let [a, b, c, d] = t.quad(e).unwrap();
        t.flip(e);
        assert_consistent(&t, 3, 3);
        let mut diagonal: Vec<u32> = (0..6)
            .filter(|&e| t.twins[e as usize] != NONE)
            .map(|e| t.corners[e as usize])
            .collect();
        diagonal.sort();
        let mut expected = vec![c, d];
        expected.sort();
        assert_eq!(diagonal, expected);
        assert!(!diagonal.contains(&a) && !diagonal.contains(&b));
    }

    #[test]
    fn in_circle_agrees_for_near_and_far_points() {
        let far = 1 << 20;
        assert!(in_circle((0, 0), (far, 0), (far, far), (far / 2, far / 2)));
        assert!(!in_circle((0, 0), (far, 0), (far, far), (0, far)));
        assert!(!in_circle((0, 0), (far, 0), (far, far), (-1, far + 1)));
        assert!(in_circle((0, 0), (9, 0), (9, 9), (1, 8)));
    }

    #[test]
    fn in_circle_near_agrees_with_in_circle() {
        let mut state = 7u64;
        let mut point = || {
            let mut coordinate = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 40) % 24) as i64
            };
            (coordinate(), coordinate())
        };
        let (mut inside, mut outside) = (0, 0);
        for _ in 0..20000 {
            let (a, b, c, d) = (point(), point(), point(), point());
            if orient(a, b, c) <= 0 {
                continue;
            }
            let near = in_circle_near(a, b, c, d);
            assert_eq!(near, in_circle(a, b, c, d), "{a:?} {b:?} {c:?} {d:?}");
            (inside, outside) = (inside + usize::from(near), outside + usize::from(!near));
        }
        assert!(inside > 100 && outside > 100);
    }

    #[test]
    fn in_circle_is_strict() {
        // Four corners of a square are cocircular: not inside.
        assert!(!in_circle((0, 0), (2, 0), (2, 2), (0, 2)));
        assert!(in_circle((0, 0), (2, 0), (2, 2), (1, 1)));
        assert!(!in_circle((0, 0), (2, 0), (2, 2), (5, 5)));
    }
}
