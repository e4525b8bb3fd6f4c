//! The counting global allocator of the allocation tests (`frond-alloc-count`): it counts the
//! allocations of the thread that asked for counting only (the test harness's threads may
//! allocate at any time).

use frond_alloc_count::{CountingAlloc, count_allocations};

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

/// Runs `f` and returns its result with the number of allocations this thread made meanwhile.
pub fn allocations_in<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let (r, n) = count_allocations(f);
    (r, n as usize)
}
