//! Lifting wavelet transforms: the reversible integer LeGall 5/3 and 13/11 and the CDF 9/7.
//!
//! # Layout and conventions
//!
//! * Images are flat row-major buffers, `data[y * width + x]`, transformed in place into
//!   the Mallat (pyramid) layout.
//! * One level transforms the current low-pass region (initially the whole image,
//!   `lw × lh`): first every row of the region (a 1-D transform over `lw` samples), then
//!   every column of the region (over `lh` samples). The next level works on the
//!   `ceil(lw/2) × ceil(lh/2)` top-left region.
//! * The 1-D transform of `n` samples writes the low-pass outputs (computed at the
//!   even-indexed samples, `ceil(n/2)` of them) first and the high-pass outputs (odd
//!   indices, `floor(n/2)`) after them. A single sample (`n = 1`) is left unchanged.
//! * Borders use whole-sample symmetric extension (mirror without repeating the edge
//!   sample: `x[-1] = x[1]`, `x[n] = x[n-2]`), as JPEG 2000 Part 1 does. Any size ≥ 1
//!   works, odd sizes and 1×N / N×1 included.
//! * Subbands are described by [`subbands`], coarse to fine; level 1 is the finest.
//!
//! # The three wavelets
//!
//! * [`forward_53`] / [`inverse_53`]: the JPEG 2000 reversible 5/3 on `i32`, exactly
//!   invertible (bit for bit). See [`forward_53`] for the safe input range.
//! * [`forward_1311`] / [`inverse_1311`]: the reversible 13/11, the 5/3 with a 6-tap
//!   predict (smooth terrain is predicted better: lossless files 1.6–6.2 % smaller), on
//!   `i32`, exactly invertible.
//! * [`forward_97`] / [`inverse_97`]: CDF 9/7 lifting on `f32` data (each 1-D pass is
//!   computed in `f64` and stored back as `f32`), scaled so the transform is close to
//!   orthonormal (analysis low-pass DC gain √2, high-pass Nyquist gain √2): coefficient
//!   energy ≈ pixel energy and every synthesis basis function has L2 norm ≈ 1.
//!
//! # Implementation notes
//!
//! Rows are de-interleaved into a scratch buffer, lifted there and copied back. Columns
//! are processed in strips of 32 adjacent columns: the strip is gathered (already
//! de-interleaved) into a scratch buffer where each lifting step is one flat, vectorisable
//! loop over all lanes, then scattered back. Scratch memory is allocated once per call.

mod in_place;
mod support;

use std::collections::BTreeMap;

pub use in_place::inverse_97_i16;
pub(crate) use support::zero_unreached;

/// Which wavelet a stream uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Wavelet {
    /// CDF 9/7 biorthogonal, floating point, lossy.
    Cdf97,
    /// Reversible integer 5/3 (LeGall), lossless.
    Int53,
    /// Reversible integer 13/11, lossless: the (6, 2) interpolating transform of
    /// Calderbank, Daubechies, Sweldens and Yeo (a 6-tap Deslauriers–Dubuc predict, the
    /// 5/3's update). What new lossless and max-error streams use where it codes smaller
    /// than the 5/3 (see `EncodeOptions::adaptive_wavelet`).
    Int1311,
}

impl Wavelet {
    /// The byte that identifies this wavelet in a stream: `Cdf97` = 1, `Int53` = 2,
    /// `Int1311` = 3.
    pub fn code(self) -> u8 {
        match self {
            Wavelet::Cdf97 => 1,
            Wavelet::Int53 => 2,
            Wavelet::Int1311 => 3,
        }
    }

    /// The wavelet identified by `code` (see [`Wavelet::code`]), or `None` if unknown.
    pub fn from_code(code: u8) -> Option<Wavelet> {
        match code {
            1 => Some(Wavelet::Cdf97),
            2 => Some(Wavelet::Int53),
            3 => Some(Wavelet::Int1311),
            _ => None,
        }
    }

    /// Short human-readable name: `"9/7"`, `"5/3"` or `"13/11"`.
    pub fn name(self) -> &'static str {
        match self {
            Wavelet::Cdf97 => "9/7",
            Wavelet::Int53 => "5/3",
            Wavelet::Int1311 => "13/11",
        }
    }

    /// Whether the transform maps integers to integers exactly (5/3, 13/11): lossless
    /// and max-error streams.
    pub fn is_reversible(self) -> bool {
        self != Wavelet::Cdf97
    }
}

/// Orientation of a subband.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Orientation {
    /// Low-pass in both directions (only at the coarsest level).
    LL,
    /// High-pass horizontally (vertical edges), right of LL.
    HL,
    /// High-pass vertically (horizontal edges), below LL.
    LH,
    /// High-pass in both directions.
    HH,
}

/// One subband's rectangle inside the transformed buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Subband {
    /// Decomposition level, 1 = finest, `levels` = coarsest (0 for the untransformed image).
    pub level: u32,
    /// Orientation.
    pub orientation: Orientation,
    /// Left column of the subband in the buffer.
    pub x0: usize,
    /// Top row of the subband in the buffer.
    pub y0: usize,
    /// Columns (may be 0).
    pub width: usize,
    /// Rows (may be 0).
    pub height: usize,
}

/// Number of adjacent columns lifted together in the vertical pass.
const STRIP: usize = 32;

/// Largest side the LL region may keep with [`default_levels`].
const DEFAULT_LL_SIDE: usize = 8;

/// Number of levels after which the LL region is 1×1: `ceil(log2(max(width, height)))`
/// (0 for a 1×1 or empty image). Every transform accepts `0..=max_levels` levels.
pub fn max_levels(width: usize, height: usize) -> u32 {
    let mut n = width.max(height);
    let mut levels = 0;
    while n > 1 {
        n = n.div_ceil(2);
        levels += 1;
    }
    levels
}

/// Default number of levels: the smallest `L` for which the LL region's larger side is at
/// most 8, capped by [`max_levels`] (2000×2000 → 8, 9×9 → 1, 8×8 → 0, 1×1 → 0).
pub fn default_levels(width: usize, height: usize) -> u32 {
    let mut n = width.max(height);
    let mut levels = 0;
    while n > DEFAULT_LL_SIDE {
        n = n.div_ceil(2);
        levels += 1;
    }
    levels.min(max_levels(width, height))
}

/// Subbands of a `levels`-level decomposition of a `width × height` image, coarse to fine:
/// `LL_L, HL_L, LH_L, HH_L, HL_{L-1}, LH_{L-1}, HH_{L-1}, …, HL_1, LH_1, HH_1`.
///
/// At level `l`, with the region `lw × lh` being transformed and `cw = ceil(lw/2)`,
/// `ch = ceil(lh/2)`: HL = (`cw`, 0, `lw - cw`, `ch`), LH = (0, `ch`, `cw`, `lh - ch`),
/// HH = (`cw`, `ch`, `lw - cw`, `lh - ch`), and LL (coarsest level only) = (0, 0, `cw`, `ch`),
/// written as (x0, y0, width, height). Empty subbands of thin images are listed too. The
/// subbands tile the buffer exactly. `levels = 0` gives a single level-0 LL subband.
pub fn subbands(width: usize, height: usize, levels: u32) -> Vec<Subband> {
    let regions = regions(width, height, levels);
    let mut out = Vec::with_capacity(1 + 3 * levels as usize);
    let &(llw, llh) = regions.last().expect("regions is never empty");
    out.push(Subband {
        level: levels,
        orientation: Orientation::LL,
        x0: 0,
        y0: 0,
        width: llw,
        height: llh,
    });
    for level in (1..=levels).rev() {
        let (lw, lh) = regions[level as usize - 1];
        let (cw, ch) = (lw.div_ceil(2), lh.div_ceil(2));
        let band = |orientation, x0, y0, width, height| Subband {
            level,
            orientation,
            x0,
            y0,
            width,
            height,
        };
        out.push(band(Orientation::HL, cw, 0, lw - cw, ch));
        out.push(band(Orientation::LH, 0, ch, cw, lh - ch));
        out.push(band(Orientation::HH, cw, ch, lw - cw, lh - ch));
    }
    out
}

/// Forward reversible 5/3 (JPEG 2000 LeGall lifting) of a `width × height` image, in place.
///
/// Per 1-D transform: `d[n] = x[2n+1] - ((x[2n] + x[2n+2]) >> 1)`, then
/// `s[n] = x[2n] + ((d[n-1] + d[n] + 2) >> 2)`, with symmetric extension.
///
/// # Input range
///
/// The arithmetic wraps on overflow, so [`inverse_53`] restores *any* `i32` input bit for
/// bit. The coefficients equal the mathematical (non-wrapping) 5/3 transform whenever
/// `|x| ≤ 2^26` for any number of levels: the worst-case (ℓ1) gains of the equivalent
/// 5/3 analysis filters converge with depth (1-D low ≤ 1.72, high ≤ 2.87), so a coefficient
/// is at most ≈ 8.3·max|x| and the largest intermediate sum (`d[n-1] + d[n] + 2` in the
/// HH column pass) at most ≈ 16.6·max|x| plus a few units of rounding, which stays below
/// `2^31` for `|x| ≤ 2^26` with a margin of almost 2. Smooth data (terrain) grows far
/// less: the LL gain is exactly 1 per level.
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn forward_53(data: &mut [i32], width: usize, height: usize, levels: u32) {
    check_args(data.len(), width, height, levels);
    forward_2d(&Int53Kernel, data, width, height, levels);
}

/// Inverse of [`forward_53`]: exact reconstruction, bit for bit.
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn inverse_53(data: &mut [i32], width: usize, height: usize, levels: u32) {
    check_args(data.len(), width, height, levels);
    inverse_2d(&Int53Kernel, data, width, height, levels, &mut NoSpill);
}

