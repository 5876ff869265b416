//! Running independent tasks on all cores, each single-threaded ([`diffsoft::base::tasks`]:
//! `workers` OS threads each own a one-thread rayon pool, so the solver's parallel loops run
//! serially inside a task, and take tasks from a shared queue). Exactly `workers` tasks run at a
//! time, so a task's thread CPU time measures its own work, and its result does not depend on
//! the number of workers.
//!
//! Several [`run`]s can share the cores: [`concurrently`] runs jobs (each a sequence of
//! [`run`]s with a little work of its own in between) on threads of their own, which take the
//! cores for their tasks from one budget, so one job's phase tail (its last tasks, with
//! workers left idle) overlaps another job's work and still at most that many tasks run at once.

use std::cell::RefCell;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};

use diffsoft::base::cancel::{self, Cancel};
use diffsoft::base::tasks;
use indicatif::ProgressBar;

pub use diffsoft::base::tasks::{panic_message, Task};

/// A budget of cores, handed out first come, first served (a ticket queue: a worker that
/// finishes a task and asks again waits behind the ones already waiting).
struct Cores {
    turns: Mutex<Turns>,
    changed: Condvar,
}

struct Turns {
    free: usize,
    /// The next ticket to hand out.
    next: u64,
    /// The ticket whose turn it is.
    serving: u64,
}

/// A core taken from [`Cores`], given back when dropped (also when its holder unwinds).
struct Held<'a>(&'a Cores);

/// A core given back for a while, taken again when dropped.
struct Lent<'a>(&'a Cores);

impl Cores {
    fn new(n: usize) -> Arc<Self> {
        Arc::new(Self {
            turns: Mutex::new(Turns {
                free: n.max(1),
                next: 0,
                serving: 0,
            }),
            changed: Condvar::new(),
        })
    }

    fn lock(&self) -> MutexGuard<'_, Turns> {
        self.turns.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn acquire(&self) {
        let mut t = self.lock();
        let ticket = t.next;
        t.next += 1;
        while t.serving != ticket || t.free == 0 {
            t = self.changed.wait(t).unwrap_or_else(PoisonError::into_inner);
        }
        t.serving += 1;
        t.free -= 1;
        // The next ticket may go at once when a core is still free.
        self.changed.notify_all();
    }

    fn release(&self) {
        self.lock().free += 1;
        self.changed.notify_all();
    }

    fn hold(&self) -> Held<'_> {
        self.acquire();
        Held(self)
    }

    fn lend(&self) -> Lent<'_> {
        self.release();
        Lent(self)
    }
}

impl Drop for Held<'_> {
    fn drop(&mut self) {
        self.0.release();
    }
}

impl Drop for Lent<'_> {
    fn drop(&mut self) {
        self.0.acquire();
    }
}

thread_local! {
    /// The budget of the [`concurrently`] job running on this thread (which holds one of its
    /// cores while it is not waiting for tasks).
    static SHARED: RefCell<Option<Arc<Cores>>> = const { RefCell::new(None) };
}

/// The budget a [`run`] or [`concurrently`] on this thread takes its cores from: the job's
/// shared one, whose core the caller lends to its tasks while it waits for them, or `own`.
fn budget(own: usize) -> (Arc<Cores>, bool) {
    match SHARED.with(|s| s.borrow().clone()) {
        Some(shared) => (shared, true),
        None => (Cores::new(own), false),
    }
}

/// Run `tasks` on `workers` threads (at least 1), in order of the queue, ticking `bar` once per
/// finished task. Results are in task order; a task that panics gives `Err(message)`. The
/// caller's cancellation token ([`Cancel::current`]) is installed for every task.
///
/// Called from a job of [`concurrently`], the tasks take their cores from the jobs' shared
/// budget (still at most `workers` of this run's at once). Tasks themselves run outside any
/// shared budget: a [`run`] inside a task has a budget of its own (inside a task
/// `rayon::current_num_threads()` is 1, so `run(tasks, rayon::current_num_threads(), ..)` there
/// runs its tasks one after another).
pub fn run<'a, T: Send>(tasks: Vec<Task<'a, T>>, workers: usize, bar: &ProgressBar) -> Vec<Result<T, String>> {
    let workers = workers.clamp(1, tasks.len().max(1));
    let (cores, shared) = budget(workers);
    let _lent = shared.then(|| cores.lend());
    tasks::run_gated(tasks, workers, 1, &|| bar.inc(1), &|| cores.hold())
}

