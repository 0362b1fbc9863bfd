//! The commands (distance, select, fit, plan, cv, cv --acquisition): keyword arguments
//! translated into the library's requests (`brdf_basis::run`), results as the JSON text
//! the command line writes.

#![allow(clippy::too_many_arguments)]

use crate::*;
use bb::run::{Ctx, Request};

/// The distance matrix (N, N), float64, as `brdf-basis distance` writes it (the library's
/// `run::DistanceRequest`).
#[pyfunction]
#[pyo3(signature = (collection, *, metric = None, mask = None, weighting = None, stride = None, backend = None, progress = None))]
pub(crate) fn distance_matrix<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    metric: Option<&str>,
    mask: Option<&str>,
    weighting: Option<&str>,
    stride: Option<usize>,
    backend: Option<&str>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let coll = coll_of(collection);
    let mut req = bb::run::DistanceRequest::default();
    set(&mut req.metric, metric.map(parse).transpose()?);
    req.grid = grid(req.grid, mask, weighting, stride)?;
    req.params(&coll).map_err(py_err)?;
    let backend = open_backend(backend)?;
    let d = run_long(py, progress, "distances", |pr| {
        match req.run(&Ctx::new(backend.as_ref(), &coll).progress(pr))? {
            bb::run::DistanceOutput::Matrix(d) => Ok(d),
            _ => unreachable!("a request without a tile computes the whole matrix"),
        }
    })?;
    let n = coll.len();
    Ok(PyArray1::from_slice(py, d.as_full())
        .reshape([n, n])?
        .into_any())
}

/// The grid settings of a request (`mask`, `weighting`, `stride`): those given replace
/// the request's defaults `g`, into a grid checked when built (`merl::GridSpec`, the
/// stride's rule in its words).
pub(crate) fn grid(
    g: bb::merl::GridSpec,
    mask: Option<&str>,
    weighting: Option<&str>,
    stride: Option<usize>,
) -> PyResult<bb::merl::GridSpec> {
    let mut g = g;
    if let Some(m) = mask {
        g = g.with_mask(parse(m)?);
    }
    if let Some(w) = weighting {
        g = g.with_weighting(parse(w)?);
    }
    match stride {
        Some(s) => g.with_stride(s).map_err(lib_err),
        None => Ok(g),
    }
}

/// A setting given (`Some`) replaces the request's default; `None` keeps it.
pub(crate) fn set<T>(field: &mut T, given: Option<T>) {
    if let Some(v) = given {
        *field = v;
    }
}

/// A basis selection as `brdf-basis select`: returns the `--json` text. The keyword
/// arguments are the fields of the library's `run::SelectRequest`, which makes every
/// rule (one wording for the command line, Python and the library).
#[pyfunction]
#[pyo3(signature = (collection, method, *, k = None, k_min = None, k_max = None, runs = None, algorithm = None, population = None, generations = None, more_than = None, candidates = None, targets = None, init = None, ga_population = None, ga_generations = None, ga_crossover = None, ga_mutation = None, metric = None, mask = None, weighting = None, stride = None, seed = None, objective = None, eps = None, backend = None, progress = None))]
pub(crate) fn select_json<'py>(
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
    mask: Option<&str>,
    weighting: Option<&str>,
    stride: Option<usize>,
    seed: Option<u64>,
    objective: Option<&str>,
    eps: Option<Bound<'py, PyAny>>,
    backend: Option<&str>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::SelectRequest::new(parse(method)?);
    req.k = k;
    req.k_min = k_min;
    req.k_max = k_max;
    req.runs = runs;
    req.algorithm = algorithm.map(parse).transpose()?;
    req.population = population;
    req.generations = generations;
    req.more_than = more_than;
    req.candidates = candidates;
    req.targets = targets;
    req.init = init;
    req.ga_population = ga_population;
    req.ga_generations = ga_generations;
    req.ga_crossover = ga_crossover;
    req.ga_mutation = ga_mutation;
    req.metric = metric.map(parse).transpose()?;
    req.grid = grid(req.grid, mask, weighting, stride)?;
    req.seed = seed;
    req.objective = objective_of(objective, eps)?;
    req.check().map_err(lib_err)?;
    let backend = open_backend(backend)?;
    let out = run_long(py, progress, method, |pr| {
        req.run(&Ctx::new(backend.as_ref(), &coll).progress(pr))
    })?;
    Ok(out.to_json())
}

