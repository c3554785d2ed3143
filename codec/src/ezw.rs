//! EZW: embedded zerotree wavelet coding (Shapiro 1993) with context-modelled
//! arithmetic coding.
//!
//! Coefficients are signed integers (the 5/3 transform's output, or 9/7 coefficients
//! quantised by the caller) laid out as [`crate::wavelet::subbands`] describes. Every subband
//! has a *shift*: its coefficients' bit-plane `p` is coded in the pass of global plane
//! `n = p + shift`. Shifts weight subbands by their contribution to pixel-domain error, so
//! the embedded order stays close to rate–distortion optimal while the 5/3 path stays
//! exactly reversible.
//!
//! Pass `n` (from the top plane down to 0) has two scans over the subbands, coarse to fine,
//! each subband in raster order:
//! 1. **dominant**: every coefficient not yet significant and not inside a zerotree found
//!    earlier in this pass gets one symbol: POSITIVE / NEGATIVE (it is significant at this
//!    plane), ISOLATED ZERO (it is not, a descendant is) or ZEROTREE ROOT (neither it nor
//!    any descendant is; its descendants are skipped for the rest of the pass).
//!    Coefficients found significant in earlier passes are skipped (EZW's zero placeholders).
//! 2. **subordinate**: every coefficient significant before this pass gets its bit at
//!    this plane.
//!
//! [`Coder::V4`], what new streams use, runs a **propagation** scan before those two:
//! the insignificant coefficients with a significant parent and a significant neighbour
//! get their significance decision first, so prefixes cut inside a pass keep more of its
//! value (see `ezw/propagation.rs`).
//!
//! The four-valued symbols go through binary decisions: significant? then the sign, or
//! (for coefficients with children) zerotree root? Each decision has its own adaptive
//! [`BitModel`], chosen by subband class and by what is known of the coefficient's
//! spatial neighbours and of its parent: their significance ([`Coder::V1`]) or their
//! magnitudes and signs ([`Coder::V2`]; [`Coder::V3`] and [`Coder::V4`] start those
//! models from trained probabilities; see [`Contexts`]).
//!
//! Encoder and decoder run the same scan (`scan_pass`) with a different `Side`; the
//! decoder stops at the first decision its bytes cannot determine, leaving every
//! coefficient with the bits it has (reconstructed mid-interval by
//! [`Decoder::into_real_coefficients`] and [`Decoder::integer_coefficients`]).

#[cfg(any(feature = "internals", feature = "research"))]
use crate::entropy::BitCounter;
use crate::entropy::{ArithmeticDecoder, ArithmeticEncoder, BitModel, BitSink};
use crate::progress::Stage;
use crate::significance::SignificanceMap;
use crate::wavelet::{Orientation, Subband};

mod contexts;
mod priors;
mod propagation;
mod store;
#[cfg(feature = "research")]
mod training;

use contexts::{dominant_contexts, refinement_context, sign_context, At};
pub use contexts::{Coder, ContextChoice, Contexts};
use std::marker::PhantomData;
pub(crate) use store::is_escape;
pub use store::{Known, Narrow, Store};
#[cfg(feature = "research")]
pub use training::{tally_priors, PriorTally, PRIOR_WINDOW};

/// Highest global plane a stream may use (descendant plane masks are `u64`).
pub const MAX_PLANE: u32 = 62;
/// Highest bit-plane of a coefficient itself (magnitudes are below 2^31).
pub const MAX_COEFFICIENT_PLANE: u32 = 30;

/// One subband as the coder sees it.
#[derive(Debug, Clone)]
struct Band {
    sub: Subband,
    shift: u32,
    /// The band holding this band's parents, if any.
    parent: Option<usize>,
    /// Parents sit at (x/2, y/2) (detail → detail) rather than (x, y) (LL → coarsest details).
    halve: bool,
    /// Context class: 0 = LL, 1 = coarse details, 2 = level 2, 3 = level 1.
    class: usize,
    /// Orientation class for sign contexts: 0 = LL, 1 = HL, 2 = LH, 3 = HH.
    orientation: usize,
    /// Whether some band holds this band's children.
    has_children: bool,
}

impl Band {
    /// The band's own bit-plane coded in the pass of global plane `n`, if the band takes
    /// part: `n − shift`, when that is a plane a coefficient can have (0 ..= 30).
    #[inline]
    fn plane_in_pass(&self, n: u32) -> Option<u32> {
        n.checked_sub(self.shift)
            .filter(|&p| p <= MAX_COEFFICIENT_PLANE)
    }
}

/// The subbands of a transformed image, with the per-band shifts and parent links.
#[derive(Debug, Clone)]
pub struct CoefficientLayout {
    pub(crate) width: usize,
    pub(crate) height: usize,
    bands: Vec<Band>,
}

impl CoefficientLayout {
    /// Builds the layout from the subbands (coarse to fine, as
    /// [`crate::wavelet::subbands`] lists them) and one shift per subband.
    pub fn new(width: usize, height: usize, subbands: &[Subband], shifts: &[u32]) -> Self {
        assert_eq!(subbands.len(), shifts.len());
        let levels = subbands.first().map_or(0, |s| s.level);
        let mut bands: Vec<Band> = Vec::with_capacity(subbands.len());
        for (&sub, &shift) in subbands.iter().zip(shifts) {
            let (parent, halve) = match sub.orientation {
                Orientation::LL => (None, false),
                // The coarsest details descend from the LL coefficient at the same position.
                _ if sub.level == levels => (Some(0), false),
                o => (
                    subbands
                        .iter()
                        .position(|s| s.orientation == o && s.level == sub.level + 1),
                    true,
                ),
            };
            let class = match (sub.orientation, sub.level) {
                (Orientation::LL, _) => 0,
                (_, 1) => 3,
                (_, 2) => 2,
                _ => 1,
            };
            let orientation = match sub.orientation {
                Orientation::LL => 0,
                Orientation::HL => 1,
                Orientation::LH => 2,
                Orientation::HH => 3,
            };
            bands.push(Band {
                sub,
                shift,
                parent,
                halve,
                class,
                orientation,
                has_children: false,
            });
        }
        for b in 0..bands.len() {
            if let Some(pb) = bands[b].parent {
                bands[pb].has_children = true;
            }
        }
        CoefficientLayout {
            width,
            height,
            bands,
        }
    }

    /// Decomposition levels (the level of the LL band).
    pub(crate) fn levels(&self) -> u32 {
        self.bands.first().map_or(0, |b| b.sub.level)
    }

    /// The detail subbands with their shifts.
    pub(crate) fn detail_bands(&self) -> impl Iterator<Item = (Subband, u32)> + '_ {
        self.bands
            .iter()
            .filter(|b| b.sub.orientation != Orientation::LL)
            .map(|b| (b.sub, b.shift))
    }

    /// Number of coefficients (= samples).
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Whether the layout is empty.
    #[cfg(feature = "internals")]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// What differs between encoding and decoding a scan.
trait Side {
    /// How the known coefficients are stored.
    type Known: Known + ?Sized;
    /// Is coefficient `i` significant at own plane `p`?
    fn significance(&mut self, i: usize, p: u32, model: &mut BitModel) -> bool;
    /// Is coefficient `i` negative?
    fn sign(&mut self, i: usize, model: &mut BitModel) -> bool;
    /// Is insignificant coefficient `i` a zerotree root at global plane `n`?
    fn zerotree_root(&mut self, i: usize, n: u32, model: &mut BitModel) -> bool;
    /// Bit `p` of the magnitude of coefficient `i`.
    fn refinement(&mut self, i: usize, p: u32, model: &mut BitModel) -> bool;
    /// Bit `p` of the magnitude of coefficient `i`, coded without a model (p = 1/2).
    fn raw_refinement(&mut self, i: usize, p: u32) -> bool;
    /// Whether the last decision is not to be trusted (decoder) or the budget is spent
    /// (encoder): the scan stops without committing it.
    fn stopped(&self) -> bool;
    /// Records that coefficient `i` became significant at plane `p` with the given sign.
    fn commit_significant(&mut self, i: usize, band: usize, p: u32, negative: bool);
    /// Records refinement bit `bit` at plane `p` of coefficient `i`.
    fn commit_refinement(&mut self, i: usize, band: usize, p: u32, bit: bool);
    /// The magnitude bits of coefficient `i` above plane `p` (known to both sides when
    /// plane `p` is refined).
    fn known_above(&self, i: usize, p: u32) -> u32;
    /// Every coefficient as far as it is known to both sides: the magnitude bits decided
    /// so far with their sign (0 while insignificant).
    fn known(&self) -> &Self::Known;
}

