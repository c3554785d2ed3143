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
//!
//! Frame to frame ([`MorphScratch`]), the morphed heights live in sample space (a vertex
//! keeps its slot whatever appears or vanishes elsewhere) and are computed split node by
//! split node, level by level from the coarsest; the mesh's vertices read them at the
//! end. A split node whose ratio was at least 2 (blend 1) keeps blend 1 without being
//! evaluated until the camera has moved as far as the ratio's bound allows (the
//! incremental selection's bound, at twice the tolerance): only the transition band is
//! evaluated again. The output is the from-scratch morph's, bit for bit.

use glam::DVec3;

use super::camera::View;
use super::incremental::{after, camera_motion, round_down, stays_above};
use super::selection::{blend_of_ratio, z_order, Rule, ViewTerrain};
use crate::mesh::cells::CellTree;
use crate::mesh::pyramid::{node_bounds, Diagonal};
use crate::mesh::GridMesh;

/// How many split nodes ahead of its evaluation a node's summary is prefetched.
const PREFETCH_AHEAD: usize = 8;

/// What morphing keeps from frame to frame, for one terrain and rule (it starts again by
/// itself when either changes, or the projection does): the morphed height of every
/// sample, so a vertex keeps its place whatever the others do, and per node how far the
/// camera may move before its blend factor could fall below 1.
#[derive(Debug, Default)]
pub struct MorphScratch {
    /// Per sample, its morphed height in the last frame it was a vertex (its true height
    /// before that).
    samples: Vec<f64>,
    /// Blend factor of every split node this frame, index `m − 1` for level `m`, row by
    /// row ([`UNSPLIT`] for nodes that did not split).
    blends: Vec<Vec<f32>>,
    /// Per level (as `blends`), the row-major indices of the nodes that split in the
    /// last frame (their blends are reset to [`UNSPLIT`] before the level is morphed).
    was_split: Vec<Vec<u32>>,
    /// Per node (as `blends`), the camera motion up to which its ratio stays at least 2
    /// (blend 1), rounded down to an `f32` (so looked at again slightly early, never
    /// late); below `travelled` when unknown.
    settled: Vec<Vec<f32>>,
    /// Camera motion accumulated since the state started (see [`camera_motion`]).
    travelled: f64,
    /// The split nodes of the level being morphed, row by row.
    split: Vec<SplitNode>,
    /// The last frame's view, and what the state belongs to.
    last: Option<View>,
    owner: Option<Owner>,
    /// Corners of the terrain's bounding box.
    extent: [DVec3; 8],
}

/// The blend factor held for a node that did not split (any negative value: a split
/// node's factor is in [0, 1]).
const UNSPLIT: f32 = -1.0;

/// A split node of the level being morphed: its column, row and Z-order index.
#[derive(Debug, Clone, Copy)]
struct SplitNode {
    i: u32,
    j: u32,
    z: usize,
}

/// The terrain and rule a [`MorphScratch`] holds state for.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Owner {
    heights: usize,
    size: (usize, usize),
    rule: Rule,
}

/// The morphed height (data units) of every vertex of `mesh`, the view mesh of `tree`
/// under `view` and `rule`. Vertices are morphed in sample space, level by level from the
/// coarsest, by the split node they are born in (its centre and edge midpoints); a node
/// whose ratio was at least 2 (blend 1) and cannot have fallen below since is not
/// evaluated again.
pub fn morph(
    terrain: &ViewTerrain<'_>,
    view: &View,
    rule: Rule,
    tree: &CellTree,
    mesh: &GridMesh,
    scratch: &mut MorphScratch,
) -> Vec<f64> {
    scratch.advance(terrain, view, rule, tree);
    for m in (1..=terrain.levels()).rev() {
        scratch.list_split(tree, m);
        scratch.level_blends(terrain, view, rule, tree, m);
        scratch.level_vertices(terrain, tree, m);
    }
    mesh.vertices
        .iter()
        .map(|&s| scratch.samples[s as usize])
        .collect()
}

impl MorphScratch {
    /// The heap bytes the state holds (its vectors' capacities).
    pub fn heap_bytes(&self) -> usize {
        let nested = |v: &Vec<Vec<f32>>| {
            v.iter().map(|l| l.capacity() * 4).sum::<usize>()
                + v.capacity() * std::mem::size_of::<Vec<f32>>()
        };
        self.samples.capacity() * std::mem::size_of::<f64>()
            + self.split.capacity() * std::mem::size_of::<SplitNode>()
            + nested(&self.blends)
            + nested(&self.settled)
            + self
                .was_split
                .iter()
                .map(|l| l.capacity() * 4)
                .sum::<usize>()
            + self.was_split.capacity() * std::mem::size_of::<Vec<u32>>()
    }

