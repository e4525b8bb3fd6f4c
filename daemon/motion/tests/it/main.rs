//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod common;
mod filters;
mod graph_no_alloc;
mod live_no_alloc;
mod mapping;
mod pure;
mod rig_files;
mod sim_no_alloc;
mod skinning;
