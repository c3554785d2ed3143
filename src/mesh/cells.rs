//! Which quadtree nodes split: the cell partition of the grid.
//!
//! Starting from the roots (the nodes of the coarsest level), a node splits into its four
//! children when the split test says so, down to single grid cells. The tests come from
//! the decoder's [`SignificanceMap`] (zerotree or own-coefficient rule at a threshold), an
//! [`ErrorPyramid`] (a height tolerance), or both; nodes touching nodata always split, a
//! grid cell (level 0) with three valid corners is the one triangle of those corners, and
//! one with fewer is left out.
//!
//! The partition keeps one split bit per node, so a cell's neighbour at any level is found
//! in constant time: that is what [`crate::mesh::triangulate`] needs to put the vertices
//! of smaller neighbours on a cell's edges.

use bitvec::prelude::*;
use wavemesh_codec::significance::nodes_along;
use wavemesh_codec::SignificanceMap;

use super::pyramid::{node_bounds, ErrorPyramid, SampleValidity, VoidPyramid};
use super::FineBorders;

/// Which coefficients decide that a node splits at a threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SplitRule {
    /// The node is no zerotree root: it or a descendant is significant (the default).
    #[default]
    Zerotree,
    /// One of the node's own three coefficients is significant (Yu, Lee & Ra's literal
    /// rule; a node's significant descendants count only if the node itself splits).
    OwnCoefficients,
}

/// One leaf of the partition: node `(level, i, j)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Cell {
    /// Quadtree level: the cell spans `2^level` grid cells a side (less at the far edges).
    pub level: u32,
    /// Column of the node at its level.
    pub i: u32,
    /// Row of the node at its level.
    pub j: u32,
}

impl Cell {
    /// Node `(level, i, j)`.
    #[inline]
    pub fn new(level: u32, i: usize, j: usize) -> Cell {
        Cell {
            level,
            i: i as u32,
            j: j as u32,
        }
    }

    /// Column and row of the node at its level.
    #[inline]
    pub fn position(self) -> (usize, usize) {
        (self.i as usize, self.j as usize)
    }
}

/// One side of a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The side along the cell's first row.
    Top,
    /// The side along its last column.
    Right,
    /// The side along its last row.
    Bottom,
    /// The side along its first column.
    Left,
}

impl Side {
    /// The four sides, clockwise on screen (counter-clockwise in the grid frame).
    pub const ALL: [Side; 4] = [Side::Top, Side::Right, Side::Bottom, Side::Left];

    /// The side of a neighbour that faces this one.
    pub fn opposite(self) -> Side {
        match self {
            Side::Top => Side::Bottom,
            Side::Right => Side::Left,
            Side::Bottom => Side::Top,
            Side::Left => Side::Right,
        }
    }
}

/// What lies across a side of a leaf.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Across {
    /// The grid's border.
    Border,
    /// A leaf of the same level.
    Leaf,
    /// Smaller leaves (the same-level node split).
    Split,
    /// Part of a larger leaf.
    Larger,
}

/// A quadtree partition of a grid into cells.
#[derive(Debug, Clone)]
pub struct CellTree {
    width: usize,
    height: usize,
    levels: u32,
    /// Nodes per row and column, index `m` for level `m`.
    dims: Vec<(usize, usize)>,
    /// Split bit of every node (bit `k % 64` of word `k / 64` for node index `k`),
    /// index `m − 1` for level `m`.
    split: Vec<Vec<u64>>,
    /// Sides given a vertex at their midpoint (between same-level leaves or on the
    /// border), index `m − 1`: horizontal sides `(rows + 1) × columns`, then vertical
    /// sides `rows × (columns + 1)`.
    midpoints: Vec<(BitVec<u64, Lsb0>, BitVec<u64, Lsb0>)>,
    /// The leaves, grid cells with fewer than three valid corners excluded, in
    /// depth-first order.
    leaves: Vec<Cell>,
    /// Which samples are valid, when some are not (from the void pyramid).
    validity: Option<SampleValidity>,
    /// Sides of the grid along which every sample is a vertex.
    fine_borders: FineBorders,
}

impl CellTree {
    /// The partition in which node `(m, i, j)` splits when `test(m, i, j)` holds (asked
    /// only of nodes whose parent split, with `m ≥ 1`) or when it touches nodata.
    pub fn build(
        width: usize,
        height: usize,
        levels: u32,
        voids: Option<&VoidPyramid>,
        test: impl FnMut(u32, usize, usize) -> bool,
    ) -> CellTree {
        let dims: Vec<(usize, usize)> = (0..=levels)
            .map(|m| (nodes_along(width, m), nodes_along(height, m)))
            .collect();
        let split = dims[1..]
            .iter()
            .map(|&(nw, nh)| vec![0u64; (nw * nh).div_ceil(64)])
            .collect();
        let mut tree = CellTree {
            width,
            height,
            levels,
            dims,
            split,
            midpoints: Vec::new(),
            leaves: Vec::new(),
            validity: None,
            fine_borders: FineBorders::default(),
        };
        tree.grow(voids, test);
        tree
    }

