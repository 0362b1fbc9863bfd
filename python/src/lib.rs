//! `brdf_basis._native`: the PyO3 bindings of the brdf-basis library.
//!
//! A thin layer: every computation is a call into the library's facade (`brdf_basis::*`,
//! `src/api.rs`) or one of the module functions the facade documents; this file only
//! converts arguments (strings to enums, NumPy arrays to slices), results (to NumPy
//! arrays or to the JSON the command line writes) and errors (to Python exceptions with
//! the library's message). Long calls run on a worker thread with the GIL released while
//! the calling thread polls for signals (Ctrl-C cancels the work through the library's
//! progress callback) and reports progress.

// PyO3's generated code and our argument lists (mirroring the command line's flags).
#![allow(clippy::too_many_arguments)]
#![allow(clippy::result_large_err)]

use brdf_basis as bb;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArrayDyn};
use numpy::{PyUntypedArrayMethods, ToPyArray};
use pyo3::exceptions::{
    PyFileNotFoundError, PyKeyboardInterrupt, PyOSError, PyPermissionError, PyRuntimeError,
    PyValueError,
};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

// ---------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------

/// The Python exception of a library error, with its message: `FileNotFoundError`,
/// `PermissionError` or `OSError` when the cause is an I/O error, `RuntimeError` for the
/// GPU, `ValueError` otherwise (bad input: a file's content, a parameter, a name).
fn py_err(e: bb::Error) -> PyErr {
    let msg = e.to_string();
    let mut cur: Option<&(dyn std::error::Error + 'static)> = Some(&e);
    while let Some(c) = cur {
        if let Some(io) = c.downcast_ref::<std::io::Error>() {
            return match io.kind() {
                std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(msg),
                std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(msg),
                _ => PyOSError::new_err(msg),
            };
        }
        cur = c.source();
    }
    match e {
        bb::Error::Gpu(_) | bb::Error::Backend(_) => PyRuntimeError::new_err(msg),
        bb::Error::Output(_) => PyOSError::new_err(msg),
        _ => PyValueError::new_err(msg),
    }
}

/// Any error of a module, through the library's one [`bb::Error`].
fn lib_err<E: Into<bb::Error>>(e: E) -> PyErr {
    py_err(e.into())
}

fn value_err(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// A string argument parsed by the library's own `FromStr` (its message names the
/// accepted spellings).
fn parse<T>(s: &str) -> PyResult<T>
where
    T: std::str::FromStr,
    T::Err: Into<bb::Error>,
{
    s.parse::<T>().map_err(lib_err)
}

/// A list argument parsed item by item with [`parse`] (surrounding spaces ignored), or
/// `default` when the caller gave none.
fn parse_list<T>(v: Option<Vec<String>>, default: &[T]) -> PyResult<Vec<T>>
where
    T: std::str::FromStr + Clone,
    T::Err: Into<bb::Error>,
{
    match v {
        None => Ok(default.to_vec()),
        Some(v) => v.iter().map(|m| parse::<T>(m.trim())).collect(),
    }
}

fn backend_choice(s: &str) -> PyResult<bb::BackendChoice> {
    [
        bb::BackendChoice::Auto,
        bb::BackendChoice::Cpu,
        bb::BackendChoice::Gpu,
    ]
    .into_iter()
    .find(|c| c.as_str() == s)
    .ok_or_else(|| value_err(format!("invalid backend `{s}` (expected auto, cpu, gpu)")))
}

/// The back-end of `s`, opened once per process (opening probes the Vulkan adapters).
fn open_backend(s: &str) -> PyResult<Arc<dyn bb::Backend>> {
    static OPEN: std::sync::Mutex<Vec<(&'static str, Arc<dyn bb::Backend>)>> =
        std::sync::Mutex::new(Vec::new());
    let choice = backend_choice(s)?;
    let mut open = OPEN.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, b)) = open.iter().find(|(c, _)| *c == choice.as_str()) {
        return Ok(b.clone());
    }
    let b: Arc<dyn bb::Backend> = bb::open_backend(choice).map_err(lib_err)?.into();
    open.push((choice.as_str(), b.clone()));
    Ok(b)
}

// ---------------------------------------------------------------------------------------
// Long calls: GIL released, Ctrl-C, progress
// ---------------------------------------------------------------------------------------

/// The panic payload that unwinds a cancelled computation out of the library (raised in
/// its progress callback, caught here).
struct Cancelled;

/// How progress is reported: not at all, a line on `sys.stderr`, or a Python callable
/// `f(done, total)`.
enum Report<'py> {
    None,
    Stderr(String),
    Callable(Bound<'py, PyAny>),
}

impl<'py> Report<'py> {
    fn of(progress: Option<Bound<'py, PyAny>>, label: &str) -> PyResult<Self> {
        Ok(match progress {
            None => Report::None,
            Some(p) if p.is_callable() => Report::Callable(p),
            Some(p) if p.is_truthy()? => Report::Stderr(label.to_string()),
            Some(_) => Report::None,
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
fn run_long<'py, T: Send>(
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

// ---------------------------------------------------------------------------------------
// Collection
// ---------------------------------------------------------------------------------------

/// An ordered collection of uniquely named materials (see the stub file for the docs).
#[pyclass(frozen, module = "brdf_basis._native", name = "Collection")]
struct Collection {
    inner: Arc<bb::Collection>,
}

#[pymethods]
impl Collection {
    /// Loads COLLECTION arguments (analytic .csv, MERL .binary, directories of .binary),
    /// in order; no argument: the embedded default collection.
    #[staticmethod]
    #[pyo3(signature = (*paths))]
    fn load(paths: Vec<PathBuf>) -> PyResult<Self> {
        let c = bb::Collection::load_many(&paths).map_err(lib_err)?;
        Ok(Self { inner: Arc::new(c) })
    }

    /// The embedded default collection.
    #[staticmethod]
    fn default() -> Self {
        Self {
            inner: Arc::new(bb::Collection::embedded_default()),
        }
    }

    #[getter]
    fn names(&self) -> Vec<String> {
        self.inner.names()
    }

    #[getter]
    fn kinds(&self) -> Vec<&'static str> {
        self.inner
            .materials()
            .iter()
            .map(bb::material_kind)
            .collect()
    }

    #[getter]
    fn fingerprint(&self) -> String {
        self.inner.fingerprint()
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __contains__(&self, name: &str) -> bool {
        self.inner.index_of(name).is_ok()
    }

    fn __repr__(&self) -> String {
        let kinds = self.kinds();
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for k in &kinds {
            match counts.iter_mut().find(|(n, _)| n == k) {
                Some((_, c)) => *c += 1,
                None => counts.push((k, 1)),
            }
        }
        let parts: Vec<String> = counts.iter().map(|(k, c)| format!("{c} {k}")).collect();
        format!(
            "Collection({} materials: {})",
            kinds.len(),
            parts.join(", ")
        )
    }

    /// The index of `name` (ValueError naming close names when unknown).
    fn index(&self, name: &str) -> PyResult<usize> {
        self.inner.index_of(name).map_err(lib_err)
    }

    /// Ashikhmin-Shirley parameters of an analytic material, `None` for a measured one.
    fn analytic<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Option<Bound<'py, PyAny>>> {
        let m = self.inner.get(name).map_err(lib_err)?;
        match m.analytic() {
            None => Ok(None),
            Some(a) => {
                let d = pyo3::types::PyDict::new(py);
                d.set_item("d", a.d.to_vec())?;
                d.set_item("s", a.s.to_vec())?;
                d.set_item("F0", a.f0)?;
                d.set_item("n", a.n)?;
                Ok(Some(d.into_any()))
            }
        }
    }

    /// The material on the full MERL grid, shape (3, 90, 90, 180), float32, invalid
    /// cells -1 (what `brdf-basis tabulate` writes).
    #[pyo3(signature = (name, *, backend = "auto", progress = None))]
    fn tabulate<'py>(
        &self,
        py: Python<'py>,
        name: &str,
        backend: &str,
        progress: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let backend = open_backend(backend)?;
        let coll = &self.inner;
        let rgb = run_long(py, progress, "tabulate", |_| {
            bb::tabulate(backend.as_ref(), coll, name)
        })?;
        let a = PyArray1::from_vec(py, rgb);
        Ok(a.reshape([3usize, 90, 90, 180])?.into_any())
    }
}

fn coll_of(c: &Bound<'_, Collection>) -> Arc<bb::Collection> {
    c.get().inner.clone()
}

/// The boolean mask of the MERL grid, shape (90, 90, 180): `"valid"` (both directions
/// above the horizon) or `"evaluation"` (theta_i, theta_o <= 80 deg, 2 theta_d >= 3 deg).
#[pyfunction]
#[pyo3(signature = (name = "evaluation"))]
fn mask<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let m: bb::Mask = parse(name)?;
    let v: Vec<bool> = (0..bb::merl::grid::N_CELLS)
        .map(|c| {
            let info = bb::merl::grid::cell_info(c);
            match m {
                bb::Mask::Evaluation => info.evaluation,
                _ => info.valid,
            }
        })
        .collect();
    Ok(PyArray1::from_vec(py, v)
        .reshape([90usize, 90, 180])?
        .into_any())
}

// ---------------------------------------------------------------------------------------
// Distances, selection, fits, cross-validation
// ---------------------------------------------------------------------------------------

/// The distance matrix (N, N), float64, as `brdf-basis distance` writes it (the library's
/// `run::DistanceRequest`).
#[pyfunction]
#[pyo3(signature = (collection, *, metric = "brdf-it", mask = "evaluation", weighting = "uniform", stride = 1, backend = "auto", progress = None))]
fn distance_matrix<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    metric: &str,
    mask: &str,
    weighting: &str,
    stride: usize,
    backend: &str,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let coll = coll_of(collection);
    let mut req = bb::run::DistanceRequest::default();
    req.metric = parse(metric)?;
    req.grid = grid(mask, weighting, stride)?;
    let valid = req.params(&coll).map_err(py_err)?;
    let backend = open_backend(backend)?;
    let d = run_long(py, progress, "distances", |pr| {
        match req.run(backend.as_ref(), &coll, &valid, pr)? {
            bb::run::DistanceOutput::Matrix(d) => Ok(d),
            _ => unreachable!("a request without a tile computes the whole matrix"),
        }
    })?;
    let n = coll.len();
    Ok(PyArray1::from_slice(py, d.as_full())
        .reshape([n, n])?
        .into_any())
}

/// The grid settings of a request (`mask`, `weighting`, `stride`).
fn grid(mask: &str, weighting: &str, stride: usize) -> PyResult<bb::run::Grid> {
    Ok(bb::run::Grid {
        mask: parse(mask)?,
        weighting: parse(weighting)?,
        stride,
    })
}

/// A basis selection as `brdf-basis select`: returns the `--json` text. The keyword
/// arguments are the fields of the library's `run::SelectRequest`, which makes every
/// rule (one wording for the command line, Python and the library).
#[pyfunction]
#[pyo3(signature = (collection, method, *, k = None, k_min = None, k_max = None, runs = None, algorithm = None, population = None, generations = None, more_than = None, candidates = None, targets = None, init = None, ga_population = None, ga_generations = None, ga_crossover = None, ga_mutation = None, metric = None, mask = "evaluation", weighting = "uniform", stride = 1, seed = 1, backend = "auto", progress = None))]
fn select_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    method: &str,
    k: Option<usize>,
    k_min: Option<usize>,
    k_max: Option<usize>,
    runs: Option<usize>,
    algorithm: Option<&str>,
    population: Option<usize>,
    generations: Option<usize>,
    more_than: Option<usize>,
    candidates: Option<Vec<String>>,
    targets: Option<Vec<String>>,
    init: Option<Vec<String>>,
    ga_population: Option<usize>,
    ga_generations: Option<usize>,
    ga_crossover: Option<f64>,
    ga_mutation: Option<f64>,
    metric: Option<&str>,
    mask: &str,
    weighting: &str,
    stride: usize,
    seed: u64,
    backend: &str,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::SelectRequest::new(parse(method)?);
    req.k = k;
    req.k_min = k_min;
    req.k_max = k_max;
    req.runs = runs.unwrap_or(req.runs);
    if let Some(a) = algorithm {
        req.algorithm = parse(a)?;
    }
    req.population = population.unwrap_or(req.population);
    req.generations = generations.unwrap_or(req.generations);
    req.more_than = more_than.unwrap_or(req.more_than);
    req.candidates = candidates;
    req.targets = targets;
    req.init = init;
    req.ga_population = ga_population;
    req.ga_generations = ga_generations;
    req.ga_crossover = ga_crossover;
    req.ga_mutation = ga_mutation;
    if let Some(m) = metric {
        req.metric = parse(m)?;
    }
    req.grid = grid(mask, weighting, stride)?;
    req.seed = seed;
    req.check().map_err(py_err)?;
    let backend = open_backend(backend)?;
    let out = run_long(py, progress, method, |pr| {
        req.run(backend.as_ref(), &coll, pr)
    })?;
    Ok(out.to_json())
}