/// The scans' state beside the known coefficients (a coefficient is significant when
/// its known value is not 0): bitmaps, one bit per coefficient, band after band, each
/// band row padded to whole 64-bit words (so a scan's 64-coefficient chunk is one
/// word), that let the scans jump straight to the coefficients that need a decision:
/// `sig_bits` (significant) and `zt_bits` (the zerotree coverage of the current pass).
#[derive(Debug, Clone)]
struct FlagGrid {
    /// Width and height of the coefficient array.
    width: usize,
    height: usize,
    sig_bits: Vec<u64>,
    zt_bits: Vec<u64>,
    /// Coefficients whose significance the propagation scan of the current pass coded
    /// (empty when the coder has no propagation scan).
    prop_bits: Vec<u64>,
    /// Significant coefficients in each band.
    significant_in_band: Vec<u32>,
    /// Each band's first word in the bitmaps and words per row.
    band_words: Vec<(usize, usize)>,
}

impl FlagGrid {
    fn new(layout: &CoefficientLayout, coder: Coder) -> FlagGrid {
        let mut words = 0;
        let band_words = (layout.bands.iter())
            .map(|band| {
                let (first, per_row) = (words, band.sub.width.div_ceil(64));
                words += per_row * band.sub.height;
                (first, per_row)
            })
            .collect();
        FlagGrid {
            width: layout.width,
            height: layout.height,
            sig_bits: vec![0; words],
            zt_bits: vec![0; words],
            prop_bits: if coder.propagates() {
                vec![0; words]
            } else {
                Vec::new()
            },
            significant_in_band: vec![0; layout.bands.len()],
            band_words,
        }
    }

    /// Bit index of coefficient (x, y) of band `b` (in the band's coordinates) in the
    /// bitmaps.
    #[inline]
    fn bit(&self, b: usize, x: usize, y: usize) -> usize {
        let (first, per_row) = self.band_words[b];
        (first + y * per_row) * 64 + x
    }

    /// Index of the neighbour at (dx, dy) of coefficient `at`, if inside the array.
    #[inline]
    fn neighbour(&self, at: At, dx: isize, dy: isize) -> Option<usize> {
        let w = self.width;
        if at.interior {
            return Some(at.index.wrapping_add_signed(dy * w as isize + dx));
        }
        let x = (at.index % w).checked_add_signed(dx)?;
        let y = (at.index / w).checked_add_signed(dy)?;
        (x < w && y < self.height).then_some(y * w + x)
    }
}

/// The bits of `words` from bit `start` to the end of its word, in the low bits: a
/// chunk of a band row, which starts a word, or a halved parent row's chunk, the
/// 32-bit half word at `start`. Bits past a row's end read as 0: the bitmaps only ever
/// hold bits of coefficients.
#[inline(always)]
fn chunk_bits(words: &[u64], start: usize) -> u64 {
    words[start / 64] >> (start % 64)
}

/// Stores `value`, bits of the chunk's coefficients only (`len` of them), as the chunk
/// of a band row at bit `start` (which starts a word).
#[inline(always)]
fn store_chunk(words: &mut [u64], start: usize, len: usize, value: u64) {
    debug_assert!(start.is_multiple_of(64) && value & !ones(len) == 0);
    words[start / 64] = value;
}

/// Doubles every bit of `x`: bit k goes to bits 2k and 2k + 1 (parent → two children).
#[inline]
fn spread_bits(x: u32) -> u64 {
    let mut v = x as u64;
    v = (v | (v << 16)) & 0x0000_FFFF_0000_FFFF;
    v = (v | (v << 8)) & 0x00FF_00FF_00FF_00FF;
    v = (v | (v << 4)) & 0x0F0F_0F0F_0F0F_0F0F;
    v = (v | (v << 2)) & 0x3333_3333_3333_3333;
    v = (v | (v << 1)) & 0x5555_5555_5555_5555;
    v | (v << 1)
}

/// Where a band's parents are, resolved once per pass.
struct ParentBand {
    /// The parent band's number.
    band: usize,
    x0: usize,
    y0: usize,
    width: usize,
    height: usize,
    halve: bool,
    /// The parent band's own plane in this pass.
    plane: u32,
}

/// One row of parents: where its first coefficient is in the bitmaps and the
/// coefficients.
#[derive(Clone, Copy)]
struct ParentRow {
    bit: usize,
    index: usize,
    width: usize,
    halve: bool,
    plane: u32,
}

impl ParentRow {
    /// Column of the parent of column `x`, if the row has one there.
    #[inline]
    fn column(&self, x: usize) -> Option<usize> {
        let px = if self.halve { x >> 1 } else { x };
        (px < self.width).then_some(px)
    }
}

/// Where row `y` of a band starts in the coefficients and the bitmaps.
#[derive(Clone, Copy)]
struct BandRow {
    index: usize,
    bit: usize,
    /// The row's columns whose 8 neighbours are all inside the array: from `inner_from`,
    /// `inner_len` of them.
    inner_from: usize,
    inner_len: usize,
}

impl BandRow {
    /// Row `y` of band `b`, `sub`, of an array `width` × `height`.
    fn new(
        grid: &FlagGrid,
        b: usize,
        sub: Subband,
        y: usize,
        (width, height): (usize, usize),
    ) -> BandRow {
        let gy = sub.y0 + y;
        // Array columns 1 ..= width − 2 of rows 1 ..= height − 2.
        let inner_from = usize::from(sub.x0 == 0);
        let inner_to = if (1..height - 1).contains(&gy) {
            (width - 1).saturating_sub(sub.x0)
        } else {
            0
        };
        BandRow {
            index: gy * width + sub.x0,
            bit: grid.bit(b, 0, y),
            inner_from,
            inner_len: inner_to.saturating_sub(inner_from),
        }
    }

    /// Column `x` of the row.
    #[inline]
    fn at(&self, x: usize) -> At {
        At {
            index: self.index + x,
            x,
            interior: x.wrapping_sub(self.inner_from) < self.inner_len,
        }
    }
}

/// Outcome of one scan.
enum ScanEnd {
    Finished,
    Stopped,
}

/// Runs pass `n` for one side: with fractional passes ([`Coder::V4`]) the propagation
/// scan first, then the dominant and the subordinate scans.
fn scan_pass<S: Side>(
    layout: &CoefficientLayout,
    grid: &mut FlagGrid,
    contexts: &mut Contexts,
    side: &mut S,
    n: u32,
) -> ScanEnd {
    if contexts.coder.propagates() {
        grid.prop_bits.fill(0);
        if let ScanEnd::Stopped = propagation::scan(layout, grid, contexts, side, n) {
            return ScanEnd::Stopped;
        }
    }
    if let ScanEnd::Stopped = dominant_scan(layout, grid, contexts, side, n) {
        return ScanEnd::Stopped;
    }
    subordinate_scan(layout, grid, contexts, side, n)
}

/// Clears the zerotree coverage of band `b`, `height` rows, which takes no part in
/// pass `n`: it covers none of its children.
fn clear_coverage(grid: &mut FlagGrid, b: usize, height: usize) {
    let (first, per_row) = grid.band_words[b];
    grid.zt_bits[first..first + per_row * height].fill(0);
}

/// Where band `band`'s parents are in pass `n`, if it has parents taking part.
fn parent_band(layout: &CoefficientLayout, band: &Band, n: u32) -> Option<ParentBand> {
    let pb = band.parent?;
    let ps = layout.bands[pb].sub;
    Some(ParentBand {
        band: pb,
        x0: ps.x0,
        y0: ps.y0,
        width: ps.width,
        height: ps.height,
        halve: band.halve,
        plane: layout.bands[pb].plane_in_pass(n)?,
    })
}

