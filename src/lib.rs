//! # wavemesh
//!
//! DEM input/output, metrics and the command line around [`wavemesh_codec`].

pub mod dem;
