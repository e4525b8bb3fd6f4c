//! A counting global allocator for allocation-per-tick measurements, the one every allocation
//! test and `frond-bench` install.
//!
//! Install it with `#[global_allocator] static A: CountingAlloc = CountingAlloc;` (in a test
//! binary, or `frond-bench`). Disabled, it costs one relaxed load of a static per allocation
//! before calling the system allocator; counting is per thread, switched on by
//! [`count_allocations`] for the closure it runs.

#![warn(missing_docs)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// The system allocator, counting allocations (and reallocations) on threads that ask for it.
pub struct CountingAlloc;

/// Threads currently counting; 0 keeps the fast path to a single load.
static ACTIVE: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<u64> = const { Cell::new(0) };
}

#[inline]
fn note() {
    if ACTIVE.load(Relaxed) != 0 && COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    }
}

// SAFETY: every call is passed to the system allocator unchanged; the only extra work touches
// const-initialised thread-locals without destructors, which never allocate.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: same contract as our caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note();
        // SAFETY: same contract as our caller's.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as our caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        // SAFETY: same contract as our caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Runs `f` and returns its result with the number of allocations it made on this thread.
/// Always 0 when [`CountingAlloc`] is not the global allocator: see [`counting_installed`].
pub fn count_allocations<R>(f: impl FnOnce() -> R) -> (R, u64) {
    ACTIVE.fetch_add(1, Relaxed);
    let before = COUNT.with(Cell::get);
    COUNTING.with(|c| c.set(true));
    let r = f();
    COUNTING.with(|c| c.set(false));
    let after = COUNT.with(Cell::get);
    ACTIVE.fetch_sub(1, Relaxed);
    (r, after - before)
}

/// Whether this process counts allocations (one probe allocation must be seen).
pub fn counting_installed() -> bool {
    let (_, n) = count_allocations(|| std::hint::black_box(Box::new(7u64)));
    n >= 1
}
