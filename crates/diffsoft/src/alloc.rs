//! A counting global allocator (installed by the `diffsoft` binary and by the allocation tests)
//! so reports can state the peak heap use of a computation and tests can check that a loop
//! allocates nothing. Without it installed, the counters stay at zero and [`peak_since_reset`]
//! and [`allocations`] return `None`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static BASE: AtomicUsize = AtomicUsize::new(0);
static ACTIVE: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// This thread's scope of [`thread_peak`]: whether one is open, the bytes allocated minus
    /// freed on this thread since it opened, and their largest value. Constant-initialised
    /// cells of plain data: reading them allocates nothing, as an allocator must not.
    static SCOPE: Cell<(bool, isize, isize)> = const { Cell::new((false, 0, 0)) };
}

/// Count `delta` bytes (allocated: positive, freed: negative) in this thread's open scope.
fn scope_add(delta: isize) {
    // `try_with`: a thread being torn down has no scope to count in.
    let _ = SCOPE.try_with(|s| {
        let (open, now, peak) = s.get();
        if open {
            let now = now + delta;
            s.set((true, now, peak.max(now)));
        }
    });
}

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
            scope_add(layout.size() as isize);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::Relaxed);
        scope_add(-(layout.size() as isize));
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
            scope_add(new_size as isize - layout.size() as isize);
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

/// Run `f` and return its result with the peak heap growth of the calling thread during it
/// (bytes allocated minus freed on this thread, at their largest), if the counting allocator
/// is installed. Unlike [`peak_since_reset`] it is not disturbed by other threads, so
/// measurements can run side by side; it sees only this thread's allocations, so `f` should
/// run single-threaded (a task of [`crate::base::tasks`], or inside a one-thread rayon pool).
/// Memory freed during `f` that was allocated before it lowers the count, as it lowers the
/// heap. Scopes nest: an inner one is measured from its own start.
///
/// ```
/// use diffsoft::alloc::{thread_peak, Counting};
///
/// #[global_allocator]
/// static ALLOC: Counting = Counting;
///
/// fn main() -> Result<(), Box<dyn std::error::Error>> {
///     let (len, peak) = thread_peak(|| vec![0u8; 1 << 20].len());
///     assert_eq!(len, 1 << 20);
///     assert!(peak.ok_or("not installed")? >= 1 << 20);
///     Ok(())
/// }
/// ```
pub fn thread_peak<R>(f: impl FnOnce() -> R) -> (R, Option<usize>) {
    let outer = SCOPE.with(|s| s.replace((true, 0, 0)));
    let r = f();
    let (_, now, peak) = SCOPE.with(|s| s.replace(outer));
    // The enclosing scope sees this one's net change, and its peak on top of where it stood.
    if outer.0 {
        SCOPE.with(|s| s.set((true, outer.1 + now, outer.2.max(outer.1 + peak))));
    }
    let installed = ACTIVE.load(Ordering::Relaxed);
    (r, installed.then_some(peak.max(0) as usize))
}

/// Reserve, on the calling thread, the buffers the dense kernels keep for the thread's
/// lifetime, so that a peak measured afterwards ([`thread_peak`]) is the computation's own.
/// faer's matrix products above a small size pack their operands into a per-thread buffer
/// allocated on the thread's first such product and never freed: twice the L3 cache's size
/// (629 MB on this project's machine, which reports a 315 MB L3), reserved but touched only as
/// far as the products need. The contact solve's dense LU reaches it once its systems are a
/// few dozen unknowns, so without this call the first large contact set on a fresh thread
/// shows as hundreds of megabytes.
pub fn reserve_thread_buffers() {
    use faer::linalg::matmul::matmul;
    use faer::{Accum, Mat, Par};
    // 32^3 products: above faer's threshold (16^3) for its small-matrix kernels.
    let a = Mat::<f64>::identity(32, 32);
    let mut c = Mat::<f64>::zeros(32, 32);
    matmul(c.as_mut(), Accum::Replace, a.as_ref(), a.as_ref(), 1.0, Par::Seq);
    std::hint::black_box(&c);
}