/// The parents of row `y` of a band whose parent band is `parent`, if the row has any.
fn parent_row(
    grid: &FlagGrid,
    parent: Option<&ParentBand>,
    y: usize,
    width: usize,
) -> Option<ParentRow> {
    let pb = parent?;
    let py = if pb.halve { y / 2 } else { y };
    (py < pb.height).then(|| ParentRow {
        bit: grid.bit(pb.band, 0, py),
        index: (pb.y0 + py) * width + pb.x0,
        width: pb.width,
        halve: pb.halve,
        plane: pb.plane,
    })
}

/// Mask of `len` (≤ 64) ones.
#[inline(always)]
fn ones(len: usize) -> u64 {
    u64::MAX.checked_shr(64 - len as u32).unwrap_or(0)
}

/// Where a significance decision is coded: the coefficient, its band (and the band's
/// number), its own plane in the pass, its parent's row and its bit in the bitmaps.
#[derive(Clone, Copy)]
struct Site<'a> {
    at: At,
    band: &'a Band,
    b: usize,
    p: u32,
    parent_row: Option<ParentRow>,
    bit: usize,
}

/// Codes the significance decision (and the sign, when significant) of the insignificant
/// coefficient at `site`, committing it when significant. `None` when the side stopped;
/// else whether it became significant and the zerotree model index.
#[inline]
fn code_significance<S: Side>(
    grid: &mut FlagGrid,
    contexts: &mut Contexts,
    side: &mut S,
    site: Site,
) -> Option<(bool, usize)> {
    let Site {
        at,
        band,
        b,
        p,
        parent_row,
        bit,
    } = site;
    let class = band.class * contexts.choice.subband_class as usize;
    let (ctx, zctx) = dominant_contexts(contexts, grid, side, at, class, p, parent_row);
    let i = at.index;
    let is_significant = side.significance(i, p, &mut contexts.significance[ctx]);
    if side.stopped() {
        return None;
    }
    if is_significant {
        let sctx = sign_context(contexts, grid, side, at, band.orientation, parent_row);
        let negative = side.sign(i, &mut contexts.sign[sctx]);
        if side.stopped() {
            return None;
        }
        side.commit_significant(i, b, p, negative);
        grid.sig_bits[bit / 64] |= 1 << (bit % 64);
        grid.significant_in_band[b] += 1;
    }
    Some((is_significant, zctx))
}

/// The dominant scan of pass `n`, 64 coefficients of a band row at a time: the bitmaps
/// give the coefficients that are neither significant nor covered by their parent's
/// zerotree, and only those get decisions (those the propagation scan visited only the
/// zerotree one).
fn dominant_scan<S: Side>(
    layout: &CoefficientLayout,
    grid: &mut FlagGrid,
    contexts: &mut Contexts,
    side: &mut S,
    n: u32,
) -> ScanEnd {
    let (w, h) = (layout.width, layout.height);
    for (b, band) in layout.bands.iter().enumerate() {
        let sub = band.sub;
        if sub.width == 0 || sub.height == 0 {
            continue;
        }
        let Some(p) = band.plane_in_pass(n) else {
            clear_coverage(grid, b, sub.height);
            continue;
        };
        let parent = parent_band(layout, band, n);
        for y in 0..sub.height {
            let row = BandRow::new(grid, b, sub, y, (w, h));
            let parent_row = parent_row(grid, parent.as_ref(), y, w);
            for chunk in (0..sub.width).step_by(64) {
                let len = (sub.width - chunk).min(64);
                let covered = match parent_row {
                    Some(pr) if pr.halve && chunk / 2 < pr.width => {
                        spread_bits(chunk_bits(&grid.zt_bits, pr.bit + chunk / 2) as u32)
                    }
                    Some(pr) if !pr.halve && chunk < pr.width => {
                        chunk_bits(&grid.zt_bits, pr.bit + chunk)
                    }
                    _ => 0,
                };
                let live = ones(len);
                let covered = covered & live;
                let significant = chunk_bits(&grid.sig_bits, row.bit + chunk);
                let visited = if grid.prop_bits.is_empty() {
                    0
                } else {
                    chunk_bits(&grid.prop_bits, row.bit + chunk)
                };
                let mut todo = live & !covered & !significant;
                // Significant coefficients pass their parent's zerotree on; new roots
                // are added below.
                let mut roots = covered;
                while todo != 0 {
                    let k = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    let x = chunk + k;
                    let at = row.at(x);
                    let zctx = if visited >> k & 1 != 0 {
                        if !band.has_children {
                            continue;
                        }
                        let class = band.class * contexts.choice.subband_class as usize;
                        dominant_contexts(contexts, grid, side, at, class, p, parent_row).1
                    } else {
                        let site = Site {
                            at,
                            band,
                            b,
                            p,
                            parent_row,
                            bit: row.bit + x,
                        };
                        let coded = code_significance(grid, contexts, side, site);
                        match coded {
                            None => {
                                store_chunk(&mut grid.zt_bits, row.bit + chunk, len, roots);
                                return ScanEnd::Stopped;
                            }
                            Some((true, _)) => continue,
                            Some((false, _)) if !band.has_children => continue,
                            Some((false, zctx)) => zctx,
                        }
                    };
                    let root = side.zerotree_root(at.index, n, &mut contexts.zerotree[zctx]);
                    if side.stopped() {
                        store_chunk(&mut grid.zt_bits, row.bit + chunk, len, roots);
                        return ScanEnd::Stopped;
                    }
                    roots |= (root as u64) << k;
                }
                store_chunk(&mut grid.zt_bits, row.bit + chunk, len, roots);
            }
        }
    }
    ScanEnd::Finished
}

/// The subordinate scan of pass `n`: every coefficient significant before this pass
/// gets its bit at this plane, in the dominant scan's order.
fn subordinate_scan<S: Side>(
    layout: &CoefficientLayout,
    grid: &mut FlagGrid,
    contexts: &mut Contexts,
    side: &mut S,
    n: u32,
) -> ScanEnd {
    let (w, h) = (layout.width, layout.height);
    for (b, band) in layout.bands.iter().enumerate() {
        let Some(p) = band.plane_in_pass(n) else {
            continue;
        };
        if grid.significant_in_band[b] == 0 {
            continue;
        }
        let sub = band.sub;
        for y in 0..sub.height {
            let row = BandRow::new(grid, b, sub, y, (w, h));
            for chunk in (0..sub.width).step_by(64) {
                let mut todo = chunk_bits(&grid.sig_bits, row.bit + chunk);
                while todo != 0 {
                    let x = chunk + todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    let i = row.index + x;
                    let above = side.known_above(i, p);
                    // Significant since this pass (magnitude 2^p): no refinement bit yet.
                    if above == 0 {
                        continue;
                    }
                    let choice = contexts.choice;
                    // Age: 0 = first refinement (significant since the previous pass),
                    // 1 = second, 2 = older.
                    let age = match above {
                        1 => 0,
                        2 | 3 => 1,
                        _ => 2,
                    } * choice.refinement_age as usize;
                    // Bits of magnitudes known to 3+ planes are all but random: raw.
                    let bit = if age == 2 {
                        side.raw_refinement(i, p)
                    } else {
                        let at = row.at(x);
                        let rctx = refinement_context(
                            contexts,
                            grid,
                            side.known(),
                            at,
                            p,
                            age,
                            band.class,
                        );
                        side.refinement(i, p, &mut contexts.refinement[rctx])
                    };
                    if side.stopped() {
                        return ScanEnd::Stopped;
                    }
                    side.commit_refinement(i, b, p, bit);
                }
            }
        }
    }
    ScanEnd::Finished
}

/// Bytes and estimated distortion after each complete pass, highest plane first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassRecord {
    /// Global bit-plane of the pass.
    pub plane: u32,
    /// Payload bytes needed to decode through the end of this pass.
    pub end_byte: u64,
    /// Estimated sum of squared pixel errors after this pass (from the coefficient
    /// errors weighted by each subband's synthesis norm).
    pub squared_error: f64,
}

/// What the encoder produced.
#[derive(Debug, Clone)]
pub struct EncodedPayload {
    /// The arithmetic-coded payload.
    pub bytes: Vec<u8>,
    /// One record per completed pass.
    pub passes: Vec<PassRecord>,
    /// Estimated sum of squared pixel errors before the first pass.
    pub initial_error: f64,
    /// Whether every pass down to plane 0 was coded (false when stopped at a budget).
    pub complete: bool,
    /// Truncation points inside the passes: payload bytes and the estimated sum of
    /// squared errors of a decode of that prefix (a few hundred at most).
    pub checkpoints: Vec<(u64, f64)>,
}

