//! Measurements of the coder's design choices, for `wavemesh report`. **Unstable**: behind
//! the `research` feature, and free to change with the coder.

use crate::error::CodecError;
use crate::ezw::{self, CoefficientLayout, ContextChoice};
use crate::pipeline::Quality;
use crate::pipeline::SHIFT_RULE;
use crate::quantize::{prepare_97, prepare_integer, FinestStep, VoidCoefficients};
use crate::raster::Raster;
use crate::wavelet::{self, ShiftRule, Wavelet};

/// What each context buys on `raster`'s lossless 5/3 coefficients: the ideal code length
/// (bits) with every context, with each one removed in turn, and with none.
pub fn context_ablation(raster: &Raster) -> Result<Vec<(&'static str, f64)>, CodecError> {
    let (layout, coefficients) = complete_coefficients(
        raster,
        Wavelet::Int53,
        (VoidCoefficients::Zeroed, SHIFT_RULE),
    )?;
    Ok(context_choices()
        .into_iter()
        .map(|(name, choice)| (name, ezw::count_bits(&layout, &coefficients, choice)))
        .collect())
}

pub use crate::ezw::{PriorTally, PRIOR_WINDOW};

/// Adds to `tally` the first decisions of every context model in `raster`'s complete
/// stream with `wavelet` (lossless 5/3, or 9/7 at its finest step): the training of
/// coder 3's starting probabilities (see [`PriorTally`]), with the coefficients of voids
/// and the 5/3 subbands' shifts as they were when the tables were trained (the transform
/// of the filled voids, [`ShiftRule::Rounded`]).
pub fn tally_priors(
    raster: &Raster,
    wavelet: Wavelet,
    tally: &mut PriorTally,
) -> Result<(), CodecError> {
    let trained = (VoidCoefficients::Filled, ShiftRule::Rounded);
    let (layout, coefficients) = complete_coefficients(raster, wavelet, trained)?;
    ezw::tally_priors(&layout, &coefficients, tally);
    Ok(())
}

/// `raster`'s coefficients for a complete stream with `wavelet` (lossless 5/3, or 9/7 at
/// its finest step) at the default levels, `voids` and the shifts' `rule` as asked, and
/// their layout.
fn complete_coefficients(
    raster: &Raster,
    wavelet: Wavelet,
    (voids, rule): (VoidCoefficients, ShiftRule),
) -> Result<(CoefficientLayout, Vec<i32>), CodecError> {
    let (width, height) = (raster.width, raster.height);
    let levels = wavelet::default_levels(width, height);
    let norms = wavelet::coding_norms(wavelet, width, height, levels);
    let mask = raster.valid_mask();
    let prepared = match wavelet {
        Wavelet::Int53 | Wavelet::Int1311 => {
            let kind = (wavelet, Quality::Lossless);
            prepare_integer(raster, &mask, kind, &norms, (voids, rule))?
        }
        Wavelet::Cdf97 => prepare_97(raster, &mask, &norms, (voids, FinestStep::AsTrained)),
    };
    let subbands = wavelet::subbands(width, height, levels);
    let layout = CoefficientLayout::new(width, height, &subbands, &prepared.shifts);
    Ok((layout, prepared.coefficients))
}

/// Every context, each one left out in turn, and none.
fn context_choices() -> [(&'static str, ContextChoice); 7] {
    let all = ContextChoice::ALL;
    [
        ("all contexts", all),
        (
            "without subband class",
            ContextChoice {
                subband_class: false,
                ..all
            },
        ),
        (
            "without neighbours",
            ContextChoice {
                neighbours: false,
                ..all
            },
        ),
        (
            "without parent",
            ContextChoice {
                parent: false,
                ..all
            },
        ),
        (
            "without neighbour signs",
            ContextChoice {
                neighbour_signs: false,
                ..all
            },
        ),
        (
            "without refinement age",
            ContextChoice {
                refinement_age: false,
                ..all
            },
        ),
        ("no contexts", ContextChoice::NONE),
    ]
}
