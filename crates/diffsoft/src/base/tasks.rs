//! Independent tasks on all cores, each single-threaded: `workers` OS threads each own a
//! one-thread rayon pool (so the solver's parallel loops run serially inside a task) and take
//! tasks from a shared queue. At most `workers` tasks run at a time and none of them splits
//! further, so a batch of runs scales like as many independent processes (no nested
//! parallelism, no oversubscription), a task's thread CPU time measures its own work, and its
//! result does not depend on the number of workers. The batches of the Python package and the
//! harness's studies run on it.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use super::cancel::{self, Cancel};

/// A task.
pub type Task<'a, T> = Box<dyn FnOnce() -> T + Send + 'a>;

/// The text of a panic payload.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-text payload".into()
    }
}

/// Run `tasks` on `workers` threads (at least 1, at most one per task), in queue order, calling
/// `done()` once per finished task. Results are in task order; a task that panics gives
/// `Err(message)`. The caller's cancellation token ([`Cancel::current`]) is installed for
/// every task.
///
/// ```
/// use diffsoft::base::tasks::{run, Task};
///
/// let tasks: Vec<Task<'_, usize>> = (0..4)
///     .map(|i| -> Task<'_, usize> { Box::new(move || i * rayon::current_num_threads()) })
///     .collect();
/// let out: Vec<usize> = run(tasks, 2, &|| {}).into_iter().map(Result::unwrap).collect();
/// assert_eq!(out, [0, 1, 2, 3]); // each task saw a one-thread pool
/// ```
pub fn run<'a, T: Send>(tasks: Vec<Task<'a, T>>, workers: usize, done: &(dyn Fn() + Sync)) -> Vec<Result<T, String>> {
    run_pools(tasks, workers, 1, done)
}

/// [`run`] with `threads_each` threads in each worker's pool.
fn run_pools<'a, T: Send>(
    tasks: Vec<Task<'a, T>>,
    workers: usize,
    threads_each: usize,
    done: &(dyn Fn() + Sync),
) -> Vec<Result<T, String>> {
    run_gated(tasks, workers, threads_each, done, &|| ())
}

/// [`run`] with `threads_each` threads in each worker's pool, where a worker calls `gate()`
/// before it takes each task and holds what it returns (a guard) until the task is done: a
/// caller that shares a budget of cores among several runs makes the gate wait for a core.
///
/// ```
/// use std::sync::atomic::{AtomicUsize, Ordering};
/// use diffsoft::base::tasks::{run_gated, Task};
///
/// let gates = AtomicUsize::new(0);
/// let tasks: Vec<Task<'_, usize>> = (0..3).map(|i| -> Task<'_, usize> { Box::new(move || i) }).collect();
/// let out = run_gated(tasks, 2, 1, &|| {}, &|| {
///     gates.fetch_add(1, Ordering::Relaxed);
/// });
/// assert_eq!(out, [Ok(0), Ok(1), Ok(2)]);
/// // Once per task, and once more per worker that found the queue empty.
/// assert!(gates.into_inner() >= 3);
/// ```
pub fn run_gated<'a, T: Send, G>(
    tasks: Vec<Task<'a, T>>,
    workers: usize,
    threads_each: usize,
    done: &(dyn Fn() + Sync),
    gate: &(dyn Fn() -> G + Sync),
) -> Vec<Result<T, String>> {
    let n = tasks.len();
    let queue: Vec<Mutex<Option<Task<'a, T>>>> = tasks.into_iter().map(|t| Mutex::new(Some(t))).collect();
    let results: Vec<Mutex<Option<Result<T, String>>>> = (0..n).map(|_| Mutex::new(None)).collect();
    let next = AtomicUsize::new(0);
    let workers = workers.clamp(1, n.max(1));
    // The caller's cancellation token reaches every task (they run on other threads).
    let token = Cancel::current();
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads_each).build();
                loop {
                    let _gate = gate();
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n {
                        break;
                    }
                    let task = queue[i].lock().map(|mut g| g.take()).ok().flatten();
                    let Some(task) = task else {
                        continue;
                    };
                    let task = || cancel::within(token.as_ref(), task);
                    let r = match &pool {
                        Ok(p) => p.install(|| catch_unwind(AssertUnwindSafe(task))),
                        Err(_) => catch_unwind(AssertUnwindSafe(task)),
                    };
                    let r = r.map_err(|p| panic_message(p.as_ref()));
                    if let Ok(mut slot) = results[i].lock() {
                        *slot = Some(r);
                    }
                    done();
                }
            });
        }
    });
    results
        .into_iter()
        .map(|m| {
            m.into_inner()
                .ok()
                .flatten()
                .unwrap_or_else(|| Err("task did not run".into()))
        })
        .collect()
}

/// `f` of every item on the current rayon pool's threads: one worker per item up to the
/// number of threads, each item single-threaded when there are at least as many items as
/// threads, and the threads shared out among the workers when there are fewer (one item gets
/// them all). The batches' default.
pub fn map_each<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<Result<R, String>> {
    let f = &f;
    let tasks: Vec<Task<'_, R>> = items
        .iter()
        .map(|x| -> Task<'_, R> { Box::new(move || f(x)) })
        .collect();
    let threads = rayon::current_num_threads().max(1);
    let workers = threads.min(items.len()).max(1);
    run_pools(tasks, workers, threads / workers, &|| {})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_in_order_panics_reported_one_thread_each() {
        let tasks: Vec<Task<'_, usize>> = (0..7)
            .map(|i| -> Task<'_, usize> {
                Box::new(move || {
                    if i == 3 {
                        panic!("task three");
                    }
                    assert_eq!(rayon::current_num_threads(), 1);
                    i * 10
                })
            })
            .collect();
        let count = AtomicUsize::new(0);
        let r = run(tasks, 3, &|| {
            count.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(count.into_inner(), 7);
        for (i, x) in r.iter().enumerate() {
            match x {
                Ok(v) => assert_eq!(*v, i * 10),
                Err(m) => {
                    assert_eq!(i, 3);
                    assert!(m.contains("task three"));
                }
            }
        }
    }

    #[test]
    fn map_each_keeps_order_and_shares_threads() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
        let items: Vec<usize> = (0..20).collect();
        let r: Vec<(usize, usize)> = pool.install(|| {
            map_each(&items, |x| (x * 2, rayon::current_num_threads()))
                .into_iter()
                .map(Result::unwrap)
                .collect()
        });
        assert_eq!(r, items.iter().map(|x| (x * 2, 1)).collect::<Vec<_>>());
        // Fewer items than threads: the threads are shared out.
        let two = pool.install(|| map_each(&[0, 1], |_| rayon::current_num_threads()));
        assert_eq!(two, [Ok(2), Ok(2)]);
        let one = pool.install(|| map_each(&[0], |_| rayon::current_num_threads()));
        assert_eq!(one, [Ok(4)]);
    }
}
