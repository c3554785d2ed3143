//! The live triangle mesh the simplification edits: every triangle ever made (dead ones
//! stay, unreachable from the live ones, because the history needs their corners), the
//! neighbour across each edge, one live triangle at each vertex, and the stars (fans)
//! of vertices found by rotating through neighbours.

use crate::mesh::qem::flags::Diagonal;
use crate::mesh::qem::grid::Grid;

/// No triangle (a border edge) or no vertex.
pub const NONE: u32 = u32::MAX;

/// Triangles with adjacency over the samples of a grid.
#[derive(Debug, Clone, Default)]
pub struct Topology {
    /// Samples per row.
    pub width: usize,
    /// Corners of every triangle made so far, positively oriented in (column, row).
    pub corners: Vec<[u32; 3]>,
    /// `neighbours[t][i]`: the triangle across the edge from corner `i` to `i + 1`.
    pub neighbours: Vec<[u32; 3]>,
    /// One live triangle at each sample ([`NONE`]: not a vertex).
    pub corner_of: Vec<u32>,
    /// Samples whose triangles do not form one fan (two cells meeting at a corner
    /// only): they never move.
    pub non_manifold: Vec<bool>,
}

/// The triangles around a vertex in counter-clockwise order, from the border when
/// the vertex is on one.
#[derive(Debug, Clone, Default)]
pub struct Star {
    /// The triangles, counter-clockwise.
    pub triangles: Vec<u32>,
    /// The other ends of the vertex's edges, counter-clockwise; one more than the
    /// triangles on the border.
    pub ring: Vec<u32>,
    /// Whether the vertex is on the mesh's border.
    pub boundary: bool,
}

impl Topology {
    /// The grid's valid cell triangles (each cell split along the QEM mesher's diagonal
    /// rule, cells with one void corner kept as one triangle), with adjacency.
    pub fn of_grid(grid: &Grid) -> Topology {
        let mut corners = Vec::new();
        for y in 0..grid.height - 1 {
            for x in 0..grid.width - 1 {
                let cell = y * grid.width + x;
                let diagonal: Diagonal = grid.choose_diagonal(cell);
                for t in grid.cell_triangles(cell, diagonal) {
                    if grid.is_valid_triangle(t) {
                        corners.push(t);
                    }
                }
            }
        }
        let neighbours = link_edges(&corners);
        let mut topology = Topology {
            width: grid.width,
            corner_of: vec![NONE; grid.len()],
            non_manifold: vec![false; grid.len()],
            corners,
            neighbours,
        };
        topology.mark_non_manifold();
        topology
    }

    fn mark_non_manifold(&mut self) {
        let mut incident = vec![0u32; self.corner_of.len()];
        for (t, c) in self.corners.iter().enumerate() {
            for &v in c {
                incident[v as usize] += 1;
                self.corner_of[v as usize] = t as u32;
            }
        }
        let mut star = Star::default();
        for (v, &count) in incident.iter().enumerate() {
            if count > 0 {
                self.star(v as u32, &mut star);
                self.non_manifold[v] = star.triangles.len() as u32 != count;
            }
        }
    }

    /// The position of `v` among the corners of `t`.
    pub fn slot(&self, t: u32, v: u32) -> usize {
        let c = self.corners[t as usize];
        if c[0] == v {
            0
        } else if c[1] == v {
            1
        } else {
            2
        }
    }

    /// Column and row of sample `v`.
    pub fn xy(&self, v: u32) -> (i64, i64) {
        let v = v as usize;
        ((v % self.width) as i64, (v / self.width) as i64)
    }

    /// Twice the signed area of `(a, b, c)` seen from above (positive: the mesh's
    /// orientation), exact.
    pub fn orient(&self, a: u32, b: u32, c: u32) -> i64 {
        orient(self.xy(a), self.xy(b), self.xy(c))
    }

    /// The star of vertex `v` (which must have a live triangle).
    pub fn star(&self, v: u32, star: &mut Star) {
        star.triangles.clear();
        star.ring.clear();
        let start = self.corner_of[v as usize];
        let mut t = start;
        star.boundary = false;
        loop {
            let before = self.neighbours[t as usize][self.slot(t, v)];
            if before == NONE {
                star.boundary = true;
                break;
            }
            if before == start {
                break;
            }
            t = before;
        }
        let first = t;
        loop {
            let i = self.slot(t, v);
            let c = self.corners[t as usize];
            star.triangles.push(t);
            star.ring.push(c[(i + 1) % 3]);
            let next = self.neighbours[t as usize][(i + 2) % 3];
            if next == NONE {
                star.ring.push(c[(i + 2) % 3]);
                return;
            }
            if next == first {
                return;
            }
            t = next;
        }
    }

    /// Adds a live triangle and returns its index.
    pub fn push(&mut self, corners: [u32; 3], neighbours: [u32; 3]) -> u32 {
        self.corners.push(corners);
        self.neighbours.push(neighbours);
        (self.corners.len() - 1) as u32
    }

    /// The slot of the edge from `p` to `q` in triangle `t`.
    pub fn edge_slot(&self, t: u32, p: u32, q: u32) -> usize {
        let c = self.corners[t as usize];
        (0..3)
            .find(|&i| c[i] == p && c[(i + 1) % 3] == q)
            .expect("the edge is in the triangle")
    }
}

/// Twice the signed area of the triangle `(a, b, c)` of integer points.
pub fn orient(a: (i64, i64), b: (i64, i64), c: (i64, i64)) -> i64 {
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

/// The neighbour across every edge of `corners`: half-edges sorted by their undirected
/// edge, twins adjacent.
fn link_edges(corners: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut half_edges: Vec<(u64, u32)> = Vec::with_capacity(corners.len() * 3);
    for (t, c) in corners.iter().enumerate() {
        for i in 0..3 {
            let (p, q) = (c[i], c[(i + 1) % 3]);
            let key = (u64::from(p.min(q)) << 32) | u64::from(p.max(q));
            half_edges.push((key, (t as u32) * 3 + i as u32));
        }
    }
    half_edges.sort_unstable();
    let mut neighbours = vec![[NONE; 3]; corners.len()];
    for pair in half_edges.windows(2) {
        if pair[0].0 == pair[1].0 {
            let (a, b) = (pair[0].1, pair[1].1);
            neighbours[(a / 3) as usize][(a % 3) as usize] = b / 3;
            neighbours[(b / 3) as usize][(b % 3) as usize] = a / 3;
        }
    }
    neighbours
}
