//! Long calls: the work on a worker thread with the GIL released, Ctrl-C through the
//! library's progress callback, progress reports to stderr or a Python callable.

use crate::*;

/// The panic payload that unwinds a cancelled computation out of the library (raised in
/// its progress callback, caught here).
pub(crate) struct Cancelled;

/// How progress is reported: not at all, a line on `sys.stderr`, or a Python callable
/// `f(done, total)`.
pub(crate) enum Report<'py> {
    None,
    Stderr(String),
    Callable(Bound<'py, PyAny>),
}

impl<'py> Report<'py> {
    fn of(progress: Option<Bound<'py, PyAny>>, label: &str) -> PyResult<Self> {
        Ok(match progress {
            None => Report::None,
            Some(p) if p.is_callable() => Report::Callable(p),
            // Only a bool turns the line on or off (`progress=5` was taken as on).
            Some(p) if p.is_instance_of::<pyo3::types::PyBool>() => {
                if p.is_truthy()? {
                    Report::Stderr(label.to_string())
                } else {
                    Report::None
                }
            }
            Some(p) => {
                return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                    "progress: expected True, False, None or a callable f(done, total), got {}",
                    p.repr()?
                )))
            }
        })
    }

    /// Ends the stderr line after the last report.
    fn end(&self, py: Python<'py>) -> PyResult<()> {
        match self {
            Report::Stderr(_) => py
                .import("sys")?
                .getattr("stderr")?
                .call_method1("write", ("\n",))
                .map(|_| ()),
            _ => Ok(()),
        }
    }

    fn show(&self, py: Python<'py>, done: u64, total: u64, last: bool) -> PyResult<()> {
        match self {
            Report::None => Ok(()),
            Report::Callable(f) => f.call1((done, total)).map(|_| ()),
            Report::Stderr(label) => {
                let err = py.import("sys")?.getattr("stderr")?;
                let end = if last { "\n" } else { "" };
                err.call_method1("write", (format!("\r{label}: {done}/{total}{end}"),))?;
                err.call_method0("flush").map(|_| ())
            }
        }
    }
}

/// Runs `work` on a worker thread with the GIL released. The calling thread wakes every
/// 20 ms to run Python's signal handlers (a `KeyboardInterrupt` sets the cancel flag,
/// which the library's progress callback turns into an unwind: the work stops at its
/// next progress report) and to report progress.
pub(crate) fn run_long<'py, T: Send>(
    py: Python<'py>,
    progress: Option<Bound<'py, PyAny>>,
    label: &str,
    work: impl FnOnce(bb::Progress<'_>) -> bb::Result<T> + Send,
) -> PyResult<T> {
    let report = Report::of(progress, label)?;
    let cancel = AtomicBool::new(false);
    let finished = AtomicBool::new(false);
    let done = AtomicU64::new(0);
    let total = AtomicU64::new(0);
    let callback = |d: u64, t: u64| {
        done.store(d, Ordering::Relaxed);
        total.store(t, Ordering::Relaxed);
        if cancel.load(Ordering::Relaxed) {
            std::panic::resume_unwind(Box::new(Cancelled));
        }
    };
    let (outcome, interrupt, shown) = std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(&callback)));
            finished.store(true, Ordering::SeqCst);
            r
        });
        let mut interrupt: Option<PyErr> = None;
        let mut shown = (u64::MAX, u64::MAX);
        let mut report_err: Option<PyErr> = None;
        while !finished.load(Ordering::SeqCst) {
            py.detach(|| {
                for _ in 0..4 {
                    if finished.load(Ordering::SeqCst) {
                        break;
                    }
                    std::thread::sleep(std::time::Duration::from_millis(5));
                }
            });
            if interrupt.is_none() {
                if let Err(e) = py.check_signals() {
                    cancel.store(true, Ordering::SeqCst);
                    interrupt = Some(e);
                }
            }
            let now = (done.load(Ordering::Relaxed), total.load(Ordering::Relaxed));
            if now != shown && now.1 > 0 && report_err.is_none() {
                shown = now;
                if let Err(e) = report.show(py, now.0, now.1, false) {
                    // A failing progress callable cancels the work and is raised.
                    cancel.store(true, Ordering::SeqCst);
                    report_err = Some(e);
                }
            }
        }
        let joined = worker.join();
        (joined, interrupt.or(report_err), shown)
    });
    if let Some(e) = interrupt {
        return Err(e);
    }
    let last = (done.load(Ordering::Relaxed), total.load(Ordering::Relaxed));
    if last.1 > 0 && last != shown {
        report.show(py, last.0, last.1, true)?;
    } else if last.1 > 0 {
        report.end(py)?;
    }
    match outcome {
        Ok(Ok(r)) => r.map_err(py_err),
        Ok(Err(payload)) | Err(payload) => {
            if payload.is::<Cancelled>() {
                Err(PyKeyboardInterrupt::new_err("interrupted"))
            } else {
                let msg = payload
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "internal error".into());
                Err(PyRuntimeError::new_err(format!(
                    "brdf-basis panicked: {msg}"
                )))
            }
        }
    }
}
