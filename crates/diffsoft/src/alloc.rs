//! A counting global allocator (installed by the `diffsoft` binary and by the allocation tests)
//! so reports can state the peak heap use of a computation and tests can check that a loop
//! allocates nothing. Without it installed, the counters stay at zero and [`peak_since_reset`]
//! and [`allocations`] return `None`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static BASE: AtomicUsize = AtomicUsize::new(0);
static ACTIVE: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

/// The system allocator with live-byte and peak counters, installed as the global allocator:
///
/// ```
/// use diffsoft::alloc::{allocations, peak_since_reset, reset_peak, Counting};
///
/// #[global_allocator]
/// static ALLOC: Counting = Counting;
///
/// fn main() -> Result<(), Box<dyn std::error::Error>> {
///     reset_peak();
///     let before = allocations().ok_or("not installed")?;
///     let buffer = vec![1u8; 1 << 20];
///     assert!(peak_since_reset().ok_or("not installed")? >= 1 << 20);
///     assert!(allocations().ok_or("not installed")? > before);
///     drop(buffer);
///     Ok(())
/// }
/// ```
#[derive(Debug, Default)]
pub struct Counting;

// SAFETY: forwards every call to the system allocator unchanged; only counts bytes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: same contract as the caller's.
        let p = unsafe { System.alloc(layout) };
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        if !p.is_null() {
            let now = CURRENT.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
            ACTIVE.store(true, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: same contract as the caller's.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        if !p.is_null() {
            if new_size >= layout.size() {
                let now = CURRENT.fetch_add(new_size - layout.size(), Ordering::Relaxed) + new_size - layout.size();
                PEAK.fetch_max(now, Ordering::Relaxed);
            } else {
                CURRENT.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

/// Start a new peak measurement from the current heap size.
pub fn reset_peak() {
    let now = CURRENT.load(Ordering::Relaxed);
    BASE.store(now, Ordering::Relaxed);
    PEAK.store(now, Ordering::Relaxed);
}

/// Peak heap growth since [`reset_peak`] (bytes), if the counting allocator is installed.
pub fn peak_since_reset() -> Option<usize> {
    ACTIVE.load(Ordering::Relaxed).then(|| {
        PEAK.load(Ordering::Relaxed)
            .saturating_sub(BASE.load(Ordering::Relaxed))
    })
}

/// Calls to `alloc` and `realloc` so far (all threads), if the counting allocator is installed.
pub fn allocations() -> Option<usize> {
    ACTIVE
        .load(Ordering::Relaxed)
        .then(|| ALLOCATIONS.load(Ordering::Relaxed))
}
