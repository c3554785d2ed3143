//! Geomorphing (Röttger et al. 1998, with Ju & Kim's crack fixes): every vertex of a view
//! mesh is drawn at `v = v_p + b · (v_c − v_p)`, between the height `v_p` the coarser cell
//! gives it and its true height `v_c`, with the blend factor `b` of the node whose split
//! made it appear.
//!
//! A vertex is born at the finest level `L` at which it is no node corner; its parent is
//! level `L + 1`:
//! - on a parent's edge (a *midpoint*, or a child's corner on it): `v_p` interpolates the
//!   edge's two ends and `b` is the smaller blend factor of the two parents sharing the
//!   edge, so both sides morph it identically;
//! - inside a parent (its *centre*, or a grandchild's corner on an ancestor's diagonal):
//!   `v_p` interpolates the parent's two triangles (its diagonal) and `b` is the parent's.
//!
//! The ends and corners `v_p` reads are themselves morphed (they are born at coarser
//! levels, so they are computed first): a vertex on an ancestor's edge or diagonal follows
//! that ancestor's blend however many levels up it sits. Every height is a function of the
//! vertex alone, so an edge shared by two triangles has the same ends on both sides, and
//! every height moves continuously with the camera.

use super::camera::View;
use super::selection::{blend_of_ratio, Rule, ViewTerrain};
use crate::mesh::cells::CellTree;
use crate::mesh::pyramid::{node_bounds, Diagonal};
use crate::mesh::GridMesh;

/// Reusable buffers for morphing frame after frame.
#[derive(Debug, Default)]
pub struct MorphScratch {
    /// The sample → vertex numbering of the current mesh.
    index: VertexIndex,
    /// Mesh vertex indices ordered by birth level, coarsest first.
    order: Vec<u32>,
    /// Vertices per birth level.
    counts: Vec<usize>,
    /// Blend factor of every split node this frame, index `m − 1` for level `m`
    /// (meaningless for nodes that did not split).
    blends: Vec<Vec<f32>>,
}

/// Which samples are vertices of a mesh and their vertex numbers (the mesh numbers its
/// vertices in sample order): one bit a sample and a running count a 64-sample word, so
/// a lookup is two loads and a population count, in 1/48 of the memory of a
/// per-sample table.
#[derive(Debug, Default)]
struct VertexIndex {
    /// Bit `s % 64` of word `s / 64`: sample `s` is a vertex.
    is_vertex: Vec<u64>,
    /// Vertices before each word of `is_vertex`.
    rank_before: Vec<u32>,
}

impl VertexIndex {
    /// The numbering of `mesh`'s vertices.
    fn rebuild(&mut self, mesh: &GridMesh) {
        let words = (mesh.width * mesh.height).div_ceil(64);
        self.is_vertex.clear();
        self.is_vertex.resize(words, 0);
        for &s in &mesh.vertices {
            self.is_vertex[s as usize / 64] |= 1 << (s % 64);
        }
        self.rank_before.clear();
        let mut total = 0u32;
        for &word in &self.is_vertex {
            self.rank_before.push(total);
            total += word.count_ones();
        }
    }

    /// The vertex at sample `s`, if it is one.
    #[inline]
    fn vertex(&self, s: usize) -> Option<usize> {
        let (word, bit) = (self.is_vertex[s / 64], s % 64);
        (word >> bit & 1 != 0).then(|| {
            (self.rank_before[s / 64] + (word & ((1u64 << bit) - 1)).count_ones()) as usize
        })
    }
}

/// How coarse a coordinate is along a side of `samples` samples: the highest level at
/// which it is a node corner (the ends are corners at every level).
#[inline]
fn corner_level(c: usize, samples: usize, levels: u32) -> u32 {
    if c == 0 || c + 1 == samples {
        levels
    } else {
        c.trailing_zeros().min(levels)
    }
}

/// What a vertex's morph reads: the frame's selection and blends, and the heights
/// morphed so far (by vertex).
struct MorphFrame<'s> {
    terrain: &'s ViewTerrain<'s>,
    tree: &'s CellTree,
    blends: &'s [Vec<f32>],
    index: &'s VertexIndex,
    morphed: &'s [f64],
}

