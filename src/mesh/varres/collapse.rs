//! One edge collapse without a new vertex: vertex `from` moves onto its neighbour `to`,
//! the one or two triangles on the edge vanish and the others of `from`'s star are
//! re-made around `to`. Here: whether a collapse keeps the mesh valid, what it costs,
//! and carrying it out, with the removed samples each triangle covers handed on to
//! the new triangles (the paper's reassignment).

use super::error::{ErrorMetric, Plane};
use super::topology::{Star, Topology, NONE};

/// The most triangles a vertex may end with: collapses that would give `to` more are
/// refused, so flat water does not end as fans of hundreds of slivers whose every
/// evaluation walks them all.
pub const MAX_DEGREE: usize = 24;

/// The removed samples each triangle covers, as linked lists through the samples.
#[derive(Debug, Clone, Default)]
pub struct Owned {
    /// First sample of each triangle's list ([`NONE`]: empty).
    head: Vec<u32>,
    /// Next sample in the same list.
    next: Vec<u32>,
}

impl Owned {
    /// No sample owned, for `samples` samples and `triangles` triangles.
    pub fn new(samples: usize, triangles: usize) -> Owned {
        Owned {
            head: vec![NONE; triangles],
            next: vec![NONE; samples],
        }
    }

    /// The samples triangle `t` covers.
    pub fn of(&self, t: u32) -> impl Iterator<Item = u32> + '_ {
        let mut at = self.head.get(t as usize).copied().unwrap_or(NONE);
        std::iter::from_fn(move || {
            (at != NONE).then(|| {
                let s = at;
                at = self.next[s as usize];
                s
            })
        })
    }

    fn give(&mut self, t: u32, s: u32) {
        if self.head.len() <= t as usize {
            self.head.resize(t as usize + 1, NONE);
        }
        self.next[s as usize] = self.head[t as usize];
        self.head[t as usize] = s;
    }
}

/// The far corners `(a, b)` of star triangle `t` of `from`, counter-clockwise.
fn far_corners(topology: &Topology, t: u32, from: u32) -> (u32, u32) {
    let i = topology.slot(t, from);
    let c = topology.corners[t as usize];
    (c[(i + 1) % 3], c[(i + 2) % 3])
}

/// Whether `from` (star `star`) may collapse onto `to` (star `to_star`): no new
/// triangle flipped or flat, the link condition (the edge's ends share no neighbour
/// but the corners of its triangles: the mesh stays manifold) and `to` within
/// [`MAX_DEGREE`].
pub fn is_valid(topology: &Topology, star: &Star, to_star: &Star, from: u32, to: u32) -> bool {
    let mut kept = 0;
    let mut opposite = [NONE; 2];
    for &t in &star.triangles {
        let (a, b) = far_corners(topology, t, from);
        if a == to {
            opposite[0] = b;
        } else if b == to {
            opposite[1] = a;
        } else if topology.orient(to, a, b) <= 0 {
            return false;
        } else {
            kept += 1;
        }
    }
    let removed = star.triangles.len() - kept;
    if kept == 0 || to_star.triangles.len() + kept - removed > MAX_DEGREE {
        return false;
    }
    star.ring
        .iter()
        .filter(|&&w| w != to && !opposite.contains(&w))
        .all(|w| !to_star.ring.contains(w))
}

/// `(column, row, height)` of the samples the star of `from` covers: those its
/// triangles hold, its ring and `from` itself (the same for every edge of `from`, so
/// gathered once).
pub fn covered_samples(
    topology: &Topology,
    heights: &[f64],
    owned: &Owned,
    star: &Star,
    from: u32,
    out: &mut Vec<[f64; 3]>,
) {
    out.clear();
    let samples = star.triangles.iter().flat_map(|&t| owned.of(t));
    let all = samples.chain(star.ring.iter().copied()).chain([from]);
    out.extend(all.map(|s| {
        let (x, y) = topology.xy(s);
        [x as f64, y as f64, heights[s as usize]]
    }));
}

/// The cost of collapsing `from` (star `star`, covering `covered`) onto `to` under
/// `metric`.
pub fn cost(
    topology: &Topology,
    heights: &[f64],
    metric: ErrorMetric,
    (star, covered): (&Star, &[[f64; 3]]),
    from: u32,
    to: u32,
) -> f64 {
    let before = || star.triangles.iter().map(|&t| topology.corners[t as usize]);
    match metric {
        ErrorMetric::VertexPlane => Plane::average(topology, heights, before())
            .map_or(0.0, |plane| plane.distance(topology, heights, from)),
        ErrorMetric::AveragePlane => {
            let after = before().filter(|c| !c.contains(&to)).map(|c| {
                let mut c = c;
                c.iter_mut().filter(|v| **v == from).for_each(|v| *v = to);
                c
            });
            let Some(plane) = Plane::average(topology, heights, after) else {
                return f64::INFINITY;
            };
            covered
                .iter()
                .map(|&p| plane.distance_to(p))
                .fold(0.0, f64::max)
        }
    }
}

/// Collapses `from` (star `star`, checked with [`is_valid`]) onto `to`: kills the star,
/// makes the new triangles (returned in `created`), links them to their neighbours
/// and hands every sample the star covered, `from` included, to the new triangle
/// that covers it.
pub fn apply(
    topology: &mut Topology,
    owned: &mut Owned,
    star: &Star,
    from: u32,
    to: u32,
    created: &mut Vec<u32>,
) {
    created.clear();
    // Half-edges still to be paired with their twins: (start, end, triangle, slot).
    let mut open: Vec<(u32, u32, u32, usize)> = Vec::with_capacity(2 * star.triangles.len());
    for &t in &star.triangles {
        let (a, b) = far_corners(topology, t, from);
        let outer = topology.neighbours[t as usize][(topology.slot(t, from) + 1) % 3];
        if a == to || b == to {
            if outer != NONE {
                open.push((b, a, outer, topology.edge_slot(outer, b, a)));
            }
            continue;
        }
        let n = topology.push([to, a, b], [NONE, outer, NONE]);
        if outer != NONE {
            let s = topology.edge_slot(outer, b, a);
            topology.neighbours[outer as usize][s] = n;
        }
        open.push((to, a, n, 0));
        open.push((b, to, n, 2));
        created.push(n);
    }
    for k in 0..open.len() {
        let (p, q, t, s) = open[k];
        if let Some(&(_, _, twin, _)) = open.iter().find(|e| e.0 == q && e.1 == p) {
            topology.neighbours[t as usize][s] = twin;
        }
    }
    for &n in created.iter() {
        for v in topology.corners[n as usize] {
            topology.corner_of[v as usize] = n;
        }
    }
    topology.corner_of[from as usize] = NONE;
    hand_on_samples(topology, owned, star, from, created);
}

/// Gives every sample the dead star covered, and `from`, to the new triangle that
/// covers it (the first one when it is on an edge they share).
fn hand_on_samples(
    topology: &Topology,
    owned: &mut Owned,
    star: &Star,
    from: u32,
    created: &[u32],
) {
    let mut samples: Vec<u32> = star.triangles.iter().flat_map(|&t| owned.of(t)).collect();
    samples.push(from);
    for s in samples {
        let p = topology.xy(s);
        let inside = created.iter().copied().find(|&n| {
            let [a, b, c] = topology.corners[n as usize].map(|v| topology.xy(v));
            super::topology::orient(a, b, p) >= 0
                && super::topology::orient(b, c, p) >= 0
                && super::topology::orient(c, a, p) >= 0
        });
        debug_assert!(inside.is_some(), "the new triangles cover the old star");
        owned.give(inside.unwrap_or(created[0]), s);
    }
}
