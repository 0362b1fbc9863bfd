//! The `Collection` class and the grid masks.

use crate::*;

/// An ordered collection of uniquely named materials (see the stub file for the docs).
#[pyclass(frozen, module = "brdf_basis._native", name = "Collection")]
pub(crate) struct Collection {
    pub(crate) inner: Arc<bb::Collection>,
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
    #[pyo3(signature = (name, *, backend = None, progress = None))]
    fn tabulate<'py>(
        &self,
        py: Python<'py>,
        name: &str,
        backend: Option<&str>,
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

pub(crate) fn coll_of(c: &Bound<'_, Collection>) -> Arc<bb::Collection> {
    c.get().inner.clone()
}

/// The boolean mask of the MERL grid, shape (90, 90, 180): `"valid"` (both directions
/// above the horizon) or `"evaluation"` (theta_i, theta_o <= 80 deg, 2 theta_d >= 3 deg);
/// `None`: the library's default grid's mask (`merl::GridSpec::default()`, `defaults()`).
#[pyfunction]
#[pyo3(signature = (name = None))]
pub(crate) fn mask<'py>(py: Python<'py>, name: Option<&str>) -> PyResult<Bound<'py, PyAny>> {
    let m: bb::Mask = match name {
        Some(name) => parse(name)?,
        None => bb::merl::GridSpec::default().mask(),
    };
    let v: Vec<bool> = (0..bb::merl::N_CELLS)
        .map(|c| {
            let info = bb::merl::cell_info(c);
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