/// The inverse of the reversible `wavelet` ([`inverse_53`], [`inverse_1311`]; 5/3 for
/// the 9/7) on coefficients stored as `i16`, lifted in `i32` line buffers, with the
/// values that do not fit in an `i16` (coefficients, each level's outputs) kept in
/// `spilled` by index (their slots in `data` are left as they are): on input, the
/// coefficients whose value is there; on output, the samples. Returns false, `data`
/// unfinished, when `spilled` would hold more than [`max_spilled`] values; else `data`
/// with `spilled` is what the `i32` inverse makes of the same coefficients.
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn inverse_integer_i16(
    wavelet: Wavelet,
    data: &mut [i16],
    spilled: &mut BTreeMap<usize, i32>,
    width: usize,
    height: usize,
    levels: u32,
) -> bool {
    check_args(data.len(), width, height, levels);
    let cap = max_spilled(data.len());
    let mut spill = SpillMap { map: spilled, cap };
    spill.map.len() <= cap
        && match wavelet {
            Wavelet::Int1311 => inverse_2d(&Int1311Kernel, data, width, height, levels, &mut spill),
            Wavelet::Int53 | Wavelet::Cdf97 => {
                inverse_2d(&Int53Kernel, data, width, height, levels, &mut spill)
            }
        }
}

/// Forward reversible 13/11 of a `width × height` image, in place.
///
/// Per 1-D transform, the predict `d[n] = x[2n+1] − ((150·(x[2n] + x[2n+2]) −
/// 25·(x[2n−2] + x[2n+4]) + 3·(x[2n−4] + x[2n+6]) + 128) >> 8)`, then the 5/3's update
/// `s[n] = x[2n] + ((d[n-1] + d[n] + 2) >> 2)`, with symmetric extension. The
/// arithmetic wraps, so [`inverse_1311`] restores any `i32` input bit for bit; the
/// coefficients equal the
/// mathematical transform while the predict's sums stay below `2^31`, which
/// [`MAX_EXACT_1311`] ensures: a sum is at most 356 times the values it reads, those at
/// most 2.39 times (the ℓ1 norm of the 1-D high-pass, 1.5 for the low-pass) the
/// region's samples, and those at most 2.43 times the image's (the 2-D low-pass's ℓ1
/// gain through any number of levels), so `|x| ≤ 2^19` stays below `2^31` with a margin
/// of almost 2.
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn forward_1311(data: &mut [i32], width: usize, height: usize, levels: u32) {
    check_args(data.len(), width, height, levels);
    forward_2d(&Int1311Kernel, data, width, height, levels);
}

/// Largest sample magnitude whose [`forward_1311`] is the mathematical transform.
pub const MAX_EXACT_1311: i32 = 1 << 19;

/// Inverse of [`forward_1311`]: exact reconstruction, bit for bit.
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn inverse_1311(data: &mut [i32], width: usize, height: usize, levels: u32) {
    check_args(data.len(), width, height, levels);
    inverse_2d(&Int1311Kernel, data, width, height, levels, &mut NoSpill);
}

/// [`forward_1311`] for [`Wavelet::Int1311`], else [`forward_53`] (the 9/7 has no
/// integer form; callers pass a reversible wavelet), the invalid samples of `valid` (a
/// mask of the image, `None` when every sample is valid) given the values their row
/// neighbours predict: the finest level's row high-pass is zero there.
///
/// The finest rows' predict step is the last step of the inverse, so an odd sample's
/// value changes nothing but that sample and its high-pass output. Every other step's
/// outputs feed other samples' reconstruction, so only this one is free: zeroing at voids
/// in every pass is not lossless, and restoring the valid samples after each inverse
/// (repeated) codes more, not less (README, *Voids predicted by their row*).
pub(crate) fn forward_integer(
    wavelet: Wavelet,
    data: &mut [i32],
    (width, height): (usize, usize),
    levels: u32,
    valid: Option<&[bool]>,
) {
    match (wavelet, valid) {
        (Wavelet::Int1311, None) => forward_1311(data, width, height, levels),
        (_, None) => forward_53(data, width, height, levels),
        (Wavelet::Int1311, Some(_)) => {
            check_args(data.len(), width, height, levels);
            forward_2d_around(&Int1311Kernel, data, width, height, levels, valid);
        }
        (_, Some(_)) => {
            check_args(data.len(), width, height, levels);
            forward_2d_around(&Int53Kernel, data, width, height, levels, valid);
        }
    }
}

/// [`inverse_1311`] for [`Wavelet::Int1311`], else [`inverse_53`].
pub(crate) fn inverse_integer(
    wavelet: Wavelet,
    data: &mut [i32],
    width: usize,
    height: usize,
    levels: u32,
) {
    match wavelet {
        Wavelet::Int1311 => inverse_1311(data, width, height, levels),
        Wavelet::Int53 | Wavelet::Cdf97 => inverse_53(data, width, height, levels),
    }
}

/// Most values [`inverse_integer_i16`] keeps beside `n` samples: one in 64 (and 64).
pub fn max_spilled(n: usize) -> usize {
    n / 64 + 64
}

/// Forward CDF 9/7 of a `width × height` image, in place.
///
/// Four lifting steps (α, β, γ, δ) followed by scaling the low-pass outputs by `√2/K` and
/// the high-pass outputs by `K/√2` (`K ≈ 1.2302`), so the analysis low-pass has DC gain √2
/// and the high-pass Nyquist gain √2: the 2-D transform is close to orthonormal.
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn forward_97(data: &mut [f32], width: usize, height: usize, levels: u32) {
    check_args(data.len(), width, height, levels);
    forward_2d(&CDF97, data, width, height, levels);
}

/// Inverse of [`forward_97`], exact up to `f32` rounding: every pass stores its outputs as
/// `f32`, so a round trip is off by a few units in the last place of the data's magnitude
/// (measured on 2000×2000 terrain-like data of magnitude ≤ 1e4, 8 levels: max 4.9e-3,
/// RMS 7.7e-4, where one ulp at 1e4 is 9.8e-4).
///
/// # Panics
///
/// If `data.len() != width * height` or `levels > max_levels(width, height)`.
pub fn inverse_97(data: &mut [f32], width: usize, height: usize, levels: u32) {
    check_args(data.len(), width, height, levels);
    inverse_2d(&CDF97, data, width, height, levels, &mut NoSpill);
}

/// Synthesis L2 norms per subband, in [`subbands`] order: for each subband, the L2 norm of
/// the image obtained by inverse-transforming a single unit coefficient placed in the middle
/// of that subband (at `(x0 + width/2, y0 + height/2)`). Empty subbands get 0.
///
/// The norms weight subbands by their contribution to pixel-domain squared error. For 9/7
/// they are all close to 1; for 5/3 (computed with the real-valued 5/3 filters, i.e. the
/// same lifting without rounding) they grow with the level, LL fastest (≈ 2 per level).
///
/// Each level transforms rows and columns separably, so every synthesis basis function is
/// the outer product of two 1-D pyramid basis functions and its norm is the product of
/// their norms: the result is exact for the real image size and costs
/// `O((width + height) · levels)`. Deterministic.
///
/// In subbands many coefficients wide the middle coefficient is interior, so the value is
/// the interior one (9/7 on 2000×2000, 8 levels: 0.97–1.09). In subbands only one or two
/// coefficients wide every coefficient touches the border and the value says so (9/7 on
/// 64×64 with 6 levels: up to 1.63).
///
/// # Panics
///
/// If `levels > max_levels(width, height)`.
pub fn synthesis_norms(wavelet: Wavelet, width: usize, height: usize, levels: u32) -> Vec<f64> {
    assert!(
        levels <= max_levels(width, height),
        "{levels} levels exceed the maximum {} for {width}x{height}",
        max_levels(width, height)
    );
    let unit_norm = |n: usize, level: u32, pos: usize| match wavelet {
        Wavelet::Cdf97 => unit_norm_1d(&CDF97, n, level, pos),
        Wavelet::Int53 => unit_norm_1d(&REAL53, n, level, pos),
        Wavelet::Int1311 => unit_norm_1d(&Real1311, n, level, pos),
    };
    subbands(width, height, levels)
        .iter()
        .map(|band| {
            if band.width == 0 || band.height == 0 {
                return 0.0;
            }
            let x = band.x0 + band.width / 2;
            let y = band.y0 + band.height / 2;
            unit_norm(width, band.level, x) * unit_norm(height, band.level, y)
        })
        .collect()
}

/// The norms the coder weighs subbands by: [`synthesis_norms`], with empty subbands (which
/// have no norm to speak of) given 1 so shifts and scales stay sane.
pub fn coding_norms(wavelet: Wavelet, width: usize, height: usize, levels: u32) -> Vec<f64> {
    synthesis_norms(wavelet, width, height, levels)
        .into_iter()
        .map(|n| if n.is_finite() && n > 0.0 { n } else { 1.0 })
        .collect()
}

/// How the 5/3 coder rounds each subband's norm, relative to the smallest, to whole
/// bit-planes: the order in which a lossless stream's prefixes refine the subbands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ShiftRule {
    /// `round(log2(norm / smallest))` (files written before [`ShiftRule::Lowered`]).
    #[default]
    Rounded,
    /// `round(log2(norm / smallest) − 1/4)`: the finest horizontal and vertical subbands
    /// (norms 2^0.53 the finest diagonal's) share its planes instead of going a plane
    /// ahead, which suits their rate: prefixes gain up to 1 dB, lossless files 0.1–0.5 %.
    Lowered,
}