    /// Moves the state to `view` (from scratch for another terrain, rule or projection).
    fn advance(&mut self, terrain: &ViewTerrain<'_>, view: &View, rule: Rule, tree: &CellTree) {
        let heights = terrain.heights();
        let owner = Owner {
            heights: heights.values.as_ptr() as usize,
            size: (heights.width, heights.height),
            rule,
        };
        if self.owner != Some(owner) {
            self.owner = Some(owner);
            self.samples.clear();
            self.samples.extend_from_slice(heights.values);
            self.last = None;
            self.blends.clear();
            self.was_split.clear();
            let (lo, hi) = terrain.extent();
            self.extent = [0, 1, 2, 3, 4, 5, 6, 7].map(|k| {
                DVec3::select(glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0), hi, lo)
            });
        }
        let motion = self.last.map_or(f64::INFINITY, |last| {
            camera_motion(&last, view, &self.extent, f64::INFINITY)
        });
        self.last = Some(*view);
        let levels = terrain.levels() as usize;
        if motion.is_finite() {
            self.travelled += motion;
        } else {
            self.travelled = 0.0;
            self.settled.clear();
        }
        self.blends.resize(levels, Vec::new());
        self.was_split.resize(levels, Vec::new());
        self.settled.resize(levels, Vec::new());
        for m in 1..=levels {
            let (nw, nh) = tree.nodes(m as u32);
            self.blends[m - 1].resize(nw * nh, UNSPLIT);
            self.settled[m - 1].resize(nw * nh, f32::NEG_INFINITY);
        }
    }

    /// Lists the split nodes of level `m` with their Z-order indices (a row's half of the
    /// index computed once).
    fn list_split(&mut self, tree: &CellTree, m: u32) {
        self.split.clear();
        let mut row = (usize::MAX, 0);
        for (i, j) in tree.split_nodes(m) {
            if row.0 != j {
                row = (j, z_order(0, j));
            }
            let z = z_order(i, 0) | row.1;
            self.split.push(SplitNode {
                i: i as u32,
                j: j as u32,
                z,
            });
        }
    }

    /// The blend factor of every split node of level `m` (1 for void ones, and for those
    /// still settled), evaluating the others and settling those at blend 1; the nodes
    /// that split in the last frame and no longer do get [`UNSPLIT`]. The nodes'
    /// summaries are stored in Z order and read here row by row, so each is prefetched
    /// [`PREFETCH_AHEAD`] nodes before its evaluation.
    fn level_blends(
        &mut self,
        terrain: &ViewTerrain<'_>,
        view: &View,
        rule: Rule,
        tree: &CellTree,
        m: u32,
    ) {
        let nw = tree.nodes(m).0;
        let level = m as usize - 1;
        let (blends, settled, was_split) = (
            &mut self.blends[level],
            &mut self.settled[level],
            &mut self.was_split[level],
        );
        for &k in was_split.iter() {
            blends[k as usize] = UNSPLIT;
        }
        was_split.clear();
        for (n, node) in self.split.iter().enumerate() {
            if let Some(ahead) = self.split.get(n + PREFETCH_AHEAD) {
                terrain.prefetch_node(m, ahead.z);
            }
            let (i, j) = (node.i as usize, node.j as usize);
            let k = j * nw + i;
            was_split.push(k as u32);
            blends[k] = if f64::from(settled[k]) > self.travelled || terrain.is_void(m, i, j) {
                1.0
            } else {
                let b = blend_of_ratio(terrain.ratio_at(view, rule, m, i, j, node.z));
                if b >= 1.0 {
                    let node = terrain.evaluate(view, rule, m, i, j);
                    settled[k] = round_down(after(self.travelled, stays_above(rule, node, 2.0)));
                }
                b as f32
            };
        }
    }

    /// Morphs the vertices born in the split nodes of level `m`: each node's centre and
    /// the midpoints of its bottom and right edges, and of its top and left ones where
    /// the node across does not split (which would morph them itself). A midpoint blends
    /// with the smaller factor of the two nodes sharing its edge (0 beside a node that
    /// does not split: it stays on the coarse edge), a centre with its node's.
    fn level_vertices(&mut self, terrain: &ViewTerrain<'_>, tree: &CellTree, m: u32) {
        let heights = terrain.heights();
        let (w, h) = (heights.width, heights.height);
        let half = 1usize << (m - 1);
        let nw = tree.nodes(m).0;
        let blends = &self.blends[m as usize - 1];
        // The blend factor of the node at `k`, 0 where it does not split.
        let blend = |k: usize| f64::from(blends[k]).max(0.0);
        // Where a node is clipped by the grid's edge its midpoint is off centre.
        let at = |mid: usize, lo: usize, hi: usize| {
            if hi - lo == 2 * half {
                0.5
            } else {
                (mid - lo) as f64 / (hi - lo) as f64
            }
        };
        let mut out = Vertices {
            samples: &mut self.samples,
            truth: heights.values,
            width: w,
        };
        for node in &self.split {
            let (i, j) = (node.i as usize, node.j as usize);
            let k = j * nw + i;
            let (x0, y0, x1, y1) = node_bounds(w, h, m, i, j);
            let (xm, ym) = (x0 + half, y0 + half);
            let own = f64::from(blends[k]);
            let (u, v) = (at(xm, x0, x1), at(ym, y0, y1));
            if xm < x1 {
                if j == 0 || blends[k - nw] < 0.0 {
                    let b = if j == 0 { own } else { own.min(blend(k - nw)) };
                    out.edge((xm, y0), [(x0, y0), (x1, y0)], u, b);
                }
                let b = if y1 + 1 < h {
                    own.min(blend(k + nw))
                } else {
                    own
                };
                out.edge((xm, y1), [(x0, y1), (x1, y1)], u, b);
            }
            if ym < y1 {
                if i == 0 || blends[k - 1] < 0.0 {
                    let b = if i == 0 { own } else { own.min(blend(k - 1)) };
                    out.edge((x0, ym), [(x0, y0), (x0, y1)], v, b);
                }
                let b = if x1 + 1 < w {
                    own.min(blend(k + 1))
                } else {
                    own
                };
                out.edge((x1, ym), [(x1, y0), (x1, y1)], v, b);
                if xm < x1 {
                    let diagonal = || terrain.diagonal_at(m, node.z);
                    out.centre((xm, ym), (x0, y0, x1, y1), diagonal, (u, v), own);
                }
            }
        }
    }
}

