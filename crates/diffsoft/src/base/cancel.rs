//! Cooperative cancellation of long calls (a Python caller's Ctrl-C, a host's deadline).
//!
//! A [`Cancel`] token is installed for the current thread by [`Cancel::scope`]; the step loops
//! of the simulator and of the backward passes ask [`requested`] before every step (and a
//! step asks again in its iterations, contact rounds and contact solves), and stop
//! with an "interrupted" error once the token is cancelled. Code that fans work out to other
//! threads (a pool, a rayon `par_iter`) passes the token on with [`Cancel::current`] and
//! `scope` in each worker. Without a token installed nothing is ever cancelled, and the check
//! costs one thread-local read.

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

thread_local! {
    static CURRENT: RefCell<Option<Cancel>> = const { RefCell::new(None) };
}

/// A cancellation flag shared by the caller (who cancels) and the work (which polls).
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A token not yet cancelled.
    ///
    /// ```
    /// use diffsoft::base::cancel::{self, Cancel};
    ///
    /// let token = Cancel::new();
    /// assert!(!token.scope(cancel::requested));
    /// token.cancel();
    /// assert!(token.scope(cancel::requested));
    /// // Outside the scope nothing is requested.
    /// assert!(!cancel::requested());
    /// ```
    pub fn new() -> Self {
        Self::default()
    }

    /// Ask the work that holds this token to stop at its next check.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// Whether [`cancel`](Self::cancel) was called.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }

    /// Run `f` with this token installed for the current thread (the previous one is restored
    /// afterwards, also when `f` unwinds).
    pub fn scope<T>(&self, f: impl FnOnce() -> T) -> T {
        struct Restore(Option<Cancel>);
        impl Drop for Restore {
            fn drop(&mut self) {
                let previous = self.0.take();
                CURRENT.with(|c| *c.borrow_mut() = previous);
            }
        }
        let previous = CURRENT.with(|c| c.borrow_mut().replace(self.clone()));
        let _restore = Restore(previous);
        f()
    }

    /// The token installed for the current thread, to pass on to workers.
    pub fn current() -> Option<Cancel> {
        CURRENT.with(|c| c.borrow().clone())
    }
}

/// Run `f` under `token` when there is one (a worker's side of [`Cancel::current`]).
pub fn within<T>(token: Option<&Cancel>, f: impl FnOnce() -> T) -> T {
    match token {
        Some(t) => t.scope(f),
        None => f(),
    }
}

/// Whether the token installed for the current thread has been cancelled.
pub fn requested() -> bool {
    CURRENT.with(|c| c.borrow().as_ref().is_some_and(Cancel::is_cancelled))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scopes_nest_and_restore() {
        let (outer, inner) = (Cancel::new(), Cancel::new());
        outer.cancel();
        outer.scope(|| {
            assert!(requested());
            inner.scope(|| assert!(!requested()));
            assert!(requested());
        });
        assert!(!requested());
        assert!(Cancel::current().is_none());
    }

    #[test]
    fn a_token_reaches_a_worker_thread_only_when_passed_on() {
        let t = Cancel::new();
        t.cancel();
        t.scope(|| {
            let passed = Cancel::current();
            std::thread::scope(|s| {
                assert!(!s.spawn(requested).join().unwrap());
                assert!(s.spawn(|| within(passed.as_ref(), requested)).join().unwrap());
            });
        });
    }
}
