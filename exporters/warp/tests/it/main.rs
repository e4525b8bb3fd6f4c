//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod browser;
mod cage;
mod cli;
mod common;
mod morph;
mod remap_reference;
mod warp_behaviour;