/// `solver`: `exact` or `pgd`.
fn solver(s: &str) -> PyResult<bb::Solver> {
    match s {
        "exact" => Ok(bb::Solver::Exact),
        "pgd" => Ok(bb::Solver::Pgd),
        s => Err(value_err(format!(
            "invalid solver `{s}` (expected exact, pgd)"
        ))),
    }
}

/// `gram`: `auto` or `grid`.
fn gram_mode(s: &str) -> PyResult<bb::GramMode> {
    match s {
        "auto" => Ok(bb::GramMode::Auto),
        "grid" => Ok(bb::GramMode::Grid),
        s => Err(value_err(format!(
            "invalid gram `{s}` (expected auto, grid)"
        ))),
    }
}

/// Fits `targets` (default: every material outside the basis) by `basis`: returns the
/// JSON `brdf-basis fit --json` writes (the library's `run::FitRequest`).
#[pyfunction]
#[pyo3(signature = (collection, basis, targets = None, *, mask = "evaluation", weighting = "uniform", stride = 1, solver = "exact", gram = "auto", backend = "auto", progress = None))]
fn fit_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    basis: Vec<String>,
    targets: Option<Vec<String>>,
    mask: &str,
    weighting: &str,
    stride: usize,
    solver: &str,
    gram: &str,
    backend: &str,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::FitRequest::new(basis);
    req.targets = match targets {
        Some(t) => bb::run::FitTargets::Named(t),
        None => bb::run::FitTargets::AllOthers,
    };
    req.grid = grid(mask, weighting, stride)?;
    req.solver = self::solver(solver)?;
    req.gram = gram_mode(gram)?;
    let backend = open_backend(backend)?;
    let fitted = run_long(py, progress, "fit", |pr| {
        req.run(backend.as_ref(), &coll, pr)
    })?;
    let text = serde_json::to_string_pretty(&fitted.file).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}

