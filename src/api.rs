//! The embedding facade: the few types and functions a host program needs, re-exported at
//! the crate root ([`crate`] has the example).
//!
//! * Collections: [`Collection::load`] (a CSV of analytic materials, a `.binary`, or a
//!   directory of them), [`Collection::embedded_default`].
//! * Back-ends: [`gpu_backend`] wraps the host's own wgpu device and queue (use
//!   [`crate::wgpu`], the version this crate is built against; feature `gpu`, on by
//!   default), [`CpuBackend`], or [`open_backend`] by [`BackendChoice`].
//! * The commands: one typed request each in [`crate::run`] (the one door of the command
//!   line and Python too: the same defaults, rules and output). Below them, each stage's
//!   module function ([`crate::distance::distance_matrix`], [`crate::select::greedy`],
//!   [`crate::fit::fit`], ...) takes checked parameters and a progress callback
//!   `(done, total)`; k-medoids on a matrix is [`KMedoidsParams::fit`].
//! * One error type, [`Error`], with `From` for each module's error, and [`Result`].
//! * Acquisition (SPEC 10): [`crate::plan_samples`] (where to measure, on given candidates)
//!   and [`fit_from_arrays`] (a material from samples given as arrays).

pub use crate::acquire::{
    acquisition_cv, AcqCv, AcqCvParams, AcquireError, Candidate, Criterion, Plan, PlanParams,
    Sample, SampleFit,
};
pub use crate::backend::cpu::CpuBackend;
#[cfg(feature = "gpu")]
pub use crate::backend::gpu::GpuBackend;
pub use crate::backend::{open as open_backend, Backend, BackendChoice};
pub use crate::cluster::{
    KMedoids, KMedoidsAlgorithm, KMedoidsInit, KMedoidsOrder, KMedoidsParams,
};
pub use crate::collection::Collection;
pub use crate::distance::{DistanceMatrix, DistanceParams, Distances, Metric};
pub use crate::fit::{FitParams, GramMode, Solver, TargetFit};
pub use crate::merl::{Mask, Weighting};
pub use crate::select::cv::{CvMethod, CvParams, CvResult};
pub use crate::select::{
    Empirical, EmpiricalParams, GaParams, Objective, ObjectiveParams, SearchParams, Selection,
};

