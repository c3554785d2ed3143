//! The context models: which adaptive [`BitModel`] codes each EZW decision, chosen from
//! what encoder and decoder both know at that moment of the scan (the known coefficient
//! values, which say which are significant, and the parent).

use super::priors::primed;
use super::{FlagGrid, Known, ParentRow, Side};
use crate::entropy::BitModel;

/// Which context information the models are selected by (all of it in every stream; the
/// others exist to measure what each piece buys, with `count_bits`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContextChoice {
    /// Subband class (LL, coarse, level 2, level 1) for significance, zerotree, refinement.
    pub subband_class: bool,
    /// Significance of the spatial neighbours (significance, zerotree, refinement).
    pub neighbours: bool,
    /// Significance of the parent (significance, zerotree).
    pub parent: bool,
    /// Signs of the left and upper neighbours (sign).
    pub neighbour_signs: bool,
    /// How many planes ago the coefficient became significant (refinement).
    pub refinement_age: bool,
}

impl ContextChoice {
    /// Every context in use: what streams are coded with.
    pub const ALL: ContextChoice = ContextChoice {
        subband_class: true,
        neighbours: true,
        parent: true,
        neighbour_signs: true,
        refinement_age: true,
    };
    /// One model per decision kind.
    #[cfg(feature = "research")]
    pub const NONE: ContextChoice = ContextChoice {
        subband_class: false,
        neighbours: false,
        parent: false,
        neighbour_signs: false,
        refinement_age: false,
    };
}

/// Which context models a stream is coded with (the header's "coder 2" flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Coder {
    /// The first models: neighbour and parent *significance* only.
    V1,
    /// Models chosen by the known *magnitudes* of the 8 neighbours and the parent.
    V2,
    /// Coder 2's models, each starting from a trained probability instead of ½ (see
    /// `ezw/priors.rs`).
    V3,
    /// Coder 3's models with a propagation scan first in every pass (see
    /// `ezw/propagation.rs`), and residual lengths modelled on the previous one: what
    /// every new stream is coded with.
    #[default]
    V4,
}

impl Coder {
    /// Whether each pass starts with the propagation scan.
    pub(crate) fn propagates(self) -> bool {
        self == Coder::V4
    }

    /// Whether float residuals and max-error corrections choose their length models by
    /// the previous residual's length (see `residual.rs`).
    pub(crate) fn models_residuals(self) -> bool {
        self == Coder::V4
    }
}

/// The adaptive models, grouped by decision.
#[derive(Debug, Clone)]
pub struct Contexts {
    pub(super) coder: Coder,
    pub(super) choice: ContextChoice,
    /// Significance. V1: class (4) × horizontal+vertical significant neighbours (3)
    /// × any diagonal neighbour significant (2) × parent significant (2). V2: class (4)
    /// × neighbour activity (8) × parent activity (3).
    pub(super) significance: Vec<BitModel>,
    /// Zerotree root vs isolated zero. V1: class (4) × neighbours (3) × parent
    /// significant (2). V2: as significance.
    pub(super) zerotree: Vec<BitModel>,
    /// Sign. V1: orientation (4) × left neighbour (3: none, +, −) × upper neighbour (3).
    /// V2: orientation (4) × horizontal sign balance (3) × vertical (3) × parent sign (3).
    pub(super) sign: Vec<BitModel>,
    /// Refinement: age of the coefficient's significance (2: first refinement, second;
    /// older ones are coded raw) × neighbourhood (V1: busy or not, 2; V2: activity, 4)
    /// × class (4).
    pub(super) refinement: Vec<BitModel>,
}

impl Default for Contexts {
    fn default() -> Self {
        Contexts::new(Coder::default(), ContextChoice::ALL)
    }
}