/// The 5/3 coder's per-subband plane shifts: each norm relative to the smallest, in whole
/// bit-planes as `rule` rounds them.
pub fn plane_shifts(norms: &[f64], rule: ShiftRule) -> Vec<u32> {
    let smallest = norms.iter().cloned().fold(f64::INFINITY, f64::min);
    let bias = match rule {
        ShiftRule::Rounded => 0.0,
        ShiftRule::Lowered => -0.25,
    };
    norms
        .iter()
        .map(|&n| ((n / smallest).log2() + bias).round().max(0.0) as u32)
        .collect()
}

/// L2 norm of the 1-D signal of length `n` synthesised from a unit coefficient at `pos` of
/// a `levels`-level 1-D pyramid.
fn unit_norm_1d<K: Kernel<f64>>(kernel: &K, n: usize, levels: u32, pos: usize) -> f64 {
    let mut buf = vec![0.0f64; n];
    buf[pos] = 1.0;
    inverse_2d(kernel, &mut buf, n, 1, levels, &mut NoSpill);
    buf.iter().map(|v| v * v).sum::<f64>().sqrt()
}

fn check_args(len: usize, width: usize, height: usize, levels: u32) {
    assert!(
        width.checked_mul(height) == Some(len),
        "buffer of {len} samples for a {width}x{height} image"
    );
    assert!(
        levels <= max_levels(width, height),
        "{levels} levels exceed the maximum {} for {width}x{height}",
        max_levels(width, height)
    );
}

/// Region sizes: `[0]` is the whole image, `[l]` the LL region after `l` levels.
fn regions(width: usize, height: usize, levels: u32) -> Vec<(usize, usize)> {
    let mut out = Vec::with_capacity(levels as usize + 1);
    let (mut w, mut h) = (width, height);
    out.push((w, h));
    for _ in 0..levels {
        w = w.div_ceil(2);
        h = h.div_ceil(2);
        out.push((w, h));
    }
    out
}

// ---------------------------------------------------------------------------------------
// 1-D lifting on de-interleaved lanes
// ---------------------------------------------------------------------------------------

/// A 1-D lifting transform acting on de-interleaved data.
///
/// `lo` holds the even-indexed samples and `hi` the odd-indexed ones, each as `lanes`
/// interleaved independent signals: sample `i` of lane `k` is at `i * lanes + k`. So
/// `lo.len() = ceil(n/2) * lanes` and `hi.len() = floor(n/2) * lanes` for signals of `n`
/// samples. On return `lo` holds the low-pass and `hi` the high-pass outputs.
trait Kernel<T> {
    /// Analysis, `after_predict` applied to the high-pass outputs right after the first
    /// predict step (where each still depends on its own odd sample and the even ones
    /// only: changing one there is changing that odd sample).
    fn analyze_then(
        &self,
        lo: &mut [T],
        hi: &mut [T],
        lanes: usize,
        after_predict: impl FnOnce(&mut [T]),
    );
    fn synthesize(&self, lo: &mut [T], hi: &mut [T], lanes: usize);

    #[inline(always)]
    fn analyze(&self, lo: &mut [T], hi: &mut [T], lanes: usize) {
        self.analyze_then(lo, hi, lanes, |_| {});
    }
}

/// Predict step: `hi[i] = f(hi[i], lo[i], lo[i+1])`, with `lo[nl] = lo[nl-1]` (symmetric
/// extension: `x[n] = x[n-2]` when `n` is even).
#[inline(always)]
fn predict<T: Copy>(lo: &[T], hi: &mut [T], lanes: usize, f: impl Fn(T, T, T) -> T) {
    let nl = lo.len() / lanes;
    let nh = hi.len() / lanes;
    if nh == 0 {
        return;
    }
    let inner = (nl - 1).min(nh) * lanes;
    for ((h, &a), &b) in hi[..inner]
        .iter_mut()
        .zip(&lo[..inner])
        .zip(&lo[lanes..lanes + inner])
    {
        *h = f(*h, a, b);
    }
    if nh == nl {
        for (h, &a) in hi[inner..].iter_mut().zip(&lo[inner..]) {
            *h = f(*h, a, a);
        }
    }
}

/// Update step: `lo[i] = f(lo[i], hi[i-1], hi[i])`, with `hi[-1] = hi[0]` and
/// `hi[nh] = hi[nh-1]` (symmetric extension: `x[-1] = x[1]`, `x[n] = x[n-2]` when `n` is
/// odd).
#[inline(always)]
fn update<T: Copy>(lo: &mut [T], hi: &[T], lanes: usize, f: impl Fn(T, T, T) -> T) {
    let nl = lo.len() / lanes;
    let nh = hi.len() / lanes;
    if nh == 0 {
        return;
    }
    for (l, &d) in lo[..lanes].iter_mut().zip(&hi[..lanes]) {
        *l = f(*l, d, d);
    }
    let inner = (nh - 1) * lanes;
    for ((l, &a), &b) in lo[lanes..lanes + inner]
        .iter_mut()
        .zip(&hi[..inner])
        .zip(&hi[lanes..lanes + inner])
    {
        *l = f(*l, a, b);
    }
    if nl > nh {
        for (l, &d) in lo[nh * lanes..].iter_mut().zip(&hi[inner..]) {
            *l = f(*l, d, d);
        }
    }
}

/// Predict step over six low-pass neighbours: `hi[i] = f(hi[i], [lo[i−2], …, lo[i+3]])`,
/// a neighbour out of range taken where whole-sample symmetric extension of the signal
/// puts it ([`mirrored_low`]). The interior is one flat loop over every lane.
#[inline(always)]
fn predict6<T: Copy>(lo: &[T], hi: &mut [T], lanes: usize, f: impl Fn(T, [T; 6]) -> T) {
    let nl = lo.len() / lanes;
    let nh = hi.len() / lanes;
    let interior = 2..nh.min(nl.saturating_sub(3)).max(2);
    for i in (0..nh).filter(|i| !interior.contains(i)) {
        let taps: [usize; 6] =
            std::array::from_fn(|t| mirrored_low(i as isize + t as isize - 2, nl + nh));
        for k in 0..lanes {
            let h = &mut hi[i * lanes + k];
            *h = f(*h, taps.map(|j| lo[j * lanes + k]));
        }
    }
    let (first, end) = (interior.start * lanes, interior.end * lanes);
    if first >= end {
        return;
    }
    let len = end - first;
    let tap = |t: usize| &lo[first + t * lanes - 2 * lanes..][..len];
    let (l0, l1, l2, l3, l4, l5) = (tap(0), tap(1), tap(2), tap(3), tap(4), tap(5));
    for (j, h) in hi[first..end].iter_mut().enumerate() {
        *h = f(*h, [l0[j], l1[j], l2[j], l3[j], l4[j], l5[j]]);
    }
}

/// The index in the low-pass half of even sample `2j` of a signal of `n ≥ 2` samples,
/// `j` possibly out of range: whole-sample symmetric extension (`x[−k] = x[k]`,
/// `x[n−1+k] = x[n−1−k]`), repeated for signals shorter than the reach.
fn mirrored_low(j: isize, n: usize) -> usize {
    let last = n as isize - 1;
    let mut x = 2 * j;
    while x < 0 || x > last {
        x = if x < 0 { -x } else { 2 * last - x };
    }
    (x / 2) as usize
}

/// The 5/3's (and 13/11's) integer update of a low-pass sample from its two high-pass
/// neighbours `a`, `b`.
#[inline(always)]
fn integer_update(a: i32, b: i32) -> i32 {
    a.wrapping_add(b).wrapping_add(2) >> 2
}

/// The JPEG 2000 reversible 5/3 (wrapping arithmetic, see [`forward_53`]).
struct Int53Kernel;

impl Kernel<i32> for Int53Kernel {
    fn analyze_then(
        &self,
        lo: &mut [i32],
        hi: &mut [i32],
        lanes: usize,
        after_predict: impl FnOnce(&mut [i32]),
    ) {
        predict(lo, hi, lanes, |h, a, b| {
            h.wrapping_sub(a.wrapping_add(b) >> 1)
        });
        after_predict(hi);
        update(lo, hi, lanes, |l, a, b| {
            l.wrapping_add(integer_update(a, b))
        });
    }

    fn synthesize(&self, lo: &mut [i32], hi: &mut [i32], lanes: usize) {
        update(lo, hi, lanes, |l, a, b| {
            l.wrapping_sub(integer_update(a, b))
        });
        predict(lo, hi, lanes, |h, a, b| {
            h.wrapping_add(a.wrapping_add(b) >> 1)
        });
    }
}

/// The reversible 13/11 (wrapping arithmetic, see [`forward_1311`]).
struct Int1311Kernel;

/// The 13/11's integer prediction of an odd sample from its six even neighbours `s`
/// (`x[2n−4]`, …, `x[2n+6]`): Deslauriers–Dubuc's `(3, −25, 150, 150, −25, 3) / 256`,
/// rounded.
#[inline(always)]
fn integer_predict_1311(s: [i32; 6]) -> i32 {
    let near = s[2].wrapping_add(s[3]).wrapping_mul(150);
    let middle = s[1].wrapping_add(s[4]).wrapping_mul(25);
    let far = s[0].wrapping_add(s[5]).wrapping_mul(3);
    near.wrapping_sub(middle)
        .wrapping_add(far)
        .wrapping_add(128)
        >> 8
}

impl Kernel<i32> for Int1311Kernel {
    fn analyze_then(
        &self,
        lo: &mut [i32],
        hi: &mut [i32],
        lanes: usize,
        after_predict: impl FnOnce(&mut [i32]),
    ) {
        predict6(lo, hi, lanes, |h, s| {
            h.wrapping_sub(integer_predict_1311(s))
        });
        after_predict(hi);
        update(lo, hi, lanes, |l, a, b| {
            l.wrapping_add(integer_update(a, b))
        });
    }