/// Any error of the library: the error of the module that failed, unchanged (its message
/// names the file, material or parameter).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading or parsing a collection.
    #[error(transparent)]
    Collection(#[from] crate::error::CollectionError),
    /// Reading or parsing a MERL `.binary`.
    #[error(transparent)]
    Merl(#[from] crate::error::MerlError),
    /// Opening the GPU or running a kernel.
    #[error(transparent)]
    Gpu(#[from] crate::error::GpuError),
    /// A back-end reduction.
    #[error(transparent)]
    Backend(#[from] crate::error::BackendError),
    /// Distance parameters or computation.
    #[error(transparent)]
    Distance(#[from] crate::error::DistanceError),
    /// Writing an output file.
    #[error(transparent)]
    Output(#[from] crate::error::OutputError),
    /// A saved distance matrix (`.npy` and sidecar).
    #[error(transparent)]
    MatrixFile(#[from] crate::io::MatrixFileError),
    /// Clustering (k-medoids, GCUK, validity indices).
    #[error(transparent)]
    Cluster(#[from] crate::cluster::ClusterError),
    /// Basis selection (objective, greedy, swap, GA, cross-validation).
    #[error(transparent)]
    Selection(#[from] crate::select::SelectionError),
    /// A selection result file.
    #[error(transparent)]
    SelectFile(#[from] crate::select::SelectFileError),
    /// A command's request refused before any work ([`crate::run`]).
    #[error(transparent)]
    Request(#[from] crate::error::Refusal),
    /// Fitting materials by a basis.
    #[error(transparent)]
    Fit(#[from] crate::fit::FitError),
    /// A fit result file.
    #[error(transparent)]
    FitFile(#[from] crate::fit::file::FitFileError),
    /// An NNLS solve.
    #[error(transparent)]
    Nnls(#[from] crate::nnls::NnlsError),
    /// Rendering.
    #[error(transparent)]
    Render(#[from] crate::eval::render::RenderError),
    /// Acquisition: samples, plans, acquisition cross-validation.
    #[error(transparent)]
    Acquire(#[from] crate::acquire::AcquireError),
    /// A statistical test.
    #[error(transparent)]
    Stats(#[from] crate::stats::StatsError),
    /// The paper's experiment.
    #[error(transparent)]
    Experiment(#[from] crate::experiment::ExperimentError),
    /// A tabulated material that is not finite ([`tabulate`]).
    #[error(transparent)]
    NotFinite(Box<NotFiniteError>),
}

/// `Result` with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The GPU back-end on a host's own device and queue (from [`crate::wgpu`]), compiling
/// the kernels on it. The device should have been opened with the adapter's limits
/// (`required_limits: adapter.limits()`): the kernels size their work by them.
///
/// # Errors
/// [`Error::Gpu`] when a kernel does not compile or validate on the device.
#[cfg(feature = "gpu")]
pub fn gpu_backend(
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
) -> Result<GpuBackend> {
    use std::sync::Arc;
    let ctx = crate::backend::gpu::GpuContext::from_device(Arc::new(device), Arc::new(queue), info);
    Ok(GpuBackend::with_context(ctx)?)
}

// ---------------------------------------------------------------------------------------
// What a host in another language needs beyond the stages above (the Python bindings in
// `python/`): the command line's `tabulate` as a function, a dense NNLS, and a progress
// callback on the long stages. The commands themselves are requests: [`crate::run`].
// ---------------------------------------------------------------------------------------

pub use crate::backend::Progress;
pub use crate::cluster::GcukParams;
pub use crate::nnls::NnlsSolution;
pub use crate::select::SelectOutput;

/// A material's reflectance is not a finite f32 number in some valid cells.
#[derive(Debug, thiserror::Error)]
#[error("material `{material}` ({origin}): its reflectance is not a finite f32 number in {cells} valid cells ({cause})")]
pub struct NotFiniteError {
    /// The material.
    pub material: String,
    /// Where it came from.
    pub origin: String,
    /// Number of valid cells with a non-finite value.
    pub cells: usize,
    /// Why, in words: the parameters of an analytic material, or a network's output
    /// overflowing.
    pub cause: String,
}

/// Material `name` of `coll` on the full MERL grid, as `brdf-basis tabulate` writes it:
/// `rgb[c * N_CELLS + cell]` (channel-major, [`crate::merl::flat`] cell order),
/// invalid cells `-1`. Analytic materials are tabulated on `backend`; measured ones are
/// their table.
///
/// # Errors
/// [`Error::Collection`] for an unknown name, [`Error::Backend`] for a failed pass,
/// [`Error::NotFinite`] when the parameters overflow f32 in some valid cell.
pub fn tabulate(backend: &dyn Backend, coll: &Collection, name: &str) -> Result<Vec<f32>> {
    use crate::collection::MaterialData;
    use crate::merl::{cell_info, N_CELLS};
    let m = coll.get(name)?;
    match &m.data {
        MaterialData::Measured(t) => Ok(t.rgb.clone()),
        MaterialData::Rgl(r) => Ok(r.table().rgb.clone()),
        MaterialData::Analytic(_) | MaterialData::Neural(_) => {
            let lobes: Vec<crate::backend::Lobe> = (0..3)
                .map(|c| crate::fit::channel_lobe(&m.data, c))
                .collect();
            let cells: Vec<u32> = (0..N_CELLS as u32).collect();
            let mut rgb = backend.tabulate(&lobes, &cells)?;
            let mut overflow = 0usize;
            for cell in 0..N_CELLS {
                if !cell_info(cell).valid {
                    for c in 0..3 {
                        rgb[c * N_CELLS + cell] = -1.0;
                    }
                } else if (0..3).any(|c| !rgb[c * N_CELLS + cell].is_finite()) {
                    overflow += 1;
                }
            }
            if overflow > 0 {
                return Err(Error::NotFinite(Box::new(NotFiniteError {
                    material: crate::error::short_name(&m.name).to_string(),
                    origin: m.origin.clone(),
                    cells: overflow,
                    cause: match m.analytic() {
                        Some(a) => format!("parameters too large: n = {}, s = {:?}", a.n, a.s),
                        None => "the network's output overflows f32".into(),
                    },
                })));
            }
            Ok(rgb)
        }
    }
}

/// What a material is made of, in one word: `analytic`, `measured` (a MERL table),
/// `neural` (an NBRDF) or `rgl` (an RGL-EPFL `.bsdf` file).
pub fn material_kind(m: &crate::collection::Material) -> &'static str {
    use crate::collection::MaterialData;
    match m.data {
        MaterialData::Analytic(_) => "analytic",
        MaterialData::Measured(_) => "measured",
        MaterialData::Neural(_) => "neural",
        MaterialData::Rgl(_) => "rgl",
    }
}

/// Non-negative least squares `min |A x - b|` subject to `x >= 0` for a dense row-major
/// `A` (`rows` x `cols`), by the crate's exact Lawson-Hanson solver on the Gram form
/// (`G = A^T A`, `h = A^T b`, summed in f64).
///
/// # Errors
/// [`Error::Nnls`] for mismatched lengths, non-finite entries or no column.
pub fn nnls_dense(a: &[f64], rows: usize, cols: usize, b: &[f64]) -> Result<NnlsSolution> {
    use crate::nnls::NnlsError;
    if a.len() != rows * cols {
        return Err(NnlsError::DimensionMismatch {
            what: "A",
            expected: rows * cols,
            found: a.len(),
        }
        .into());
    }
    if b.len() != rows {
        return Err(NnlsError::DimensionMismatch {
            what: "b",
            expected: rows,
            found: b.len(),
        }
        .into());
    }
    for (what, v, width) in [("A", a, cols.max(1)), ("b", b, 1)] {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(NnlsError::NonFinite {
                what,
                row: i / width,
                col: i % width,
                value: v[i],
            }
            .into());
        }
    }
    let mut g = vec![0f64; cols * cols];
    let mut h = vec![0f64; cols];
    for r in 0..rows {
        let row = &a[r * cols..(r + 1) * cols];
        for i in 0..cols {
            h[i] += row[i] * b[r];
            for j in 0..cols {
                g[i * cols + j] += row[i] * row[j];
            }
        }
    }
    let bb: f64 = b.iter().map(|x| x * x).sum();
    let problem = crate::nnls::GramProblem::new(cols, &g, &h, bb)?;
    Ok(crate::nnls::lawson_hanson::solve(
        &problem,
        &crate::nnls::lawson_hanson::LhParams::default(),
    )?)
}

/// Fits a new material from samples given as arrays (SPEC 10): per sample the angles
/// `[theta_i, phi_i, theta_o, phi_o]` in degrees and the RGB reflectance, optional
/// per-channel standard deviations; `basis` names materials of `coll`. Samples are
/// validated like a samples file (row `i` is reported as line `i + 1`).
pub fn fit_from_arrays(
    coll: &Collection,
    basis: &[&str],
    angles: &[[f64; 4]],
    rgb: &[[f64; 3]],
    sigma: Option<&[[f64; 3]]>,
    objective: crate::backend::weighted::TargetWeight,
) -> Result<SampleFit> {
    let b: Vec<usize> = basis
        .iter()
        .map(|n| coll.index_of(n))
        .collect::<std::result::Result<_, _>>()?;
    let samples = crate::acquire::samples_from_arrays(angles, rgb, sigma)?;
    Ok(crate::acquire::fit_samples(coll, &b, &samples, objective)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A module's error passes through [`Error`] with its message unchanged.
    #[test]
    fn module_errors_keep_their_message() {
        let coll = Collection::embedded_default();
        let p = DistanceParams::default().stride(0);
        let direct = p.check(&coll).unwrap_err();
        let e = Error::from(p.check(&coll).unwrap_err());
        assert!(matches!(e, Error::Distance(_)), "{e:?}");
        assert_eq!(e.to_string(), direct.to_string());
        let e = Error::from(crate::fit::FitError::EmptyBasis);
        assert!(
            matches!(e, Error::Fit(crate::fit::FitError::EmptyBasis)),
            "{e:?}"
        );
    }

    /// `tabulate` is the back-end's table of the three channel lobes, -1 outside the
    /// valid cells, within f32 rounding of the f64 model; NaN-free; parameters that
    /// overflow f32 are refused with the material's name.
    #[test]
    fn tabulate_is_the_model_on_valid_cells_and_minus_one_elsewhere() {
        use crate::merl::{cell_directions, cell_info, N_CELLS};
        let cpu = CpuBackend::new();
        let coll = Collection::embedded_default();
        let name = "polished-gold";
        let rgb = tabulate(&cpu, &coll, name).unwrap();
        assert_eq!(rgb.len(), 3 * N_CELLS);
        let a = *coll.get(name).unwrap().analytic().unwrap();
        let mut checked = 0;
        for cell in (0..N_CELLS).step_by(997) {
            if !cell_info(cell).valid {
                assert!((0..3).all(|c| rgb[c * N_CELLS + cell] == -1.0));
                continue;
            }
            let (wi, wo) = cell_directions(cell);
            let f = a.eval(wi, wo);
            for c in 0..3 {
                let v = f64::from(rgb[c * N_CELLS + cell]);
                assert!(
                    (v - f[c]).abs() <= 1e-4 * f[c].abs().max(1e-3),
                    "{cell} {c}: {v} vs {}",
                    f[c]
                );
            }
            checked += 1;
        }
        assert!(checked > 500, "{checked}");
        let e = tabulate(&cpu, &coll, "polished-golf").unwrap_err();
        assert!(matches!(e, Error::Collection(_)), "{e:?}");
        let big = crate::collection::parse_csv(
            b"material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nhot,0,0,0,3e38,3e38,3e38,1,1\n",
            std::path::Path::new("big.csv"),
        )
        .unwrap();
        let e = tabulate(&cpu, &big, "hot").unwrap_err();
        assert!(matches!(e, Error::NotFinite(_)), "{e:?}");
        assert!(e.to_string().contains("material `hot`"), "{e}");
    }

    /// Dense NNLS: hand-solved cases, the dimension checks.
    #[test]
    fn nnls_hand_cases() {
        // min |x - (1, -1)| s.t. x >= 0: (1, 0).
        let s = nnls_dense(&[1.0, 0.0, 0.0, 1.0], 2, 2, &[1.0, -1.0]).unwrap();
        assert_eq!(s.x, vec![1.0, 0.0]);
        // A = [[1, 1], [1, 2], [1, 3]], b = A (2, 1): exact and positive.
        let a = [1.0, 1.0, 1.0, 2.0, 1.0, 3.0];
        let s = nnls_dense(&a, 3, 2, &[3.0, 4.0, 5.0]).unwrap();
        assert!(
            (s.x[0] - 2.0).abs() < 1e-12 && (s.x[1] - 1.0).abs() < 1e-12,
            "{:?}",
            s.x
        );
        // b = (3, 2, 1): the unconstrained slope is -1; with x >= 0, x = (2, 0).
        let s = nnls_dense(&a, 3, 2, &[3.0, 2.0, 1.0]).unwrap();
        assert!((s.x[0] - 2.0).abs() < 1e-12 && s.x[1] == 0.0, "{:?}", s.x);
        assert!(matches!(nnls_dense(&a, 3, 2, &[1.0]), Err(Error::Nnls(_))));
        assert!(matches!(
            nnls_dense(&a[..5], 3, 2, &[1.0; 3]),
            Err(Error::Nnls(_))
        ));
        assert!(matches!(
            nnls_dense(&[f64::NAN], 1, 1, &[1.0]),
            Err(Error::Nnls(_))
        ));
    }
}
