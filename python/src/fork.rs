//! Fork safety. rayon's global thread pool does not survive `fork()`: a child of a process
//! whose pool had started inherits a pool whose threads are gone, and its first parallel loop
//! waits for them forever (`multiprocessing`'s default start method on Linux forks). So the
//! library's work runs in the global pool only in the process that imported the module; in a
//! forked child it runs in a pool of the child's own, built on first use (and again in a child
//! of that child).

use std::sync::{Arc, Mutex, OnceLock};

/// The process that imported the module.
static IMPORTED_IN: OnceLock<u32> = OnceLock::new();

/// The pool of a forked process, with that process's id.
static CHILD_POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);

/// Note the importing process (at module import).
pub fn init() {
    IMPORTED_IN.get_or_init(std::process::id);
}

/// Whether this process is a fork of the one that imported the module.
pub fn forked() -> bool {
    IMPORTED_IN.get().is_some_and(|&pid| pid != std::process::id())
}

/// Run `work` with rayon's global pool in the importing process, with a pool of this process's
/// own in a forked one (as many threads as the global pool would have).
pub fn install<T: Send>(work: impl FnOnce() -> T + Send) -> T {
    if !forked() {
        return work();
    }
    let pid = std::process::id();
    let pool = {
        // A lock poisoned by a panic elsewhere still guards a usable value.
        let mut slot = CHILD_POOL.lock().unwrap_or_else(|e| e.into_inner());
        match slot.as_ref() {
            Some((p, pool)) if *p == pid => Some(pool.clone()),
            _ => {
                let threads = std::thread::available_parallelism().map_or(1, usize::from);
                let built = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .ok()
                    .map(Arc::new);
                *slot = built.clone().map(|b| (pid, b));
                built
            }
        }
    };
    match pool {
        Some(p) => p.install(work),
        // No thread could be started: run on this thread, in a one-thread pool's place.
        None => work(),
    }
}
