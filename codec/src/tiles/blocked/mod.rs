//! Tiles cut into code blocks (header flag 15): each tile is one transform, and the
//! coefficients below each `side × side` square of its samples
//! ([`BlockGrid`](super::blocks::BlockGrid)) are coded as an embedded stream of their
//! own. The index lists, tile by tile, the tile's head (a
//! tile-layout header with no payload, the nodata mask and the residual section) and
//! then its blocks. Block borders do not show as tile borders do (no transform edge
//! there), while a reader still fetches only the blocks a window needs and, at a bit
//! rate, a prefix of each, shared out by [`allocate()`](super::allocate()) over every
//! block.
//!
//! A block's stream is one head byte (bit 7: the payload was cut; bits 0–6: its top
//! plane plus one, 0 when every coefficient is zero) and its payload, framed.

mod decode;
mod encode;

pub(crate) use decode::decode_windows;
pub(crate) use encode::encode;
pub use encode::{blocked_head, cut_units, EncodedUnit};

use super::TileGrid;
use crate::wavelet::{self, Wavelet};

/// Bytes of a block's stream before its payload.
pub(super) const BLOCK_HEAD: u64 = 1;

/// The tiles a raster of `width × height` is coded in when its blocks are `side` a side
/// (a multiple of 64): tiles no larger than `max_tile` (rounded up to whole blocks) and
/// as equal as whole blocks allow, one tile when it fits, each coding
/// [`TILE_OVERLAP`](super::TILE_OVERLAP) samples more on every side that has a neighbour
/// (as independent tiles do: the transform's edge then falls outside the tile). `None`
/// when one block covers the raster (one stream does better).
pub fn unit_grid(width: usize, height: usize, max_tile: usize, side: usize) -> Option<TileGrid> {
    if width <= side && height <= side {
        return None;
    }
    let max_tile = max_tile.div_ceil(side).max(1) * side;
    let tile_side = |len: usize| len.div_ceil(len.div_ceil(max_tile)).div_ceil(side) * side;
    Some(TileGrid {
        width,
        height,
        tile_width: tile_side(width).min(width),
        tile_height: tile_side(height).min(height),
        overlap: super::TILE_OVERLAP,
    })
}

/// Decomposition levels of a `width × height` tile in blocks of `side`: those asked (or
/// the default), at most what leaves each block's coarsest band 4 samples a side (6
/// levels for blocks of 256: best on two of three DEMs measured, README *Code blocks*).
pub(super) fn unit_levels(width: usize, height: usize, side: usize, asked: Option<u32>) -> u32 {
    asked
        .unwrap_or_else(|| wavelet::default_levels(width, height))
        .min(side.trailing_zeros().saturating_sub(2))
        .min(wavelet::max_levels(width, height))
}

/// Samples beyond a window whose blocks a decode of it reads: the reach of the
/// coefficients outside them into the window through `levels` levels of `wavelet`'s
/// synthesis (a 9/7 coefficient of level `l` reaches about `4 · 2^l` samples, a 5/3 one
/// `2 · 2^l`), so the window decodes to the same samples as the whole tile.
pub(super) fn reach(wavelet: Wavelet, levels: u32) -> usize {
    match wavelet {
        Wavelet::Cdf97 => 4 << levels,
        Wavelet::Int53 => 2 << levels,
        Wavelet::Int1311 => 6 << levels,
    }
}
