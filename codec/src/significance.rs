//! The decoder's per-node significance map: the seam between the codec and the mesher.
//!
//! A detail coefficient at decomposition level `m` (1 = finest) and position `(i, j)` of its
//! subband stands for the `2^m × 2^m` block of grid cells whose corners are the samples
//! `i·2^m ..= (i+1)·2^m` (columns) by `j·2^m ..= (j+1)·2^m` (rows): the quadtree *node*
//! `(m, i, j)`. Its four children are the nodes `(m−1, 2i + a, 2j + b)`; level-0 nodes are
//! single grid cells and carry no coefficient. Node `(m, i, j)` exists for
//! `i < ceil((width − 1) / 2^m)` and `j < ceil((height − 1) / 2^m)`, which differs from a
//! level-`m` subband's size by at most one: a coefficient past the last node (the far
//! edge's column or row) belongs to the last node, and a node past the band's last
//! coefficient (a clipped cell at the far edge) has no coefficient of its own.
//!
//! For every node the map stores two pass indices, as the global bit-plane `n` of the pass
//! (of the zerotree coder) plus one (0: never significant in what was decoded):
//! - [`SignificanceMap::own_plane`]: the pass at which one of the node's own three
//!   coefficients became significant;
//! - [`SignificanceMap::subtree_plane`]: the same over the node and all its descendants, the
//!   pass at which the node stopped being part of a zerotree.
//!
//! A node is split at threshold `2^t` when its subtree plane is at least `t + 1`; since a
//! parent's subtree plane is the maximum of its own and its children's, the split nodes
//! form a tree (every split node's parent is split), and the partition at any coarser
//! threshold comes from the same map with no further decoding.

use crate::ezw::CoefficientLayout;
use crate::wavelet::Orientation;

/// Per-node pass indices of a decoded stream (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SignificanceMap {
    width: usize,
    height: usize,
    levels: u32,
    /// Start of each level's nodes in `own` / `subtree`, index `m − 1`, plus the end.
    offsets: Vec<usize>,
    own: Vec<u8>,
    subtree: Vec<u8>,
}

/// Number of level-`m` nodes along a side of `samples` samples: `ceil((samples − 1) / 2^m)`.
pub fn nodes_along(samples: usize, level: u32) -> usize {
    let cells = samples.saturating_sub(1);
    if level >= usize::BITS {
        return usize::from(cells > 0);
    }
    cells.div_ceil(1 << level)
}

impl SignificanceMap {
    /// Builds the map from decoded coefficient values (each one's leading bit is the plane
    /// at which it became significant) laid out as `layout` describes.
    pub(crate) fn from_values(layout: &CoefficientLayout, values: &[i32]) -> SignificanceMap {
        let (width, height) = (layout.width, layout.height);
        let levels = layout.levels();
        let mut offsets = Vec::with_capacity(levels as usize + 1);
        let mut total = 0;
        for m in 1..=levels {
            offsets.push(total);
            total += nodes_along(width, m) * nodes_along(height, m);
        }
        offsets.push(total);
        let mut own = vec![0u8; total];
        for (sub, shift) in layout.detail_bands() {
            let m = sub.level;
            let (nw, nh) = (nodes_along(width, m), nodes_along(height, m));
            if nw == 0 || nh == 0 {
                continue;
            }
            let base = offsets[m as usize - 1];
            for y in 0..sub.height {
                let row = &values[(sub.y0 + y) * width + sub.x0..][..sub.width];
                let node_row = base + y.min(nh - 1) * nw;
                for (x, &v) in row.iter().enumerate() {
                    if v != 0 {
                        let plane = (v.unsigned_abs().ilog2() + shift + 1).min(u8::MAX as u32);
                        let node = &mut own[node_row + x.min(nw - 1)];
                        *node = (*node).max(plane as u8);
                    }
                }
            }
            debug_assert!(matches!(
                sub.orientation,
                Orientation::HL | Orientation::LH | Orientation::HH
            ));
        }
        let mut subtree = own.clone();
        for m in 2..=levels {
            let (nw, nh) = (nodes_along(width, m), nodes_along(height, m));
            let (cw, ch) = (nodes_along(width, m - 1), nodes_along(height, m - 1));
            let (base, child_base) = (offsets[m as usize - 1], offsets[m as usize - 2]);
            for cy in 0..ch {
                for cx in 0..cw {
                    let child = subtree[child_base + cy * cw + cx];
                    let parent =
                        &mut subtree[base + (cy / 2).min(nh - 1) * nw + (cx / 2).min(nw - 1)];
                    *parent = (*parent).max(child);
                }
            }
        }
        SignificanceMap {
            width,
            height,
            levels,
            offsets,
            own,
            subtree,
        }
    }

