//! The facade's one error type ([`Error`], with `From` for each module's error), its
//! [`Result`], and the error of a material that does not tabulate ([`NotFiniteError`]).

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
    /// A tabulated material that is not finite ([`crate::tabulate`]).
    #[error(transparent)]
    NotFinite(Box<NotFiniteError>),
}

/// `Result` with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collection::Collection;
    use crate::distance::DistanceParams;

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
}