    /// The zerotree partition at threshold `2^plane` (global bit-plane of the passes):
    /// a node splits when `rule` finds a coefficient significant at that plane or above.
    pub fn from_significance(
        map: &SignificanceMap,
        plane: u32,
        rule: SplitRule,
        voids: Option<&VoidPyramid>,
    ) -> CellTree {
        // Per-level slices, so the test is one load and one compare.
        let planes: Vec<(&[u8], usize)> = (1..=map.levels())
            .map(|m| {
                let level = match rule {
                    SplitRule::Zerotree => map.subtree_level(m),
                    SplitRule::OwnCoefficients => map.own_level(m),
                };
                (level, map.nodes(m).0)
            })
            .collect();
        CellTree::build(map.width(), map.height(), map.levels(), voids, |m, i, j| {
            let (level, nw) = planes[m as usize - 1];
            u32::from(level[j * nw + i]) > plane
        })
    }

    /// Re-runs the descent from the roots: nodes already split stay split, leaves split
    /// when `test` or a void says so. Used to refine a partition.
    pub fn grow(
        &mut self,
        voids: Option<&VoidPyramid>,
        mut test: impl FnMut(u32, usize, usize) -> bool,
    ) {
        self.leaves.clear();
        self.validity = voids.map(|v| v.validity().clone());
        let (rw, rh) = self.nodes(self.levels);
        for j in 0..rh {
            for i in 0..rw {
                self.descend(self.levels, i, j, voids, &mut test);
            }
        }
    }

    /// Visits node `(level, i, j)` (which exists) for [`CellTree::grow`]: a leaf is
    /// pushed, a split node's children are visited in Z order (depth first).
    fn descend<F: FnMut(u32, usize, usize) -> bool>(
        &mut self,
        level: u32,
        i: usize,
        j: usize,
        voids: Option<&VoidPyramid>,
        test: &mut F,
    ) {
        let cell = Cell::new(level, i, j);
        if level == 0 {
            if self.is_meshed(cell) {
                self.leaves.push(cell);
            }
            return;
        }
        let void = voids.is_some_and(|v| v.is_void(level, i, j));
        let k = self.node_index(level, i, j);
        let words = &mut self.split[level as usize - 1];
        if !(words[k / 64] >> (k % 64) & 1 != 0 || void || test(level, i, j)) {
            self.leaves.push(cell);
            return;
        }
        words[k / 64] |= 1 << (k % 64);
        let (cw, ch) = self.dims[level as usize - 1];
        let (ci, cj) = (2 * i, 2 * j);
        let (right, below) = (ci + 1 < cw, cj + 1 < ch);
        let children = [
            (ci, cj, true),
            (ci + 1, cj, right),
            (ci, cj + 1, below),
            (ci + 1, cj + 1, right && below),
        ];
        for (x, y, exists) in children {
            if !exists {
                continue;
            }
            if level == 1 {
                // Grid cells are leaves.
                let child = Cell::new(0, x, y);
                if self.is_meshed(child) {
                    self.leaves.push(child);
                }
            } else {
                self.descend(level - 1, x, y, voids, test);
            }
        }
    }

    /// Splits leaf `cell` (its children are leaves until the next [`CellTree::grow`]).
    pub fn force_split(&mut self, cell: Cell) {
        if cell.level > 0 {
            let (i, j) = cell.position();
            let k = self.node_index(cell.level, i, j);
            self.split[cell.level as usize - 1][k / 64] |= 1 << (k % 64);
        }
    }

    /// Sets or clears the split bit of node `cell` (`level ≥ 1`) without touching the
    /// leaves: for callers that maintain the leaves themselves (view-dependent
    /// split/merge).
    pub fn set_split(&mut self, cell: Cell, split: bool) {
        if cell.level > 0 {
            let (i, j) = cell.position();
            let k = self.node_index(cell.level, i, j);
            let word = &mut self.split[cell.level as usize - 1][k / 64];
            if split {
                *word |= 1 << (k % 64);
            } else {
                *word &= !(1 << (k % 64));
            }
        }
    }

    /// Exchanges the leaves with `leaves` (which must be the leaves of the split bits, in
    /// depth-first order, once the caller is done): the two buffers of a ping-pong update.
    pub fn swap_leaves(&mut self, leaves: &mut Vec<Cell>) {
        std::mem::swap(&mut self.leaves, leaves);
    }

    /// Makes every sample along `sides` of the grid a vertex of the triangulation: the
    /// cells along them get those samples on their sides, as if smaller cells lay across.
    pub fn set_fine_borders(&mut self, sides: FineBorders) {
        self.fine_borders = sides;
    }

