//! `fit`: materials of the collection as non-negative combinations of a basis.

use super::{all_others, indices_of, refuse, Ctx, ObjectiveSetting, Refusal, Request};
use crate::acquire::SampleFit;
use crate::backend::weighted::ObjectiveKind;
use crate::collection::Collection;
use crate::eval::appearance::Appearance;
use crate::fit::diagnostics::{fit_warnings, WARN_RELATIVE_RESIDUAL};
use crate::fit::file::FitFile;
use crate::fit::{fit, FitParams, GramMode, Solver, TargetFit};
use crate::merl::GridSpec;
use crate::Result;
use std::path::PathBuf;

/// The materials `fit` fits.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub enum FitTargets {
    /// `--all-others`: every material outside the basis (the default of the library and
    /// of Python; the command line asks for it by name).
    #[default]
    AllOthers,
    /// `--targets`: these materials, each once.
    Named(Vec<String>),
}

/// `brdf-basis fit` (without `--samples`): its settings, with the defaults of
/// `fit --help` ([`FitParams::default`]).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct FitRequest {
    /// `--basis` (no default).
    pub basis: Vec<String>,
    /// `--targets` or `--all-others`.
    pub targets: FitTargets,
    /// `--mask`, `--weighting`, `--stride`.
    pub grid: GridSpec,
    /// `--solver`.
    pub solver: Solver,
    /// `--gram`.
    pub gram: GramMode,
    /// `--objective` and `--eps` (SPEC 11), as given.
    pub objective: ObjectiveSetting,
    /// The appearance metrics of every fit (SPEC 11: log-RMSE, and image error, CIEDE2000
    /// and FLIP under four lights); `--no-appearance` turns them off.
    pub appearance: bool,
}

/// What `fit` computes: the fits, the JSON file, and the warnings on targets the basis
/// cannot represent.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct FitOutput {
    /// Basis (collection indices, in column order).
    pub basis: Vec<usize>,
    /// One fit per target, in target order.
    pub fits: Vec<TargetFit>,
    /// What `fit --json` writes.
    pub file: FitFile,
    /// Targets this basis cannot represent, in words ([`fit_warnings`]).
    pub warnings: Vec<String>,
    /// The appearance metrics of every fit (target order); empty without
    /// [`FitRequest::appearance`].
    pub appearance: Vec<Appearance>,
}

impl FitRequest {
    /// The defaults with `basis`.
    pub fn new(basis: Vec<String>) -> Self {
        let d = FitParams::default();
        Self {
            basis,
            targets: FitTargets::default(),
            grid: GridSpec::default(),
            solver: d.solver,
            gram: d.gram,
            objective: ObjectiveSetting::default(),
            appearance: true,
        }
    }

    /// The library's parameters, the defaults applied.
    ///
    /// # Errors
    /// As [`Self::check`].
    pub fn params(&self) -> Result<FitParams> {
        Ok(FitParams {
            solver: self.solver,
            gram: self.gram,
            objective: self.objective.weight()?,
            ..FitParams::default()
        }
        .grid(self.grid))
    }

    /// The basis and target indices in `coll`: targets each once, never empty.
    ///
    /// # Errors
    /// An unknown material, a target given twice, no target left.
    pub fn indices(&self, coll: &Collection) -> Result<(Vec<usize>, Vec<usize>)> {
        let basis = indices_of(coll, &self.basis)?;
        let targets = match &self.targets {
            FitTargets::AllOthers => all_others(coll, &basis),
            FitTargets::Named(names) if names.is_empty() => refuse!(Refusal::Missing {
                setting: "--targets",
                message: "give --targets X,Y or --all-others".into(),
            }),
            FitTargets::Named(names) => indices_of(coll, names)?,
        };
        for (i, &t) in targets.iter().enumerate() {
            if targets[..i].contains(&t) {
                refuse!(Refusal::Rule {
                    setting: "--targets",
                    message: format!(
                        "--targets: material `{}` is given twice",
                        crate::error::short_name(&coll.materials()[t].name)
                    ),
                });
            }
        }
        if targets.is_empty() {
            refuse!(Refusal::Rule {
                setting: "--all-others",
                message:
                    "--all-others: every material of the collection is in the basis; nothing to fit"
                        .into(),
            });
        }
        Ok((basis, targets))
    }
}

