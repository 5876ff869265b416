//! Long calls that Ctrl-C can stop: the work runs on a worker thread without the GIL while the
//! calling thread polls Python's signal handlers every [`POLL`]. When a handler raises (a
//! `KeyboardInterrupt`, or whatever a user's handler raises), the work's cancellation token
//! ([`diffsoft::base::cancel`]) is cancelled, the worker stops within its current step, its partial
//! result is dropped, and the handler's exception is raised. Nothing the call was given is
//! changed, so the scene stays usable.

use std::sync::mpsc;
use std::time::Duration;

use diffsoft::base::cancel::Cancel;
use pyo3::prelude::*;

/// How often signal handlers run during a call.
const POLL: Duration = Duration::from_millis(50);

/// Run `work` without the GIL, raising the exception of a signal handler (Ctrl-C:
/// `KeyboardInterrupt`) within [`POLL`] of the signal.
pub fn run<T: Send>(py: Python<'_>, work: impl FnOnce() -> T + Send) -> PyResult<T> {
    let token = Cancel::new();
    std::thread::scope(|scope| {
        let (tx, mut rx) = mpsc::channel();
        let worker = {
            let token = token.clone();
            scope.spawn(move || {
                let out = token.scope(|| crate::fork::install(work));
                // The receiver lives until the worker is joined.
                let _ = tx.send(out);
            })
        };
        let finish = |worker: std::thread::ScopedJoinHandle<'_, ()>| {
            worker
                .join()
                .map_err(|p| crate::errors::panicked(diffsoft::base::tasks::panic_message(p.as_ref())))
        };
        match wait(py, &mut rx) {
            Ok(Some(out)) => {
                finish(worker)?;
                Ok(out)
            }
            Ok(None) => {
                // The worker ended without a result: it panicked.
                finish(worker)?;
                Err(crate::errors::panicked("the call ended without a result"))
            }
            Err(signal) => {
                token.cancel();
                // The worker stops at its next step; its result is not wanted.
                let _ = py.detach(|| finish(worker));
                Err(signal)
            }
        }
    })
}

/// Run `work` on a thread of its own without the GIL, raising the exception of a signal handler
/// (Ctrl-C: `KeyboardInterrupt`) within [`POLL`] of the signal. Unlike [`run`], the work is not
/// waited for after a signal: this is for reading files, which can block in the system (a named
/// pipe nobody writes to) where no cancellation token reaches; the abandoned thread ends when
/// its read returns, and its result is dropped.
pub fn abandonable<T: Send + 'static>(py: Python<'_>, work: impl FnOnce() -> T + Send + 'static) -> PyResult<T> {
    let (tx, mut rx) = mpsc::channel();
    std::thread::Builder::new()
        .name("diffsoft-read".into())
        .spawn(move || {
            let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| crate::fork::install(work)));
            // Nobody receives after a signal: the result is dropped.
            let _ = tx.send(out);
        })
        .map_err(|e| crate::errors::other(format!("cannot start a thread to read the file: {e}")))?;
    match wait(py, &mut rx)? {
        Some(Ok(out)) => Ok(out),
        Some(Err(panic)) => Err(crate::errors::panicked(diffsoft::base::tasks::panic_message(
            panic.as_ref(),
        ))),
        None => Err(crate::errors::panicked("the call ended without a result")),
    }
}

/// Wait for the value `rx` receives, without the GIL, running Python's signal handlers every
/// [`POLL`] while none has come: `Some(value)`, `None` when the sender is gone without one, or
/// the exception a handler raised (the caller decides what becomes of the work). The receiver
/// stays the caller's, so a worker's later send still finds it.
fn wait<T: Send>(py: Python<'_>, rx: &mut mpsc::Receiver<T>) -> PyResult<Option<T>> {
    loop {
        // A receiver is not `Sync`: the wait borrows it mutably, which is `Send`.
        let borrowed = &mut *rx;
        match py.detach(move || borrowed.recv_timeout(POLL)) {
            Ok(out) => return Ok(Some(out)),
            Err(mpsc::RecvTimeoutError::Disconnected) => return Ok(None),
            Err(mpsc::RecvTimeoutError::Timeout) => py.check_signals()?,
        }
    }
}