    fn synthesize(&self, lo: &mut [i32], hi: &mut [i32], lanes: usize) {
        update(lo, hi, lanes, |l, a, b| {
            l.wrapping_sub(integer_update(a, b))
        });
        predict6(lo, hi, lanes, |h, s| {
            h.wrapping_add(integer_predict_1311(s))
        });
    }
}

/// The 13/11 without rounding (the linear part of [`Int1311Kernel`]), for its norms.
struct Real1311;

/// [`integer_predict_1311`] without rounding.
#[inline(always)]
fn real_predict_1311(s: [f64; 6]) -> f64 {
    (150.0 * (s[2] + s[3]) - 25.0 * (s[1] + s[4]) + 3.0 * (s[0] + s[5])) / 256.0
}

impl Kernel<f64> for Real1311 {
    fn analyze_then(
        &self,
        lo: &mut [f64],
        hi: &mut [f64],
        lanes: usize,
        after_predict: impl FnOnce(&mut [f64]),
    ) {
        predict6(lo, hi, lanes, |h, s| h - real_predict_1311(s));
        after_predict(hi);
        update(lo, hi, lanes, |l, a, b| l + 0.25 * (a + b));
    }

    fn synthesize(&self, lo: &mut [f64], hi: &mut [f64], lanes: usize) {
        update(lo, hi, lanes, |l, a, b| l - 0.25 * (a + b));
        predict6(lo, hi, lanes, |h, s| h + real_predict_1311(s));
    }
}

/// A linear (floating-point) lifting scheme: alternating predict / update steps
/// `x += c · (left + right)`, starting with a predict step, then scaling of both bands.
struct Linear {
    steps: &'static [f64],
    lo_gain: f64,
    hi_gain: f64,
}

/// CDF 9/7 lifting coefficients.
const ALPHA: f64 = -1.586_134_342_059_924;
const BETA: f64 = -0.052_980_118_572_961;
const GAMMA: f64 = 0.882_911_075_530_934;
const DELTA: f64 = 0.443_506_852_043_971;
/// DC gain of the 9/7 low-pass after the four lifting steps (and 2/K is the Nyquist gain
/// of the high-pass).
const K97: f64 = 1.230_174_104_914_001;

/// CDF 9/7, scaled to DC gain √2 (low) and Nyquist gain √2 (high).
const CDF97: Linear = Linear {
    steps: &[ALPHA, BETA, GAMMA, DELTA],
    lo_gain: std::f64::consts::SQRT_2 / K97,
    hi_gain: K97 / std::f64::consts::SQRT_2,
};

/// The 5/3 without rounding (the linear part of [`Int53Kernel`]).
const REAL53: Linear = Linear {
    steps: &[-0.5, 0.25],
    lo_gain: 1.0,
    hi_gain: 1.0,
};

impl Kernel<f64> for Linear {
    fn analyze_then(
        &self,
        lo: &mut [f64],
        hi: &mut [f64],
        lanes: usize,
        after_predict: impl FnOnce(&mut [f64]),
    ) {
        // A single sample (no high-pass) is passed through unchanged, unscaled.
        if hi.is_empty() {
            return;
        }
        let first = self.steps[0];
        predict(lo, hi, lanes, |h, a, b| h + first * (a + b));
        after_predict(hi);
        for (i, &c) in self.steps.iter().enumerate().skip(1) {
            if i % 2 == 0 {
                predict(lo, hi, lanes, |h, a, b| h + c * (a + b));
            } else {
                update(lo, hi, lanes, |l, a, b| l + c * (a + b));
            }
        }
        scale(lo, self.lo_gain);
        scale(hi, self.hi_gain);
    }

    fn synthesize(&self, lo: &mut [f64], hi: &mut [f64], lanes: usize) {
        if hi.is_empty() {
            return;
        }
        scale(lo, 1.0 / self.lo_gain);
        scale(hi, 1.0 / self.hi_gain);
        for (i, &c) in self.steps.iter().enumerate().rev() {
            if i % 2 == 0 {
                predict(lo, hi, lanes, |h, a, b| h - c * (a + b));
            } else {
                update(lo, hi, lanes, |l, a, b| l - c * (a + b));
            }
        }
    }
}

#[inline(always)]
fn scale(v: &mut [f64], g: f64) {
    if g != 1.0 {
        for x in v {
            *x *= g;
        }
    }
}

// ---------------------------------------------------------------------------------------
// 2-D driver
// ---------------------------------------------------------------------------------------

/// A stored sample type and the type the lifting is computed in (`f32` data is lifted in
/// `f64`, so the only `f32` rounding is the storage of each level's outputs).
trait Sample: Copy {
    type Work: Copy + Default;
    fn widen(self) -> Self::Work;
    fn narrow(w: Self::Work) -> Self;
    /// Whether `w` is stored exactly by [`Sample::narrow`] (checked by the inverse).
    #[inline(always)]
    fn fits(_w: Self::Work) -> bool {
        true
    }
}

impl Sample for i16 {
    type Work = i32;
    #[inline(always)]
    fn widen(self) -> i32 {
        i32::from(self)
    }
    #[inline(always)]
    fn narrow(w: i32) -> i16 {
        w as i16
    }
    #[inline(always)]
    fn fits(w: i32) -> bool {
        i32::from(w as i16) == w
    }
}

impl Sample for i32 {
    type Work = i32;
    #[inline(always)]
    fn widen(self) -> i32 {
        self
    }
    #[inline(always)]
    fn narrow(w: i32) -> i32 {
        w
    }
}

