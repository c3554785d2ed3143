//! Crack-free triangulation of a cell partition.
//!
//! Every cell is triangulated with its four corners and every vertex its smaller
//! neighbours put on its edges (the *hanging* vertices), so no T-junction or crack can
//! appear: along a shared edge, both sides have the same vertices. A cell with `k`
//! hanging vertices gets `k + 2` triangles in the [`Shape::Two`] shape: the diagonal cuts
//! it into two halves, and each half `A → B → C` (with hanging vertices `a₁…` on `AB` and
//! `b₁…` on `BC`) is fanned from `C` over `A, a₁, …, a_last` and from `a_last` (or `A`)
//! over `B, b₁, …, C`; every triangle then has two vertices on one cell side and the third
//! off that side's line, so none is degenerate. In the [`Shape::Fan`] shape it gets
//! `k + 4`: one triangle from the centre sample to each boundary segment.
//!
//! A grid cell with a nodata corner (its coarser ancestors all split, so no neighbour puts
//! a vertex on its sides) is the one triangle of its three valid corners, or nothing when
//! fewer are valid. Its neighbours share the sides whose ends are both valid.
//!
//! The cost is proportional to the output: each leaf looks at its four same-level
//! neighbours' split bits and walks down only into split ones.

use super::cells::{Cell, CellTree, Side};
use super::pyramid::{Diagonal, DiagonalPyramid, Heights, Shape};
use super::GridMesh;

/// Reusable buffers for triangulating cell after cell.
#[derive(Debug, Default)]
pub struct Scratch {
    /// Hanging vertices of the current side, as coordinates along it (increasing).
    points: Vec<usize>,
    /// The cell's boundary as sample indices, counter-clockwise in the grid frame from
    /// the top-left corner, with that corner repeated at the end.
    ring: Vec<u32>,
}

/// Triangulates every leaf of `tree` in the shape `shape` gives it. Vertices are numbered
/// in raster order of their samples.
///
/// # Panics
/// If the grid has more than `u32::MAX` samples or `heights` is not the tree's grid.
pub fn triangulate(
    tree: &CellTree,
    heights: Heights<'_>,
    shape: impl Fn(Cell) -> Shape,
) -> GridMesh {
    let (width, height) = tree.size();
    assert_eq!((heights.width, heights.height), (width, height));
    let n = width * height;
    assert!(
        u32::try_from(n).is_ok(),
        "grid too large for 32-bit vertex ids"
    );
    // Pass 1: triangles over sample indices, marking the samples used in a bitmap (an
    // eighth of a byte a sample: it stays in cache where a per-sample id table would not).
    let mut used = vec![0u64; n.div_ceil(64)];
    // Most cells have two triangles and a few hanging vertices.
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(tree.leaves().len() * 5 / 2 + 16);
    let mut scratch = Scratch::default();
    let mut mark_and_push = |t: [u32; 3]| {
        for s in t {
            used[s as usize / 64] |= 1 << (s % 64);
        }
        triangles.push(t);
    };
    for &cell in tree.leaves() {
        if cell.level == 0 {
            grid_cell_triangles(
                tree.valid_corners(cell),
                grid_cell_ring(width, cell),
                &mut mark_and_push,
            );
        } else {
            cell_triangles(tree, cell, shape(cell), &mut scratch, &mut mark_and_push);
        }
    }
    // Pass 2: a vertex's id is the rank of its sample among the used ones (each word
    // beside the count of the bits before it: one cache line a look-up).
    let mut ranked: Vec<(u64, u32)> = Vec::with_capacity(used.len());
    let mut total = 0u32;
    for &word in &used {
        ranked.push((word, total));
        total += word.count_ones();
    }
    let rank = |s: u32| {
        let (word, before) = ranked[s as usize / 64];
        before + (word & ((1u64 << (s % 64)) - 1)).count_ones()
    };
    for t in &mut triangles {
        *t = [rank(t[0]), rank(t[1]), rank(t[2])];
    }
    let mut vertices = Vec::with_capacity(total as usize);
    for (w, &word) in used.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            vertices.push((w * 64) as u32 + bits.trailing_zeros());
            bits &= bits - 1;
        }
    }
    GridMesh {
        width,
        height,
        vertices,
        triangles,
    }
}

/// The two-triangle shape with the diagonal [`Heights::diagonal`] picks (read from
/// `diagonals`): the shape of cells chosen by a threshold.
#[inline]
pub fn centre_rule(diagonals: &DiagonalPyramid<'_>, cell: Cell) -> Shape {
    if cell.level == 0 {
        Shape::Two(Diagonal::Falling)
    } else {
        let (i, j) = cell.position();
        Shape::Two(diagonals.diagonal(cell.level, i, j))
    }
}