/// Truncation points recorded as the encoder goes, for rate allocation finer than whole
/// passes: after each coefficient's bits, once the payload has grown by a step since
/// the last point (16 bytes, or 1/32 of the payload so far when that is more), so a
/// stream of any length has a few hundred at most; none in the plane-0 pass.
#[derive(Debug, Default)]
struct Checkpoints {
    points: Vec<(u64, f64)>,
    next: usize,
    /// Whether the pass being coded takes checkpoints.
    open: bool,
}

/// Lowest pass (global plane) that takes checkpoints. Inside the plane-0 pass the
/// weighted coefficient errors misjudge the error of a prefix (an allocation stopping
/// 5/3 tiles there lost 1.4 dB on srtm3_n57e011 at 0.5 bpp), so that pass is allocated
/// whole or in part, as before.
const CHECKPOINT_LAST_PLANE: u32 = 1;

impl Checkpoints {
    /// Smallest step between two points, in payload bytes.
    const MIN_STEP: usize = 16;

    #[inline]
    fn observe(&mut self, bytes: usize, squared_error: f64) {
        if self.open && bytes >= self.next {
            self.points.push((bytes as u64, squared_error.max(0.0)));
            self.next = bytes + (bytes / 32).max(Self::MIN_STEP);
        }
    }
}

/// Encoder side: codes the true coefficients and tracks the squared error.
struct EncoderSide<'a, B: BitSink> {
    sink: B,
    coefficients: &'a [i32],
    /// What the decoder knows of every coefficient (see [`Side::known`]).
    known: Vec<i32>,
    /// Descendant plane masks: bit n set when some descendant has global plane n.
    descendants: &'a [u64],
    /// Squared synthesis norm of each band, in pixel units per coefficient unit.
    band_weights: &'a [f64],
    /// Reconstruction currently implied for every coefficient, as magnitude bits known.
    squared_error: f64,
    /// The encoder stops once it has produced more bytes than this (`usize::MAX`: never).
    budget: usize,
    midpoint: Midpoint,
    checkpoints: Checkpoints,
}

impl<B: BitSink> Side for EncoderSide<'_, B> {
    type Known = [i32];
    #[inline]
    fn significance(&mut self, i: usize, p: u32, model: &mut BitModel) -> bool {
        let bit = self.coefficients[i].unsigned_abs() >> p != 0;
        self.sink.encode(bit, model);
        bit
    }
    #[inline]
    fn sign(&mut self, i: usize, model: &mut BitModel) -> bool {
        let bit = self.coefficients[i] < 0;
        self.sink.encode(bit, model);
        bit
    }
    #[inline]
    fn zerotree_root(&mut self, i: usize, n: u32, model: &mut BitModel) -> bool {
        let root = self.descendants[i] & (1u64 << n) == 0;
        self.sink.encode(root, model);
        root
    }
    #[inline]
    fn refinement(&mut self, i: usize, p: u32, model: &mut BitModel) -> bool {
        let bit = (self.coefficients[i].unsigned_abs() >> p) & 1 != 0;
        self.sink.encode(bit, model);
        bit
    }
    #[inline]
    fn raw_refinement(&mut self, i: usize, p: u32) -> bool {
        let bit = (self.coefficients[i].unsigned_abs() >> p) & 1 != 0;
        self.sink.encode_raw(bit);
        bit
    }
    #[inline]
    fn stopped(&self) -> bool {
        // The bytes produced only grow: once over, always over.
        self.sink.bytes_so_far() > self.budget
    }
    #[inline]
    fn commit_significant(&mut self, i: usize, band: usize, p: u32, negative: bool) {
        let m = self.coefficients[i].unsigned_abs();
        self.known[i] = if negative { -1 << p } else { 1 << p };
        let before = m as f64;
        let known = m >> p << p;
        let after = m as f64 - self.midpoint.value(known, p);
        self.squared_error += (after * after - before * before) * self.band_weights[band];
        self.checkpoints
            .observe(self.sink.bytes_so_far(), self.squared_error);
    }
    #[inline]
    fn commit_refinement(&mut self, i: usize, band: usize, p: u32, bit: bool) {
        let m = self.coefficients[i].unsigned_abs();
        if bit {
            let k = &mut self.known[i];
            *k += if *k < 0 { -1 << p } else { 1 << p };
        }
        let old_known = m >> (p + 1) << (p + 1);
        let before = m as f64 - self.midpoint.value(old_known, p + 1);
        let known = m >> p << p;
        let after = m as f64 - self.midpoint.value(known, p);
        self.squared_error += (after * after - before * before) * self.band_weights[band];
        self.checkpoints
            .observe(self.sink.bytes_so_far(), self.squared_error);
    }
    #[inline]
    fn known_above(&self, i: usize, p: u32) -> u32 {
        self.coefficients[i].unsigned_abs() >> (p + 1)
    }
    #[inline]
    fn known(&self) -> &[i32] {
        &self.known
    }
}

/// How a magnitude whose bits are known down to plane `p` is reconstructed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Midpoint {
    /// Integer coefficients (5/3): `known + (2^p − 1) / 2`, exact when `p = 0`.
    Integer,
    /// Quantised real coefficients (9/7): the true value lies in `[q, q + 1)` of the
    /// quantiser, so `known + 2^p / 2` (with `p = 0` giving `q + 1/2`).
    Real,
}

impl Midpoint {
    /// Reconstructed magnitude of a significant coefficient.
    #[inline]
    pub fn value(self, known: u32, p: u32) -> f64 {
        match self {
            Midpoint::Integer => known as f64 + (((1u64 << p) - 1) / 2) as f64,
            Midpoint::Real => known as f64 + (1u64 << p) as f64 * 0.5,
        }
    }
}

/// Global plane of a coefficient: `None` for zero.
#[inline]
fn global_plane(c: i32, shift: u32) -> Option<u32> {
    let m = c.unsigned_abs();
    (m != 0).then(|| m.ilog2() + shift)
}

/// Computes the descendant plane masks bottom-up, band by band, row by row.
fn descendant_masks(layout: &CoefficientLayout, coefficients: &[i32]) -> Vec<u64> {
    let w = layout.width;
    let mut masks = vec![0u64; coefficients.len()];
    for band in layout.bands.iter().rev() {
        let Some(pb) = band.parent else {
            continue;
        };
        let (sub, parents) = (band.sub, layout.bands[pb].sub);
        // Parents at (x >> halve, y >> halve); coefficients past the parent band have none.
        let halve = u32::from(band.halve);
        let rows = sub.height.min(parents.height << halve);
        let columns = sub.width.min(parents.width << halve);
        for y in 0..rows {
            let row = (sub.y0 + y) * w + sub.x0;
            let parent_row = (parents.y0 + (y >> halve)) * w + parents.x0;
            for x in 0..columns {
                let i = row + x;
                let own = global_plane(coefficients[i], band.shift).map_or(0, |g| 1u64 << g);
                // A band without children leaves its masks zero, and unread: their pages
                // are never touched.
                let below = if band.has_children { masks[i] } else { 0 };
                masks[parent_row + (x >> halve)] |= own | below;
            }
        }
    }
    masks
}

/// Highest global plane over all coefficients, or `None` if all are zero.
pub fn top_plane(layout: &CoefficientLayout, coefficients: &[i32]) -> Option<u32> {
    let mut top = None;
    for band in &layout.bands {
        let sub = band.sub;
        for y in 0..sub.height {
            let row = (sub.y0 + y) * layout.width + sub.x0;
            let max = coefficients[row..row + sub.width]
                .iter()
                .map(|c| c.unsigned_abs())
                .max()
                .unwrap_or(0);
            if max != 0 {
                let g = max.ilog2() + band.shift;
                top = Some(top.map_or(g, |t: u32| t.max(g)));
            }
        }
    }
    top
}

