//! Reading a `.ezw` file without decoding it: the header and its records, the
//! checksums of every section, and where each pass ends — what `info` and `verify`
//! tools need. The byte layout is specified in `codec/FORMAT.md`.

pub use crate::container::{
    physical_offset, stored_georef, verify, SectionCheck, Tiling, Verification, MAGIC, VERSION,
};
pub use crate::container::{Header, Mode};
pub use crate::ezw::{Coder, PassRecord};
pub use crate::mask::valid_sample_count;
pub use crate::quantize::ValueMapping;
