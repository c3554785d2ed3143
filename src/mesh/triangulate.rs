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
//! [`triangulate`] finds the vertices first ([`super::vertex_set`]: every leaf corner in a
//! row-major and a column-major bitmap), then writes each leaf's triangles once with their
//! final vertex numbers, reading a side's hanging vertices from the bitmaps.
//! [`cell_triangles`] makes one leaf's triangles on its own, walking down the split
//! neighbours' subtrees for the hanging vertices.

use super::cells::{Cell, CellTree, Side};
use super::pyramid::{Diagonal, DiagonalPyramid, Heights, Shape};
use super::vertex_set::{used_samples, CornerMaps, VertexNumbers};
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
/// in raster order of their samples, triangles come leaf after leaf in the order of
/// [`CellTree::leaves`], each leaf's as [`cell_triangles`] makes them.
///
/// The vertices are found first ([`super::vertex_set`]), so every triangle is written
/// once with its final vertex numbers, and a side's hanging vertices are read from a
/// bitmap.
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
    assert!(
        u32::try_from(width * height).is_ok(),
        "grid too large for 32-bit vertex ids"
    );
    let corners = CornerMaps::of(tree, &shape);
    let numbers = if tree.has_nodata() {
        VertexNumbers::new(&used_samples(tree, &corners, &shape), width)
    } else {
        VertexNumbers::new(&corners.rows, width)
    };
    // Most cells have two triangles and a few hanging vertices.
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(tree.leaves().len() * 5 / 2 + 16);
    let mut scratch = Scratch::default();
    let mut push = |t: [u32; 3]| triangles.push(t);
    let mut block = GridBlock::default();
    let nodata = tree.has_nodata();
    for &cell in tree.leaves() {
        if cell.level > 0 {
            let maps = (&corners, &numbers);
            leaf_triangles(tree, cell, shape(cell), maps, &mut scratch, &mut push);
        } else if nodata {
            let ring = numbered_grid_cell(cell, &numbers);
            grid_cell_triangles(tree.valid_corners(cell), ring, &mut push);
        } else {
            grid_cell_triangles(0b1111, block.corners(cell, &numbers, height), &mut push);
        }
    }
    GridMesh {
        width,
        height,
        vertices: numbers.samples(),
        triangles,
    }
}

/// The vertex numbers of grid cell `cell`'s corners in [`grid_cell_ring`] order (those of
/// its nodata corners are meaningless).
#[inline]
fn numbered_grid_cell(cell: Cell, numbers: &VertexNumbers) -> [u32; 4] {
    let (x, y) = cell.position();
    [(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)].map(|(x, y)| numbers.number(x, y))
}

/// The vertex numbers of the grid cells under one split level-1 node when no sample is
/// nodata: every sample of the node is then a vertex, so the numbers along a row follow
/// each other and one look-up a row gives them all.
#[derive(Debug, Default)]
struct GridBlock {
    /// The node's top-left sample.
    origin: Option<(usize, usize)>,
    /// The number of the node's first sample on each of its rows.
    rows: [u32; 3],
}

impl GridBlock {
    /// The corner numbers of grid cell `cell` in [`grid_cell_ring`] order, on a grid of
    /// `height` rows.
    #[inline]
    fn corners(&mut self, cell: Cell, numbers: &VertexNumbers, height: usize) -> [u32; 4] {
        let (x, y) = cell.position();
        let origin = (x & !1, y & !1);
        if self.origin != Some(origin) {
            self.origin = Some(origin);
            for (k, row) in self.rows.iter_mut().enumerate() {
                if origin.1 + k < height {
                    *row = numbers.number(origin.0, origin.1 + k);
                }
            }
        }
        let (dx, dy) = ((x - origin.0) as u32, y - origin.1);
        let (tl, bl) = (self.rows[dy] + dx, self.rows[dy + 1] + dx);
        [tl, tl + 1, bl + 1, bl]
    }
}