/// Encodes `coefficients` (all magnitudes below 2^31) into an embedded payload whose
/// first pass is `top`, their [`top_plane`] (the caller has it for the header).
///
/// `band_weights[b]` is the squared synthesis norm of band `b` divided by the squared
/// quantiser scale, used only for the distortion estimates in [`PassRecord`].
/// `budget` stops the encoder soon after that many payload bytes; the caller cuts the
/// payload to the exact size.
pub fn encode(
    layout: &CoefficientLayout,
    coefficients: &[i32],
    top: Option<u32>,
    band_weights: &[f64],
    midpoint: Midpoint,
    budget: Option<usize>,
) -> EncodedPayload {
    assert_eq!(coefficients.len(), layout.len());
    let descendants = descendant_masks(layout, coefficients);
    let initial_error: f64 = layout
        .bands
        .iter()
        .zip(band_weights)
        .map(|(band, &weight)| {
            let sub = band.sub;
            let mut sum = 0.0;
            for y in 0..sub.height {
                let row = (sub.y0 + y) * layout.width + sub.x0;
                for &c in &coefficients[row..row + sub.width] {
                    sum += (c as f64) * (c as f64);
                }
            }
            sum * weight
        })
        .sum();
    debug_assert_eq!(top, top_plane(layout, coefficients));
    let side = EncoderSide {
        sink: ArithmeticEncoder::new(),
        coefficients,
        known: vec![0; coefficients.len()],
        descendants: &descendants,
        band_weights,
        squared_error: initial_error,
        budget: budget.map_or(usize::MAX, |b| b + 8),
        midpoint,
        checkpoints: Checkpoints::default(),
    };
    let mut contexts = Contexts::default();
    let (side, passes, complete) = run_encoder(layout, side, top, &mut contexts);
    let bytes = side.sink.finish();
    let mut passes = passes;
    for pass in &mut passes {
        pass.end_byte = pass.end_byte.min(bytes.len() as u64);
    }
    let checkpoints = side
        .checkpoints
        .points
        .into_iter()
        .filter(|&(end, _)| end <= bytes.len() as u64)
        .collect();
    EncodedPayload {
        bytes,
        passes,
        initial_error,
        complete,
        checkpoints,
    }
}

/// Reports `done` of `steps` steps (the passes and the transform), each step a sweep
/// over every sample (see [`crate::progress`]).
fn report_pass(layout: &CoefficientLayout, done: u32, steps: u32) {
    let samples = layout.len() as u64;
    crate::progress::report(
        Stage::Coding,
        samples * u64::from(done),
        samples * u64::from(steps),
    );
}

/// Runs every pass of the encoder over `side`'s sink with the models `contexts`.
fn run_encoder<'a, B: BitSink>(
    layout: &CoefficientLayout,
    mut side: EncoderSide<'a, B>,
    top: Option<u32>,
    contexts: &mut Contexts,
) -> (EncoderSide<'a, B>, Vec<PassRecord>, bool) {
    let mut grid = FlagGrid::new(layout, contexts.coder);
    let mut passes = Vec::new();
    let mut complete = true;
    if let Some(top) = top {
        for n in (0..=top).rev() {
            side.checkpoints.open = n >= CHECKPOINT_LAST_PLANE;
            match scan_pass(layout, &mut grid, contexts, &mut side, n) {
                ScanEnd::Finished => {
                    passes.push(PassRecord {
                        plane: n,
                        end_byte: side.sink.bytes_so_far() as u64,
                        squared_error: side.squared_error.max(0.0),
                    });
                    // The transform came first.
                    report_pass(layout, passes.len() as u32 + 1, top + 2);
                }
                ScanEnd::Stopped => {
                    complete = false;
                    break;
                }
            }
        }
    }
    (side, passes, complete)
}

#[cfg(any(feature = "internals", feature = "research"))]
/// Ideal code length in bits of the complete stream for `coefficients` with coder 2's
/// models selected by `choice` (no bytes are produced): what each context buys is the
/// difference to [`ContextChoice::ALL`].
pub fn count_bits(layout: &CoefficientLayout, coefficients: &[i32], choice: ContextChoice) -> f64 {
    let descendants = descendant_masks(layout, coefficients);
    let mut contexts = Contexts::new(Coder::V2, choice);
    let weights = vec![0.0; layout.bands.len()];
    let side = measuring_side(BitCounter::new(), coefficients, &descendants, &weights);
    let top = top_plane(layout, coefficients);
    let (side, _, _) = run_encoder(layout, side, top, &mut contexts);
    side.sink.bits()
}

#[cfg(any(feature = "internals", feature = "research"))]
/// An encoder side over `sink` that only measures (`band_weights` zero: no distortion
/// bookkeeping).
fn measuring_side<'a, B: BitSink>(
    sink: B,
    coefficients: &'a [i32],
    descendants: &'a [u64],
    band_weights: &'a [f64],
) -> EncoderSide<'a, B> {
    EncoderSide {
        sink,
        coefficients,
        known: vec![0; coefficients.len()],
        descendants,
        band_weights,
        squared_error: 0.0,
        budget: usize::MAX,
        midpoint: Midpoint::Integer,
        checkpoints: Checkpoints::default(),
    }
}

/// Decoder side: fills signed magnitudes bit by bit, the scans reading them through
/// the view `V` ([`Checked`] or [`Saturated`]).
struct DecoderSide<'a, S, V> {
    source: ArithmeticDecoder<'a>,
    values: S,
    /// The coefficient of the last refinement decision of the current pass, if any.
    refined: Option<usize>,
    view: PhantomData<V>,
}

impl<'a, S: Store> DecoderSide<'a, S, Checked> {
    /// The side of a decode into `values` (all 0) reading `source`.
    fn new(source: ArithmeticDecoder<'a>, values: S) -> Self {
        DecoderSide {
            source,
            values,
            refined: None,
            view: PhantomData,
        }
    }

    /// The same side, its scans reading through [`Store::saturated`].
    fn saturated(self) -> DecoderSide<'a, S, Saturated> {
        DecoderSide {
            source: self.source,
            values: self.values,
            refined: self.refined,
            view: PhantomData,
        }
    }
}

/// How a decoder's scans read its store.
trait View<S> {
    /// What they read.
    type Known: Known + ?Sized;
    /// The store as they read it.
    fn of(store: &S) -> &Self::Known;
}

/// Every value as it is.
struct Checked;

impl<S: Store> View<S> for Checked {
    type Known = S;
    #[inline(always)]
    fn of(store: &S) -> &S {
        store
    }
}

/// Through [`Store::saturated`]: only in passes no band codes a plane above
/// [`SATURATED_PLANE`] in.
struct Saturated;

impl<S: Store> View<S> for Saturated {
    type Known = S::Saturated;
    #[inline(always)]
    fn of(store: &S) -> &S::Saturated {
        store.saturated()
    }
}

impl<S: Store, V: View<S>> Side for DecoderSide<'_, S, V> {
    type Known = V::Known;
    #[inline]
    fn significance(&mut self, _i: usize, _p: u32, model: &mut BitModel) -> bool {
        self.source.decode(model)
    }
    #[inline]
    fn sign(&mut self, _i: usize, model: &mut BitModel) -> bool {
        self.source.decode(model)
    }
    #[inline]
    fn zerotree_root(&mut self, _i: usize, _n: u32, model: &mut BitModel) -> bool {
        self.source.decode(model)
    }
    #[inline]
    fn refinement(&mut self, i: usize, _p: u32, model: &mut BitModel) -> bool {
        self.refined = Some(i);
        self.source.decode(model)
    }
    #[inline]
    fn raw_refinement(&mut self, i: usize, _p: u32) -> bool {
        self.refined = Some(i);
        self.source.decode_raw()
    }
    #[inline]
    fn stopped(&self) -> bool {
        self.source.exhausted()
    }
    #[inline]
    fn commit_significant(&mut self, i: usize, _band: usize, p: u32, negative: bool) {
        let m = 1i32 << p;
        self.values.set(i, if negative { -m } else { m });
    }
    #[inline]
    fn commit_refinement(&mut self, i: usize, _band: usize, p: u32, bit: bool) {
        if bit {
            self.values.grow(i, p);
        }
    }
    #[inline]
    fn known_above(&self, i: usize, p: u32) -> u32 {
        V::of(&self.values).at(i).unsigned_abs() >> (p + 1)
    }
    #[inline]
    fn known(&self) -> &V::Known {
        V::of(&self.values)
    }
}

