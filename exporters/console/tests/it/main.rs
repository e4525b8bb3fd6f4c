//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod cli;
mod field_page;
mod http;