/// Emits the triangles of leaf `cell` in `shape` as triples of sample indices,
/// counter-clockwise in the grid frame; returns the number of hanging vertices (the
/// triangles are 2 or 4, by shape, plus that).
pub fn cell_triangles(
    tree: &CellTree,
    cell: Cell,
    shape: Shape,
    scratch: &mut Scratch,
    emit: &mut impl FnMut([u32; 3]),
) -> usize {
    let (width, _) = tree.size();
    if cell.level == 0 {
        grid_cell_triangles(tree.valid_corners(cell), grid_cell_ring(width, cell), emit);
        return 0;
    }
    let (x0, y0, x1, y1) = tree.bounds(cell);
    let sample = |x: usize, y: usize| (y * width + x) as u32;
    let (tl, tr) = (sample(x0, y0), sample(x1, y0));
    let (bl, br) = (sample(x0, y1), sample(x1, y1));
    // The ring: each side's corner, then its hanging vertices in ring order.
    let ring = &mut scratch.ring;
    ring.clear();
    let mut corners = [0usize; 5];
    for (s, side) in Side::ALL.into_iter().enumerate() {
        corners[s] = ring.len();
        let points = &mut scratch.points;
        points.clear();
        neighbour_points(tree, cell, side, points);
        match side {
            Side::Top => {
                ring.push(tl);
                ring.extend(points.iter().map(|&x| sample(x, y0)));
            }
            Side::Right => {
                ring.push(tr);
                ring.extend(points.iter().map(|&y| sample(x1, y)));
            }
            Side::Bottom => {
                ring.push(br);
                ring.extend(points.iter().rev().map(|&x| sample(x, y1)));
            }
            Side::Left => {
                ring.push(bl);
                ring.extend(points.iter().rev().map(|&y| sample(x0, y)));
            }
        }
    }
    corners[4] = ring.len();
    ring.push(tl);
    let hanging = corners[4] - 4;
    let side = |s: usize| &ring[corners[s]..=corners[s + 1]];
    match shape {
        Shape::Fan => {
            let centre = sample((x0 + x1) / 2, (y0 + y1) / 2);
            for pair in ring.windows(2) {
                emit([pair[0], pair[1], centre]);
            }
        }
        Shape::Two(Diagonal::Falling) => {
            fan_half(side(0), side(1), emit);
            fan_half(side(2), side(3), emit);
        }
        Shape::Two(Diagonal::Rising) => {
            fan_half(side(1), side(2), emit);
            fan_half(side(3), side(0), emit);
        }
    }
    hanging
}

/// The corner samples of grid cell `cell` (level 0) on a grid `width` samples wide:
/// top-left, top-right, bottom-right, bottom-left.
#[inline]
fn grid_cell_ring(width: usize, cell: Cell) -> [u32; 4] {
    let tl = (cell.j as usize * width + cell.i as usize) as u32;
    let bl = tl + width as u32;
    [tl, tl + 1, bl + 1, bl]
}

/// The triangles of a grid cell with corners `ring` (top-left, top-right, bottom-right,
/// bottom-left) of which those in bit mask `valid` are valid: two when all four are (no
/// neighbour is smaller than a grid cell, and the diagonal changes the height at no
/// sample), the one of the valid corners when three are, none otherwise.
#[inline]
fn grid_cell_triangles(valid: u8, ring: [u32; 4], emit: &mut impl FnMut([u32; 3])) {
    let [tl, tr, br, bl] = ring;
    match valid {
        0b1111 => {
            emit([tl, tr, br]);
            emit([br, bl, tl]);
        }
        // Dropping one corner of the counter-clockwise ring keeps it counter-clockwise.
        0b1110 => emit([tr, br, bl]),
        0b1101 => emit([tl, br, bl]),
        0b1011 => emit([tl, tr, bl]),
        0b0111 => emit([tl, tr, br]),
        _ => {}
    }
}

/// Triangulates the half-cell bounded by chains `ab` (A … B) and `bc` (B … C) and the
/// diagonal C → A.
#[inline]
fn fan_half(ab: &[u32], bc: &[u32], emit: &mut impl FnMut([u32; 3])) {
    let c = bc[bc.len() - 1];
    // Fan from C over A, a₁, …, a_last.
    let last = ab.len() - 2;
    for k in 0..last {
        emit([ab[k], ab[k + 1], c]);
    }
    // Fan from a_last (A when AB has no hanging vertex) over B, b₁, …, C.
    let pivot = ab[last];
    for pair in bc.windows(2) {
        emit([pivot, pair[0], pair[1]]);
    }
}

/// Appends to `points` the coordinates (along `side`, increasing) of the vertices strictly
/// inside `side` of `cell`: every sample on a fine border, else those the smaller cells
/// across it put there, or its marked midpoint.
fn neighbour_points(tree: &CellTree, cell: Cell, side: Side, points: &mut Vec<usize>) {
    if tree.on_fine_border(cell, side) {
        let (x0, y0, x1, y1) = tree.bounds(cell);
        match side {
            Side::Top | Side::Bottom => points.extend(x0 + 1..x1),
            Side::Left | Side::Right => points.extend(y0 + 1..y1),
        }
        return;
    }
    if let Some((ni, nj)) = tree.neighbour(cell, side) {
        if tree.is_split(cell.level, ni, nj) {
            collect_side(tree, cell.level, ni, nj, side.opposite(), points);
            // The last point is the far corner of the shared side, not a hanging vertex.
            points.pop();
            return;
        }
    }
    if tree.has_midpoint(cell, side) {
        points.extend(tree.midpoint(cell, side));
    }
}

/// Appends the end coordinate (along `side`) of every leaf of split node
/// `(level, i, j)`'s subtree lying along its `side`, in increasing order.
fn collect_side(
    tree: &CellTree,
    level: u32,
    i: usize,
    j: usize,
    side: Side,
    points: &mut Vec<usize>,
) {
    let (cw, ch) = tree.nodes(level - 1);
    for k in 0..2 {
        let (ci, cj) = match side {
            Side::Top => (2 * i + k, 2 * j),
            Side::Bottom => (2 * i + k, 2 * j + 1),
            Side::Left => (2 * i, 2 * j + k),
            Side::Right => (2 * i + 1, 2 * j + k),
        };
        if ci >= cw || cj >= ch {
            continue;
        }
        if tree.is_split(level - 1, ci, cj) {
            collect_side(tree, level - 1, ci, cj, side, points);
        } else {
            let (_, _, x1, y1) = tree.bounds(Cell::new(level - 1, ci, cj));
            points.push(match side {
                Side::Top | Side::Bottom => x1,
                Side::Left | Side::Right => y1,
            });
        }
    }
}