    /// Whether `side` of `cell` lies on a fine border (see [`CellTree::set_fine_borders`]).
    #[inline]
    pub fn on_fine_border(&self, cell: Cell, side: Side) -> bool {
        let fine = self.fine_borders;
        if fine == FineBorders::default() {
            return false;
        }
        let (x0, y0, x1, y1) = self.bounds(cell);
        match side {
            Side::Top => fine.top && y0 == 0,
            Side::Right => fine.right && x1 == self.width - 1,
            Side::Bottom => fine.bottom && y1 == self.height - 1,
            Side::Left => fine.left && x0 == 0,
        }
    }

    /// What lies across `side` of leaf `cell`.
    pub fn across(&self, cell: Cell, side: Side) -> Across {
        let Some((ni, nj)) = self.neighbour(cell, side) else {
            return Across::Border;
        };
        let (nw, nh) = self.nodes(cell.level);
        if ni >= nw || nj >= nh {
            return Across::Border;
        }
        if self.is_split(cell.level, ni, nj) {
            Across::Split
        } else if cell.level == self.levels || self.is_split(cell.level + 1, ni / 2, nj / 2) {
            Across::Leaf
        } else {
            Across::Larger
        }
    }

    /// The same-level node across `side` of `cell` (which may not exist).
    pub fn neighbour(&self, cell: Cell, side: Side) -> Option<(usize, usize)> {
        let (i, j) = cell.position();
        match side {
            Side::Top => j.checked_sub(1).map(|nj| (i, nj)),
            Side::Right => Some((i + 1, j)),
            Side::Bottom => Some((i, j + 1)),
            Side::Left => i.checked_sub(1).map(|ni| (ni, j)),
        }
    }

    /// The coordinate (column for top and bottom, row for left and right) of the
    /// midpoint of `side` of `cell`, where its children would meet: `None` for cells too
    /// small or too clipped to have one.
    pub fn midpoint(&self, cell: Cell, side: Side) -> Option<usize> {
        if cell.level == 0 {
            return None;
        }
        let half = 1usize << (cell.level - 1);
        let (x0, y0, x1, y1) = self.bounds(cell);
        match side {
            Side::Top | Side::Bottom => (x0 + half < x1).then_some(x0 + half),
            Side::Left | Side::Right => (y0 + half < y1).then_some(y0 + half),
        }
    }

    fn midpoint_bit(&self, cell: Cell, side: Side) -> (bool, usize) {
        let (nw, _) = self.nodes(cell.level);
        let (i, j) = cell.position();
        match side {
            Side::Top => (true, j * nw + i),
            Side::Bottom => (true, (j + 1) * nw + i),
            Side::Left => (false, j * (nw + 1) + i),
            Side::Right => (false, j * (nw + 1) + i + 1),
        }
    }

    /// Puts a vertex at the midpoint of `side` of `cell` (level ≥ 1, a side shared with a
    /// same-level leaf or on the border): both cells take it.
    pub fn mark_midpoint(&mut self, cell: Cell, side: Side) {
        if self.midpoints.is_empty() {
            self.midpoints = (1..=self.levels)
                .map(|m| {
                    let (nw, nh) = self.nodes(m);
                    (
                        bitvec![u64, Lsb0; 0; (nh + 1) * nw],
                        bitvec![u64, Lsb0; 0; nh * (nw + 1)],
                    )
                })
                .collect();
        }
        let (horizontal, k) = self.midpoint_bit(cell, side);
        let marks = &mut self.midpoints[cell.level as usize - 1];
        if horizontal {
            marks.0.set(k, true);
        } else {
            marks.1.set(k, true);
        }
    }

    /// Whether `side` of `cell` has a marked midpoint.
    #[inline]
    pub fn has_midpoint(&self, cell: Cell, side: Side) -> bool {
        if self.midpoints.is_empty() || cell.level == 0 {
            return false;
        }
        let (horizontal, k) = self.midpoint_bit(cell, side);
        let marks = &self.midpoints[cell.level as usize - 1];
        if horizontal {
            marks.0[k]
        } else {
            marks.1[k]
        }
    }

    /// Removes every marked midpoint.
    pub fn clear_midpoints(&mut self) {
        for (h, v) in &mut self.midpoints {
            h.fill(false);
            v.fill(false);
        }
    }

    #[inline]
    fn node_index(&self, level: u32, i: usize, j: usize) -> usize {
        j * self.dims[level as usize].0 + i
    }

    /// Nodes per row and column at `level`.
    pub fn nodes(&self, level: u32) -> (usize, usize) {
        self.dims[level as usize]
    }

