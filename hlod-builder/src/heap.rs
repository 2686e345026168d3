//! Heap accounting for the bounded-memory build, through `peak_alloc`'s
//! counting allocator: `hlod-build` (and the tests that check the limit)
//! install [`Counting`] as the global allocator and call [`mark_installed`];
//! elsewhere the build plans from estimates alone and reports no peak.

use std::sync::atomic::{AtomicBool, Ordering};

/// The system allocator, counted (install with `#[global_allocator]`).
pub use peak_alloc::PeakAlloc as Counting;

static INSTALLED: AtomicBool = AtomicBool::new(false);

/// Says that [`Counting`] is the global allocator, so that its counters mean something.
pub fn mark_installed() {
    INSTALLED.store(true, Ordering::Relaxed);
}

/// Heap bytes in use now, when counted.
pub fn in_use() -> Option<u64> {
    INSTALLED
        .load(Ordering::Relaxed)
        .then(|| Counting.current_usage() as u64)
}

/// The most heap bytes in use at once since the last [`reset_peak`], when counted.
pub fn peak() -> Option<u64> {
    INSTALLED
        .load(Ordering::Relaxed)
        .then(|| Counting.peak_usage() as u64)
}

/// Starts a new peak from what is in use now.
pub fn reset_peak() {
    Counting.reset_peak_usage();
}
