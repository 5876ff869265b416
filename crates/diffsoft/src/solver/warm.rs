//! Keeping the pool's workers awake through the short serial global step between two parallel
//! local steps.
//!
//! A sleeping rayon worker takes tens of microseconds to wake (on the 2-core virtual machines
//! this project targets, a `join` of two 50 us tasks issued after a 0.5 ms serial gap takes
//! about 110 us instead of 52 us, i.e. it runs serially). A local-global iteration on a few
//! thousand tets is a few hundred microseconds, so that latency would eat most of the parallel
//! gain. [`keep_warm`] runs the serial section on the calling worker while the other workers
//! spin on a flag (a `join`, so nothing is allocated), with a cap so a long serial section lets
//! them sleep.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Longest time a worker spins waiting for the serial section to end.
const MAX_SPIN: Duration = Duration::from_millis(2);

/// Run `f` on this thread while the other workers of the current rayon pool spin until it
/// returns (or 2 ms pass). Outside a pool, or with one thread, just runs `f`.
pub fn keep_warm<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    let threads = rayon::current_num_threads();
    if threads < 2 || rayon::current_thread_index().is_none() {
        return f();
    }
    let done = AtomicBool::new(false);
    let (r, ()) = rayon::join(
        || {
            let r = f();
            done.store(true, Ordering::Release);
            r
        },
        || spin_all(threads - 1, &done),
    );
    r
}

/// [`keep_warm`], or just `f` when `parallel` (a section with parallel work of its own needs
/// the workers free).
pub fn keep_warm_unless<R: Send>(parallel: bool, f: impl FnOnce() -> R + Send) -> R {
    if parallel {
        f()
    } else {
        keep_warm(f)
    }
}

/// `n` spinners, one per stolen `join` half (a half not stolen runs after `done` is set and
/// returns at once).
fn spin_all(n: usize, done: &AtomicBool) {
    if n <= 1 {
        spin(done);
    } else {
        rayon::join(|| spin(done), || spin_all(n - 1, done));
    }
}

fn spin(done: &AtomicBool) {
    let start = Instant::now();
    let mut k = 0u32;
    while !done.load(Ordering::Acquire) {
        std::hint::spin_loop();
        k = k.wrapping_add(1);
        if k.is_multiple_of(1024) && start.elapsed() > MAX_SPIN {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn returns_the_result_in_and_outside_a_pool() {
        assert_eq!(keep_warm(|| 7), 7);
        for n in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
            assert_eq!(pool.install(|| keep_warm(|| 2 + 3)), 5);
        }
    }
}