    /// Whether node `(level, i, j)` exists and split (level-0 nodes never do).
    #[inline]
    pub fn is_split(&self, level: u32, i: usize, j: usize) -> bool {
        if level == 0 || level > self.levels {
            return false;
        }
        let (nw, nh) = self.dims[level as usize];
        if i >= nw || j >= nh {
            return false;
        }
        let k = j * nw + i;
        self.split[level as usize - 1][k / 64] >> (k % 64) & 1 != 0
    }

    /// The split nodes of `level` (≥ 1) as `(i, j)`, row by row.
    pub fn split_nodes(&self, level: u32) -> impl Iterator<Item = (usize, usize)> + '_ {
        let nw = self.dims[level as usize].0;
        self.split[level as usize - 1]
            .iter()
            .enumerate()
            .flat_map(move |(w, &word)| {
                std::iter::successors((word != 0).then_some(word), |&bits| {
                    let rest = bits & (bits - 1);
                    (rest != 0).then_some(rest)
                })
                .map(move |bits| w * 64 + bits.trailing_zeros() as usize)
            })
            .map(move |k| (k % nw, k / nw))
    }

    /// The valid corners of grid cell `cell` (level 0), bits as
    /// [`SampleValidity::cell_corners`]: all four (`0b1111`) when every sample is valid.
    #[inline]
    pub fn valid_corners(&self, cell: Cell) -> u8 {
        let (i, j) = cell.position();
        self.validity
            .as_ref()
            .map_or(0b1111, |v| v.cell_corners(i, j))
    }

    /// Whether leaf `cell` gives triangles: every node of level ≥ 1 does (it touches no
    /// nodata), a grid cell when at least three of its corners are valid.
    #[inline]
    pub fn is_meshed(&self, cell: Cell) -> bool {
        cell.level > 0 || self.valid_corners(cell).count_ones() >= 3
    }

    /// Whether some side may hold vertices that are no leaf's corner: a fine border is
    /// set or a midpoint was ever marked.
    #[inline]
    pub fn may_have_side_extras(&self) -> bool {
        self.fine_borders != FineBorders::default() || !self.midpoints.is_empty()
    }

    /// Whether some sample of the grid is nodata.
    #[inline]
    pub fn has_nodata(&self) -> bool {
        self.validity.is_some()
    }

    /// The leaves (grid cells with fewer than three valid corners excluded), depth first.
    pub fn leaves(&self) -> &[Cell] {
        &self.leaves
    }

    /// Grid size.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Coarsest level (the roots').
    pub fn levels(&self) -> u32 {
        self.levels
    }

    /// Closed sample range `(x0, y0, x1, y1)` of `cell`.
    #[inline]
    pub fn bounds(&self, cell: Cell) -> (usize, usize, usize, usize) {
        let (i, j) = cell.position();
        node_bounds(self.width, self.height, cell.level, i, j)
    }
}

/// Whether node `(m, i, j)` splits at `plane` under `rule`.
#[inline]
pub fn significant(
    map: &SignificanceMap,
    plane: u32,
    rule: SplitRule,
    m: u32,
    i: usize,
    j: usize,
) -> bool {
    let value = match rule {
        SplitRule::Zerotree => map.subtree_plane(m, i, j),
        SplitRule::OwnCoefficients => map.own_plane(m, i, j),
    };
    u32::from(value) > plane
}

/// The split test of a height tolerance: neither of the node's shapes is within it.
#[inline]
pub fn too_rough(errors: &ErrorPyramid, tolerance: f64, m: u32, i: usize, j: usize) -> bool {
    f64::from(errors.error(m, i, j)) > tolerance
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaves_tile_the_grid() {
        for (w, h, levels) in [(9, 9, 3), (10, 7, 2), (2, 2, 0), (33, 5, 4), (1, 5, 1)] {
            let mut seed = (w * 31 + h) as u64;
            let tree = CellTree::build(w, h, levels, None, |_, _, _| {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                seed >> 62 != 0
            });
            let mut covered = vec![0u32; w.saturating_sub(1) * h.saturating_sub(1)];
            for &cell in tree.leaves() {
                let (x0, y0, x1, y1) = tree.bounds(cell);
                for y in y0..y1 {
                    for x in x0..x1 {
                        covered[y * (w - 1) + x] += 1;
                    }
                }
            }
            assert!(covered.iter().all(|&c| c == 1), "{w}x{h}");
        }
    }

    #[test]
    fn split_nodes_have_split_parents() {
        let tree = CellTree::build(17, 17, 4, None, |m, i, _| m > 2 || i % 2 == 0);
        for m in 1..4 {
            let (nw, nh) = tree.nodes(m);
            for j in 0..nh {
                for i in 0..nw {
                    if tree.is_split(m, i, j) {
                        assert!(tree.is_split(m + 1, i / 2, j / 2));
                    }
                }
            }
        }
    }
}
