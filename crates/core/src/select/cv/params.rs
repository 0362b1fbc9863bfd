//! Cross-validation parameters and the methods compared.

use super::super::ga::{GaParams, ValidGaParams};
use super::super::objective::ObjectiveParams;
use super::super::SelectionError;
use crate::distance::Metric;
use crate::eval::render::RenderParams;

/// A selection method compared by cross-validation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CvMethod {
    /// Greedy forward selection on S.
    Greedy,
    /// Swap refinement of the greedy basis.
    Swap,
    /// Genetic algorithm on S.
    Ga,
    /// k-medoids (PAM) on the distance matrix.
    Kmedoids,
    /// GCUK at fixed k on the distance matrix.
    Gcuk,
    /// The k most frequent contributors of the leave-one-out fits.
    Empirical,
    /// k random training materials.
    Random,
}

impl CvMethod {
    /// Every method.
    pub const ALL: [CvMethod; 7] = [
        CvMethod::Greedy,
        CvMethod::Swap,
        CvMethod::Ga,
        CvMethod::Kmedoids,
        CvMethod::Gcuk,
        CvMethod::Empirical,
        CvMethod::Random,
    ];

    /// The method's name on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            CvMethod::Greedy => "greedy",
            CvMethod::Swap => "swap",
            CvMethod::Ga => "ga",
            CvMethod::Kmedoids => "kmedoids",
            CvMethod::Gcuk => "gcuk",
            CvMethod::Empirical => "empirical",
            CvMethod::Random => "random",
        }
    }

    pub(crate) fn clustering(self) -> bool {
        matches!(self, CvMethod::Kmedoids | CvMethod::Gcuk)
    }

    /// Greedy, swap or GA: chosen by `S` on the training materials.
    pub(crate) fn error_driven(self) -> bool {
        matches!(self, CvMethod::Greedy | CvMethod::Swap | CvMethod::Ga)
    }
}

impl std::fmt::Display for CvMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for CvMethod {
    type Err = SelectionError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        CvMethod::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| SelectionError::InvalidParam {
                name: "--methods",
                value: s.into(),
                expected: "one of greedy, swap, ga, kmedoids, gcuk, empirical, random",
            })
    }
}

/// Cross-validation parameters (builder; validate with [`CvParams::check`]).
#[derive(Clone, Debug, PartialEq)]
pub struct CvParams {
    /// Methods compared (default: greedy, swap, kmedoids, gcuk, empirical, random).
    pub methods: Vec<CvMethod>,
    /// Basis sizes (default 5 and 12, the sizes of the paper's bases).
    pub ks: Vec<usize>,
    /// Number of folds K, `2 <= K <= N` (default 5).
    pub folds: usize,
    /// Seed of the fold permutation and of every stochastic method (default 1, as the
    /// command line's `--seed`).
    pub seed: u64,
    /// Fit cells and Gram mode (default: evaluation mask, uniform, full grid).
    pub objective: ObjectiveParams,
    /// Distance of the clustering methods (default BRDF_it, SPEC 4 lobe).
    pub metric: Metric,
    /// k-medoids restarts and GCUK runs per fold (default 10).
    pub runs: usize,
    /// Genetic-algorithm settings (its seed is offset by the fold).
    pub ga: GaParams,
    /// Render size for the image errors, `>= 1` (default 64).
    pub render_size: u32,
    /// The appearance metrics of every held-out fit (SPEC 11: renders at 256 x 256 under
    /// four lights, CIEDE2000 and FLIP; default on).
    pub appearance: bool,
}

impl Default for CvParams {
    fn default() -> Self {
        Self {
            methods: vec![
                CvMethod::Greedy,
                CvMethod::Swap,
                CvMethod::Kmedoids,
                CvMethod::Gcuk,
                CvMethod::Empirical,
                CvMethod::Random,
            ],
            ks: vec![5, 12],
            folds: 5,
            seed: 1,
            objective: ObjectiveParams::default(),
            metric: Metric::BrdfIt,
            runs: 10,
            ga: GaParams::default(),
            render_size: 64,
            appearance: true,
        }
    }
}