/// Emits the triangles of leaf `cell` (level ≥ 1) in `shape`, numbered by `numbers`, its
/// hanging vertices read from `corners`.
#[inline]
fn leaf_triangles(
    tree: &CellTree,
    cell: Cell,
    shape: Shape,
    (corners, numbers): (&CornerMaps, &VertexNumbers),
    scratch: &mut Scratch,
    emit: &mut impl FnMut([u32; 3]),
) {
    let bounds = tree.bounds(cell);
    let (x0, y0, x1, y1) = bounds;
    let ring = [
        numbers.number(x0, y0),
        numbers.number(x1, y0),
        numbers.number(x1, y1),
        numbers.number(x0, y1),
    ];
    match shape {
        Shape::Two(diagonal) if !has_hanging(bounds, ring, corners) => {
            two_triangles(diagonal, ring, emit);
        }
        shape => {
            let sides = numbered_ring(bounds, ring, corners, numbers, scratch);
            let centre = match shape {
                Shape::Fan => numbers.number((x0 + x1) / 2, (y0 + y1) / 2),
                Shape::Two(_) => 0,
            };
            emit_ring(&scratch.ring, sides, shape, centre, emit);
        }
    }
}

/// Whether a leaf with closed sample range `bounds` and corner vertex numbers `ring`
/// (top-left, top-right, bottom-right, bottom-left) has vertices inside its sides: a
/// horizontal side has when its corners' numbers do not follow each other.
#[inline]
fn has_hanging(
    (x0, y0, x1, y1): (usize, usize, usize, usize),
    [tl, tr, br, bl]: [u32; 4],
    corners: &CornerMaps,
) -> bool {
    tr != tl + 1
        || br != bl + 1
        || corners.columns.any_between(x0, y0, y1)
        || corners.columns.any_between(x1, y0, y1)
}

/// The two triangles of a leaf without hanging vertices, corners `ring` (top-left,
/// top-right, bottom-right, bottom-left), as [`cell_triangles`] makes them.
#[inline]
fn two_triangles(diagonal: Diagonal, [tl, tr, br, bl]: [u32; 4], emit: &mut impl FnMut([u32; 3])) {
    match diagonal {
        Diagonal::Falling => {
            emit([tl, tr, br]);
            emit([br, bl, tl]);
        }
        Diagonal::Rising => {
            emit([tr, br, bl]);
            emit([bl, tl, tr]);
        }
    }
}

/// Fills `scratch.ring` with the vertex numbers of the boundary of the leaf with closed
/// sample range `bounds` and corner numbers `ring` (top-left, top-right, bottom-right,
/// bottom-left), in the order [`cell_triangles`] builds its ring, and returns where each
/// side starts (and the closing corner's slot). The vertices strictly inside a
/// horizontal side are numbered consecutively between its corners; those of a vertical
/// side are read from the column bitmap.
#[inline]
fn numbered_ring(
    (x0, y0, x1, y1): (usize, usize, usize, usize),
    [tl, tr, br, bl]: [u32; 4],
    corners: &CornerMaps,
    numbers: &VertexNumbers,
    scratch: &mut Scratch,
) -> [usize; 5] {
    let (ring, points) = (&mut scratch.ring, &mut scratch.points);
    ring.clear();
    ring.extend(tl..tr);
    let right = ring.len();
    ring.push(tr);
    points.clear();
    corners.columns.ones_between(x1, y0, y1, points);
    ring.extend(points.iter().map(|&y| numbers.number(x1, y)));
    let bottom = ring.len();
    ring.extend((bl + 1..=br).rev());
    let left = ring.len();
    ring.push(bl);
    points.clear();
    corners.columns.ones_between(x0, y0, y1, points);
    ring.extend(points.iter().rev().map(|&y| numbers.number(x0, y)));
    let end = ring.len();
    ring.push(tl);
    [0, right, bottom, left, end]
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
    let centre = sample((x0 + x1) / 2, (y0 + y1) / 2);
    emit_ring(ring, corners, shape, centre, emit);
    corners[4] - 4
}