impl Sample for f32 {
    type Work = f64;
    #[inline(always)]
    fn widen(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn narrow(w: f64) -> f32 {
        w as f32
    }
}

impl Sample for f64 {
    type Work = f64;
    #[inline(always)]
    fn widen(self) -> f64 {
        self
    }
    #[inline(always)]
    fn narrow(w: f64) -> f64 {
        w
    }
}

#[inline(always)]
fn load<T: Sample>(dst: &mut [T::Work], src: &[T]) {
    for (d, &s) in dst.iter_mut().zip(src) {
        *d = s.widen();
    }
}

#[inline(always)]
fn store<T: Sample>(dst: &mut [T], src: &[T::Work]) {
    for (d, &s) in dst.iter_mut().zip(src) {
        *d = T::narrow(s);
    }
}

/// [`store`], returning whether every value fitted (see [`Sample::fits`]).
#[inline(always)]
fn store_fits<T: Sample>(dst: &mut [T], src: &[T::Work]) -> bool {
    let mut fits = true;
    for (d, &s) in dst.iter_mut().zip(src) {
        fits &= T::fits(s);
        *d = T::narrow(s);
    }
    fits
}

/// Scratch large enough for one row or one column strip of a `width × height` image.
fn scratch_for<T: Sample>(width: usize, height: usize) -> Vec<T::Work> {
    vec![T::Work::default(); width.max(height * STRIP.min(width))]
}

/// Forward transform of `levels` levels (no argument checks; extra levels on a 1×1
/// region are no-ops).
fn forward_2d<T: Sample, K: Kernel<T::Work>>(
    kernel: &K,
    data: &mut [T],
    width: usize,
    height: usize,
    levels: u32,
) {
    forward_2d_around(kernel, data, width, height, levels, None);
}

/// [`forward_2d`]; with `valid`, the finest rows' high-pass outputs at invalid (void)
/// samples are zeroed right after the predict step: the voids take the values their
/// neighbours predict, which changes no valid sample and codes nothing there.
fn forward_2d_around<T: Sample, K: Kernel<T::Work>>(
    kernel: &K,
    data: &mut [T],
    width: usize,
    height: usize,
    levels: u32,
    mut valid: Option<&[bool]>,
) {
    if width == 0 || height == 0 {
        return;
    }
    let mut scratch = scratch_for::<T>(width, height);
    for &(lw, lh) in regions(width, height, levels).iter().take(levels as usize) {
        rows_analyze(kernel, data, width, (lw, lh), &mut scratch, valid.take());
        cols_analyze(kernel, data, width, lw, lh, &mut scratch);
    }
}

/// Inverse of [`forward_2d`]; whether every value stored fitted (see [`Sample::fits`])
/// or `spill` kept it.
fn inverse_2d<T: Sample, K: Kernel<T::Work>>(
    kernel: &K,
    data: &mut [T],
    width: usize,
    height: usize,
    levels: u32,
    spill: &mut impl Spill<T::Work>,
) -> bool {
    if width == 0 || height == 0 {
        return true;
    }
    let mut scratch = scratch_for::<T>(width, height);
    let mut fits = true;
    for &(lw, lh) in regions(width, height, levels)
        .iter()
        .take(levels as usize)
        .rev()
    {
        let region = Region { width, lw, lh };
        fits = fits
            && cols_synthesize(kernel, data, region, &mut scratch, spill)
            && rows_synthesize(kernel, data, region, &mut scratch, spill);
    }
    fits
}

/// 1-D analysis of the first `lw` samples of the first `lh` rows; with `valid` (a mask
/// of the whole image), each high-pass output at an invalid odd sample is zeroed after
/// the predict step.
fn rows_analyze<T: Sample, K: Kernel<T::Work>>(
    kernel: &K,
    data: &mut [T],
    width: usize,
    (lw, lh): (usize, usize),
    scratch: &mut [T::Work],
    valid: Option<&[bool]>,
) {
    if lw < 2 {
        return;
    }
    let nl = lw.div_ceil(2);
    let (lo, rest) = scratch.split_at_mut(nl);
    let hi = &mut rest[..lw - nl];
    for (y, row) in data.chunks_exact_mut(width).take(lh).enumerate() {
        let row = &mut row[..lw];
        for ((pair, l), h) in row.chunks_exact(2).zip(lo.iter_mut()).zip(hi.iter_mut()) {
            *l = pair[0].widen();
            *h = pair[1].widen();
        }
        if lw % 2 == 1 {
            lo[nl - 1] = row[lw - 1].widen();
        }
        match valid {
            Some(valid) => {
                let row_valid = &valid[y * width..][..lw];
                kernel.analyze_then(lo, hi, 1, |hi| zero_at_voids(hi, row_valid));
            }
            None => kernel.analyze(lo, hi, 1),
        }
        store(&mut row[..nl], lo);
        store(&mut row[nl..], hi);
    }
}

/// Zeroes the high-pass outputs `hi` of a row whose odd samples `row_valid` says are
/// invalid.
#[inline(always)]
fn zero_at_voids<W: Default>(hi: &mut [W], row_valid: &[bool]) {
    for (h, pair) in hi.iter_mut().zip(row_valid.chunks_exact(2)) {
        if !pair[1] {
            *h = W::default();
        }
    }
}

/// A level's region: the first `lw` columns of the first `lh` rows of an image `width`
/// wide.
#[derive(Clone, Copy)]
struct Region {
    width: usize,
    lw: usize,
    lh: usize,
}

/// Inverse of [`rows_analyze`]; whether every value stored fitted or was spilled.
fn rows_synthesize<T: Sample, K: Kernel<T::Work>>(
    kernel: &K,
    data: &mut [T],
    Region { width, lw, lh }: Region,
    scratch: &mut [T::Work],
    spill: &mut impl Spill<T::Work>,
) -> bool {
    if lw < 2 {
        return true;
    }
    let nl = lw.div_ceil(2);
    let (lo, rest) = scratch.split_at_mut(nl);
    let hi = &mut rest[..lw - nl];
    for (y, row) in data.chunks_exact_mut(width).take(lh).enumerate() {
        let start = y * width;
        let row = &mut row[..lw];
        load(lo, &row[..nl]);
        load(hi, &row[nl..]);
        spill.patch(start, lo);
        spill.patch(start + nl, hi);
        kernel.synthesize(lo, hi, 1);
        let mut fits = true;
        for ((pair, &l), &h) in row.chunks_exact_mut(2).zip(lo.iter()).zip(hi.iter()) {
            fits &= T::fits(l) & T::fits(h);
            pair[0] = T::narrow(l);
            pair[1] = T::narrow(h);
        }
        if lw % 2 == 1 {
            fits &= T::fits(lo[nl - 1]);
            row[lw - 1] = T::narrow(lo[nl - 1]);
        }
        if !(spill.settle(start, 2, lo, fits) && spill.settle(start + 1, 2, hi, fits)) {
            return false;
        }
    }
    true
}

/// 1-D analysis of the first `lh` samples of the first `lw` columns, [`STRIP`] columns at
/// a time.
fn cols_analyze<T: Sample, K: Kernel<T::Work>>(
    kernel: &K,
    data: &mut [T],
    width: usize,
    lw: usize,
    lh: usize,
    scratch: &mut [T::Work],
) {
    if lh < 2 {
        return;
    }
    let nl = lh.div_ceil(2);
    let nh = lh - nl;
    let mut x0 = 0;
    while x0 < lw {
        let lanes = STRIP.min(lw - x0);
        let (lo, rest) = scratch.split_at_mut(nl * lanes);
        let hi = &mut rest[..nh * lanes];
        for (i, dst) in lo.chunks_exact_mut(lanes).enumerate() {
            let src = 2 * i * width + x0;
            load(dst, &data[src..src + lanes]);
        }
        for (i, dst) in hi.chunks_exact_mut(lanes).enumerate() {
            let src = (2 * i + 1) * width + x0;
            load(dst, &data[src..src + lanes]);
        }
        kernel.analyze(lo, hi, lanes);
        for (i, src) in lo
            .chunks_exact(lanes)
            .chain(hi.chunks_exact(lanes))
            .enumerate()
        {
            let dst = i * width + x0;
            store(&mut data[dst..dst + lanes], src);
        }
        x0 += lanes;
    }
}

/// Inverse of [`cols_analyze`]; whether every value stored fitted or was spilled.
fn cols_synthesize<T: Sample, K: Kernel<T::Work>>(
    kernel: &K,
    data: &mut [T],
    Region { width, lw, lh }: Region,
    scratch: &mut [T::Work],
    spill: &mut impl Spill<T::Work>,
) -> bool {
    if lh < 2 {
        return true;
    }
    let nl = lh.div_ceil(2);
    let nh = lh - nl;
    let mut x0 = 0;
    while x0 < lw {
        let lanes = STRIP.min(lw - x0);
        let (lo, rest) = scratch.split_at_mut(nl * lanes);
        let hi = &mut rest[..nh * lanes];
        for (i, dst) in lo
            .chunks_exact_mut(lanes)
            .chain(hi.chunks_exact_mut(lanes))
            .enumerate()
        {
            let src = i * width + x0;
            load(dst, &data[src..src + lanes]);
            spill.patch(src, dst);
        }
        kernel.synthesize(lo, hi, lanes);
        for (i, src) in lo.chunks_exact(lanes).enumerate() {
            let dst = 2 * i * width + x0;
            let fits = store_fits(&mut data[dst..dst + lanes], src);
            if !spill.settle(dst, 1, src, fits) {
                return false;
            }
        }
        for (i, src) in hi.chunks_exact(lanes).enumerate() {
            let dst = (2 * i + 1) * width + x0;
            let fits = store_fits(&mut data[dst..dst + lanes], src);
            if !spill.settle(dst, 1, src, fits) {
                return false;
            }
        }
        x0 += lanes;
    }
    true
}

/// Where an inverse transform keeps the values its buffer's type cannot hold.
trait Spill<W> {
    /// Overwrites the values of `dst`, read from `start..` of the buffer, that are kept
    /// here.
    fn patch(&self, start: usize, dst: &mut [W]);
    /// After `src` was stored at every `stride`-th place from `start` (`fitted`: every
    /// value fitted): forgets what was kept at those places, keeps the values that did
    /// not fit; false when it cannot.
    fn settle(&mut self, start: usize, stride: usize, src: &[W], fitted: bool) -> bool;
}

/// No spilling: a value that does not fit fails the transform.
struct NoSpill;

impl<W> Spill<W> for NoSpill {
    #[inline(always)]
    fn patch(&self, _start: usize, _dst: &mut [W]) {}
    #[inline(always)]
    fn settle(&mut self, _start: usize, _stride: usize, _src: &[W], fitted: bool) -> bool {
        fitted
    }
}

/// Spilled `i16` values by index, at most `cap` of them.
struct SpillMap<'a> {
    map: &'a mut BTreeMap<usize, i32>,
    cap: usize,
}

impl Spill<i32> for SpillMap<'_> {
    #[inline(always)]
    fn patch(&self, start: usize, dst: &mut [i32]) {
        if !self.map.is_empty() {
            self.patch_kept(start, dst);
        }
    }
    #[inline(always)]
    fn settle(&mut self, start: usize, stride: usize, src: &[i32], fitted: bool) -> bool {
        (fitted && self.map.is_empty()) || self.settle_kept(start, stride, src)
    }
}

