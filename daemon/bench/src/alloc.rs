//! The counting allocator `frond-bench` installs (one implementation for every allocation test
//! and benchmark: `frond-alloc-count`).

pub use frond_alloc_count::{CountingAlloc, count_allocations, counting_installed};