/// The highest plane of the passes a decoder's scans may read through
/// [`Store::saturated`] of a store in units of 1 (in units of 2^s, this plane + s): there
/// an escaped magnitude (at least 32767 units, seen as 32767 or 32768) saturates every
/// context it takes part in, as the true one does: the activity and refinement levels of
/// `sum >> p ≥ 64` (32767 >> 8 = 127), the parent level of `m >> p >> 2 ≥ 1`, the
/// refinement age of `m >> (p + 1) ≥ 4`.
pub const SATURATED_PLANE: u32 = 8;

/// A decode's passes: what they share, and how far they went.
struct PassRun<'l> {
    layout: &'l CoefficientLayout,
    grid: FlagGrid,
    contexts: Contexts,
    /// Passes the decode means to run (for the progress report).
    planned: u32,
    passes_completed: u32,
    /// Where the decode stopped inside a pass, if it did.
    stop: Option<Stop>,
}

impl PassRun<'_> {
    /// Runs the passes of `planes` (global planes, in decreasing order) while the
    /// payload lasts and [`Self::planned`] allows: whether every one of them ran to its
    /// end, `None` when the store overflowed.
    fn passes<S: Store, V: View<S>>(
        &mut self,
        side: &mut DecoderSide<'_, S, V>,
        planes: impl Iterator<Item = i64>,
    ) -> Option<bool> {
        for n in planes {
            if self.passes_completed >= self.planned {
                return Some(false);
            }
            side.refined = None;
            let n = n as u32;
            let end = scan_pass(self.layout, &mut self.grid, &mut self.contexts, side, n);
            if side.values.overflowed() {
                return None;
            }
            if let ScanEnd::Stopped = end {
                let refined = side.refined;
                self.stop = Some(Stop { pass: n, refined });
                return Some(false);
            }
            self.passes_completed += 1;
            // The inverse transform comes last.
            report_pass(self.layout, self.passes_completed, self.planned + 1);
        }
        Some(true)
    }
}

/// The state of a decode: the bits known of every coefficient, kept in `S`.
#[derive(Debug, Clone)]
pub struct Decoder<S = Vec<i32>> {
    values: S,
    /// Every band's place and shift.
    bands: Vec<(Subband, u32)>,
    width: usize,
    /// The first pass not decoded completely, if the decode stopped inside one: where.
    stop: Option<Stop>,
    /// The stream's first pass.
    top_plane: Option<u32>,
    /// Passes decoded completely.
    pub passes_completed: u32,
    /// Whether the decode ran through plane 0 (every bit of every coefficient known).
    pub complete: bool,
}

impl Decoder {
    /// Decodes `payload` (all of it when `payload_complete`, else a prefix) for a stream
    /// whose first pass is `top_plane` (`None`: every coefficient is zero), stopping after
    /// `max_passes` passes if given.
    #[cfg(any(test, feature = "internals"))]
    pub fn run(
        layout: &CoefficientLayout,
        coder: Coder,
        payload: &[u8],
        payload_complete: bool,
        top_plane: Option<u32>,
        max_passes: Option<u32>,
    ) -> Decoder {
        let source = ArithmeticDecoder::new(payload, payload_complete);
        Decoder::run_from(layout, coder, source, top_plane, max_passes)
    }

    /// As `Decoder::run` (tests and the `internals` feature), reading the payload
    /// through `source` (e.g. a decoder over a framed section, read in place).
    pub fn run_from(
        layout: &CoefficientLayout,
        coder: Coder,
        source: ArithmeticDecoder<'_>,
        top_plane: Option<u32>,
        max_passes: Option<u32>,
    ) -> Decoder {
        // Every own plane (≤ MAX_COEFFICIENT_PLANE) fits an i32.
        Decoder::try_run_from(layout, coder, source, top_plane, max_passes)
            .unwrap_or_else(|| unreachable!("an i32 holds every coefficient plane"))
    }
}

impl<S: Store> Decoder<S> {
    /// As [`Decoder::run_from`], keeping the coefficients in `S`: `None` (at the end of
    /// the first pass that shows it) when `S` overflows.
    pub fn try_run_from(
        layout: &CoefficientLayout,
        coder: Coder,
        source: ArithmeticDecoder<'_>,
        top_plane: Option<u32>,
        max_passes: Option<u32>,
    ) -> Option<Decoder<S>> {
        let values = S::zeroed(layout.len());
        Decoder::try_run_into(values, layout, coder, source, (top_plane, max_passes))
    }

    /// As [`Decoder::try_run_from`], into `values` (as many coefficients as `layout`
    /// has, all 0).
    pub fn try_run_into(
        values: S,
        layout: &CoefficientLayout,
        coder: Coder,
        source: ArithmeticDecoder<'_>,
        (top_plane, max_passes): (Option<u32>, Option<u32>),
    ) -> Option<Decoder<S>> {
        let mut run = PassRun {
            layout,
            grid: FlagGrid::new(layout, coder),
            contexts: Contexts::new(coder, ContextChoice::ALL),
            planned: top_plane.map_or(0, |top| max_passes.map_or(top + 1, |m| m.min(top + 1))),
            passes_completed: 0,
            stop: None,
        };
        let saturated_plane = values.saturated_plane();
        let mut side = DecoderSide::<S, Checked>::new(source, values);
        let top = top_plane.map_or(-1, |t| t as i64);
        let saturated_top = top.min(i64::from(saturated_plane));
        // The passes above the store's saturated plane, then the others.
        let mut going = run.passes(&mut side, (saturated_top + 1..=top).rev())?;
        let mut side = side.saturated();
        if going {
            going = run.passes(&mut side, (0..=saturated_top).rev())?;
        }
        let complete = going && run.stop.is_none();
        let (passes_completed, stop) = (run.passes_completed, run.stop);
        Some(Decoder {
            values: side.values,
            bands: layout.bands.iter().map(|b| (b.sub, b.shift)).collect(),
            width: layout.width,
            stop,
            top_plane,
            passes_completed,
            complete,
        })
    }

    /// Integer reconstruction (5/3): mid-interval, rounded down; exact where all bits
    /// are known.
    pub fn integer_coefficients(mut self) -> S {
        // Known to plane 1 or lower, a value is its own midpoint ((2^p − 1) / 2 = 0):
        // a decode that knows every band that far (every complete one) keeps them all.
        let exact = self
            .all_band_planes()
            .iter()
            .all(|planes| planes.settled <= 1 && planes.partial.is_none_or(|(p, _)| p <= 1));
        if !exact {
            self.map_significant(|v, p| {
                let extra = (((1u64 << p) - 1) / 2) as i32;
                if v < 0 {
                    v - extra
                } else {
                    v + extra
                }
            });
        }
        self.values
    }

    /// Replaces every significant coefficient `v` by `f(v, p)`, `p` the lowest plane
    /// known of it; the others stay 0.
    fn map_significant(&mut self, f: impl Fn(i32, u32) -> i32) {
        let w = self.width;
        for (b, planes) in self.all_band_planes().into_iter().enumerate() {
            let (sub, _) = self.bands[b];
            for y in 0..sub.height {
                let start = (sub.y0 + y) * w + sub.x0;
                for i in start..start + sub.width {
                    let value = self.values.at(i);
                    if value != 0 {
                        self.values
                            .set(i, f(value, planes.lowest(i, value.unsigned_abs())));
                    }
                }
            }
        }
    }

    /// The planes known of every band's significant coefficients, in band order.
    fn all_band_planes(&self) -> Vec<BandPlanes> {
        let w = self.width;
        let refined_band = self.stop.and_then(|s| s.refined).and_then(|r| {
            let (x, y) = (r % w, r / w);
            self.bands.iter().position(|(sub, _)| {
                (sub.x0..sub.x0 + sub.width).contains(&x)
                    && (sub.y0..sub.y0 + sub.height).contains(&y)
            })
        });
        (0..self.bands.len())
            .map(|b| self.band_planes(b, self.bands[b].1, refined_band))
            .collect()
    }

    /// The store and the 9/7 reconstruction of its values ([`RealValues`]), for an
    /// inverse that reads the coefficients where they are.
    pub fn into_real_parts(self) -> (S, RealValues) {
        let planes = self.all_band_planes();
        (self.values, RealValues { planes })
    }