/// Plans where to measure a new material (SPEC 10), as `brdf-basis plan --json` on the
/// evaluation-mask cell centres (the library's `run::PlanRequest`): returns the JSON text.
#[pyfunction]
#[pyo3(signature = (collection, basis, n, *, criterion = None, targets = None, candidates_per_step = None, shortlist = None, seed = 1, restarts = None, backend = "auto", progress = None))]
fn plan_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    basis: Vec<String>,
    n: usize,
    criterion: Option<&str>,
    targets: Option<Vec<String>>,
    candidates_per_step: Option<usize>,
    shortlist: Option<usize>,
    seed: u64,
    restarts: Option<usize>,
    backend: &str,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::PlanRequest::new(basis);
    req.n = n;
    if let Some(c) = criterion {
        req.criterion = parse(c)?;
    }
    req.targets = targets;
    req.candidates_per_step = candidates_per_step.unwrap_or(req.candidates_per_step);
    req.shortlist = shortlist.unwrap_or(req.shortlist);
    req.restarts = restarts.unwrap_or(req.restarts);
    req.seed = seed;
    req.check().map_err(py_err)?;
    let backend = open_backend(backend)?;
    let plan = run_long(py, progress, "plan", |_| req.run(backend.as_ref(), &coll))?;
    let text = serde_json::to_string_pretty(&plan).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}

