//! Which samples a partition's triangles use, found before any triangle is made.
//!
//! The hanging vertices on a side of a leaf are exactly the corners of the leaves across
//! it that lie strictly inside the side (no corner of a node of the leaf's level or
//! coarser can). So one pass over the leaves marks every leaf corner in two bitmaps, one
//! row-major and one column-major, and a side's hanging vertices are then the set bits of
//! one row or column between its ends: a few word operations instead of a walk down the
//! neighbour's subtree. The same bitmap (minus the samples no triangle reaches, which only
//! voids create) numbers the vertices: a vertex's number is its rank among the set bits,
//! and the vertices strictly inside a horizontal side are numbered consecutively between
//! its two corners.

use super::cells::{Cell, CellTree, Side};
use super::pyramid::Shape;

/// One bit per sample of a `lines × length` grid, each line padded to whole words.
#[derive(Debug, Clone)]
pub struct LineBits {
    words_per_line: usize,
    words: Vec<u64>,
}

impl LineBits {
    /// No bit set, `lines` lines of `length` bits.
    pub fn new(lines: usize, length: usize) -> LineBits {
        let words_per_line = length.div_ceil(64);
        LineBits {
            words_per_line,
            words: vec![0; lines * words_per_line],
        }
    }

    /// Sets bit `k` of line `line`.
    #[inline]
    pub fn set(&mut self, line: usize, k: usize) {
        self.words[line * self.words_per_line + k / 64] |= 1 << (k % 64);
    }

    /// Sets bits `first..=last` of line `line`.
    #[inline]
    pub fn set_run(&mut self, line: usize, first: usize, last: usize) {
        let start = line * self.words_per_line;
        for w in first / 64..=last / 64 {
            self.words[start + w] |= range_mask(w, first, last);
        }
    }

    /// Appends to `out` the positions of the set bits of line `line` strictly between
    /// `lo` and `hi`, increasing.
    #[inline]
    pub fn ones_between(&self, line: usize, lo: usize, hi: usize, out: &mut Vec<usize>) {
        if hi <= lo + 1 {
            return;
        }
        let start = line * self.words_per_line;
        let (first, last) = (lo + 1, hi - 1);
        for w in first / 64..=last / 64 {
            let mut bits = self.words[start + w] & range_mask(w, first, last);
            while bits != 0 {
                out.push(w * 64 + bits.trailing_zeros() as usize);
                bits &= bits - 1;
            }
        }
    }

    /// Whether a bit of line `line` strictly between `lo` and `hi` is set.
    #[inline]
    pub fn any_between(&self, line: usize, lo: usize, hi: usize) -> bool {
        if hi <= lo + 1 {
            return false;
        }
        let start = line * self.words_per_line;
        let (first, last) = (lo + 1, hi - 1);
        (first / 64..=last / 64).any(|w| self.words[start + w] & range_mask(w, first, last) != 0)
    }

    /// Sets in `self` the bits of `other` (same shape) on line `line` strictly between
    /// `lo` and `hi`.
    #[inline]
    fn or_between(&mut self, other: &LineBits, line: usize, lo: usize, hi: usize) {
        if hi <= lo + 1 {
            return;
        }
        let start = line * self.words_per_line;
        let (first, last) = (lo + 1, hi - 1);
        for w in first / 64..=last / 64 {
            self.words[start + w] |= other.words[start + w] & range_mask(w, first, last);
        }
    }
}

/// The bits of word `w` (bits `64·w ..`) that lie in `first..=last`.
#[inline]
fn range_mask(w: usize, first: usize, last: usize) -> u64 {
    let low = if first / 64 == w { first % 64 } else { 0 };
    let high = if last / 64 == w { last % 64 } else { 63 };
    (u64::MAX >> (63 - high)) & (u64::MAX << low)
}

/// The corners of every leaf of a partition (and the other samples a triangle may use
/// without being a leaf's corner: fine borders, marked midpoints, fan centres), in both
/// orders.
#[derive(Debug, Clone)]
pub struct CornerMaps {
    /// Line `y`, bit `x`.
    pub rows: LineBits,
    /// Line `x`, bit `y`.
    pub columns: LineBits,
}

impl CornerMaps {
    /// Marks the corners of `tree`'s leaves, the grid cells it leaves out included, and
    /// the centre of every leaf `shape` draws as a fan.
    pub fn of(tree: &CellTree, shape: impl Fn(Cell) -> Shape) -> CornerMaps {
        let (w, h) = tree.size();
        let mut maps = CornerMaps {
            rows: LineBits::new(h, w),
            columns: LineBits::new(w, h),
        };
        let extras = tree.may_have_side_extras();
        for &cell in tree.leaves().iter().filter(|c| c.level > 0) {
            let (x0, y0, x1, y1) = tree.bounds(cell);
            for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
                maps.mark(x, y);
            }
            if shape(cell) == Shape::Fan {
                maps.mark((x0 + x1) / 2, (y0 + y1) / 2);
            }
            if extras {
                maps.mark_side_extras(tree, cell);
            }
        }
        // Grid cells, meshed or not, are the children of split level-1 nodes: their
        // corners are those nodes' samples.
        if tree.levels() >= 1 {
            for (i, j) in tree.split_nodes(1) {
                let (x1, y1) = ((2 * i + 2).min(w - 1), (2 * j + 2).min(h - 1));
                for y in 2 * j..=y1 {
                    maps.rows.set_run(y, 2 * i, x1);
                }
                for x in 2 * i..=x1 {
                    maps.columns.set_run(x, 2 * j, y1);
                }
            }
        } else {
            for y in 0..h {
                for x in 0..w {
                    maps.mark(x, y);
                }
            }
        }
        maps
    }

    #[inline]
    fn mark(&mut self, x: usize, y: usize) {
        self.rows.set(y, x);
        self.columns.set(x, y);
    }

    /// Marks the samples inside the sides of `cell` that are vertices without being leaf
    /// corners: every sample of a side on a fine border, and marked midpoints.
    fn mark_side_extras(&mut self, tree: &CellTree, cell: Cell) {
        let (x0, y0, x1, y1) = tree.bounds(cell);
        for side in Side::ALL {
            let (fixed, from, to) = match side {
                Side::Top => (y0, x0, x1),
                Side::Bottom => (y1, x0, x1),
                Side::Left => (x0, y0, y1),
                Side::Right => (x1, y0, y1),
            };
            let horizontal = matches!(side, Side::Top | Side::Bottom);
            let along: Vec<usize> = if tree.on_fine_border(cell, side) {
                (from + 1..to).collect()
            } else if tree.has_midpoint(cell, side) {
                tree.midpoint(cell, side).into_iter().collect()
            } else {
                continue;
            };
            for c in along {
                if horizontal {
                    self.mark(c, fixed);
                } else {
                    self.mark(fixed, c);
                }
            }
        }
    }
}

