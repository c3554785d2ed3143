//! # wavemesh
//!
//! DEM input/output, metrics and the command line around [`wavemesh_codec`].

pub mod atomic;
pub mod byte_source;
pub mod dem;
pub mod fuzzing;
pub mod lod;
pub mod memory;
pub mod mesh;
pub mod meshers;
pub mod metrics;
pub mod report;
pub mod synth;
pub mod tiled_encode;
pub mod view;