impl Request for FitRequest {
    type Output = FitOutput;

    /// The rules of the settings that need no collection: the objective's
    /// ([`ObjectiveSetting::weight`]), and `--solver`/`--gram` only with `l2`.
    fn check(&self) -> std::result::Result<(), Refusal> {
        let w = self.objective.weight()?;
        let d = FitParams::default();
        let given: Vec<(&'static str, &'static str)> = [
            (self.solver != d.solver, ("--solver", "--solver pgd")),
            (self.gram != d.gram, ("--gram", "--gram grid")),
        ]
        .into_iter()
        .filter_map(|(g, f)| g.then_some(f))
        .collect();
        if w.kind() != ObjectiveKind::L2 && !given.is_empty() {
            let shown: Vec<&str> = given.iter().map(|g| g.1).collect();
            refuse!(Refusal::DoesNotApply {
                settings: given.iter().map(|g| g.0).collect(),
                shown: shown.join(" and "),
                context: format!("to --objective {}", w.kind().name()),
                why: format!(
                    ": a weighted objective solves each target's own system exactly (Lawson-Hanson), with no shared Gram matrix and no projected gradient; --solver and --gram concern --objective l2 only: leave {} out, or give --objective l2",
                    if given.len() == 1 { "it" } else { "them" },
                ),
            });
        }
        Ok(())
    }

    /// Fits the targets on the back-end and returns the fits and the `--json` file.
    fn run(&self, ctx: &Ctx<'_>) -> Result<FitOutput> {
        let (backend, coll) = (ctx.need_backend()?, ctx.need_collection()?);
        self.check()?;
        let p = self.params()?;
        let (basis, targets) = self.indices(coll)?;
        let fits = fit(backend, coll, &basis, &targets, &p, ctx.progress)?;
        let warnings = fit_warnings(coll, &basis, &targets, &fits, p.objective);
        let appearance = if self.appearance {
            let mut all = basis.clone();
            all.extend_from_slice(&targets);
            let cells = crate::fit::fit_cells(coll, &all, &p)?;
            crate::fit::appearance::appearance(coll, &basis, &targets, &fits, &cells)?
        } else {
            Vec::new()
        };
        let mut file = FitFile::new(coll, &basis, &fits, &p);
        for (t, a) in file.targets.iter_mut().zip(&appearance) {
            t.appearance = Some(a.clone());
        }
        Ok(FitOutput {
            basis,
            fits,
            file,
            warnings,
            appearance,
        })
    }
}

/// `brdf-basis fit --samples`: a new material fitted from its measured samples (SPEC 10),
/// with the defaults of `fit --help`.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct FitSamplesRequest {
    /// `--basis` (no default).
    pub basis: Vec<String>,
    /// `--samples`: a samples file, or the arrays of Python's `fit_samples`.
    pub samples: Samples,
    /// `--mask`, `--weighting`, `--stride`: do not apply (the defaults only, recorded in
    /// the JSON; [`Self::check`] refuses others).
    pub grid: GridSpec,
    /// `--solver`: does not apply (the default only, recorded in the JSON).
    pub solver: Solver,
    /// `--gram`: does not apply (the default only, recorded in the JSON).
    pub gram: GramMode,
    /// `--seed`: of the directions suggested when the samples do not determine the fit.
    pub seed: u64,
    /// `--objective` and `--eps` (SPEC 11: each sample weighted by the objective's weight
    /// at its measured value), as given.
    pub objective: ObjectiveSetting,
}