/// Fits a new material from samples (SPEC 10): `angles` (n, 4) in degrees
/// `theta_i, phi_i, theta_o, phi_o`, `rgb` (n, 3), optional `sigma` (n, 3). Returns
/// `(coefficients (1 + k, 3), residual (3), mae, relative_residual, rank, condition)`.
#[pyfunction]
#[pyo3(signature = (collection, basis, angles, rgb, sigma = None))]
#[allow(clippy::type_complexity)]
fn fit_samples<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    basis: Vec<String>,
    angles: Vec<[f64; 4]>,
    rgb: Vec<[f64; 3]>,
    sigma: Option<Vec<[f64; 3]>>,
) -> PyResult<(Bound<'py, PyAny>, [f64; 3], f64, f64, usize, f64)> {
    let coll = coll_of(collection);
    let names: Vec<&str> = basis.iter().map(|b| b.trim()).collect();
    let f = bb::fit_from_arrays(&coll, &names, &angles, &rgb, sigma.as_deref()).map_err(lib_err)?;
    let flat: Vec<f64> = f.coefficients.iter().flatten().copied().collect();
    let coefficients = numpy::PyArray1::from_vec(py, flat)
        .reshape([f.coefficients.len(), 3])?
        .into_any();
    Ok((
        coefficients,
        f.residual,
        f.mae,
        f.relative_residual,
        f.determination.rank,
        f.determination.condition,
    ))
}