/// Where a vertex's coarse height `v_p` comes from.
enum Coarse {
    /// The parents' edge `[x0, y0, x1, y1]` through it, at `t` from the first end.
    Edge([usize; 4], f64),
    /// The two triangles of parent `(i, j)`.
    Inside(usize, usize),
}

/// The morphed height (data units) of every vertex of `mesh`, the view mesh of `tree`
/// under `view` and `rule`.
pub fn morph(
    terrain: &ViewTerrain<'_>,
    view: &View,
    rule: Rule,
    tree: &CellTree,
    mesh: &GridMesh,
    scratch: &mut MorphScratch,
) -> Vec<f64> {
    let heights = terrain.heights();
    let (w, h) = (heights.width, heights.height);
    let levels = terrain.levels();
    scratch.index.rebuild(mesh);
    order_by_birth(mesh, levels, scratch);
    split_blends(terrain, view, rule, tree, &mut scratch.blends);
    let mut out = vec![0.0; mesh.vertices.len()];
    for &v in &scratch.order {
        let s = mesh.vertices[v as usize] as usize;
        let (x, y) = (s % w, s / w);
        let truth = heights.values[s];
        let birth = corner_level(x, w, levels).min(corner_level(y, h, levels));
        out[v as usize] = if birth >= levels {
            truth
        } else {
            let frame = MorphFrame {
                terrain,
                tree,
                blends: &scratch.blends,
                index: &scratch.index,
                morphed: &out,
            };
            frame.height(x, y, truth, birth + 1)
        };
    }
    out
}

/// Counting sort of the vertices by birth level, coarsest first, into `scratch.order`.
fn order_by_birth(mesh: &GridMesh, levels: u32, scratch: &mut MorphScratch) {
    let (w, h) = (mesh.width, mesh.height);
    let birth = |s: u32| {
        let s = s as usize;
        corner_level(s % w, w, levels).min(corner_level(s / w, h, levels)) as usize
    };
    scratch.counts.clear();
    scratch.counts.resize(levels as usize + 2, 0);
    for &s in &mesh.vertices {
        scratch.counts[levels as usize - birth(s)] += 1;
    }
    let mut start = 0;
    for c in scratch.counts.iter_mut() {
        let n = *c;
        *c = start;
        start += n;
    }
    scratch.order.clear();
    scratch.order.resize(mesh.vertices.len(), 0);
    for (v, &s) in mesh.vertices.iter().enumerate() {
        let slot = &mut scratch.counts[levels as usize - birth(s)];
        scratch.order[*slot] = v as u32;
        *slot += 1;
    }
}

/// The blend factor of every split node of `tree` (1 for void ones), one evaluation each,
/// into `blends`, level by level in row order (every split node's parent split too, so
/// these are the nodes a descent from the roots would reach).
fn split_blends(
    terrain: &ViewTerrain<'_>,
    view: &View,
    rule: Rule,
    tree: &CellTree,
    blends: &mut Vec<Vec<f32>>,
) {
    let levels = terrain.levels();
    blends.resize(levels as usize, Vec::new());
    for m in 1..=levels {
        let (nw, nh) = tree.nodes(m);
        let level = &mut blends[m as usize - 1];
        level.resize(nw * nh, 0.0);
        for (i, j) in tree.split_nodes(m) {
            let b = if terrain.is_void(m, i, j) {
                1.0
            } else {
                blend_of_ratio(terrain.evaluate(view, rule, m, i, j).ratio)
            };
            level[j * nw + i] = b as f32;
        }
    }
}