impl SpillMap<'_> {
    /// [`Spill::patch`] with some values kept.
    #[cold]
    fn patch_kept(&self, start: usize, dst: &mut [i32]) {
        for (&i, &v) in self.map.range(start..start + dst.len()) {
            dst[i - start] = v;
        }
    }

    /// [`Spill::settle`] with some values kept or to keep.
    #[cold]
    fn settle_kept(&mut self, start: usize, stride: usize, src: &[i32]) -> bool {
        let end = start + stride * src.len();
        let stale: Vec<usize> = (self.map.range(start..end).map(|(&i, _)| i))
            .filter(|i| (i - start).is_multiple_of(stride))
            .collect();
        for i in stale {
            self.map.remove(&i);
        }
        for (k, &v) in src.iter().enumerate() {
            if !i16::fits(v) {
                self.map.insert(start + k * stride, v);
            }
        }
        self.map.len() <= self.cap
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn lowered_shifts_move_the_finest_horizontal_and_vertical_bands_down() {
        let (width, height, levels) = (512, 512, 6);
        let norms = coding_norms(Wavelet::Int53, width, height, levels);
        let rounded = plane_shifts(&norms, ShiftRule::Rounded);
        let lowered = plane_shifts(&norms, ShiftRule::Lowered);
        for ((band, r), l) in subbands(width, height, levels)
            .iter()
            .zip(rounded)
            .zip(lowered)
        {
            let finest_hl_lh = band.level == 1 && band.orientation != Orientation::HH;
            assert_eq!(l + u32::from(finest_hl_lh), r, "{band:?}");
        }
    }

    /// Deterministic pseudo-random numbers (SplitMix64).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }

        /// Uniform in `[-1, 1)`.
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// Whole-sample symmetric extension of index `i` into `0..n`.
    fn mirror(i: isize, n: usize) -> usize {
        if n == 1 {
            return 0;
        }
        let period = 2 * (n as isize - 1);
        let i = i.rem_euclid(period);
        (if i >= n as isize { period - i } else { i }) as usize
    }

    /// Straight-from-the-formula 1-D 5/3 on an interleaved signal (reference).
    fn reference_53_1d(x: &[i32]) -> Vec<i32> {
        let n = x.len();
        if n == 1 {
            return x.to_vec();
        }
        let at = |v: &[i32], i: isize| v[mirror(i, n)];
        let mut y = x.to_vec();
        for i in (1..n).step_by(2) {
            let i = i as isize;
            y[i as usize] = x[i as usize] - ((at(x, i - 1) + at(x, i + 1)) >> 1);
        }
        let z = y.clone();
        for i in (0..n).step_by(2) {
            let i = i as isize;
            y[i as usize] = z[i as usize] + ((at(&z, i - 1) + at(&z, i + 1) + 2) >> 2);
        }
        let mut out: Vec<i32> = y.iter().step_by(2).copied().collect();
        out.extend(y.iter().skip(1).step_by(2));
        out
    }

    /// Reference 1-D 13/11, sample by sample, in `i64`.
    fn reference_1311_1d(x: &[i32]) -> Vec<i32> {
        let n = x.len();
        if n == 1 {
            return x.to_vec();
        }
        let at = |v: &[i32], i: isize| i64::from(v[mirror(i, n)]);
        let mut y = x.to_vec();
        for i in (1..n as isize).step_by(2) {
            let near = at(x, i - 1) + at(x, i + 1);
            let middle = at(x, i - 3) + at(x, i + 3);
            let far = at(x, i - 5) + at(x, i + 5);
            let predicted = (150 * near - 25 * middle + 3 * far + 128) >> 8;
            y[i as usize] = (i64::from(x[i as usize]) - predicted) as i32;
        }
        let z = y.clone();
        for i in (0..n as isize).step_by(2) {
            y[i as usize] = z[i as usize] + ((at(&z, i - 1) + at(&z, i + 1) + 2) >> 2) as i32;
        }
        let mut out: Vec<i32> = y.iter().step_by(2).copied().collect();
        out.extend(y.iter().skip(1).step_by(2));
        out
    }

    /// Reference 2-D transform by `one_d`: rows then columns per level, one column at a
    /// time.
    fn reference_2d(
        data: &mut [i32],
        (width, height, levels): (usize, usize, u32),
        one_d: fn(&[i32]) -> Vec<i32>,
    ) {
        for &(lw, lh) in regions(width, height, levels).iter().take(levels as usize) {
            for y in 0..lh {
                let row = one_d(&data[y * width..y * width + lw]);
                data[y * width..y * width + lw].copy_from_slice(&row);
            }
            for x in 0..lw {
                let col: Vec<i32> = (0..lh).map(|y| data[y * width + x]).collect();
                for (y, v) in one_d(&col).into_iter().enumerate() {
                    data[y * width + x] = v;
                }
            }
        }
    }

    /// Reference 2-D 5/3.
    fn reference_53(data: &mut [i32], width: usize, height: usize, levels: u32) {
        reference_2d(data, (width, height, levels), reference_53_1d);
    }

    fn image_strategy(
        max_side: usize,
        magnitude: i32,
    ) -> impl Strategy<Value = (usize, usize, Vec<i32>, u32)> {
        (1..=max_side, 1..=max_side).prop_flat_map(move |(w, h)| {
            (
                Just(w),
                Just(h),
                proptest::collection::vec(-magnitude..=magnitude, w * h),
                0..=max_levels(w, h),
            )
        })
    }

    #[test]
    fn inverse_integer_in_i16_matches_i32_or_says_it_did_not_fit() {
        for wavelet in [Wavelet::Int53, Wavelet::Int1311] {
            inverse_in_i16_matches_i32(wavelet);
        }
    }

    fn inverse_in_i16_matches_i32(wavelet: Wavelet) {
        let mut rng = Rng(7);
        let sizes = [
            (1, 1, 0),
            (9, 1, 3),
            (1, 13, 3),
            (33, 17, 4),
            (64, 48, 5),
            (65, 47, 5),
        ];
        for &(w, h, levels) in &sizes {
            // Noise of ±4000 fits everywhere; a ramp over 0 ..= 65535 shifted down by
            // 32768 (a u16 raster spanning its range, shifted as the decoder shifts it)
            // with three samples beyond i16 has coefficients and values of the inverse
            // that do not fit: those are spilled.
            for wide in [false, true] {
                let mut data: Vec<i32> = (0..w * h)
                    .map(|i| match wide {
                        false => (rng.next() % 8000) as i32 - 4000,
                        true => ((i % w + i / w) * 65535 / (w + h)) as i32 - 32768,
                    })
                    .collect();
                if wide {
                    for v in [40000, -40000, 33000] {
                        data[(rng.next() % (w * h) as u64) as usize] = v;
                    }
                }
                let mut coefficients = data.clone();
                forward_integer(wavelet, &mut coefficients, (w, h), levels, None);
                let mut spilled = BTreeMap::new();
                let mut narrow: Vec<i16> = (coefficients.iter().enumerate())
                    .map(|(i, &c)| {
                        i16::try_from(c).unwrap_or_else(|_| {
                            spilled.insert(i, c);
                            i16::MIN
                        })
                    })
                    .collect();
                let spilled_before = spilled.len();
                assert!(inverse_integer_i16(
                    wavelet,
                    &mut narrow,
                    &mut spilled,
                    w,
                    h,
                    levels
                ));
                let back = (narrow.iter().enumerate())
                    .map(|(i, &v)| spilled.get(&i).copied().unwrap_or(v.into()));
                assert!(back.eq(data.iter().copied()), "{w}x{h}, wide {wide}");
                assert_eq!(spilled_before + spilled.len() > 0, wide, "{w}x{h}");
            }
        }
        // More values beyond i16 than one in 64: 40000 at every sample of a 64x64 LL.
        let mut big = vec![0i16; 64 * 64];
        let mut spilled: BTreeMap<usize, i32> = (0..64 * 64).map(|i| (i, 40000)).collect();
        assert!(!inverse_integer_i16(
            wavelet,
            &mut big,
            &mut spilled,
            64,
            64,
            0
        ));
        let mut spilled: BTreeMap<usize, i32> =
            (0..max_spilled(64 * 64)).map(|i| (i, 40000)).collect();
        assert!(inverse_integer_i16(
            wavelet,
            &mut big,
            &mut spilled,
            64,
            64,
            0
        ));
    }

    fn roundtrip_53(data: &[i32], w: usize, h: usize, levels: u32) {
        let mut buf = data.to_vec();
        forward_53(&mut buf, w, h, levels);
        let mut reference = data.to_vec();
        reference_53(&mut reference, w, h, levels);
        assert_eq!(
            buf, reference,
            "{w}x{h}, {levels} levels: differs from reference"
        );
        inverse_53(&mut buf, w, h, levels);
        assert_eq!(buf, data, "{w}x{h}, {levels} levels: not reconstructed");
    }

    /// Max and RMS absolute error of a 9/7 round trip.
    fn error_97(data: &[f32], w: usize, h: usize, levels: u32) -> (f64, f64) {
        let mut buf = data.to_vec();
        forward_97(&mut buf, w, h, levels);
        inverse_97(&mut buf, w, h, levels);
        let (mut max, mut sum) = (0.0f64, 0.0f64);
        for (&a, &b) in buf.iter().zip(data) {
            let e = (a as f64 - b as f64).abs();
            max = max.max(e);
            sum += e * e;
        }
        (max, (sum / data.len().max(1) as f64).sqrt())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn prop_53_perfect_reconstruction((w, h, data, levels) in image_strategy(70, 1 << 20)) {
            roundtrip_53(&data, w, h, levels);
        }

        #[test]
        fn prop_1311_is_the_reference_and_inverts((w, h, data, levels) in image_strategy(70, 1 << 20)) {
            let mut buf = data.clone();
            forward_1311(&mut buf, w, h, levels);
            let mut reference = data.clone();
            reference_2d(&mut reference, (w, h, levels), reference_1311_1d);
            prop_assert_eq!(&buf, &reference, "{}x{}, {} levels", w, h, levels);
            inverse_1311(&mut buf, w, h, levels);
            prop_assert_eq!(buf, data);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        #[test]
        fn prop_97_reconstruction((w, h, data, levels) in image_strategy(70, 10_000)) {
            let data: Vec<f32> = data.iter().map(|&v| v as f32).collect();
            let (max, rms) = error_97(&data, w, h, levels);
            // Values up to 1e4 = 2^13.3, where one f32 ulp is 2^-10 ≈ 1e-3.
            prop_assert!(max < 1e-2 && rms < 2e-3, "{w}x{h}, {levels} levels: {max} {rms}");
        }
    }

    #[test]
    fn fixed_sizes_53_roundtrip() {
        let mut rng = Rng(7);
        for &(w, h) in &[
            (1, 1),
            (1, 2),
            (2, 1),
            (1, 37),
            (37, 1),
            (1, 1024),
            (1025, 1),
            (1025, 3),
            (3, 1201),
            (33, 65),
            (129, 17),
        ] {
            let data: Vec<i32> = (0..w * h)
                .map(|_| (rng.next() % (1 << 21)) as i32 - (1 << 20))
                .collect();
            for levels in [0, default_levels(w, h), max_levels(w, h)] {
                roundtrip_53(&data, w, h, levels);
            }
        }
    }

    #[test]
    fn extreme_values_53_roundtrip() {
        // Wrapping arithmetic makes even out-of-range inputs exactly invertible.
        let mut rng = Rng(11);
        let (w, h) = (45, 31);
        let data: Vec<i32> = (0..w * h).map(|_| rng.next() as i32).collect();
        let mut buf = data.clone();
        forward_53(&mut buf, w, h, max_levels(w, h));
        inverse_53(&mut buf, w, h, max_levels(w, h));
        assert_eq!(buf, data);
    }

    #[test]
    fn worst_case_53_growth_stays_in_range() {
        // Input ±2^26 with the sign pattern of the analysis filter of the central HH
        // coefficient of each level, i.e. the input that maximises that coefficient. The
        // (wrapping) result must equal the exact unrounded transform up to rounding.
        let n = 200;
        let levels = max_levels(n, n);
        let m = (1 << 26) as f64;
        for level in 1..=levels - 2 {
            let bands = subbands(n, n, levels);
            let hh = bands
                .iter()
                .find(|b| b.level == level && b.orientation == Orientation::HH)
                .unwrap();
            let c = hh.x0 + hh.width / 2;
            // The 2-D analysis filter is the outer product of 1-D ones: find the 1-D
            // analysis row of coefficient c by transforming every unit impulse.
            let mut sign = vec![0.0f64; n];
            let mut imp = vec![0.0f64; n];
            let mut l1 = 0.0;
            for (i, s) in sign.iter_mut().enumerate() {
                imp.fill(0.0);
                imp[i] = 1.0;
                forward_2d(&REAL53, &mut imp, n, 1, levels);
                *s = imp[c].signum();
                l1 += imp[c].abs();
            }
            let data: Vec<i32> = (0..n * n)
                .map(|i| (sign[i % n] * sign[i / n] * m) as i32)
                .collect();
            let mut exact: Vec<f64> = data.iter().map(|&v| v as f64).collect();
            forward_2d(&REAL53, &mut exact, n, n, levels);
            let mut buf = data.clone();
            forward_53(&mut buf, n, n, levels);
            let peak = buf[c * n + c] as f64;
            // Worst-case gain l1^2: 4 at level 1, 6.25 at level 2, ... ≈ 8.2 from level 6.
            assert!(
                (peak.abs() - l1 * l1 * m).abs() < 32.0,
                "level {level}: {peak} is not the worst case {}",
                l1 * l1 * m
            );
            assert!(l1 * l1 < 8.3, "level {level}: gain {}", l1 * l1);
            let dev = buf
                .iter()
                .zip(&exact)
                .map(|(&a, &b)| (a as f64 - b).abs())
                .fold(0.0, f64::max);
            assert!(
                dev < 32.0,
                "level {level}: deviates {dev} from the exact transform"
            );
            inverse_53(&mut buf, n, n, levels);
            assert_eq!(buf, data);
        }
    }

    #[test]
    fn known_answer_53_even_length() {
        // x = [3, 7, 1, 8, 2, 9, 4, 6]
        // d0 = 7 - (3+1)>>1 = 5, d1 = 8 - (1+2)>>1 = 7, d2 = 9 - (2+4)>>1 = 6,
        // d3 = 6 - (4+4)>>1 = 2 (x[8] mirrors to x[6]);
        // s0 = 3 + (5+5+2)>>2 = 6 (d[-1] mirrors to d0), s1 = 1 + (5+7+2)>>2 = 4,
        // s2 = 2 + (7+6+2)>>2 = 5, s3 = 4 + (6+2+2)>>2 = 6.
        let x = [3, 7, 1, 8, 2, 9, 4, 6];
        let expected = [6, 4, 5, 6, 5, 7, 6, 2];
        let mut row = x;
        forward_53(&mut row, 8, 1, 1);
        assert_eq!(row, expected);
        let mut col = x;
        forward_53(&mut col, 1, 8, 1);
        assert_eq!(col, expected);
        inverse_53(&mut row, 8, 1, 1);
        assert_eq!(row, x);
    }

    #[test]
    fn known_answer_53_odd_length_negative() {
        // x = [5, -1, 4, 1, -5, 9, 2, 6, 5] (floor of negative halves matters)
        // d0 = -1 - (5+4)>>1 = -5, d1 = 1 - (4-5)>>1 = 2, d2 = 9 - (-5+2)>>1 = 11,
        // d3 = 6 - (2+5)>>1 = 3;
        // s0 = 5 + (-5-5+2)>>2 = 3, s1 = 4 + (-5+2+2)>>2 = 3, s2 = -5 + (2+11+2)>>2 = -2,
        // s3 = 2 + (11+3+2)>>2 = 6, s4 = 5 + (3+3+2)>>2 = 7 (d4 mirrors to d3).
        let x = [5, -1, 4, 1, -5, 9, 2, 6, 5];
        let expected = [3, 3, -2, 6, 7, -5, 2, 11, 3];
        let mut row = x;
        forward_53(&mut row, 9, 1, 1);
        assert_eq!(row, expected);
        let mut col = x;
        forward_53(&mut col, 1, 9, 1);
        assert_eq!(col, expected);
        // Second level works on the 5 low-pass samples [3, 3, -2, 6, 7]:
        // d0 = 3 - (3-2)>>1 = 3, d1 = 6 - (-2+7)>>1 = 4;
        // s0 = 3 + (3+3+2)>>2 = 5, s1 = -2 + (3+4+2)>>2 = 0, s2 = 7 + (4+4+2)>>2 = 9.
        let mut two = x;
        forward_53(&mut two, 9, 1, 2);
        assert_eq!(two, [5, 0, 9, 3, 4, -5, 2, 11, 3]);
    }

    #[test]
    fn known_answer_53_tiny() {
        let mut one = [42];
        forward_53(&mut one, 1, 1, 0);
        assert_eq!(one, [42]);
        // n = 2: d0 = 9 - 4 = 5 (x[2] mirrors to x[0]), s0 = 4 + (5+5+2)>>2 = 7.
        let mut two = [4, 9];
        forward_53(&mut two, 2, 1, 1);
        assert_eq!(two, [7, 5]);
        // 2x2 with one level: rows [1,2] -> [2,1], [3,5] -> [4,2]; then columns
        // [2,4] -> [3,2], [1,2] -> [2,1].
        let mut square = [1, 2, 3, 5];
        forward_53(&mut square, 2, 2, 1);
        assert_eq!(square, [3, 2, 2, 1]);
    }

    #[test]
    fn gains_97() {
        // Interior DC gain of the low-pass and Nyquist gain of the high-pass are √2.
        let n = 64;
        let mut dc = vec![1.0f32; n];
        forward_97(&mut dc, n, 1, 1);
        let mut nyq: Vec<f32> = (0..n)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        forward_97(&mut nyq, n, 1, 1);
        for i in 0..n / 2 {
            assert!(
                (dc[i] - std::f32::consts::SQRT_2).abs() < 1e-5,
                "dc low {}",
                dc[i]
            );
            assert!(dc[n / 2 + i].abs() < 1e-5, "dc high {}", dc[n / 2 + i]);
            assert!(nyq[i].abs() < 1e-5, "nyquist low {}", nyq[i]);
            assert!(
                (nyq[n / 2 + i].abs() - std::f32::consts::SQRT_2).abs() < 1e-5,
                "nyquist high {}",
                nyq[n / 2 + i]
            );
        }
    }

    #[test]
    fn reconstruction_97_large_magnitude() {
        let (w, h) = (300, 260);
        let levels = 8;
        let mut rng = Rng(3);
        let data: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                (5000.0 + 3000.0 * (x / 37.0).sin() * (y / 23.0).cos() + 1500.0 * rng.unit()) as f32
            })
            .collect();
        // Measured: max ≈ 5.4e-3, RMS ≈ 8e-4. One f32 ulp at 1e4 is 2^-10 ≈ 1e-3; every
        // level stores its row and column outputs in f32 both ways (32 roundings for 8
        // levels), each adding up to half an ulp of the data's magnitude in pixel terms.
        let (max, rms) = error_97(&data, w, h, levels);
        assert!(max < 1e-2 && rms < 2e-3, "max error {max}, rms {rms}");
        let noise: Vec<f32> = (0..w * h).map(|_| (1e4 * rng.unit()) as f32).collect();
        let (max, rms) = error_97(&noise, w, h, levels);
        assert!(
            max < 1e-2 && rms < 2e-3,
            "noise: max error {max}, rms {rms}"
        );
    }

    #[test]
    fn constant_image_has_no_detail() {
        for &(w, h) in &[(1, 1), (1, 9), (16, 16), (37, 21), (64, 3)] {
            let levels = max_levels(w, h);
            let mut ints = vec![1234i32; w * h];
            forward_53(&mut ints, w, h, levels);
            let mut floats = vec![1234.0f32; w * h];
            forward_97(&mut floats, w, h, levels);
            for band in subbands(w, h, levels) {
                for y in band.y0..band.y0 + band.height {
                    for x in band.x0..band.x0 + band.width {
                        let (i, f) = (ints[y * w + x], floats[y * w + x]);
                        if band.orientation == Orientation::LL {
                            assert_eq!(i, 1234, "5/3 LL {w}x{h}");
                        } else {
                            assert_eq!(i, 0, "5/3 {band:?} of {w}x{h}");
                            assert!(f.abs() < 0.05, "9/7 {band:?} of {w}x{h}: {f}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn subbands_tile_exactly() {
        for &(w, h) in &[
            (1, 1),
            (1, 5),
            (5, 1),
            (2, 2),
            (8, 8),
            (9, 9),
            (17, 4),
            (33, 100),
            (1025, 3),
            (3, 1201),
        ] {
            for levels in 0..=max_levels(w, h) {
                let bands = subbands(w, h, levels);
                assert_eq!(bands.len(), 1 + 3 * levels as usize);
                assert_eq!(bands[0].orientation, Orientation::LL);
                assert_eq!(bands[0].level, levels);
                for (i, band) in bands[1..].iter().enumerate() {
                    let expected = [Orientation::HL, Orientation::LH, Orientation::HH][i % 3];
                    assert_eq!(band.orientation, expected);
                    assert_eq!(band.level, levels - (i / 3) as u32);
                }
                let mut hits = vec![0u8; w * h];
                for band in &bands {
                    for y in band.y0..band.y0 + band.height {
                        for x in band.x0..band.x0 + band.width {
                            hits[y * w + x] += 1;
                        }
                    }
                }
                assert!(hits.iter().all(|&c| c == 1), "{w}x{h}, {levels} levels");
            }
        }
    }

    #[test]
    fn subbands_geometry() {
        let bands = subbands(9, 5, 2);
        // Level 1 region 9x5 -> 5x3 low; level 2 region 5x3 -> 3x2 low.
        let rect = |b: &Subband| (b.x0, b.y0, b.width, b.height);
        assert_eq!(rect(&bands[0]), (0, 0, 3, 2));
        assert_eq!(rect(&bands[1]), (3, 0, 2, 2));
        assert_eq!(rect(&bands[2]), (0, 2, 3, 1));
        assert_eq!(rect(&bands[3]), (3, 2, 2, 1));
        assert_eq!(rect(&bands[4]), (5, 0, 4, 3));
        assert_eq!(rect(&bands[5]), (0, 3, 5, 2));
        assert_eq!(rect(&bands[6]), (5, 3, 4, 2));
        let none = subbands(7, 3, 0);
        assert_eq!(none.len(), 1);
        assert_eq!(rect(&none[0]), (0, 0, 7, 3));
        assert_eq!(none[0].level, 0);
    }

    #[test]
    fn level_counts() {
        assert_eq!(max_levels(1, 1), 0);
        assert_eq!(max_levels(2, 1), 1);
        assert_eq!(max_levels(1, 5), 3);
        assert_eq!(max_levels(1024, 3), 10);
        assert_eq!(max_levels(1025, 3), 11);
        assert_eq!(default_levels(2000, 2000), 8);
        assert_eq!(default_levels(8, 8), 0);
        assert_eq!(default_levels(9, 9), 1);
        assert_eq!(default_levels(1, 1), 0);
        assert_eq!(default_levels(3601, 3601), 9);
        assert_eq!(default_levels(16, 3), 1);
        for w in 1..40 {
            for h in 1..40 {
                let l = default_levels(w, h);
                let (lw, lh) = *regions(w, h, l).last().unwrap();
                assert!(lw.max(lh) <= 8);
                assert!(l <= max_levels(w, h));
                let (lw, lh) = *regions(w, h, max_levels(w, h)).last().unwrap();
                assert_eq!((lw, lh), (1, 1));
            }
        }
    }

    #[test]
    fn wavelet_codes() {
        for wv in [Wavelet::Cdf97, Wavelet::Int53, Wavelet::Int1311] {
            assert_eq!(Wavelet::from_code(wv.code()), Some(wv));
        }
        assert_eq!(Wavelet::Cdf97.code(), 1);
        assert_eq!(Wavelet::Int53.code(), 2);
        assert_eq!(Wavelet::Int1311.code(), 3);
        assert_eq!(Wavelet::from_code(0), None);
        assert_eq!(Wavelet::from_code(4), None);
        assert_eq!(Wavelet::Cdf97.name(), "9/7");
        assert_eq!(Wavelet::Int53.name(), "5/3");
        assert_eq!(Wavelet::Int1311.name(), "13/11");
    }

    #[test]
    fn energy_97_close_to_pixel_energy() {
        let mut rng = Rng(5);
        for &(w, h, levels) in &[(64, 64, 3), (100, 80, 5), (257, 129, 8)] {
            let data: Vec<f32> = (0..w * h).map(|_| (100.0 * rng.unit()) as f32).collect();
            let mut buf = data.clone();
            forward_97(&mut buf, w, h, levels);
            let energy = |v: &[f32]| v.iter().map(|&x| (x as f64).powi(2)).sum::<f64>();
            let ratio = energy(&buf) / energy(&data);
            assert!((0.9..1.1).contains(&ratio), "{w}x{h}: energy ratio {ratio}");
        }
    }

    #[test]
    fn synthesis_norms_97_near_one() {
        // Default levels leave every subband a few coefficients wide.
        for &(w, h) in &[(2000, 2000), (3601, 3601), (64, 64), (100, 37), (1025, 3)] {
            let levels = default_levels(w, h);
            let bands = subbands(w, h, levels);
            let norms = synthesis_norms(Wavelet::Cdf97, w, h, levels);
            assert_eq!(norms.len(), bands.len());
            for (band, &norm) in bands.iter().zip(&norms) {
                if band.width == 0 || band.height == 0 {
                    assert_eq!(norm, 0.0);
                } else {
                    assert!((0.8..=1.25).contains(&norm), "{w}x{h} {band:?}: {norm}");
                }
            }
        }
        // Subbands of one or two coefficients are all boundary: still of order 1.
        for &(w, h) in &[(64, 64), (37, 1), (5, 9)] {
            for norm in synthesis_norms(Wavelet::Cdf97, w, h, max_levels(w, h)) {
                assert!(norm == 0.0 || (0.5..2.0).contains(&norm), "{w}x{h}: {norm}");
            }
        }
    }

    #[test]
    fn synthesis_norms_53_grow_with_level() {
        let (w, h) = (512, 512);
        let levels = 6;
        let norms = synthesis_norms(Wavelet::Int53, w, h, levels);
        // LL: ≈ 2 per level (DC gain 2 per level of the 2-D synthesis low-pass).
        assert!(norms[0] > 40.0 && norms[0] < 80.0, "LL norm {}", norms[0]);
        // Finest HH: the 1-D high-pass synthesis filter is (-1/8, -1/4, 3/4, -1/4, -1/8),
        // of squared norm 23/32, so the 2-D norm is exactly 23/32.
        let hh1 = *norms.last().unwrap();
        assert!((hh1 - 23.0 / 32.0).abs() < 1e-12, "HH1 norm {hh1}");
        // Deterministic.
        assert_eq!(norms, synthesis_norms(Wavelet::Int53, w, h, levels));
        assert_eq!(synthesis_norms(Wavelet::Int53, 5, 5, 0), vec![1.0]);
    }

    #[test]
    fn synthesis_norms_match_2d_brute_force() {
        // The separable product must equal the norm of the real 2-D synthesis.
        for &(w, h, levels) in &[(23, 17, 3), (40, 9, 4), (1, 12, 4)] {
            norms_match_brute_force(Wavelet::Cdf97, &CDF97, (w, h, levels));
            norms_match_brute_force(Wavelet::Int53, &REAL53, (w, h, levels));
            norms_match_brute_force(Wavelet::Int1311, &Real1311, (w, h, levels));
        }
    }

    fn norms_match_brute_force<K: Kernel<f64>>(
        wavelet: Wavelet,
        kernel: &K,
        (w, h, levels): (usize, usize, u32),
    ) {
        let norms = synthesis_norms(wavelet, w, h, levels);
        for (band, &norm) in subbands(w, h, levels).iter().zip(&norms) {
            if band.width == 0 || band.height == 0 {
                continue;
            }
            let mut img = vec![0.0f64; w * h];
            img[(band.y0 + band.height / 2) * w + band.x0 + band.width / 2] = 1.0;
            inverse_2d(kernel, &mut img, w, h, levels, &mut NoSpill);
            let brute = img.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!(
                (brute - norm).abs() < 1e-9 * brute,
                "{wavelet:?} {band:?}: {brute} vs {norm}"
            );
        }
    }

    #[test]
    fn the_1311_predicts_cubics_exactly() {
        // Deslauriers–Dubuc's 6 taps reproduce polynomials up to degree 5: the high-pass
        // of a cubic sampled away from the borders is 0 (rounding aside: exact here).
        let cubic: Vec<f64> = (0..40).map(|i| (i as f64 - 17.0).powi(3) / 8.0).collect();
        let mut signal = cubic.clone();
        forward_2d(&Real1311, &mut signal, 40, 1, 1);
        for &d in &signal[20 + 3..40 - 3] {
            assert!(d.abs() < 1e-9, "{d}");
        }
    }

    #[test]
    fn voids_take_the_values_their_row_neighbours_predict() {
        let (w, h, levels) = (23, 17, 3);
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let samples: Vec<i32> = (0..w * h)
            .map(|_| (rng.next() % 2001) as i32 - 1000)
            .collect();
        let valid: Vec<bool> = (0..w * h).map(|_| !rng.next().is_multiple_of(3)).collect();
        for wavelet in [Wavelet::Int53, Wavelet::Int1311] {
            let mut coefficients = samples.clone();
            forward_integer(wavelet, &mut coefficients, (w, h), levels, Some(&valid));
            inverse_integer(wavelet, &mut coefficients, w, h, levels);
            for (i, (&got, &sample)) in coefficients.iter().zip(&samples).enumerate() {
                if valid[i] || i % w % 2 == 0 {
                    assert_eq!(got, sample, "{wavelet:?}: a valid or even sample, at {i}");
                }
            }
            // The 5/3 predicts an interior odd sample by the mean of its neighbours.
            if wavelet == Wavelet::Int53 {
                for i in (0..w * h).filter(|&i| !valid[i] && i % w % 2 == 1) {
                    let mean = (samples[i - 1] + samples[i + 1]) >> 1;
                    assert_eq!(coefficients[i], mean, "void at {i}");
                }
            }
        }
    }

    #[test]
    #[should_panic]
    fn wrong_buffer_length_panics() {
        let mut buf = vec![0i32; 10];
        forward_53(&mut buf, 3, 3, 1);
    }

    #[test]
    #[should_panic]
    fn too_many_levels_panics() {
        let mut buf = vec![0.0f32; 16];
        forward_97(&mut buf, 4, 4, 3);
    }
}
