//! The crate's integration tests, one binary (one link instead of one per file: linking the
//! test binaries was a large part of CI's build). Each module is what was one test file.

mod element_id_wire;
mod field_of_rig;
mod frames;