impl Contexts {
    /// Fresh models of `coder` selected by `choice`.
    pub fn new(coder: Coder, choice: ContextChoice) -> Self {
        let (activity, busy) = match coder {
            Coder::V1 => (3 * 2 * 2, 2),
            Coder::V2 | Coder::V3 | Coder::V4 => (ACTIVITY_LEVELS * PARENT_LEVELS, 4),
        };
        Contexts {
            coder,
            choice,
            significance: primed(coder, 0, 4 * activity),
            zerotree: primed(coder, 1, 4 * activity),
            sign: primed(coder, 2, 4 * 3 * 3 * 3),
            refinement: primed(coder, 3, 2 * busy * 4),
        }
    }

    /// The four groups of models, in the order of the prior tables.
    #[cfg(feature = "research")]
    pub(super) fn groups(&self) -> [&[BitModel]; 4] {
        [
            &self.significance,
            &self.zerotree,
            &self.sign,
            &self.refinement,
        ]
    }
}

/// Levels of the quantised neighbour activity of coder 2.
const ACTIVITY_LEVELS: usize = 8;
/// Levels of the quantised parent magnitude of coder 2.
const PARENT_LEVELS: usize = 3;

/// The sign model index of coefficient `at`. V1: the left and upper neighbours' signs;
/// V2: the horizontal and vertical neighbours' sign balance and the parent's sign.
#[inline]
pub(super) fn sign_context<S: Side>(
    contexts: &Contexts,
    grid: &FlagGrid,
    side: &S,
    at: At,
    orientation: usize,
    parent_row: Option<ParentRow>,
) -> usize {
    let state = |j: Option<usize>| sign_state(side, j);
    let signs = contexts.choice.neighbour_signs as usize;
    let left = state(grid.neighbour(at, -1, 0));
    let up = state(grid.neighbour(at, 0, -1));
    match contexts.coder {
        Coder::V1 => (orientation * 3 + left * signs) * 3 + up * signs,
        Coder::V2 | Coder::V3 | Coder::V4 => {
            let balance = |a: usize, b: usize| {
                let v = SIGN_VALUE[a] + SIGN_VALUE[b];
                (v.signum() + 1) as usize
            };
            let h = balance(left, state(grid.neighbour(at, 1, 0)));
            let v = balance(up, state(grid.neighbour(at, 0, 1)));
            let parent = parent_row
                .and_then(|pr| Some(pr.index + pr.column(at.x)?))
                .map_or(0, |j| state(Some(j)) * contexts.choice.parent as usize);
            ((orientation * 3 + h * signs) * 3 + v * signs) * 3 + parent
        }
    }
}

/// Sign states (0 none, 1 +, 2 −) as numbers.
const SIGN_VALUE: [i32; 3] = [0, 1, -1];

/// Sign state of a neighbour for sign contexts: 0 = not significant (or `None`: outside
/// the array), 1 = +, 2 = −.
#[inline]
fn sign_state<S: Side>(side: &S, j: Option<usize>) -> usize {
    j.map_or(0, |j| {
        let v = side.known().at(j);
        usize::from(v != 0) + usize::from(v < 0)
    })
}

/// Whether coefficient `j` is significant: its known value is not 0.
#[inline(always)]
fn significant<K: Known + ?Sized>(known: &K, j: usize) -> bool {
    known.at(j) != 0
}

/// Significant neighbours of coefficient `at`: (left+right+up+down capped at 2, any
/// diagonal).
#[inline]
fn neighbourhood<K: Known + ?Sized>(grid: &FlagGrid, known: &K, at: At) -> (usize, usize) {
    let sig = |dx: isize, dy: isize| {
        grid.neighbour(at, dx, dy)
            .is_some_and(|j| significant(known, j)) as usize
    };
    let hv = sig(-1, 0) + sig(1, 0) + sig(0, -1) + sig(0, 1);
    let diag = sig(-1, -1) | sig(1, -1) | sig(-1, 1) | sig(1, 1);
    (hv.min(2), diag)
}

/// Where a coefficient is.
#[derive(Clone, Copy)]
pub(super) struct At {
    /// Index in the coefficient array.
    pub(super) index: usize,
    /// Column in its band.
    pub(super) x: usize,
    /// Whether all 8 neighbours are inside the array.
    pub(super) interior: bool,
}