/// K-fold cross-validation as `brdf-basis cv` (the library's `run::CvRequest`): returns
/// the `--json` text.
#[pyfunction]
#[pyo3(signature = (collection, *, methods = None, ks = None, folds = None, metric = None, mask = "evaluation", weighting = "uniform", stride = 1, runs = None, ga_population = None, ga_generations = None, render_size = None, seed = 1, backend = "auto", progress = None))]
fn cross_validate_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    methods: Option<Vec<String>>,
    ks: Option<Vec<usize>>,
    folds: Option<usize>,
    metric: Option<&str>,
    mask: &str,
    weighting: &str,
    stride: usize,
    runs: Option<usize>,
    ga_population: Option<usize>,
    ga_generations: Option<usize>,
    render_size: Option<u32>,
    seed: u64,
    backend: &str,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::CvRequest::default();
    req.methods = parse_list(methods, &req.methods)?;
    req.ks = ks.unwrap_or(req.ks);
    req.folds = folds.unwrap_or(req.folds);
    if let Some(m) = metric {
        req.metric = parse(m)?;
    }
    req.grid = grid(mask, weighting, stride)?;
    req.runs = runs.unwrap_or(req.runs);
    req.ga_population = ga_population.unwrap_or(req.ga_population);
    req.ga_generations = ga_generations.unwrap_or(req.ga_generations);
    req.render_size = render_size.unwrap_or(req.render_size);
    req.seed = seed;
    req.check(coll.len()).map_err(py_err)?;
    let backend = open_backend(backend)?;
    let res = run_long(py, progress, "cv", |pr| {
        req.run(backend.as_ref(), &coll, pr)
    })?;
    let text = serde_json::to_string_pretty(&res).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}

