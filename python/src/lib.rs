//! `brdf_basis._native`: the PyO3 bindings of the brdf-basis library.
//!
//! A thin layer: every computation is a call into the library's facade (`brdf_basis::*`,
//! `src/api.rs`), its requests (`brdf_basis::run`) or the module functions the facade
//! documents; this crate only converts arguments (strings to enums, NumPy arrays to
//! slices), results (to NumPy arrays or to the JSON the command line writes) and errors
//! (to Python exceptions with the library's message). Long calls run on a worker thread with the GIL released while
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
pub(crate) fn py_err(e: bb::Error) -> PyErr {
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
pub(crate) fn lib_err<E: Into<bb::Error>>(e: E) -> PyErr {
    py_err(e.into())
}

pub(crate) fn value_err(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// A string argument parsed by the library's own `FromStr` (its message names the
/// accepted spellings).
pub(crate) fn parse<T>(s: &str) -> PyResult<T>
where
    T: std::str::FromStr,
    T::Err: Into<bb::Error>,
{
    s.parse::<T>().map_err(lib_err)
}

/// A list argument parsed item by item with [`parse`] (surrounding spaces ignored), or
/// `default` when the caller gave none.
pub(crate) fn parse_list<T>(v: Option<Vec<String>>, default: &[T]) -> PyResult<Vec<T>>
where
    T: std::str::FromStr + Clone,
    T::Err: Into<bb::Error>,
{
    match v {
        None => Ok(default.to_vec()),
        Some(v) => v.iter().map(|m| parse::<T>(m.trim())).collect(),
    }
}

pub(crate) fn backend_choice(s: Option<&str>) -> PyResult<bb::BackendChoice> {
    let Some(s) = s else {
        return Ok(bb::BackendChoice::default());
    };
    [
        bb::BackendChoice::Auto,
        bb::BackendChoice::Cpu,
        bb::BackendChoice::Gpu,
    ]
    .into_iter()
    .find(|c| c.as_str() == s)
    .ok_or_else(|| value_err(format!("invalid backend `{s}` (expected auto, cpu, gpu)")))
}

/// The back-end of `s` (`None`: the library's default), opened once per process (opening
/// probes the Vulkan adapters).
pub(crate) fn open_backend(s: Option<&str>) -> PyResult<Arc<dyn bb::Backend>> {
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

mod arrays;
mod brdf;
mod collection;
mod commands;
mod defaults;
mod long;

use arrays::*;
use brdf::*;
use collection::*;
use commands::*;
use defaults::*;
use long::*;

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
    m.add_function(wrap_pyfunction!(image_metrics, m)?)?;
    m.add_function(wrap_pyfunction!(ciede2000, m)?)?;
    m.add_function(wrap_pyfunction!(srgb_to_lab, m)?)?;
    m.add_function(wrap_pyfunction!(srgb_to_ictcp, m)?)?;
    m.add_function(wrap_pyfunction!(delta_e_itp, m)?)?;
    m.add_function(wrap_pyfunction!(backend_name, m)?)?;
    m.add_function(wrap_pyfunction!(defaults_json, m)?)?;
    Ok(())
}