impl CvParams {
    /// Sets the methods.
    pub fn methods(mut self, m: Vec<CvMethod>) -> Self {
        self.methods = m;
        self
    }
    /// Sets the basis sizes.
    pub fn ks(mut self, ks: Vec<usize>) -> Self {
        self.ks = ks;
        self
    }
    /// Sets the number of folds.
    pub fn folds(mut self, f: usize) -> Self {
        self.folds = f;
        self
    }
    /// Sets the seed.
    pub fn seed(mut self, s: u64) -> Self {
        self.seed = s;
        self
    }
    /// Sets the objective parameters.
    pub fn objective(mut self, o: ObjectiveParams) -> Self {
        self.objective = o;
        self
    }
    /// Sets the clustering restarts / runs.
    pub fn runs(mut self, r: usize) -> Self {
        self.runs = r;
        self
    }
    /// Sets the render size.
    pub fn render_size(mut self, s: u32) -> Self {
        self.render_size = s;
        self
    }
    /// Sets whether the appearance metrics are computed.
    pub fn appearance(mut self, a: bool) -> Self {
        self.appearance = a;
        self
    }

    /// Validates against a collection of `n` materials: at least one method, each once;
    /// at least one k, each `>= 1` (`>= 2` with a clustering method) and at most the
    /// smallest training set; `2 <= folds <= n`; `runs >= 1`; valid GA, objective and
    /// render settings.
    pub fn check(&self, n: usize) -> Result<ValidCvParams, SelectionError> {
        self.check_held(n, None)
    }

    /// [`Self::check`] of one fixed split (`folds` 1) whose held-out set has `held`
    /// materials: `held` from 1 to `n - 1`, every other rule as [`Self::check`] with the
    /// training fold `n - held`.
    ///
    /// # Errors
    /// As [`Self::check`].
    pub fn check_split(&self, n: usize, held: usize) -> Result<ValidCvParams, SelectionError> {
        if held == 0 || held >= n {
            return Err(SelectionError::InvalidParam {
                name: "--test",
                value: format!(
                    "{} (a collection of {})",
                    crate::error::plural(held, "material", "materials"),
                    crate::error::plural(n, "material", "materials")
                ),
                expected: "at least one held-out material and at least one to train on",
            });
        }
        CvParams {
            folds: 1,
            ..self.clone()
        }
        .check_held(n, Some(held))
    }

    /// The rules of [`Self::check`]; with `split` (a fixed split's held-out count) no
    /// rule on the number of folds and that count as the largest held-out fold.
    fn check_held(&self, n: usize, split: Option<usize>) -> Result<ValidCvParams, SelectionError> {
        let bad = |name, value: String, expected| {
            Err(SelectionError::InvalidParam {
                name,
                value,
                expected,
            })
        };
        if self.methods.is_empty() {
            return bad("--methods", "none".into(), "at least one method");
        }
        for (i, m) in self.methods.iter().enumerate() {
            if self.methods[..i].contains(m) {
                return Err(SelectionError::DuplicateMethod(m.name().into()));
            }
        }
        if split.is_none() && (self.folds < 2 || self.folds > n) {
            return bad(
                "--folds",
                format!(
                    "{} (a collection of {})",
                    self.folds,
                    crate::error::plural(n, "material", "materials")
                ),
                "between 2 and the number of materials",
            );
        }
        let train = n - split.unwrap_or_else(|| n.div_ceil(self.folds));
        if self.ks.is_empty() {
            return bad("-k", "none".into(), "at least one basis size");
        }
        let kmin = if self.methods.iter().any(|m| m.clustering()) {
            2
        } else {
            1
        };
        for &k in &self.ks {
            if k < kmin || k > train {
                return bad(
                    "-k",
                    format!(
                        "{k} (smallest training fold: {})",
                        crate::error::plural(train, "material", "materials")
                    ),
                    "at least 1 (2 with kmedoids or gcuk) and at most the smallest training fold",
                );
            }
            // greedy, swap and ga score the training materials outside the basis: a basis
            // of the whole training fold leaves none.
            if k == train && self.methods.iter().any(|m| m.error_driven()) {
                return bad(
                    "-k",
                    format!(
                        "{k} (smallest training fold: {})",
                        crate::error::plural(train, "material", "materials")
                    ),
                    "below the smallest training fold with greedy, swap or ga (a basis of every training material leaves no target to score)",
                );
            }
        }
        if self.runs == 0 {
            return bad("--runs", "0".into(), "at least 1");
        }
        let ga = self.ga.check()?;
        self.objective.check()?;
        RenderParams::default()
            .with_size(self.render_size)
            .check()?;
        let mut ks = self.ks.clone();
        ks.dedup();
        Ok(ValidCvParams {
            p: CvParams { ks, ..self.clone() },
            ga,
        })
    }
}

/// Validated [`CvParams`].
#[derive(Clone, Debug, PartialEq)]
pub struct ValidCvParams {
    p: CvParams,
    pub(crate) ga: ValidGaParams,
}

impl ValidCvParams {
    /// The parameters.
    pub fn params(&self) -> &CvParams {
        &self.p
    }
}
