//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod calibration_toml;
mod common;
mod field_json;
mod field_limits;
mod frame_count;
mod graph_file;
mod no_alloc;
mod rig_toml;
mod robustness;
mod take;
