//! Long calls that Ctrl-C stops. Python runs signal handlers only on its main thread, and
//! a call that releases the GIL and waits for its work (rayon's workers) never looks for
//! them: Ctrl-C waited for the end of a sweep or a batch. Here the work runs on a scoped
//! thread without the GIL while the calling thread checks for signals every
//! [`CHECK_PERIOD`]; on one (the handler's exception: `KeyboardInterrupt` for Ctrl-C) the
//! work's stop flag is set, the work ends at its next check (a workspace ray, a batch
//! row, a trajectory step) and the exception is raised. Starting the thread costs tens of
//! microseconds, so short calls run on the calling thread as before ([`MIN_ROWS`]).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// How often the calling thread looks for signals.
const CHECK_PERIOD: Duration = Duration::from_millis(50);

/// Batches and trajectories of fewer rows run on the calling thread, not interruptible
/// (a thread's start is tens of microseconds, a warm step 20–150 µs; fifteen cold 9-DoF
/// FK solves can take up to about 0.7 s, the longest such call).
pub const MIN_ROWS: usize = 16;

/// `work(stop)` without the GIL, stopped by a signal: see the module documentation. With
/// `interruptible` false it runs on this thread (the flag never set).
///
/// # Errors
/// The signal handler's exception (the work was asked to stop and has ended), or
/// `RuntimeError` if the work's thread ended without a result (a panic).
pub fn run<T: Send>(
    py: Python<'_>,
    interruptible: bool,
    work: impl FnOnce(&AtomicBool) -> T + Send,
) -> PyResult<T> {
    if !interruptible {
        return Ok(py.detach(|| work(&AtomicBool::new(false))));
    }
    run_polling(py, work, |_| Ok(()))
}

/// [`run`] (interruptible), calling `poll` on this thread with the GIL at each check for
/// signals (every [`CHECK_PERIOD`]) while the work runs: a progress callback runs there,
/// one call at a time and never on the work's threads (called from rayon's workers, two
/// ran at once, and one that used rayon itself waited for the workers it blocked).
///
/// # Errors
/// As [`run`]; an error of `poll` stops the work the same way and is returned.
pub fn run_polling<T: Send>(
    py: Python<'_>,
    work: impl FnOnce(&AtomicBool) -> T + Send,
    mut poll: impl FnMut(Python<'_>) -> PyResult<()>,
) -> PyResult<T> {
    let stop = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let (tx, rx) = mpsc::sync_channel(1);
        let flag = &stop;
        let worker = scope.spawn(move || {
            // The receiver is gone only after a signal, when the result is not wanted.
            let _ = tx.send(work(flag));
        });
        let mut rx = rx;
        loop {
            let (back, received) = py.detach(move || {
                let received = rx.recv_timeout(CHECK_PERIOD);
                (rx, received)
            });
            rx = back;
            match received {
                Ok(value) => return Ok(value),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals().and_then(|()| poll(py)) {
                        stop.store(true, Ordering::Relaxed);
                        // The work ends at its next check; its result (or its panic: the
                        // user asked to stop) is dropped.
                        py.detach(move || drop(worker.join()));
                        return Err(e);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    // The work panicked: the panic goes on here, with its own message
                    // (PyO3 raises it as `PanicException`, as it did on this thread).
                    return match py.detach(move || worker.join()) {
                        Err(panic) => std::panic::resume_unwind(panic),
                        Ok(()) => Err(PyRuntimeError::new_err(
                            "the call's worker thread ended without a result",
                        )),
                    };
                }
            }
        }
    })
}
