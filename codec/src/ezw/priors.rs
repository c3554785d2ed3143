//! The trained starting probabilities of [`Coder::V3`]'s models.
//!
//! An adaptive model starting at p = ½ pays for what it learns: a few bits for each of
//! the ~260 models a stream uses, which is several percent of a small tile's bytes at low
//! rates. Coder 3 starts each model at the probability its first 16 decisions had over
//! the training rasters (`training::PriorTally`, with the `research` feature), as sure
//! of it as [`crate::entropy::PRIMED_AGE`] bits would make it. The tables below are part
//! of the format: a decoder must start from exactly these values.

use super::contexts::Coder;
use crate::entropy::BitModel;

/// Starting probabilities of a 0 bit (1/65536 units) of coder 3's models, in the order
/// of [`super::Contexts`]' groups: significance, zerotree, sign, refinement.
const TABLES: [&[u16]; 4] = [&SIGNIFICANCE, &ZEROTREE, &SIGN, &REFINEMENT];

include!("prior_tables.rs");

/// Coder 3's models, each at its trained starting probability.
pub(super) fn primed(coder: Coder, group: usize, len: usize) -> Vec<BitModel> {
    match coder {
        Coder::V3 | Coder::V4 => {
            assert_eq!(TABLES[group].len(), len, "prior table {group} size");
            TABLES[group]
                .iter()
                .map(|&p0| BitModel::primed(p0))
                .collect()
        }
        Coder::V1 | Coder::V2 => vec![BitModel::new(); len],
    }
}