/// Emits the triangles of a leaf with boundary `ring` (counter-clockwise from the
/// top-left corner, which closes it again; side `s` runs from `ring[sides[s]]` to
/// `ring[sides[s + 1]]`) in `shape`; `centre` is the fan's centre vertex.
#[inline]
fn emit_ring(
    ring: &[u32],
    sides: [usize; 5],
    shape: Shape,
    centre: u32,
    emit: &mut impl FnMut([u32; 3]),
) {
    let side = |s: usize| &ring[sides[s]..=sides[s + 1]];
    match shape {
        Shape::Fan => {
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

#[cfg(test)]
mod tests {
    use bitvec::prelude::*;

    use super::*;
    use crate::mesh::cells::Across;
    use crate::mesh::pyramid::VoidPyramid;
    use crate::mesh::FineBorders;

    /// The triangulation leaf by leaf: each leaf's triangles from [`cell_triangles`] over
    /// sample indices, then every sample numbered by its rank among the used ones. What
    /// [`triangulate`] must equal, triangle for triangle.
    fn by_cells(tree: &CellTree, shape: impl Fn(Cell) -> Shape) -> GridMesh {
        let (width, height) = tree.size();
        let mut triangles = Vec::new();
        let mut scratch = Scratch::default();
        for &cell in tree.leaves() {
            cell_triangles(tree, cell, shape(cell), &mut scratch, &mut |t| {
                triangles.push(t)
            });
        }
        let mut vertices: Vec<u32> = triangles.iter().flatten().copied().collect();
        vertices.sort_unstable();
        vertices.dedup();
        for t in &mut triangles {
            *t = t.map(|s| vertices.binary_search(&s).expect("a vertex") as u32);
        }
        GridMesh {
            width,
            height,
            vertices,
            triangles,
        }
    }

    /// A random partition of a `w × h` grid (nodata where `void_share` says), with
    /// random fine borders, fans and marked midpoints, and the shape of every leaf.
    fn random_case(
        w: usize,
        h: usize,
        levels: u32,
        void_share: u64,
        seed: u64,
    ) -> (CellTree, Vec<(Cell, Shape)>) {
        let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let valid: BitVec<u64, Lsb0> = (0..w * h).map(|_| random() % 100 >= void_share).collect();
        let voids = VoidPyramid::new(w, h, levels, &valid);
        let split_share = random() % 60 + 20;
        let mut tree = CellTree::build(w, h, levels, voids.as_ref(), |_, _, _| {
            random() % 100 < split_share
        });
        let bits = random();
        tree.set_fine_borders(FineBorders {
            top: bits & 1 != 0,
            right: bits & 2 != 0,
            bottom: bits & 4 != 0,
            left: bits & 8 != 0,
        });
        let mut shapes = Vec::new();
        for &cell in tree.clone().leaves() {
            let (x0, y0, x1, y1) = tree.bounds(cell);
            let shape = match random() % 3 {
                0 if cell.level > 0 && x1 - x0 >= 2 && y1 - y0 >= 2 => Shape::Fan,
                1 => Shape::Two(Diagonal::Rising),
                _ => Shape::Two(Diagonal::Falling),
            };
            if shape == Shape::Fan {
                for side in Side::ALL {
                    let open = matches!(tree.across(cell, side), Across::Border | Across::Leaf);
                    if open && random() % 2 == 0 {
                        tree.mark_midpoint(cell, side);
                    }
                }
            }
            shapes.push((cell, shape));
        }
        shapes.sort_unstable_by_key(|&(cell, _)| cell);
        (tree, shapes)
    }

    #[test]
    fn triangulate_equals_the_leaf_by_leaf_triangulation() {
        let sizes = [
            (9, 9, 3),
            (10, 7, 2),
            (2, 2, 0),
            (33, 5, 4),
            (1, 5, 1),
            (130, 70, 6),
        ];
        for (case, &(w, h, levels)) in sizes.iter().cycle().take(120).enumerate() {
            let void_share = [0, 0, 5, 30][case % 4];
            let (tree, shapes) = random_case(w, h, levels, void_share, case as u64);
            let shape = |cell: Cell| {
                let k = shapes.binary_search_by(|(c, _)| c.cmp(&cell));
                shapes[k.expect("every leaf has a shape")].1
            };
            let heights = vec![0.0; w * h];
            let heights = Heights {
                width: w,
                height: h,
                values: &heights,
            };
            let fast = triangulate(&tree, heights, shape);
            assert!(!fast.triangles.is_empty() || void_share > 0 || w < 2 || h < 2);
            assert_eq!(fast, by_cells(&tree, shape), "case {case}: {w}x{h}");
        }
    }
}
