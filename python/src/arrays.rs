//! Solvers, clustering and statistical tests on NumPy arrays.

use crate::*;

/// `argmin |A x - b|` subject to `x >= 0` (the crate's Lawson-Hanson solver).
#[pyfunction]
pub(crate) fn nnls<'py>(
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

pub(crate) fn matrix_of(d: &PyReadonlyArray2<'_, f64>) -> PyResult<bb::DistanceMatrix> {
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
pub(crate) fn silhouette(d: PyReadonlyArray2<'_, f64>, labels: Vec<usize>) -> PyResult<f64> {
    let m = matrix_of(&d)?;
    bb::cluster::indices::silhouette(&m, &labels).map_err(lib_err)
}

/// What [`kmedoids`] returns: (medoids, labels, loss, iterations, db_index).
pub(crate) type KMedoidsTuple = (Vec<usize>, Vec<usize>, f64, usize, f64);

/// k-medoids on a precomputed matrix: (medoids, labels, loss, iterations, db_index).
/// With `medoids`, one run from those initial medoids (`init` and `restarts` unused).
/// A setting left out (`None`) is the library's (`KMedoidsParams::new`, `defaults()`).
#[pyfunction]
#[pyo3(signature = (d, k, *, seed = None, init = None, algorithm = None, restarts = None, max_iter = None, order = None, tolerance = None, medoids = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn kmedoids(
    py: Python<'_>,
    d: PyReadonlyArray2<'_, f64>,
    k: usize,
    seed: Option<u64>,
    init: Option<&str>,
    algorithm: Option<&str>,
    restarts: Option<usize>,
    max_iter: Option<usize>,
    order: Option<&str>,
    tolerance: Option<f64>,
    medoids: Option<Vec<usize>>,
) -> PyResult<KMedoidsTuple> {
    let m = matrix_of(&d)?;
    let init = init
        .map(|init| match init {
            "build" => Ok(bb::KMedoidsInit::Build),
            "random" => Ok(bb::KMedoidsInit::Random),
            s => Err(value_err(format!(
                "invalid init `{s}` (expected build, random)"
            ))),
        })
        .transpose()?;
    let order = order
        .map(|order| match order {
            "shuffled" => Ok(bb::KMedoidsOrder::Shuffled),
            "sequential" => Ok(bb::KMedoidsOrder::Sequential),
            s => Err(value_err(format!(
                "invalid order `{s}` (expected shuffled, sequential)"
            ))),
        })
        .transpose()?;
    let mut p = bb::KMedoidsParams::new(k);
    set(&mut p.seed, seed);
    set(&mut p.init, init);
    set(&mut p.algorithm, algorithm.map(parse).transpose()?);
    set(&mut p.restarts, restarts);
    set(&mut p.max_iter, max_iter);
    set(&mut p.order, order);
    set(&mut p.tolerance, tolerance);
    let p = p.check().map_err(lib_err)?;
    let r = py
        .detach(|| match &medoids {
            Some(start) => p.fit_from(&m, start),
            None => p.fit(&m),
        })
        .map_err(lib_err)?;
    Ok((r.medoids, r.labels, r.loss, r.iterations, r.db_index))
}

pub(crate) fn json_of<T: serde::Serialize>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(|e| value_err(e.to_string()))
}

/// Wilcoxon signed-rank test of paired samples (JSON of the library's result).
#[pyfunction]
pub(crate) fn wilcoxon_json(x: Vec<f64>, y: Vec<f64>) -> PyResult<String> {
    json_of(&bb::stats::wilcoxon_signed_rank(&x, &y).map_err(lib_err)?)
}

/// Friedman test: `blocks[r][j]` is treatment `j` in block `r` (JSON of the result).
#[pyfunction]
pub(crate) fn friedman_json(blocks: PyReadonlyArray2<'_, f64>) -> PyResult<String> {
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
pub(crate) fn mann_whitney_json(x: Vec<f64>, y: Vec<f64>) -> PyResult<String> {
    json_of(&bb::stats::mann_whitney_u(&x, &y).map_err(lib_err)?)
}