/// Acquisition cross-validation (SPEC 10) as `brdf-basis cv --acquisition` (the library's
/// `run::AcquisitionRequest`): returns the `--json` text.
#[pyfunction]
#[pyo3(signature = (collection, *, methods = None, k = None, plans = None, ns = None, noises = None, folds = None, candidates_per_step = None, shortlist = None, restarts = None, render_size = None, mask = "evaluation", weighting = "uniform", stride = 1, seed = 1, backend = "auto", progress = None))]
fn acquisition_cv_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    methods: Option<Vec<String>>,
    k: Option<usize>,
    plans: Option<Vec<String>>,
    ns: Option<Vec<usize>>,
    noises: Option<Vec<f64>>,
    folds: Option<usize>,
    candidates_per_step: Option<usize>,
    shortlist: Option<usize>,
    restarts: Option<usize>,
    render_size: Option<u32>,
    mask: &str,
    weighting: &str,
    stride: usize,
    seed: u64,
    backend: &str,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::AcquisitionRequest::default();
    req.methods = parse_list(methods, &req.methods)?;
    req.k = k.unwrap_or(req.k);
    req.plans = parse_list(plans, &req.plans)?;
    req.ns = ns.unwrap_or(req.ns);
    req.noises = noises.unwrap_or(req.noises);
    req.folds = folds.unwrap_or(req.folds);
    req.candidates_per_step = candidates_per_step.unwrap_or(req.candidates_per_step);
    req.shortlist = shortlist.unwrap_or(req.shortlist);
    req.restarts = restarts.unwrap_or(req.restarts);
    req.render_size = render_size.unwrap_or(req.render_size);
    req.grid = grid(mask, weighting, stride)?;
    req.seed = seed;
    req.check().map_err(py_err)?;
    let backend = open_backend(backend)?;
    let res = run_long(py, progress, "cv --acquisition", |_| {
        req.run(backend.as_ref(), &coll)
    })?;
    let text = serde_json::to_string_pretty(&res).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}

// ---------------------------------------------------------------------------------------
// Solvers, clustering and statistics on arrays
// ---------------------------------------------------------------------------------------

/// `argmin |A x - b|` subject to `x >= 0` (the crate's Lawson-Hanson solver).
#[pyfunction]
fn nnls<'py>(
    py: Python<'py>,
    a: PyReadonlyArray2<'py, f64>,
    b: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let (rows, cols) = (a.shape()[0], a.shape()[1]);
    let av: Vec<f64> = a.as_array().iter().copied().collect();
    let bv: Vec<f64> = b.as_array().iter().copied().collect();
    let s = py
        .detach(|| bb::nnls_dense(&av, rows, cols, &bv))
        .map_err(py_err)?;
    Ok(PyArray1::from_vec(py, s.x))
}

fn matrix_of(d: &PyReadonlyArray2<'_, f64>) -> PyResult<bb::DistanceMatrix> {
    let (r, c) = (d.shape()[0], d.shape()[1]);
    if r != c {
        return Err(value_err(format!(
            "the distance matrix must be square, got {r} x {c}"
        )));
    }
    let names = (0..r).map(|i| format!("item {i}")).collect();
    bb::DistanceMatrix::from_full(names, d.as_array().iter().copied().collect()).map_err(lib_err)
}

/// Mean silhouette of `labels` on the precomputed distance matrix `d`.
#[pyfunction]
fn silhouette(d: PyReadonlyArray2<'_, f64>, labels: Vec<usize>) -> PyResult<f64> {
    let m = matrix_of(&d)?;
    bb::cluster::indices::silhouette(&m, &labels).map_err(lib_err)
}

/// What [`kmedoids`] returns: (medoids, labels, loss, iterations, db_index).
type KMedoidsTuple = (Vec<usize>, Vec<usize>, f64, usize, f64);

/// k-medoids on a precomputed matrix: (medoids, labels, loss, iterations, db_index).
#[pyfunction]
#[pyo3(signature = (d, k, *, seed = 1, init = "build", algorithm = "fasterpam"))]
fn kmedoids(
    py: Python<'_>,
    d: PyReadonlyArray2<'_, f64>,
    k: usize,
    seed: u64,
    init: &str,
    algorithm: &str,
) -> PyResult<KMedoidsTuple> {
    let m = matrix_of(&d)?;
    let init = match init {
        "build" => bb::KMedoidsInit::Build,
        "random" => bb::KMedoidsInit::Random,
        s => {
            return Err(value_err(format!(
                "invalid init `{s}` (expected build, random)"
            )))
        }
    };
    let p = bb::KMedoidsParams::new(k)
        .seed(seed)
        .init(init)
        .algorithm(parse(algorithm)?);
    let r = py.detach(|| p.fit(&m)).map_err(lib_err)?;
    Ok((r.medoids, r.labels, r.loss, r.iterations, r.db_index))
}

