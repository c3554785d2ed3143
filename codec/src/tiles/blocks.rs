//! Code blocks under one transform: the raster is transformed once and the coefficients
//! below each `block × block` square of samples — at every level, the part of each
//! subband that square maps to — form a block's own pyramid, shaped as the transform of
//! a raster of the block's size would be. Each block can then be coded as an embedded
//! stream of its own while the decoder inverts one transform, so block borders do not
//! show as tile borders do (issue 9's seams).
//!
//! Blocks start at multiples of `block` from the top-left corner, which must be a
//! multiple of `2^levels`: then a block's part of a level-`l` subband starts at its
//! corner `>> l` and has the size of the same subband of a raster of the block's size.
//! The last column and row of blocks end with the raster: narrower, or, when less than a
//! quarter of a block would be left for them, wider (the rest joins the blocks before
//! it, as the two samples a tile codes beyond its edge do).

use crate::wavelet::{self, Subband};

/// How a `width × height` raster transformed with `levels` levels is cut into blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct BlockGrid {
    pub width: usize,
    pub height: usize,
    pub block: usize,
    pub levels: u32,
}

/// One block: its samples' corner and size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Block {
    pub x: usize,
    pub y: usize,
    pub width: usize,
    pub height: usize,
}

impl BlockGrid {
    /// The grid, or `None` when `block` is 0 or not a multiple of `2^levels`.
    pub fn new(width: usize, height: usize, block: usize, levels: u32) -> Option<BlockGrid> {
        let aligned = block > 0 && block.trailing_zeros() >= levels;
        aligned.then_some(BlockGrid {
            width,
            height,
            block,
            levels,
        })
    }

    /// Every block, row-major.
    pub fn blocks(&self) -> impl Iterator<Item = Block> + '_ {
        let (columns, rows) = (self.along(self.width), self.along(self.height));
        let side = |start: usize, index: usize, count: usize, len: usize| match index + 1 == count {
            true => len - start,
            false => self.block,
        };
        (0..rows * columns).map(move |i| {
            let (column, row) = (i % columns, i / columns);
            let (x, y) = (column * self.block, row * self.block);
            Block {
                x,
                y,
                width: side(x, column, columns, self.width),
                height: side(y, row, rows, self.height),
            }
        })
    }

    /// Number of blocks.
    pub fn count(&self) -> usize {
        self.along(self.width) * self.along(self.height)
    }

    /// Blocks along a side of `len` samples: one a `block`, the rest joining the last
    /// one when it is under a quarter of a block.
    fn along(&self, len: usize) -> usize {
        let (whole, rest) = (len / self.block, len % self.block);
        match whole > 0 && rest < self.block / 4 {
            true => whole,
            false => whole + usize::from(rest > 0),
        }
    }

    /// The subbands of `block`'s own pyramid.
    pub fn subbands(&self, block: Block) -> Vec<Subband> {
        wavelet::subbands(block.width, block.height, self.levels)
    }

    /// `block`'s coefficients, copied from the raster's pyramid `all` into its own.
    pub fn gather<T: Copy + Default>(&self, all: &[T], block: Block) -> Vec<T> {
        let mut own = vec![T::default(); block.width * block.height];
        self.for_each_row(block, |from, to, len| {
            own[to..to + len].copy_from_slice(&all[from..from + len]);
        });
        own
    }

    /// Puts `own`, `block`'s pyramid, back into the raster's pyramid `all`.
    pub fn scatter<T: Copy>(&self, own: &[T], all: &mut [T], block: Block) {
        self.for_each_row(block, |from, to, len| {
            all[from..from + len].copy_from_slice(&own[to..to + len]);
        });
    }

    /// Calls `copy(raster offset, block offset, length)` for every subband row the block
    /// holds.
    fn for_each_row(&self, block: Block, mut copy: impl FnMut(usize, usize, usize)) {
        let global = wavelet::subbands(self.width, self.height, self.levels);
        for (g, own) in global.iter().zip(self.subbands(block)) {
            // The LL subband is listed with the coarsest level.
            let shift = g.level.max(1).min(self.levels);
            let (x, y) = (block.x >> shift, block.y >> shift);
            for row in 0..own.height {
                let from = (g.y0 + y + row) * self.width + g.x0 + x;
                let to = (own.y0 + row) * block.width + own.x0;
                copy(from, to, own.width);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_partition_the_pyramid() {
        // Odd sides: the last blocks are narrow, and their subbands' halves uneven.
        // 66 = 64 + 2: the two samples join the block before them.
        for (width, height, block, levels) in [
            (77, 50, 16, 4),
            (64, 64, 32, 5),
            (33, 9, 8, 3),
            (66, 130, 32, 4),
        ] {
            let grid = BlockGrid::new(width, height, block, levels).unwrap();
            let all: Vec<u32> = (0..(width * height) as u32).collect();
            let mut rebuilt = vec![u32::MAX; width * height];
            let mut seen = 0;
            for b in grid.blocks() {
                let own = grid.gather(&all, b);
                seen += own.len();
                grid.scatter(&own, &mut rebuilt, b);
            }
            assert_eq!(seen, width * height);
            assert_eq!(rebuilt, all, "{width}x{height} in {block}");
            assert_eq!(grid.blocks().count(), grid.count());
        }
    }

    #[test]
    fn a_block_holds_the_coefficients_below_its_samples() {
        // The 5/3 transform of a raster that is zero except inside one block has (away
        // from that block's borders' reach) its large coefficients in that block.
        let (width, height, levels) = (64, 64, 3);
        let grid = BlockGrid::new(width, height, 16, levels).unwrap();
        let mut values = vec![0i32; width * height];
        for y in 20..28 {
            for x in 36..44 {
                values[y * width + x] = 1000 + ((x * 7 + y * 3) % 11) as i32;
            }
        }
        wavelet::forward_53(&mut values, width, height, levels);
        let energy = |b: Block| -> i64 {
            grid.gather(&values, b)
                .iter()
                .map(|&c| i64::from(c) * i64::from(c))
                .sum()
        };
        let target = grid.blocks().find(|b| (b.x, b.y) == (32, 16)).unwrap();
        let total: i64 = grid.blocks().map(energy).sum();
        assert!(
            energy(target) * 10 > total * 9,
            "{} of {total}",
            energy(target)
        );
    }

    #[test]
    fn blocks_must_be_aligned_to_the_coarsest_level() {
        assert!(BlockGrid::new(100, 100, 24, 3).is_some());
        assert!(BlockGrid::new(100, 100, 24, 4).is_none());
        assert!(BlockGrid::new(100, 100, 0, 0).is_none());
    }

    #[test]
    fn a_sliver_joins_the_block_before_it() {
        let widths = |len: usize| -> Vec<usize> {
            let grid = BlockGrid::new(len, 1, 64, 2).unwrap();
            grid.blocks().map(|b| b.width).collect()
        };
        assert_eq!(widths(130), vec![64, 66]);
        assert_eq!(widths(144), vec![64, 64, 16]);
        assert_eq!(widths(10), vec![10]);
    }
}