    /// The planes known of band `b`'s significant coefficients (see [`BandPlanes`]);
    /// `refined_band` holds the coefficient whose refinement the decode stopped at.
    fn band_planes(&self, b: usize, shift: u32, refined_band: Option<usize>) -> BandPlanes {
        let Some(top) = self.top_plane else {
            return BandPlanes::default();
        };
        // The last pass decoded completely (top + 1: none).
        let last = top + 1 - self.passes_completed;
        let settled = last.saturating_sub(shift);
        let partial = self.stop.and_then(|stop| {
            let plane = stop.pass.checked_sub(shift)?;
            let refined_below = match (stop.refined, refined_band) {
                (Some(r), Some(rb)) if rb == b => r,
                (Some(_), Some(rb)) if rb > b => usize::MAX,
                _ => 0,
            };
            Some((plane, refined_below))
        });
        BandPlanes { settled, partial }
    }
}

/// The 9/7 reconstruction of a significant coefficient of known value `v` whose lowest
/// plane known is `p`: mid-interval, in quantiser units.
#[inline]
fn real_value(v: i32, p: u32) -> f32 {
    let magnitude = Midpoint::Real.value(v.unsigned_abs(), p);
    (if v < 0 { -magnitude } else { magnitude }) as f32
}

/// The 9/7 reconstruction of a decode's coefficients one at a time, as
/// [`Decoder::into_real_coefficients`] makes them all.
#[derive(Debug, Clone)]
pub struct RealValues {
    planes: Vec<BandPlanes>,
}

impl RealValues {
    /// The value of coefficient `i` of band `b` (in [`crate::wavelet::subbands`] order),
    /// whose known value is `v`.
    #[inline]
    pub fn value(&self, b: usize, i: usize, v: i32) -> f32 {
        if v == 0 {
            0.0
        } else {
            real_value(v, self.planes[b].lowest(i, v.unsigned_abs()))
        }
    }
}

/// Where a decode stopped inside a pass.
#[derive(Debug, Clone, Copy)]
struct Stop {
    /// The pass (global plane).
    pass: u32,
    /// The coefficient whose refinement bit was missing, when the decode stopped in the
    /// subordinate scan (which refined the coefficients before it in scan order).
    refined: Option<usize>,
}

/// The lowest plane known of a band's significant coefficients: `settled` after the
/// passes decoded completely; in a pass the decode stopped inside (its plane, and the
/// coefficient index below which the subordinate scan refined this band), that plane
/// for those refined there or significant since it (magnitude below 2^(plane + 1)).
#[derive(Debug, Default, Clone, Copy)]
struct BandPlanes {
    settled: u32,
    partial: Option<(u32, usize)>,
}

impl BandPlanes {
    /// Lowest plane known of coefficient `i`, of known magnitude `m`.
    #[inline]
    fn lowest(self, i: usize, m: u32) -> u32 {
        match self.partial {
            Some((p, refined_below)) if i < refined_below || m >> (p + 1) == 0 => p,
            _ => self.settled,
        }
    }
}

impl Decoder {
    /// The per-node significance map of what was decoded (see
    /// [`crate::significance`]): built from the coefficients' leading bits, which are the
    /// planes at which they became significant.
    pub fn significance(&self, layout: &CoefficientLayout) -> SignificanceMap {
        SignificanceMap::from_values(layout, &self.values)
    }