/// The morphed heights of a frame in sample space, and the true ones.
struct Vertices<'a> {
    samples: &'a mut [f64],
    truth: &'a [f64],
    width: usize,
}

impl Vertices<'_> {
    /// Morphs the vertex at `(x, y)`, at `t` along the coarse edge between `ends`, with
    /// blend factor `blend`.
    #[inline]
    fn edge(&mut self, (x, y): (usize, usize), ends: [(usize, usize); 2], t: f64, blend: f64) {
        let w = self.width;
        self.blend(y * w + x, blend, |heights| {
            let [(ax, ay), (bx, by)] = ends;
            let (a, b) = (heights[ay * w + ax], heights[by * w + bx]);
            a + t * (b - a)
        });
    }

    /// Morphs the vertex at `(x, y)`, at `(u, v)` inside the coarse node `bounds` drawn
    /// as two triangles along `diagonal`, with blend factor `blend`.
    #[inline]
    fn centre(
        &mut self,
        (x, y): (usize, usize),
        (x0, y0, x1, y1): (usize, usize, usize, usize),
        diagonal: impl Fn() -> Diagonal,
        (u, v): (f64, f64),
        blend: f64,
    ) {
        let w = self.width;
        self.blend(y * w + x, blend, |heights| {
            let at = |x: usize, y: usize| heights[y * w + x];
            let corners = [at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)];
            two_triangles(corners, diagonal(), u, v)
        });
    }

    /// Sets sample `s` to its true height, or below blend factor 1 to the height
    /// `coarse` reads off the morphed heights, moved `blend` of the way to the truth.
    #[inline]
    fn blend(&mut self, s: usize, blend: f64, coarse: impl FnOnce(&[f64]) -> f64) {
        let truth = self.truth[s];
        self.samples[s] = if blend >= 1.0 {
            truth
        } else {
            let coarse = coarse(self.samples);
            coarse + blend * (truth - coarse)
        };
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