/// `objective=` and `eps=` as given (`None`: not given): the request applies the
/// defaults and makes the rules (`run::ObjectiveSetting`).
pub(crate) fn objective_of(
    objective: Option<&str>,
    eps: Option<Bound<'_, PyAny>>,
) -> PyResult<bb::run::ObjectiveSetting> {
    // A bool is an int to Python and a float to `extract`: `eps=True` ran with eps 1.
    let eps = match eps {
        None => None,
        Some(e) if e.is_instance_of::<pyo3::types::PyBool>() => {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "eps: expected a number, got {}",
                e.repr()?
            )))
        }
        Some(e) => Some(e.extract::<f64>()?),
    };
    Ok(bb::run::ObjectiveSetting {
        objective: objective
            .map(|o| o.parse::<bb::backend::weighted::ObjectiveKind>())
            .transpose()
            .map_err(value_err)?,
        eps,
    })
}

/// `solver`: `exact` or `pgd` (the library's names and refusal).
pub(crate) fn solver(s: &str) -> PyResult<bb::Solver> {
    s.parse().map_err(value_err)
}

/// `gram`: `auto` or `grid` (the library's names and refusal).
pub(crate) fn gram_mode(s: &str) -> PyResult<bb::GramMode> {
    s.parse().map_err(value_err)
}

/// Fits `targets` (default: every material outside the basis) by `basis`: returns the
/// JSON `brdf-basis fit --json` writes (the library's `run::FitRequest`).
#[pyfunction]
#[pyo3(signature = (collection, basis, targets = None, *, mask = None, weighting = None, stride = None, solver = None, gram = None, objective = None, eps = None, appearance = None, backend = None, progress = None))]
pub(crate) fn fit_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    basis: Vec<String>,
    targets: Option<Vec<String>>,
    mask: Option<&str>,
    weighting: Option<&str>,
    stride: Option<usize>,
    solver: Option<&str>,
    gram: Option<&str>,
    objective: Option<&str>,
    eps: Option<Bound<'py, PyAny>>,
    appearance: Option<bool>,
    backend: Option<&str>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::FitRequest::new(basis);
    req.targets = match targets {
        Some(t) => bb::run::FitTargets::Named(t),
        None => bb::run::FitTargets::AllOthers,
    };
    req.grid = grid(req.grid, mask, weighting, stride)?;
    set(&mut req.solver, solver.map(self::solver).transpose()?);
    set(&mut req.gram, gram.map(gram_mode).transpose()?);
    req.objective = objective_of(objective, eps)?;
    set(&mut req.appearance, appearance);
    req.check().map_err(lib_err)?;
    let backend = open_backend(backend)?;
    let fitted = run_long(py, progress, "fit", |pr| {
        req.run(&Ctx::new(backend.as_ref(), &coll).progress(pr))
    })?;
    let text = serde_json::to_string_pretty(&fitted.file).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}

/// Plans where to measure a new material (SPEC 10), as `brdf-basis plan --json` on the
/// evaluation-mask cell centres (the library's `run::PlanRequest`): returns the JSON text.
#[pyfunction]
#[pyo3(signature = (collection, basis, n, *, criterion = None, targets = None, candidates_per_step = None, shortlist = None, seed = None, restarts = None, objective = None, eps = None, backend = None, progress = None))]
pub(crate) fn plan_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    basis: Vec<String>,
    n: usize,
    criterion: Option<&str>,
    targets: Option<Vec<String>>,
    candidates_per_step: Option<usize>,
    shortlist: Option<usize>,
    seed: Option<u64>,
    restarts: Option<usize>,
    objective: Option<&str>,
    eps: Option<Bound<'py, PyAny>>,
    backend: Option<&str>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::PlanRequest::new(basis);
    req.objective = objective_of(objective, eps)?;
    req.n = n;
    if let Some(c) = criterion {
        req.criterion = parse(c)?;
    }
    req.targets = targets;
    req.candidates_per_step = candidates_per_step;
    req.shortlist = shortlist;
    req.restarts = restarts;
    req.seed = seed;
    req.check().map_err(lib_err)?;
    let backend = open_backend(backend)?;
    let plan = run_long(py, progress, "plan", |pr| {
        req.run(&Ctx::new(backend.as_ref(), &coll).progress(pr))
    })?;
    let text = serde_json::to_string_pretty(&plan).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}

/// Fits a new material from samples (SPEC 10) as `brdf-basis fit --samples` (the
/// library's `run::FitSamplesRequest`, its rules and warnings): `angles` (n, 4) in
/// degrees `theta_i, phi_i, theta_o, phi_o`, `rgb` (n, 3), optional `sigma` (n, 3).
/// Returns `(coefficients (1 + k, 3), residual (3), mae, relative_residual, rank,
/// condition, warnings)`.
#[pyfunction]
#[pyo3(signature = (collection, basis, angles, rgb, sigma = None, objective = None, eps = None, seed = None))]
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
pub(crate) fn fit_samples<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    basis: Vec<String>,
    angles: Vec<[f64; 4]>,
    rgb: Vec<[f64; 3]>,
    sigma: Option<Vec<[f64; 3]>>,
    objective: Option<&str>,
    eps: Option<Bound<'py, PyAny>>,
    seed: Option<u64>,
) -> PyResult<(
    Bound<'py, PyAny>,
    [f64; 3],
    f64,
    f64,
    usize,
    f64,
    Vec<String>,
)> {
    let coll = coll_of(collection);
    let samples = bb::run::Samples::Arrays { angles, rgb, sigma };
    let mut req = bb::run::FitSamplesRequest::of(basis, samples);
    req.objective = objective_of(objective, eps)?;
    set(&mut req.seed, seed);
    req.check().map_err(lib_err)?;
    let out = req.run(&Ctx::collection(&coll)).map_err(py_err)?;
    let f = &out.fit;
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
        out.warnings,
    ))
}