/// The vertices of a triangulation, numbered in sample order: a bit per sample beside
/// the count of set bits before its word (one cache line a look-up).
#[derive(Debug, Clone)]
pub struct VertexNumbers {
    width: usize,
    words_per_row: usize,
    /// Each word of the row-major bitmap with the number of vertices before it.
    ranked: Vec<(u64, u32)>,
    count: u32,
}

impl VertexNumbers {
    /// Numbers the set bits of `rows` (a `width`-sample-wide grid).
    pub fn new(rows: &LineBits, width: usize) -> VertexNumbers {
        let mut total = 0u32;
        let ranked = rows
            .words
            .iter()
            .map(|&word| {
                let entry = (word, total);
                total += word.count_ones();
                entry
            })
            .collect();
        VertexNumbers {
            width,
            words_per_row: rows.words_per_line,
            ranked,
            count: total,
        }
    }

    /// The number of the vertex at (`x`, `y`) (if that sample is none, of the next one).
    #[inline]
    pub fn number(&self, x: usize, y: usize) -> u32 {
        let (word, before) = self.ranked[y * self.words_per_row + x / 64];
        before + (word & ((1u64 << (x % 64)) - 1)).count_ones()
    }

    /// How many vertices there are.
    pub fn count(&self) -> usize {
        self.count as usize
    }

    /// The sample index of every vertex, in number order.
    pub fn samples(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.count as usize);
        for (k, &(word, _)) in self.ranked.iter().enumerate() {
            let (y, w) = (k / self.words_per_row, k % self.words_per_row);
            let base = (y * self.width + w * 64) as u32;
            let mut bits = word;
            while bits != 0 {
                out.push(base + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
        out
    }
}

/// The samples the triangles of `tree` use when some samples are nodata: a leaf's
/// corners, fan centre and hanging vertices for cells of level ≥ 1, the valid corners of
/// meshed grid cells. (Without nodata these are exactly `corners.rows`.)
pub fn used_samples(
    tree: &CellTree,
    corners: &CornerMaps,
    shape: impl Fn(Cell) -> Shape,
) -> LineBits {
    let (w, h) = tree.size();
    let mut used = LineBits::new(h, w);
    let mut hanging = Vec::new();
    for &cell in tree.leaves() {
        let (x0, y0, x1, y1) = tree.bounds(cell);
        if cell.level == 0 {
            let valid = tree.valid_corners(cell);
            for (bit, (x, y)) in [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
                .into_iter()
                .enumerate()
            {
                if valid >> bit & 1 != 0 {
                    used.set(y, x);
                }
            }
            continue;
        }
        for (x, y) in [(x0, y0), (x1, y0), (x0, y1), (x1, y1)] {
            used.set(y, x);
        }
        if shape(cell) == Shape::Fan {
            used.set((y0 + y1) / 2, (x0 + x1) / 2);
        }
        used.or_between(&corners.rows, y0, x0, x1);
        used.or_between(&corners.rows, y1, x0, x1);
        for x in [x0, x1] {
            hanging.clear();
            corners.columns.ones_between(x, y0, y1, &mut hanging);
            for &y in &hanging {
                used.set(y, x);
            }
        }
    }
    used
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ones_between_finds_the_bits_strictly_inside() {
        let mut bits = LineBits::new(2, 200);
        for k in [0, 5, 63, 64, 65, 127, 128, 199] {
            bits.set(1, k);
        }
        bits.set(0, 70);
        let mut out = Vec::new();
        bits.ones_between(1, 0, 199, &mut out);
        assert_eq!(out, [5, 63, 64, 65, 127, 128]);
        out.clear();
        bits.ones_between(1, 63, 128, &mut out);
        assert_eq!(out, [64, 65, 127]);
        out.clear();
        bits.ones_between(1, 5, 6, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn numbers_are_ranks_in_sample_order() {
        let (w, h) = (70, 3);
        let mut bits = LineBits::new(h, w);
        let samples = [(0, 0), (69, 0), (3, 1), (64, 1), (1, 2)];
        for (x, y) in samples {
            bits.set(y, x);
        }
        let numbers = VertexNumbers::new(&bits, w);
        assert_eq!(numbers.count(), samples.len());
        for (k, (x, y)) in samples.into_iter().enumerate() {
            assert_eq!(numbers.number(x, y), k as u32);
        }
        let expected: Vec<u32> = samples.iter().map(|&(x, y)| (y * w + x) as u32).collect();
        assert_eq!(numbers.samples(), expected);
    }
}
