//! # wavemesh
//!
//! DEM input/output, metrics and the command line around [`wavemesh_codec`].

pub mod atomic;
pub mod dem;
pub mod fuzzing;
pub mod memory;
pub mod metrics;
pub mod report;