/// K-fold cross-validation as `brdf-basis cv` (the library's `run::CvRequest`): returns
/// the `--json` text.
#[pyfunction]
#[pyo3(signature = (collection, *, methods = None, ks = None, folds = None, metric = None, mask = None, weighting = None, stride = None, runs = None, ga_population = None, ga_generations = None, render_size = None, seed = None, objective = None, eps = None, appearance = None, backend = None, progress = None))]
pub(crate) fn cross_validate_json<'py>(
    py: Python<'py>,
    collection: &Bound<'py, Collection>,
    methods: Option<Vec<String>>,
    ks: Option<Vec<usize>>,
    folds: Option<usize>,
    metric: Option<&str>,
    mask: Option<&str>,
    weighting: Option<&str>,
    stride: Option<usize>,
    runs: Option<usize>,
    ga_population: Option<usize>,
    ga_generations: Option<usize>,
    render_size: Option<u32>,
    seed: Option<u64>,
    objective: Option<&str>,
    eps: Option<Bound<'py, PyAny>>,
    appearance: Option<bool>,
    backend: Option<&str>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::CvRequest::default();
    req.methods = parse_list(methods, &req.methods)?;
    req.ks = ks.unwrap_or(req.ks);
    req.folds = folds.unwrap_or(req.folds);
    req.metric = metric.map(parse).transpose()?;
    req.grid = grid(req.grid, mask, weighting, stride)?;
    req.runs = runs;
    req.ga_population = ga_population;
    req.ga_generations = ga_generations;
    req.render_size = render_size.unwrap_or(req.render_size);
    set(&mut req.seed, seed);
    req.objective = objective_of(objective, eps)?;
    set(&mut req.appearance, appearance);
    req.check_count(coll.len()).map_err(py_err)?;
    let backend = open_backend(backend)?;
    let res = run_long(py, progress, "cv", |pr| {
        req.run(&Ctx::new(backend.as_ref(), &coll).progress(pr))
    })?;
    let text = serde_json::to_string_pretty(&res).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}

/// Acquisition cross-validation (SPEC 10) as `brdf-basis cv --acquisition` (the library's
/// `run::AcquisitionRequest`): returns the `--json` text.
#[pyfunction]
#[pyo3(signature = (collection, *, methods = None, k = None, plans = None, ns = None, noises = None, folds = None, candidates_per_step = None, shortlist = None, restarts = None, render_size = None, mask = None, weighting = None, stride = None, seed = None, objective = None, eps = None, appearance = None, ridge = None, test = None, backend = None, progress = None))]
pub(crate) fn acquisition_cv_json<'py>(
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
    mask: Option<&str>,
    weighting: Option<&str>,
    stride: Option<usize>,
    seed: Option<u64>,
    objective: Option<&str>,
    eps: Option<Bound<'py, PyAny>>,
    appearance: Option<bool>,
    ridge: Option<bool>,
    test: Option<Vec<String>>,
    backend: Option<&str>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<String> {
    let coll = coll_of(collection);
    let mut req = bb::run::AcquisitionRequest::default();
    req.objective = objective_of(objective, eps)?;
    set(&mut req.appearance, appearance);
    set(&mut req.ridge, ridge);
    if let Some(t) = test {
        req.test = t;
    }
    req.methods = parse_list(methods, &req.methods)?;
    req.k = k.unwrap_or(req.k);
    req.plans = parse_list(plans, &req.plans)?;
    req.ns = ns.unwrap_or(req.ns);
    req.noises = noises.unwrap_or(req.noises);
    req.folds = folds;
    req.candidates_per_step = candidates_per_step;
    req.shortlist = shortlist;
    req.restarts = restarts;
    req.render_size = render_size.unwrap_or(req.render_size);
    req.grid = grid(req.grid, mask, weighting, stride)?;
    set(&mut req.seed, seed);
    req.check().map_err(lib_err)?;
    let backend = open_backend(backend)?;
    let res = run_long(py, progress, "cv --acquisition", |pr| {
        req.run(&Ctx::new(backend.as_ref(), &coll).progress(pr))
    })?;
    let text = serde_json::to_string_pretty(&res).map_err(|e| value_err(e.to_string()))?;
    Ok(text + "\n")
}
