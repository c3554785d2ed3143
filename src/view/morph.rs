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
use crate::mesh::cells::{Cell, CellTree};
use crate::mesh::pyramid::{node_bounds, Diagonal};
use crate::mesh::GridMesh;

/// Reusable buffers for morphing frame after frame.
#[derive(Debug, Default)]
pub struct MorphScratch {
    /// Morphed height by sample index (only the current mesh's vertices are meaningful).
    by_sample: Vec<f64>,
    /// Mesh vertex indices ordered by birth level, coarsest first.
    order: Vec<u32>,
    /// Vertices per birth level.
    counts: Vec<usize>,
    /// Blend factor of every split node this frame, index `m − 1` for level `m`
    /// (meaningless for nodes that did not split).
    blends: Vec<Vec<f32>>,
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
    if scratch.by_sample.len() != w * h {
        scratch.by_sample = vec![0.0; w * h];
    }
    order_by_birth(mesh, levels, scratch);
    split_blends(terrain, view, rule, tree, &mut scratch.blends);
    let blends = &scratch.blends;
    let blend = |m: u32, i: usize, j: usize| {
        if tree.is_split(m, i, j) {
            f64::from(blends[m as usize - 1][j * tree.nodes(m).0 + i])
        } else {
            0.0
        }
    };
    let mut out = vec![0.0; mesh.vertices.len()];
    for &v in &scratch.order {
        let s = mesh.vertices[v as usize] as usize;
        let (x, y) = (s % w, s / w);
        let truth = heights.values[s];
        let birth = corner_level(x, w, levels).min(corner_level(y, h, levels));
        let z = if birth >= levels {
            truth
        } else {
            let (coarse, blend) =
                parent_height(terrain, &blend, &scratch.by_sample, x, y, birth + 1);
            if blend >= 1.0 {
                truth
            } else {
                coarse + blend * (truth - coarse)
            }
        };
        scratch.by_sample[s] = z;
        out[v as usize] = z;
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
/// into `blends`.
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
        blends[m as usize - 1].resize(nw * nh, 0.0);
    }
    let mut stack: Vec<Cell> = Vec::new();
    if levels > 0 {
        let (rw, rh) = tree.nodes(levels);
        stack.extend((0..rh).flat_map(|j| (0..rw).map(move |i| Cell::new(levels, i, j))));
    }
    while let Some(cell) = stack.pop() {
        let (i, j) = cell.position();
        if !tree.is_split(cell.level, i, j) {
            continue;
        }
        let b = if terrain.is_void(cell.level, i, j) {
            1.0
        } else {
            blend_of_ratio(terrain.evaluate(view, rule, cell.level, i, j).ratio)
        };
        let nw = tree.nodes(cell.level).0;
        blends[cell.level as usize - 1][j * nw + i] = b as f32;
        if cell.level > 1 {
            let (cw, ch) = tree.nodes(cell.level - 1);
            for (ci, cj) in [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(a, b)| (2 * i + a, 2 * j + b)) {
                if ci < cw && cj < ch {
                    stack.push(Cell::new(cell.level - 1, ci, cj));
                }
            }
        }
    }
}

/// `(v_p, b)` of the vertex at (`x`, `y`) born below level `parent`: from the parents'
/// edge through it, or from the parent it lies inside (`blend(m, i, j)`: a node's blend
/// factor).
fn parent_height(
    terrain: &ViewTerrain<'_>,
    blend: &impl Fn(u32, usize, usize) -> f64,
    morphed: &[f64],
    x: usize,
    y: usize,
    parent: u32,
) -> (f64, f64) {
    let heights = terrain.heights();
    let (w, h) = (heights.width, heights.height);
    let levels = terrain.levels();
    let at = |x: usize, y: usize| morphed[y * w + x];
    let blend = |i: usize, j: usize| blend(parent, i, j);
    let span = 1usize << parent;
    let along = |c: usize, samples: usize| {
        let c0 = c / span * span;
        (c0, (c0 + span).min(samples - 1))
    };
    // The nodes on either side of corner coordinate c: the one ending there and the one
    // starting there.
    let sides = |c: usize, samples: usize| {
        let before = (c > 0).then(|| c.div_ceil(span) - 1);
        let after = (c + 1 < samples).then_some(c / span);
        (before, after)
    };
    if corner_level(x, w, levels) >= parent {
        // On a vertical edge of the parents at column x.
        let (y0, y1) = along(y, h);
        let t = (y - y0) as f64 / (y1 - y0) as f64;
        let j = y / span;
        let (left, right) = sides(x, w);
        let b = [left, right]
            .into_iter()
            .flatten()
            .map(|i| blend(i, j))
            .fold(1.0, f64::min);
        return (at(x, y0) + t * (at(x, y1) - at(x, y0)), b);
    }
    if corner_level(y, h, levels) >= parent {
        let (x0, x1) = along(x, w);
        let t = (x - x0) as f64 / (x1 - x0) as f64;
        let i = x / span;
        let (top, bottom) = sides(y, h);
        let b = [top, bottom]
            .into_iter()
            .flatten()
            .map(|j| blend(i, j))
            .fold(1.0, f64::min);
        return (at(x0, y) + t * (at(x1, y) - at(x0, y)), b);
    }
    let (i, j) = (x / span, y / span);
    let bounds = node_bounds(w, h, parent, i, j);
    let (x0, y0, x1, y1) = bounds;
    let corners = [at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)];
    let u = (x - x0) as f64 / (x1 - x0) as f64;
    let v = (y - y0) as f64 / (y1 - y0) as f64;
    let z = two_triangles(corners, terrain.diagonal(parent, i, j), u, v);
    (z, blend(i, j))
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