fn json_of<T: serde::Serialize>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| value_err(e.to_string()))
}

/// Wilcoxon signed-rank test of paired samples (JSON of the library's result).
#[pyfunction]
fn wilcoxon_json(x: Vec<f64>, y: Vec<f64>) -> PyResult<String> {
    json_of(&bb::stats::wilcoxon_signed_rank(&x, &y).map_err(lib_err)?)
}

/// Friedman test: `blocks[r][j]` is treatment `j` in block `r` (JSON of the result).
#[pyfunction]
fn friedman_json(blocks: PyReadonlyArray2<'_, f64>) -> PyResult<String> {
    let rows: Vec<Vec<f64>> = blocks
        .as_array()
        .rows()
        .into_iter()
        .map(|r| r.to_vec())
        .collect();
    json_of(&bb::stats::friedman(&rows).map_err(lib_err)?)
}

/// Mann-Whitney U test of two independent samples (JSON of the result).
#[pyfunction]
fn mann_whitney_json(x: Vec<f64>, y: Vec<f64>) -> PyResult<String> {
    json_of(&bb::stats::mann_whitney_u(&x, &y).map_err(lib_err)?)
}

// ---------------------------------------------------------------------------------------
// BRDFs and the sphere renderer (SPEC 7)
// ---------------------------------------------------------------------------------------

/// A BRDF `f(wi, wo) -> RGB` in a local frame with the normal on +z: an analytic
/// material, a measured one (MERL lookup), or a fitted combination.
#[pyclass(frozen, module = "brdf_basis._native", name = "Brdf")]
struct Brdf {
    f: bb::eval::shade::BrdfFn,
    label: String,
}

#[pymethods]
impl Brdf {
    /// The BRDF of material `name` of `collection`.
    #[staticmethod]
    fn material(collection: &Bound<'_, Collection>, name: &str) -> PyResult<Self> {
        let coll = coll_of(collection);
        let m = coll.get(name).map_err(lib_err)?;
        Ok(Self {
            f: bb::eval::shade::material_brdf(&m.data),
            label: name.to_string(),
        })
    }

    /// The fitted combination of `target` read from a `fit` JSON file.
    #[staticmethod]
    fn fitted(collection: &Bound<'_, Collection>, fit: PathBuf, target: &str) -> PyResult<Self> {
        let coll = coll_of(collection);
        let f = bb::fit::file::FitFile::combination_from(&fit, &coll, target).map_err(lib_err)?;
        Ok(Self {
            f,
            label: format!("fit of {target} ({})", fit.display()),
        })
    }

    /// Evaluates at one pair of directions (3 floats each): (r, g, b).
    fn eval1(&self, wi: [f64; 3], wo: [f64; 3]) -> (f64, f64, f64) {
        let v = (self.f)(wi, wo);
        (v[0], v[1], v[2])
    }

    /// Evaluates at arrays of directions, shape (..., 3) each: returns (..., 3) float64.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wi: PyReadonlyArrayDyn<'py, f64>,
        wo: PyReadonlyArrayDyn<'py, f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let shape = wi.shape().to_vec();
        if shape != wo.shape() || shape.last() != Some(&3) {
            return Err(value_err(format!(
                "wi and wo must have the same shape (..., 3), got {:?} and {:?}",
                shape,
                wo.shape()
            )));
        }
        let a: Vec<f64> = wi.as_array().iter().copied().collect();
        let b: Vec<f64> = wo.as_array().iter().copied().collect();
        let f = &self.f;
        let out = py.detach(|| {
            let mut out = vec![0f64; a.len()];
            for ((o, x), y) in out.chunks_mut(3).zip(a.chunks(3)).zip(b.chunks(3)) {
                o.copy_from_slice(&f([x[0], x[1], x[2]], [y[0], y[1], y[2]]));
            }
            out
        });
        Ok(PyArray1::from_vec(py, out).reshape(shape)?.into_any())
    }

    fn __repr__(&self) -> String {
        format!("Brdf({})", self.label)
    }
}