    /// Real reconstruction (9/7): every coefficient mid-interval ([`Midpoint::Real`]),
    /// in quantiser units, reusing the coefficient buffer.
    pub fn into_real_coefficients(mut self) -> Vec<f32> {
        // The f32 bits are made in place, then reinterpreted in place.
        self.map_significant(|v, p| real_value(v, p).to_bits() as i32);
        self.values
            .into_iter()
            .map(|bits| f32::from_bits(bits as u32))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wavelet::{subbands, Subband};

    fn layout_for(
        w: usize,
        h: usize,
        levels: u32,
        shift: impl Fn(&Subband) -> u32,
    ) -> CoefficientLayout {
        let subs = subbands(w, h, levels);
        let shifts: Vec<u32> = subs.iter().map(shift).collect();
        CoefficientLayout::new(w, h, &subs, &shifts)
    }

    /// The payload of `c` with every band weighing 1 and integer midpoints.
    fn unit_weight_encode(
        layout: &CoefficientLayout,
        c: &[i32],
        budget: Option<usize>,
    ) -> EncodedPayload {
        let weights = vec![1.0; layout.bands.len()];
        encode(
            layout,
            c,
            top_plane(layout, c),
            &weights,
            Midpoint::Integer,
            budget,
        )
    }

    fn pseudo_random(n: usize, seed: u64, scale: i32) -> Vec<i32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let r = ((s >> 33) as i64 % (2 * scale as i64 + 1)) as i32 - scale;
                // Laplacian-ish: most values small.
                if s.is_multiple_of(5) {
                    r
                } else {
                    r / 64
                }
            })
            .collect()
    }

    fn round_trip(
        w: usize,
        h: usize,
        levels: u32,
        coefficients: &[i32],
        shift: impl Fn(&Subband) -> u32,
    ) {
        let layout = layout_for(w, h, levels, shift);
        let enc = unit_weight_encode(&layout, coefficients, None);
        assert!(enc.complete);
        let dec = Decoder::run(
            &layout,
            Coder::default(),
            &enc.bytes,
            true,
            top_plane(&layout, coefficients),
            None,
        );
        assert!(dec.complete);
        assert_eq!(dec.integer_coefficients(), coefficients);
    }

    /// The decoder of `bytes` (a prefix when not `complete`) keeping its coefficients
    /// in `S`.
    fn decode_as<S: Store>(
        layout: &CoefficientLayout,
        bytes: &[u8],
        complete: bool,
        top: Option<u32>,
    ) -> Option<Decoder<S>> {
        let source = ArithmeticDecoder::new(bytes, complete);
        Decoder::try_run_from(layout, Coder::default(), source, top, None)
    }

    /// The reconstructed coefficients of a decoder of `n` coefficients, as `i32`.
    fn reconstructed<S: Store>(decoder: Decoder<S>, n: usize) -> Vec<i32> {
        let store = decoder.integer_coefficients();
        (0..n).map(|i| store.at(i)).collect()
    }

    #[test]
    fn narrow_decoders_match_i32_and_decline_what_does_not_fit() {
        let (w, h) = (48, 40);
        let layout = layout_for(w, h, 3, |s| s.level);
        // Magnitudes up to 32767 fit without escapes; a few of 32768 and more (plane
        // 15 and up) only with them.
        let mut c = pseudo_random(w * h, 11, 32767);
        c[5] = -32767;
        for wide_ones in [false, true] {
            if wide_ones {
                (c[0], c[1], c[7], c[w + 3]) = (-32768, 70000, 40000, -1 << 20);
            }
            let top = top_plane(&layout, &c);
            let full = unit_weight_encode(&layout, &c, None);
            for cut in [full.bytes.len(), 900, 300] {
                let bytes = &full.bytes[..cut];
                let complete = cut == full.bytes.len();
                let wide = decode_as::<Vec<i32>>(&layout, bytes, complete, top).unwrap();
                let passes = wide.passes_completed;
                let wide = reconstructed(wide, w * h);
                let escaped = decode_as::<Narrow<true>>(&layout, bytes, complete, top).unwrap();
                assert_eq!(escaped.passes_completed, passes);
                assert_eq!(reconstructed(escaped, w * h), wide, "{cut} bytes");
                let plain = decode_as::<Narrow<false>>(&layout, bytes, complete, top);
                // The first pass shows the coefficient of plane 20.
                assert_eq!(plain.is_none(), wide_ones, "{cut} bytes");
                if let Some(plain) = plain {
                    assert_eq!(reconstructed(plain, w * h), wide, "{cut} bytes");
                }
            }
            if wide_ones {
                assert_eq!(
                    reconstructed(
                        decode_as::<Vec<i32>>(&layout, &full.bytes, true, top).unwrap(),
                        w * h
                    ),
                    c
                );
            }
        }
    }

    #[test]
    fn every_prefix_knows_exactly_the_planes_it_decoded() {
        let (w, h) = (40, 36);
        let layout = layout_for(w, h, 3, |s| s.level);
        let c = pseudo_random(w * h, 5, 9000);
        let full = unit_weight_encode(&layout, &c, None);
        let top = top_plane(&layout, &c);
        for cut in (1..=full.bytes.len()).step_by(7) {
            let complete = cut == full.bytes.len();
            let mut dec =
                decode_as::<Vec<i32>>(&layout, &full.bytes[..cut], complete, top).unwrap();
            let known = dec.values.clone();
            // Each significant coefficient as (its known magnitude, its lowest plane).
            dec.map_significant(|v, p| (v.unsigned_abs() << 5 | p) as i32);
            for (i, (&k, &packed)) in known.iter().zip(&dec.values).enumerate() {
                if k == 0 {
                    continue;
                }
                let p = packed as u32 & 31;
                let (m, truth) = (k.unsigned_abs(), c[i].unsigned_abs());
                // The bits below p are unknown (zero); the truth lies in [m, m + 2^p).
                assert_eq!(
                    m & ((1 << p) - 1),
                    0,
                    "{cut} bytes, coefficient {i}: plane {p}"
                );
                assert!((m..m + (1 << p)).contains(&truth), "{cut} bytes, {i}");
                assert_eq!(k < 0, c[i] < 0);
            }
        }
    }

    #[test]
    fn lossless_round_trip_assorted_shapes() {
        for &(w, h, levels) in &[
            (1, 1, 0),
            (5, 1, 2),
            (1, 7, 3),
            (13, 9, 2),
            (64, 64, 4),
            (37, 50, 5),
        ] {
            let c = pseudo_random(w * h, (w * 31 + h) as u64, 5000);
            round_trip(w, h, levels, &c, |_| 0);
            round_trip(w, h, levels, &c, |s| s.level);
        }
    }

    /// The complete stream of `coefficients` coded by `coder`, and its top plane.
    fn encode_with(
        layout: &CoefficientLayout,
        coefficients: &[i32],
        coder: Coder,
    ) -> (Vec<u8>, Option<u32>) {
        let descendants = descendant_masks(layout, coefficients);
        let weights = vec![0.0; layout.bands.len()];
        let side = measuring_side(
            ArithmeticEncoder::new(),
            coefficients,
            &descendants,
            &weights,
        );
        let mut contexts = Contexts::new(coder, ContextChoice::ALL);
        let top = top_plane(layout, coefficients);
        let (side, _, _) = run_encoder(layout, side, top, &mut contexts);
        (side.sink.finish(), top)
    }

    #[test]
    fn every_coder_round_trips_and_coders_3_and_4_agree_at_pass_ends() {
        let (w, h, levels) = (45, 38, 3);
        let c = pseudo_random(w * h, 11, 6000);
        let layout = layout_for(w, h, levels, |s| s.level);
        let decode = |coder, bytes: &[u8], top, passes| {
            Decoder::run(&layout, coder, bytes, true, top, passes).integer_coefficients()
        };
        let mut streams = Vec::new();
        for coder in [Coder::V1, Coder::V2, Coder::V3, Coder::V4] {
            let (bytes, top) = encode_with(&layout, &c, coder);
            assert_eq!(decode(coder, &bytes, top, None), c, "{coder:?}");
            streams.push((bytes, top));
        }
        let ((v3, top), (v4, _)) = (&streams[2], &streams[3]);
        assert_ne!(v3, v4, "the propagation scan reorders decisions");
        // A complete pass carries the same information in either order.
        for passes in 1..=top.unwrap() + 1 {
            assert_eq!(
                decode(Coder::V3, v3, *top, Some(passes)),
                decode(Coder::V4, v4, *top, Some(passes)),
                "after {passes} passes"
            );
        }
    }

    #[test]
    fn all_zero_coefficients() {
        round_trip(8, 8, 2, &[0; 64], |_| 0);
    }

    #[test]
    fn prefixes_decode_and_error_never_grows() {
        let (w, h, levels) = (40, 30, 3);
        let c = pseudo_random(w * h, 7, 3000);
        let layout = layout_for(w, h, levels, |s| s.level);
        let enc = unit_weight_encode(&layout, &c, None);
        let mut previous = f64::INFINITY;
        for cut in (0..=enc.bytes.len()).step_by(7).chain([enc.bytes.len()]) {
            let complete = cut == enc.bytes.len();
            let dec = Decoder::run(
                &layout,
                Coder::default(),
                &enc.bytes[..cut],
                complete,
                top_plane(&layout, &c),
                None,
            );
            let rec = dec.integer_coefficients();
            let err: f64 = rec
                .iter()
                .zip(&c)
                .map(|(&a, &b)| ((a - b) as f64).powi(2))
                .sum();
            // Mid-interval reconstruction: error is non-increasing at pass granularity;
            // allow the small wobble of single decisions inside a pass.
            assert!(
                err <= previous * 1.05 + 1.0,
                "cut {cut}: {err} after {previous}"
            );
            previous = previous.min(err);
        }
        assert_eq!(previous, 0.0);
    }

    #[test]
    fn budget_stops_early_and_prefix_is_consistent() {
        let (w, h) = (64, 64);
        let c = pseudo_random(w * h, 3, 20000);
        let layout = layout_for(w, h, 4, |_| 0);
        let full = unit_weight_encode(&layout, &c, None);
        let cut = unit_weight_encode(&layout, &c, Some(500));
        assert!(!cut.complete);
        assert!(cut.bytes.len() >= 500 && cut.bytes.len() < full.bytes.len());
        assert_eq!(&cut.bytes[..500], &full.bytes[..500]);
    }

    #[test]
    fn pass_records_track_true_error() {
        let (w, h) = (32, 32);
        let c = pseudo_random(w * h, 5, 4000);
        let layout = layout_for(w, h, 3, |_| 0);
        let enc = unit_weight_encode(&layout, &c, None);
        for (k, record) in enc.passes.iter().enumerate() {
            let dec = Decoder::run(
                &layout,
                Coder::default(),
                &enc.bytes,
                true,
                top_plane(&layout, &c),
                Some(k as u32 + 1),
            );
            let rec = dec.integer_coefficients();
            let err: f64 = rec
                .iter()
                .zip(&c)
                .map(|(&a, &b)| ((a - b) as f64).powi(2))
                .sum();
            assert!(
                (err - record.squared_error).abs() <= 1e-6 * err.max(1.0),
                "pass {k}: {err} vs {}",
                record.squared_error
            );
            // The recorded byte count suffices to decode the whole pass.
            let prefix = Decoder::run(
                &layout,
                Coder::default(),
                &enc.bytes[..record.end_byte as usize],
                record.end_byte as usize == enc.bytes.len(),
                top_plane(&layout, &c),
                Some(k as u32 + 1),
            );
            assert_eq!(prefix.passes_completed, k as u32 + 1);
        }
        assert_eq!(enc.passes.last().unwrap().squared_error, 0.0);
    }

    #[test]
    fn checkpoints_track_the_error_of_their_prefixes() {
        let (w, h) = (64, 64);
        let c = pseudo_random(w * h, 9, 30000);
        let layout = layout_for(w, h, 4, |_| 0);
        let enc = unit_weight_encode(&layout, &c, None);
        assert!(
            enc.checkpoints.len() > 2 * enc.passes.len(),
            "{}",
            enc.checkpoints.len()
        );
        let mut last = (0, f64::INFINITY);
        for &(end, estimate) in &enc.checkpoints {
            assert!(
                end > last.0 && estimate <= last.1,
                "{end} {estimate} after {last:?}"
            );
            last = (end, estimate);
            let prefix = &enc.bytes[..end as usize];
            let dec = Decoder::run(
                &layout,
                Coder::default(),
                prefix,
                false,
                top_plane(&layout, &c),
                None,
            );
            let err: f64 = dec
                .integer_coefficients()
                .iter()
                .zip(&c)
                .map(|(&a, &b)| ((a - b) as f64).powi(2))
                .sum();
            // The prefix may hold a decision or two past the checkpoint.
            assert!(
                (err - estimate).abs() <= 0.02 * estimate + 1.0,
                "prefix of {end} bytes: error {err}, checkpoint says {estimate}"
            );
        }
    }
}
