//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod config;
mod device;
mod field;
mod graph_file;
mod http;
mod motion;
mod osc;
mod protocol;
mod triggers;
mod webcam;