/// The significance and zerotree model indices of insignificant coefficient `at` at own
/// plane `p`.
#[inline(always)]
pub(super) fn dominant_contexts<S: Side>(
    contexts: &Contexts,
    grid: &FlagGrid,
    side: &S,
    at: At,
    class: usize,
    p: u32,
    parent_row: Option<ParentRow>,
) -> (usize, usize) {
    let choice = contexts.choice;
    // The parent's plane in the pass and known magnitude, when significant.
    let parent = parent_row
        .filter(|_| choice.parent)
        .and_then(|pr| {
            let j = pr.index + pr.column(at.x)?;
            Some((pr.plane, side.known().at(j).unsigned_abs()))
        })
        .filter(|&(_, m)| m != 0);
    match contexts.coder {
        Coder::V1 => {
            let parent_sig = parent.is_some() as usize;
            let (hv, diag) = neighbourhood(grid, side.known(), at);
            let (hv, diag) = (
                hv * choice.neighbours as usize,
                diag * choice.neighbours as usize,
            );
            (
                ((class * 3 + hv) * 2 + diag) * 2 + parent_sig,
                (class * 3 + hv) * 2 + parent_sig,
            )
        }
        Coder::V2 | Coder::V3 | Coder::V4 => {
            let activity = if choice.neighbours {
                log_level(neighbour_sum(grid, side.known(), at) >> p, ACTIVITY_LEVELS)
            } else {
                0
            };
            let parent = parent.map_or(0, |(plane, known)| {
                1 + log_level((known >> plane) as u64 >> 2, PARENT_LEVELS - 1)
            });
            let ctx = (class * ACTIVITY_LEVELS + activity) * PARENT_LEVELS + parent;
            (ctx, ctx)
        }
    }
}

/// Known magnitudes of the 8 neighbours of coefficient `at`, the horizontal and vertical
/// ones counted twice.
#[inline(always)]
fn neighbour_sum<K: Known + ?Sized>(grid: &FlagGrid, known: &K, at: At) -> u64 {
    let w = grid.width;
    let i = at.index;
    let m = |j: usize| u64::from(known.at(j).unsigned_abs());
    if at.interior {
        return known.interior_sum(i, w);
    }
    // On the array's edge: only the neighbours inside it count.
    let mut sum = 0u64;
    for (dx, dy, weight) in [
        (-1, 0, 2),
        (1, 0, 2),
        (0, -1, 2),
        (0, 1, 2),
        (-1, -1, 1),
        (1, -1, 1),
        (-1, 1, 1),
        (1, 1, 1),
    ] {
        if let Some(j) = grid.neighbour(at, dx, dy) {
            sum += weight * m(j);
        }
    }
    sum
}

/// The refinement model index of coefficient `at` at plane `p` (`age` 0 or 1).
#[inline(always)]
pub(super) fn refinement_context<K: Known + ?Sized>(
    contexts: &Contexts,
    grid: &FlagGrid,
    known: &K,
    at: At,
    p: u32,
    age: usize,
    class: usize,
) -> usize {
    let choice = contexts.choice;
    let (busy, levels) = match contexts.coder {
        Coder::V1 => {
            let (hv, diag) = neighbourhood(grid, known, at);
            ((hv + diag > 1) as usize, 2)
        }
        // Coder 2: the neighbours' known magnitudes at plane `p`.
        Coder::V2 | Coder::V3 | Coder::V4 => {
            let level = match neighbour_sum(grid, known, at) >> p {
                0 => 0,
                1..16 => 1,
                16..64 => 2,
                _ => 3,
            };
            (level, 4)
        }
    };
    ((age * levels) + busy * choice.neighbours as usize) * 4 + class * choice.subband_class as usize
}

/// `0` for 0, else 1 + ⌊log2 a⌋, at most `levels − 1`.
#[inline]
fn log_level(a: u64, levels: usize) -> usize {
    ((64 - a.leading_zeros()) as usize).min(levels - 1)
}
