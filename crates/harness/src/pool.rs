//! Running independent tasks on all cores, each single-threaded: `workers` OS threads each own a
//! one-thread rayon pool (so the solver's parallel loops run serially inside a task) and take
//! tasks from a shared queue. Exactly `workers` tasks run at a time, so a task's thread CPU time
//! measures its own work, and its result does not depend on the number of workers.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use diffsoft::base::cancel::{self, Cancel};
use indicatif::ProgressBar;

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

/// Run `tasks` on `workers` threads (at least 1), in order of the queue, ticking `bar` once per
/// finished task. Results are in task order; a task that panics gives `Err(message)`. The
/// caller's cancellation token ([`Cancel::current`]) is installed for every task.
pub fn run<'a, T: Send>(tasks: Vec<Task<'a, T>>, workers: usize, bar: &ProgressBar) -> Vec<Result<T, String>> {
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
                let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build();
                loop {
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
                    bar.inc(1);
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
        let r = run(tasks, 2, &ProgressBar::hidden());
        assert_eq!(r.len(), 7);
        for (i, x) in r.iter().enumerate() {
            match x {
                Ok(v) => assert_eq!(*v, i * 10),
                Err(m) => assert!(i == 3 && m.contains("task three"), "{m}"),
            }
        }
    }
}