/// Run `jobs` at once, each on a thread of its own, sharing `cores` cores (at least 1): a job
/// holds one while it works itself, and lends it to its tasks while it waits in [`run`], whose
/// tasks take theirs from the same budget. So at most `cores` threads work at any time, however
/// the jobs' phases interleave. Results are in job order; a job that panics panics here. The
/// caller's cancellation token is installed for every job. Called from a job, the jobs share
/// that job's budget instead.
///
/// A job should do little work of its own outside [`run`] (it runs on the caller's rayon pool,
/// not a one-thread one).
pub fn concurrently<'a, T: Send>(jobs: Vec<Task<'a, T>>, cores: usize) -> Vec<T> {
    let (cores, shared) = budget(cores);
    let _lent = shared.then(|| cores.lend());
    let token = Cancel::current();
    std::thread::scope(|scope| {
        let handles: Vec<_> = jobs
            .into_iter()
            .map(|job| {
                let (cores, token) = (&cores, &token);
                scope.spawn(move || {
                    let _core = cores.hold();
                    SHARED.with(|s| *s.borrow_mut() = Some(Arc::clone(cores)));
                    cancel::within(token.as_ref(), job)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    })
}

/// [`concurrently`] for two jobs of different result types.
pub fn both<'a, A: Send + 'a, B: Send + 'a>(
    a: impl FnOnce() -> A + Send + 'a,
    b: impl FnOnce() -> B + Send + 'a,
    cores: usize,
) -> (A, B) {
    enum Either<A, B> {
        A(A),
        B(B),
    }
    let jobs: Vec<Task<'a, Either<A, B>>> = vec![Box::new(move || Either::A(a())), Box::new(move || Either::B(b()))];
    match <[_; 2]>::try_from(concurrently(jobs, cores)) {
        Ok([Either::A(a), Either::B(b)]) => (a, b),
        _ => unreachable!("concurrently returns its jobs' results in order"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

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

    #[test]
    fn concurrent_jobs_share_the_cores() {
        let (active, most) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let work = |x: usize| {
            let now = active.fetch_add(1, Ordering::SeqCst) + 1;
            most.fetch_max(now, Ordering::SeqCst);
            std::thread::sleep(std::time::Duration::from_millis(2));
            active.fetch_sub(1, Ordering::SeqCst);
            x
        };
        let work = &work;
        // Each job: two phases of tasks, each task with a nested run of its own.
        let jobs: Vec<Task<'_, Vec<usize>>> = (0..3)
            .map(|j| -> Task<'_, Vec<usize>> {
                Box::new(move || {
                    let mut out = Vec::new();
                    for phase in 0..2 {
                        let tasks: Vec<Task<'_, usize>> = (0..5)
                            .map(|i| -> Task<'_, usize> {
                                Box::new(move || {
                                    let inner: Vec<Task<'_, usize>> =
                                        vec![Box::new(move || work(100 * j + 10 * phase + i))];
                                    let r = run(inner, rayon::current_num_threads(), &ProgressBar::hidden());
                                    r.into_iter().map(|x| x.unwrap_or(usize::MAX)).sum()
                                })
                            })
                            .collect();
                        out.extend(
                            run(tasks, 2, &ProgressBar::hidden())
                                .into_iter()
                                .map(|x| x.unwrap_or(0)),
                        );
                    }
                    out
                })
            })
            .collect();
        let r = concurrently(jobs, 2);
        for (j, v) in r.iter().enumerate() {
            let want: Vec<usize> = (0..2).flat_map(|p| (0..5).map(move |i| 100 * j + 10 * p + i)).collect();
            assert_eq!(*v, want);
        }
        assert!(
            most.load(Ordering::SeqCst) <= 2,
            "{} tasks at once",
            most.load(Ordering::SeqCst)
        );
        let (a, b) = both(|| 1, || "two", 2);
        assert_eq!((a, b), (1, "two"));
    }
}