/// The samples of [`FitSamplesRequest`].
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// A samples CSV or an ASTM E1392 `.astm` file; the target is named after its stem.
    File(PathBuf),
    /// Per sample the angles `[theta_i, phi_i, theta_o, phi_o]` in degrees, the RGB
    /// reflectance and optional per-channel standard deviations (Python's `fit_samples`),
    /// validated as a samples file's rows (row `i` is reported as line `i + 1` of
    /// `<arrays>`); the target is named `samples`.
    Arrays {
        /// The angles of each sample, in degrees.
        angles: Vec<[f64; 4]>,
        /// The RGB reflectance of each sample.
        rgb: Vec<[f64; 3]>,
        /// The standard deviations of each sample's channels.
        sigma: Option<Vec<[f64; 3]>>,
    },
}

/// What `fit --samples` computes.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct FitSamplesOutput {
    /// Basis (collection indices, in column order).
    pub basis: Vec<usize>,
    /// The target's name (the samples file's stem).
    pub name: String,
    /// Number of samples.
    pub samples: usize,
    /// The fit from the samples, with the determination of the sampled design.
    pub fit: SampleFit,
    /// The fit as a collection target's (for `--export`).
    pub target: TargetFit,
    /// What `fit --json` writes (the `fit` schema with `samples` and `fitted_from`).
    pub file: FitFile,
    /// Samples too few or a design ill-conditioned, in words, with where to measure next.
    pub warnings: Vec<String>,
}

impl FitSamplesRequest {
    /// The files this request reads besides the collection, with what they are called in
    /// messages: the output layer refuses any output that names one of them.
    pub fn input_files(&self) -> Vec<(PathBuf, &'static str)> {
        match &self.samples {
            Samples::File(path) => vec![(path.clone(), "samples file")],
            Samples::Arrays { .. } => Vec::new(),
        }
    }

    /// The defaults with `basis` and the samples file.
    pub fn new(basis: Vec<String>, samples: PathBuf) -> Self {
        Self::of(basis, Samples::File(samples))
    }

    /// The defaults with `basis` and `samples`.
    pub fn of(basis: Vec<String>, samples: Samples) -> Self {
        let d = FitParams::default();
        Self {
            basis,
            samples,
            grid: GridSpec::default(),
            solver: d.solver,
            gram: d.gram,
            seed: super::SEED,
            objective: ObjectiveSetting::default(),
        }
    }

    /// The target's name: the samples file's stem (`samples` when it has none, and for
    /// arrays).
    pub fn target_name(&self) -> String {
        match &self.samples {
            Samples::File(path) => path.file_stem().map(|s| s.to_string_lossy().into_owned()),
            Samples::Arrays { .. } => None,
        }
        .unwrap_or_else(|| "samples".into())
    }
}

impl Request for FitSamplesRequest {
    type Output = FitSamplesOutput;