    /// Samples per row of the grid the map describes.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows of the grid the map describes.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Decomposition levels: the coarsest nodes (the roots) are at this level.
    pub fn levels(&self) -> u32 {
        self.levels
    }

    /// Nodes per row and per column at `level` (`0` gives the grid cells).
    pub fn nodes(&self, level: u32) -> (usize, usize) {
        (
            nodes_along(self.width, level),
            nodes_along(self.height, level),
        )
    }

    fn index(&self, level: u32, i: usize, j: usize) -> usize {
        debug_assert!((1..=self.levels).contains(&level));
        let (nw, nh) = self.nodes(level);
        assert!(i < nw && j < nh, "node ({level}, {i}, {j}) outside the map");
        self.offsets[level as usize - 1] + j * nw + i
    }

    /// Global plane + 1 of the pass at which one of node `(level, i, j)`'s own coefficients
    /// became significant, 0 if none did (`level` in `1..=levels`).
    pub fn own_plane(&self, level: u32, i: usize, j: usize) -> u8 {
        self.own[self.index(level, i, j)]
    }

    /// Global plane + 1 of the pass at which node `(level, i, j)` or one of its
    /// descendants became significant, 0 if none did (`level` in `1..=levels`).
    pub fn subtree_plane(&self, level: u32, i: usize, j: usize) -> u8 {
        self.subtree[self.index(level, i, j)]
    }

    /// The subtree planes of every node of `level`, row-major (`nodes(level).0` per row).
    pub fn subtree_level(&self, level: u32) -> &[u8] {
        let m = level as usize;
        &self.subtree[self.offsets[m - 1]..self.offsets[m]]
    }

    /// The own planes of every node of `level`, row-major.
    pub fn own_level(&self, level: u32) -> &[u8] {
        let m = level as usize;
        &self.own[self.offsets[m - 1]..self.offsets[m]]
    }

    /// Highest plane + 1 in the map (0 when nothing is significant).
    pub fn top(&self) -> u8 {
        self.subtree.iter().copied().max().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wavelet::subbands;

    #[test]
    fn node_counts_follow_the_detail_bands() {
        for w in 1..70 {
            for level in 1..=crate::wavelet::max_levels(w, 1) {
                // Every child has its parent...
                let children = nodes_along(w, level - 1);
                assert_eq!(
                    nodes_along(w, level),
                    children.div_ceil(2),
                    "w {w} level {level}"
                );
                // ... and a band's coefficients map onto the nodes with at most one
                // clamped at either end.
                let bands = subbands(w, 1, level);
                let hl = bands[1];
                assert!(
                    hl.width.abs_diff(nodes_along(w, level)) <= 1,
                    "w {w} level {level}: band {} nodes {}",
                    hl.width,
                    nodes_along(w, level)
                );
            }
        }
    }

    #[test]
    fn subtree_is_the_maximum_over_descendants() {
        let (w, h, levels) = (17, 11, 3);
        let subs = subbands(w, h, levels);
        let layout = CoefficientLayout::new(w, h, &subs, &vec![0; subs.len()]);
        let mut values = vec![0i32; w * h];
        // One HH coefficient at level 1 with value 5 (plane 2): node (1, 3, 2).
        let hh1 = subs.last().unwrap();
        values[(hh1.y0 + 2) * w + hh1.x0 + 3] = -5;
        // One HL coefficient at level 3 with value 1 (plane 0): node (3, 0, 0).
        let hl3 = subs[1];
        values[hl3.y0 * w + hl3.x0] = 1;
        let map = SignificanceMap::from_values(&layout, &values);
        assert_eq!(map.own_plane(1, 3, 2), 3);
        assert_eq!(map.subtree_plane(2, 1, 1), 3);
        assert_eq!(map.own_plane(2, 1, 1), 0);
        assert_eq!(map.subtree_plane(3, 0, 0), 3);
        assert_eq!(map.own_plane(3, 0, 0), 1);
        assert_eq!(map.subtree_plane(1, 0, 0), 0);
        assert_eq!(map.top(), 3);
        for m in 2..=levels {
            let (nw, nh) = map.nodes(m);
            let (cw, ch) = map.nodes(m - 1);
            for j in 0..nh {
                for i in 0..nw {
                    let mut expect = map.own_plane(m, i, j);
                    for cj in 2 * j..(2 * j + 2).min(ch) {
                        for ci in 2 * i..(2 * i + 2).min(cw) {
                            expect = expect.max(map.subtree_plane(m - 1, ci, cj));
                        }
                    }
                    assert_eq!(map.subtree_plane(m, i, j), expect);
                }
            }
        }
    }
}