/// The sphere of SPEC 7 (orthographic from +z, one directional light from
/// `light = (theta, phi)` degrees): linear radiance, shape (size, size, 3) float32, row 0
/// at the top (what `brdf-basis render --out` writes).
#[pyfunction]
#[pyo3(signature = (brdf, *, size = 256, light = (45.0, 45.0)))]
fn render<'py>(
    py: Python<'py>,
    brdf: &Bound<'py, Brdf>,
    size: u32,
    light: (f64, f64),
) -> PyResult<Bound<'py, PyAny>> {
    let p = bb::eval::render::RenderParams::default()
        .with_size(size)
        .with_light(light.0, light.1);
    let f = &brdf.get().f;
    let img = py
        .detach(|| bb::eval::render::render_sphere(&p, f))
        .map_err(lib_err)?;
    let s = size as usize;
    Ok(img.data.to_pyarray(py).reshape([s, s, 3])?.into_any())
}

fn image_of(a: &PyReadonlyArrayDyn<'_, f32>) -> PyResult<bb::eval::render::Image> {
    let sh = a.shape();
    if sh.len() != 3 || sh[2] != 3 {
        return Err(value_err(format!(
            "an image has shape (height, width, 3), got {sh:?}"
        )));
    }
    let (h, w) = (sh[0] as u32, sh[1] as u32);
    Ok(bb::eval::render::Image {
        width: w,
        height: h,
        data: a.as_array().iter().copied().collect(),
        mask: bb::eval::render::sphere_mask(w, h),
    })
}

/// Normalised image error of SPEC 7 between two sphere renders (float32 arrays
/// (size, size, 3)): the mean over sphere pixels and channels of |a - b| after the
/// display mapping (exposure, gamma, clamp).
#[pyfunction]
#[pyo3(signature = (a, b, *, exposure = 0.0, gamma = 2.2))]
fn image_error(
    a: PyReadonlyArrayDyn<'_, f32>,
    b: PyReadonlyArrayDyn<'_, f32>,
    exposure: f64,
    gamma: f64,
) -> PyResult<f64> {
    let d = bb::eval::image_error::DisplayParams::default()
        .with_exposure(exposure)
        .with_gamma(gamma);
    d.check().map_err(lib_err)?;
    bb::eval::image_error::normalized_image_error(&image_of(&a)?, &image_of(&b)?, &d)
        .map_err(lib_err)
}

/// The name of the back-end `backend` opens (`cpu (2 threads, avx2)`, `gpu: ...`).
#[pyfunction]
#[pyo3(signature = (backend = "auto"))]
fn backend_name(backend: &str) -> PyResult<String> {
    Ok(open_backend(backend)?.name())
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Collection>()?;
    m.add_class::<Brdf>()?;
    m.add_function(wrap_pyfunction!(mask, m)?)?;
    m.add_function(wrap_pyfunction!(distance_matrix, m)?)?;
    m.add_function(wrap_pyfunction!(select_json, m)?)?;
    m.add_function(wrap_pyfunction!(fit_json, m)?)?;
    m.add_function(wrap_pyfunction!(plan_json, m)?)?;
    m.add_function(wrap_pyfunction!(fit_samples, m)?)?;
    m.add_function(wrap_pyfunction!(acquisition_cv_json, m)?)?;
    m.add_function(wrap_pyfunction!(cross_validate_json, m)?)?;
    m.add_function(wrap_pyfunction!(nnls, m)?)?;
    m.add_function(wrap_pyfunction!(silhouette, m)?)?;
    m.add_function(wrap_pyfunction!(kmedoids, m)?)?;
    m.add_function(wrap_pyfunction!(wilcoxon_json, m)?)?;
    m.add_function(wrap_pyfunction!(friedman_json, m)?)?;
    m.add_function(wrap_pyfunction!(mann_whitney_json, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(image_error, m)?)?;
    m.add_function(wrap_pyfunction!(backend_name, m)?)?;
    Ok(())
}
