//! Heap allocations counted per thread, for the zero-allocation tests: a
//! test binary installs [`CountingAllocator`] as its global allocator and
//! measures a closure with [`allocations_in`] (or two readings of
//! [`allocations`] around an `.await` on a current-thread runtime). Each
//! thread counts only its own allocations, so tests running in parallel do
//! not disturb each other's counts.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// The system allocator, counting every allocation on the calling thread
/// (reallocations too: the default `realloc` routes through `alloc`).
///
/// Install it in a test binary with
/// `#[global_allocator] static GLOBAL: CountingAllocator = CountingAllocator;`;
/// without that, [`allocations`] stays 0.
#[derive(Debug)]
pub struct CountingAllocator;

// A counting global allocator needs `unsafe impl GlobalAlloc`; it only
// forwards to `System`.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|n| n.set(n.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System.alloc` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Allocations made on this thread so far, through [`CountingAllocator`].
pub fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

/// Runs `f` and returns how many allocations it made on this thread.
pub fn allocations_in(f: impl FnOnce()) -> usize {
    let before = allocations();
    f();
    allocations() - before
}
