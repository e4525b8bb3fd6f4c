//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod addon_fuzz;
mod blender;
mod blender_meadow;
mod cli;
mod e2e;
mod encode_bytes;
mod encode_field;
mod parsers;
mod sender;
mod support;
