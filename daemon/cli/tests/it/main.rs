//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod bench;
mod bvh;
mod common;
mod docs;
mod doctor;
mod fake_daemon;
mod offline;
mod take_graph;
mod take_sim;
mod takes;
mod usd;