    /// The rules of the settings that need no collection: the objective's
    /// ([`ObjectiveSetting::weight`]), then the grid fit's settings, which do not apply to
    /// a fit from samples (given, they would be ignored and recorded in the JSON as if
    /// they had applied).
    fn check(&self) -> std::result::Result<(), Refusal> {
        self.objective.weight()?;
        let (grid, g, d) = (&self.grid, GridSpec::default(), FitParams::default());
        let ignored: Vec<&'static str> = [
            ("--stride", grid.stride() != g.stride()),
            ("--mask", grid.mask() != g.mask()),
            ("--weighting", grid.weighting() != g.weighting()),
            ("--solver", self.solver != d.solver),
            ("--gram", self.gram != d.gram),
        ]
        .into_iter()
        .filter_map(|(flag, given)| given.then_some(flag))
        .collect();
        if !ignored.is_empty() {
            refuse!(Refusal::DoesNotApply {
                shown: ignored.join(", "),
                context: "with --samples".into(),
                why: format!(
                    ": the fit from samples solves a least-squares problem over the measured samples alone (no grid cells, no Gram matrix, its own NNLS); leave {} out",
                    if ignored.len() == 1 { "it" } else { "them" },
                ),
                settings: ignored,
            });
        }
        Ok(())
    }

    /// Reads the samples and fits them by the basis of the collection (no back-end:
    /// [`Ctx::collection`] is enough).
    fn run(&self, ctx: &Ctx<'_>) -> Result<FitSamplesOutput> {
        use crate::acquire::{self as afit, read_samples};
        let coll = ctx.need_collection()?;
        self.check()?;
        let objective = self.objective.weight()?;
        let basis = indices_of(coll, &self.basis)?;
        let samples = match &self.samples {
            Samples::File(path) => read_samples(path)?,
            Samples::Arrays { angles, rgb, sigma } => {
                crate::acquire::samples_from_arrays(angles, rgb, sigma.as_deref())?
            }
        };
        let sf = afit::fit_samples(coll, &basis, &samples, objective)?;
        let d = &sf.determination;
        // As many directions as the warning says more samples would help: the missing
        // samples, else the missing rank, else "a few" (3).
        let more = if d.samples < d.columns {
            d.columns - d.rank.min(d.samples)
        } else if d.rank < d.columns {
            d.columns - d.rank
        } else {
            3
        };
        let hint = if d.rank < d.columns || d.condition > afit::WARN_CONDITION {
            afit::suggest(coll, &basis, &samples, more, self.seed)?
        } else {
            String::new()
        };
        let mut warnings = afit::determination_warnings(d, afit::WARN_CONDITION, &hint);
        // Issue 50, item 2: a peak the samples do not pin is said, never a silent wild
        // material.
        warnings.extend(afit::peak_warning(coll, &basis, &sf, &samples)?);
        let name = self.target_name();
        let samples_file = match &self.samples {
            Samples::File(path) => Some(path),
            Samples::Arrays { .. } => None,
        };
        if let Some((b, path)) = coll
            .materials()
            .iter()
            .position(|m| m.name == name)
            .zip(samples_file)
        {
            // Kept a warning (docs/hardening.md, T7): fitting a measured sample of a
            // material the collection holds is a legitimate check of the basis.
            warnings.push(format!(
                "the fitted material is named `{name}` after the samples file {}, as is {} material of the collection: the fit is of the samples, not of the collection's `{name}` (`render --fit` and `plot --fit` refuse a fit from samples); rename the samples file to tell them apart",
                path.display(),
                if basis.contains(&b) { "a basis" } else { "a" },
            ));
        }
        let p = FitParams {
            solver: self.solver,
            gram: self.gram,
            objective,
            ..FitParams::default()
        }
        .grid(self.grid);
        let target = sf.target_fit(&name);
        // Audit 3, U6: the dense fit's rule (relative residual above 0.5, under the
        // objective's weights when it is not `l2`), on the samples.
        let (rho, under) = if objective == crate::backend::weighted::TargetWeight::L2 {
            (target.relative_residual, String::new())
        } else {
            (
                target.objective_residual,
                format!(" under the `{}` objective", objective.kind().name()),
            )
        };
        if rho > WARN_RELATIVE_RESIDUAL {
            warnings.push(format!(
                "the fit of `{name}` explains little of its samples{under} (relative residual {}{}; 0 is a perfect fit, 1 explains nothing): this basis cannot represent it",
                crate::stats::num(rho),
                if under.is_empty() { "" } else { " under its weights" },
            ));
        }
        let mut file = FitFile::new(coll, &basis, std::slice::from_ref(&target), &p);
        file.samples = Some(samples.len());
        file.fitted_from = Some(match &self.samples {
            Samples::File(path) => path.display().to_string(),
            Samples::Arrays { .. } => "<arrays>".to_string(),
        });
        Ok(FitSamplesOutput {
            basis,
            name,
            samples: samples.len(),
            fit: sf,
            target,
            file,
            warnings,
        })
    }
}