impl MorphFrame<'_> {
    /// Blend factor of node `(m, i, j)`: its own when it split, else 0.
    #[inline]
    fn blend(&self, m: u32, i: usize, j: usize) -> f64 {
        if self.tree.is_split(m, i, j) {
            f64::from(self.blends[m as usize - 1][j * self.tree.nodes(m).0 + i])
        } else {
            0.0
        }
    }

    /// The morphed height of the vertex at (`x`, `y`), true height `truth`, born below
    /// level `parent`: `v_p + b·(truth − v_p)`, `(v_p, b)` from the parents' edge through
    /// it or the parent it lies inside.
    #[inline]
    fn height(&self, x: usize, y: usize, truth: f64, parent: u32) -> f64 {
        let heights = self.terrain.heights();
        let (w, h) = (heights.width, heights.height);
        let levels = self.terrain.levels();
        let span = 1usize << parent;
        // The node range along a coordinate and the nodes on either side of a corner
        // coordinate: the one ending there and the one starting there.
        let along = |c: usize, samples: usize| {
            let c0 = c / span * span;
            (c0, (c0 + span).min(samples - 1))
        };
        let sides = |c: usize, samples: usize| {
            let before = (c > 0).then(|| c.div_ceil(span) - 1);
            let after = (c + 1 < samples).then_some(c / span);
            [before, after]
        };
        let blend_of = |nodes: [Option<(usize, usize)>; 2]| {
            nodes
                .into_iter()
                .flatten()
                .map(|(i, j)| self.blend(parent, i, j))
                .fold(1.0, f64::min)
        };
        let (blend, source) = if corner_level(x, w, levels) >= parent {
            // On a vertical edge of the parents at column x.
            let (y0, y1) = along(y, h);
            let j = y / span;
            let b = blend_of(sides(x, w).map(|i| i.map(|i| (i, j))));
            (
                b,
                Coarse::Edge([x, y0, x, y1], (y - y0) as f64 / (y1 - y0) as f64),
            )
        } else if corner_level(y, h, levels) >= parent {
            let (x0, x1) = along(x, w);
            let i = x / span;
            let b = blend_of(sides(y, h).map(|j| j.map(|j| (i, j))));
            (
                b,
                Coarse::Edge([x0, y, x1, y], (x - x0) as f64 / (x1 - x0) as f64),
            )
        } else {
            let (i, j) = (x / span, y / span);
            (self.blend(parent, i, j), Coarse::Inside(i, j))
        };
        if blend >= 1.0 {
            return truth;
        }
        let coarse = match source {
            Coarse::Edge([x0, y0, x1, y1], t) => {
                let (a, b) = (self.at(x0, y0), self.at(x1, y1));
                a + t * (b - a)
            }
            Coarse::Inside(i, j) => self.inside(parent, i, j, x, y),
        };
        coarse + blend * (truth - coarse)
    }

    /// The morphed height of the vertex at (`x`, `y`); the true height of a sample that
    /// is no vertex (read only where the blend is 1, so its value does not count).
    #[inline]
    fn at(&self, x: usize, y: usize) -> f64 {
        let heights = self.terrain.heights();
        let s = y * heights.width + x;
        self.index
            .vertex(s)
            .map_or(heights.values[s], |v| self.morphed[v])
    }

    /// The height at (`x`, `y`) of parent `(parent, i, j)` drawn as two triangles.
    #[inline]
    fn inside(&self, parent: u32, i: usize, j: usize, x: usize, y: usize) -> f64 {
        let heights = self.terrain.heights();
        let (x0, y0, x1, y1) = node_bounds(heights.width, heights.height, parent, i, j);
        let corners = [
            self.at(x0, y0),
            self.at(x1, y0),
            self.at(x0, y1),
            self.at(x1, y1),
        ];
        let u = (x - x0) as f64 / (x1 - x0) as f64;
        let v = (y - y0) as f64 / (y1 - y0) as f64;
        two_triangles(corners, self.terrain.diagonal(parent, i, j), u, v)
    }
}

/// Height at (u, v) ∈ [0, 1]² of a cell with corner heights `[tl, tr, bl, br]` drawn as
/// two triangles along `diagonal`.
#[inline]
fn two_triangles([tl, tr, bl, br]: [f64; 4], diagonal: Diagonal, u: f64, v: f64) -> f64 {
    match diagonal {
        Diagonal::Falling if u >= v => tl + u * (tr - tl) + v * (br - tr),
        Diagonal::Falling => tl + v * (bl - tl) + u * (br - bl),
        Diagonal::Rising if u + v <= 1.0 => tl + u * (tr - tl) + v * (bl - tl),
        Diagonal::Rising => br + (1.0 - u) * (bl - br) + (1.0 - v) * (tr - br),
    }
}
