//! K-fold cross-validation over materials of basis-selection methods (SPEC 8).
//!
//! A permutation drawn from the seed (`ChaCha8Rng::seed_from_u64(seed)`, Fisher-Yates)
//! splits the collection into K folds of sizes differing by at most one (the first
//! `N mod K` folds hold one more). For each fold every method chooses its basis from the
//! other folds only:
//!
//! * `greedy`, `swap` (from the greedy basis), `ga`: candidates and targets are the
//!   training materials; the objective's Gram matrices (of all N, computed once) are only
//!   read at training rows and columns.
//! * `kmedoids` (PAM, `runs` restarts, lowest loss) and `gcuk` (fixed `k_min = k_max = k`,
//!   `runs` runs, lowest Davies-Bouldin index): on the distance matrix (computed once for
//!   all N) restricted to the training materials.
//! * `empirical`: the leave-one-out fits of the training materials by the other training
//!   materials; the basis is the k materials contributing to the most fits (ties:
//!   collection order).
//! * `random`: k training materials drawn uniformly (seed `seed + 1000 fold + k`).
//!
//! Each held-out material is then fitted by every basis: `rho` from the Gram form (SPEC 8),
//! MAE on the grid (SPEC 5), and the normalised image error of renders of the fit against
//! the material (SPEC 7: light (45, 45), gamma 2.2, exposure 0). Per method and k: mean and
//! median of each; between every two methods at each k, paired two-sided Wilcoxon
//! signed-rank tests on the held-out values (p = 1 when every difference is zero).

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::fmt::Write as _;

use super::objective::{Objective, ObjectiveParams};
use super::search::{ga, greedy, swap, GaParams, SearchParams, ValidGaParams};
use super::SelectionError;
use crate::backend::cpu::CpuBackend;
use crate::backend::Lobe;
use crate::backend::{Backend, Progress};
use crate::cluster::{GcukParams, KMedoidsParams};
use crate::collection::Collection;
use crate::distance::{distance_matrix, DistanceMatrix, DistanceParams, Metric};
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, material_brdf};
use crate::fit::{channel_lobe, fit_cells, FitParams, GramMode, LAMBERTIAN};
use crate::merl::{CellSet, GridTables};
use crate::separable::{CellMoments, SeparableLobe};

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

    fn clustering(self) -> bool {
        matches!(self, CvMethod::Kmedoids | CvMethod::Gcuk)
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
                name: "method",
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
    /// Seed of the fold permutation and of every stochastic method (default 0).
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
            seed: 0,
            objective: ObjectiveParams::default(),
            metric: Metric::BrdfIt,
            runs: 10,
            ga: GaParams::default(),
            render_size: 64,
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

    /// Validates against a collection of `n` materials: at least one method, each once;
    /// at least one k, each `>= 1` (`>= 2` with a clustering method) and at most the
    /// smallest training set; `2 <= folds <= n`; `runs >= 1`; valid GA, objective and
    /// render settings.
    pub fn check(&self, n: usize) -> Result<ValidCvParams, SelectionError> {
        let bad = |name, value: String, expected| {
            Err(SelectionError::InvalidParam {
                name,
                value,
                expected,
            })
        };
        if self.methods.is_empty() {
            return bad("methods", "none".into(), "at least one method");
        }
        for (i, m) in self.methods.iter().enumerate() {
            if self.methods[..i].contains(m) {
                return Err(SelectionError::Duplicate {
                    what: "methods",
                    material: m.name().into(),
                });
            }
        }
        if self.folds < 2 || self.folds > n {
            return bad(
                "folds",
                format!("{} (collection of {n})", self.folds),
                "between 2 and the number of materials",
            );
        }
        let train = n - n.div_ceil(self.folds);
        if self.ks.is_empty() {
            return bad("k", "none".into(), "at least one basis size");
        }
        let kmin = if self.methods.iter().any(|m| m.clustering()) {
            2
        } else {
            1
        };
        for &k in &self.ks {
            if k < kmin || k > train {
                return bad(
                    "k",
                    format!("{k} (smallest training fold: {train} materials)"),
                    "at least 1 (2 with kmedoids or gcuk) and at most the smallest training fold",
                );
            }
        }
        if self.runs == 0 {
            return bad("runs", "0".into(), "at least 1");
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
    ga: ValidGaParams,
}

impl ValidCvParams {
    /// The parameters.
    pub fn params(&self) -> &CvParams {
        &self.p
    }
}

/// One held-out material fitted by one method's basis.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeldOut {
    /// Material.
    pub material: String,
    /// Its fold.
    pub fold: usize,
    /// `rho` of SPEC 8.
    pub rho: f64,
    /// MAE of SPEC 5 (grid, averaged over channels).
    pub mae: f64,
    /// Normalised image error (SPEC 7).
    pub image_error: f64,
}

/// Results of one method at one k.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CvMethodResult {
    /// Method name.
    pub method: String,
    /// Basis size.
    pub k: usize,
    /// The basis chosen in each fold.
    pub fold_bases: Vec<Vec<String>>,
    /// Every held-out material (fold order, then collection order).
    pub held_out: Vec<HeldOut>,
    /// Mean held-out rho.
    pub mean_rho: f64,
    /// Median held-out rho.
    pub median_rho: f64,
    /// Mean held-out MAE.
    pub mean_mae: f64,
    /// Median held-out MAE.
    pub median_mae: f64,
    /// Mean held-out image error.
    pub mean_image_error: f64,
    /// Median held-out image error.
    pub median_image_error: f64,
}

/// Paired Wilcoxon signed-rank tests between two methods at one k.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CvTest {
    /// First method.
    pub a: String,
    /// Second method.
    pub b: String,
    /// Basis size.
    pub k: usize,
    /// Two-sided p on the held-out rho.
    pub wilcoxon_p: f64,
    /// Two-sided p on the held-out MAE.
    pub wilcoxon_p_mae: f64,
    /// Two-sided p on the held-out image errors.
    pub wilcoxon_p_image_error: f64,
    /// Number of held-out materials where `a` has the lower rho.
    pub a_better: usize,
    /// Number where `b` has the lower rho.
    pub b_better: usize,
}

/// The cross-validation result (the `cv` JSON of SPEC-cli).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CvResult {
    /// The folds, by name (collection order within a fold).
    pub folds: Vec<Vec<String>>,
    /// Seed.
    pub seed: u64,
    /// Per method and k.
    pub results: Vec<CvMethodResult>,
    /// Paired tests.
    pub tests: Vec<CvTest>,
    /// Fit mask.
    pub mask: String,
    /// Weighting.
    pub weighting: String,
}

/// The folds of `n` materials for `seed`: a seeded permutation cut into `folds` parts of
/// sizes differing by at most one, each sorted.
pub fn make_folds(n: usize, folds: usize, seed: u64) -> Vec<Vec<usize>> {
    let mut perm: Vec<usize> = (0..n).collect();
    perm.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let (base, extra) = (n / folds, n % folds);
    let mut out = Vec::with_capacity(folds);
    let mut at = 0;
    for f in 0..folds {
        let len = base + usize::from(f < extra);
        let mut fold = perm[at..at + len].to_vec();
        fold.sort_unstable();
        out.push(fold);
        at += len;
    }
    out
}

/// Runs the cross-validation: builds the objective and (for clustering methods) the
/// distance matrix of the whole collection once, then [`cross_validate_with`].
pub fn cross_validate(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ValidCvParams,
    progress: Progress<'_>,
) -> Result<CvResult, SelectionError> {
    let q = p.params();
    let obj = Objective::new(backend, coll, &q.objective.check()?, &|_, _| {})?;
    let dist = if q.methods.iter().any(|m| m.clustering()) {
        let dp = DistanceParams::default()
            .metric(q.metric)
            .mask(q.objective.mask)
            .weighting(q.objective.weighting)
            .stride(q.objective.stride)
            .check(coll)?;
        Some(distance_matrix(backend, coll, &dp, &|_, _| {})?)
    } else {
        None
    };
    cross_validate_with(coll, &obj, dist.as_ref(), p, progress)
}

/// Runs the cross-validation with a given objective (of `coll`) and distance matrix (of
/// `coll`; needed only by the clustering methods). `progress(done, total)` counts
/// (fold, method, k) selections.
pub fn cross_validate_with(
    coll: &Collection,
    obj: &Objective,
    dist: Option<&DistanceMatrix>,
    vp: &ValidCvParams,
    progress: Progress<'_>,
) -> Result<CvResult, SelectionError> {
    let p = vp.params();
    let n = coll.len();
    if obj.len() != n || dist.is_some_and(|d| d.names().len() != n) {
        return Err(SelectionError::InvalidParam {
            name: "objective / distances",
            value: format!(
                "{} / {} materials",
                obj.len(),
                dist.map_or(n, |d| d.names().len())
            ),
            expected: "the same materials as the collection",
        });
    }
    let folds = make_folds(n, p.folds, p.seed);
    let names = coll.names();
    let fp = p.objective.fit_params();
    // bases[method][k][fold]
    let mut bases = vec![vec![vec![Vec::new(); p.folds]; p.ks.len()]; p.methods.len()];
    let total = (p.folds * p.methods.len() * p.ks.len()) as u64;
    let mut done = 0;
    let kmax = p.ks.iter().copied().max().unwrap_or(1);
    for (f, fold) in folds.iter().enumerate() {
        let train: Vec<usize> = (0..n).filter(|i| fold.binary_search(i).is_err()).collect();
        let sub = dist.map(|d| d.subset(&train));
        let mut greedy_max: Option<Vec<usize>> = None;
        let mut counts: Option<Vec<usize>> = None;
        for (mi, &m) in p.methods.iter().enumerate() {
            for (ki, &k) in p.ks.iter().enumerate() {
                let sp = SearchParams::new(k)
                    .candidates(train.clone())
                    .targets(train.clone());
                let basis: Vec<usize> = match m {
                    CvMethod::Greedy | CvMethod::Swap => {
                        let g = greedy_max.get_or_insert_with(|| {
                            let spm = SearchParams::new(kmax)
                                .candidates(train.clone())
                                .targets(train.clone());
                            spm.check(&names)
                                .map(|v| greedy(obj, &v, &|_, _| {}).indices)
                                .unwrap_or_default()
                        });
                        let start = g[..k.min(g.len())].to_vec();
                        if m == CvMethod::Greedy {
                            start
                        } else {
                            swap(obj, &sp.init(start).check(&names)?, &|_, _| {}).indices
                        }
                    }
                    CvMethod::Ga => {
                        let gp = GaParams {
                            seed: vp.ga.params().seed.wrapping_add(f as u64),
                            ..vp.ga.params().clone()
                        }
                        .check()?;
                        ga(obj, &sp.check(&names)?, &gp, &|_, _| {}).indices
                    }
                    CvMethod::Kmedoids => {
                        let d = sub.as_ref().ok_or(missing_distances())?;
                        let km = KMedoidsParams::new(k)
                            .restarts(p.runs)
                            .seed(p.seed)
                            .fit(d)?;
                        km.medoids.iter().map(|&i| train[i]).collect()
                    }
                    CvMethod::Gcuk => {
                        let d = sub.as_ref().ok_or(missing_distances())?;
                        let mut best: Option<(f64, Vec<usize>)> = None;
                        for r in 0..p.runs {
                            let g = GcukParams::default()
                                .k_range(k, k)
                                .seed(p.seed.wrapping_add(r as u64))
                                .fit(d)?;
                            if best.as_ref().is_none_or(|b| g.db_index < b.0) {
                                best = Some((g.db_index, g.medoids));
                            }
                        }
                        best.map(|b| b.1)
                            .unwrap_or_default()
                            .iter()
                            .map(|&i| train[i])
                            .collect()
                    }
                    CvMethod::Empirical => {
                        let c = counts.get_or_insert_with(|| empirical_counts(obj, &train));
                        let mut order: Vec<usize> = (0..train.len()).collect();
                        order.sort_by_key(|&j| (std::cmp::Reverse(c[j]), j));
                        order[..k].iter().map(|&j| train[j]).collect()
                    }
                    CvMethod::Random => {
                        let mut rng = ChaCha8Rng::seed_from_u64(
                            p.seed.wrapping_add(1000 * f as u64 + k as u64),
                        );
                        let mut b: Vec<usize> = rand::seq::index::sample(&mut rng, train.len(), k)
                            .into_iter()
                            .map(|j| train[j])
                            .collect();
                        b.sort_unstable();
                        b
                    }
                };
                bases[mi][ki][f] = basis;
                done += 1;
                progress(done, total);
            }
        }
    }
    // Evaluation of every held-out material by every basis.
    let display = DisplayParams::default();
    let rp = RenderParams::default()
        .with_size(p.render_size)
        .with_light(45.0, 45.0);
    let originals: Vec<Image> = (0..n)
        .map(|t| render_sphere(&rp, &material_brdf(&coll.materials()[t].data)))
        .collect::<Result<_, _>>()?;
    let grid = GridEval::new(coll, &fp);
    let mut results = Vec::new();
    for (mi, &m) in p.methods.iter().enumerate() {
        for (ki, &k) in p.ks.iter().enumerate() {
            let mut held_out = Vec::with_capacity(n);
            for (f, fold) in folds.iter().enumerate() {
                let basis = &bases[mi][ki][f];
                let rows: Vec<Result<HeldOut, SelectionError>> = fold
                    .par_iter()
                    .map(|&t| {
                        let (coef, rho) = obj.fit(basis, t);
                        let img = render_sphere(&rp, &combination_brdf(coll, basis, &coef))?;
                        Ok(HeldOut {
                            material: names[t].clone(),
                            fold: f,
                            rho,
                            mae: grid.mae(basis, t, &coef),
                            image_error: normalized_image_error(&originals[t], &img, &display)?,
                        })
                    })
                    .collect();
                for r in rows {
                    held_out.push(r?);
                }
            }
            let col = |g: fn(&HeldOut) -> f64| held_out.iter().map(g).collect::<Vec<f64>>();
            let (rho, mae, img) = (col(|h| h.rho), col(|h| h.mae), col(|h| h.image_error));
            results.push(CvMethodResult {
                method: m.name().into(),
                k,
                fold_bases: bases[mi][ki]
                    .iter()
                    .map(|b| b.iter().map(|&i| names[i].clone()).collect())
                    .collect(),
                mean_rho: mean(&rho),
                median_rho: median(&rho),
                mean_mae: mean(&mae),
                median_mae: median(&mae),
                mean_image_error: mean(&img),
                median_image_error: median(&img),
                held_out,
            });
        }
    }
    let mut tests = Vec::new();
    for &k in &p.ks {
        let at_k: Vec<&CvMethodResult> = results.iter().filter(|r| r.k == k).collect();
        for (i, a) in at_k.iter().enumerate() {
            for b in &at_k[i + 1..] {
                let pv = |g: fn(&HeldOut) -> f64| {
                    let x: Vec<f64> = a.held_out.iter().map(g).collect();
                    let y: Vec<f64> = b.held_out.iter().map(g).collect();
                    match crate::stats::wilcoxon_signed_rank(&x, &y) {
                        Ok(w) => w.p_value,
                        Err(_) => 1.0,
                    }
                };
                let pairs = a.held_out.iter().zip(&b.held_out);
                tests.push(CvTest {
                    a: a.method.clone(),
                    b: b.method.clone(),
                    k,
                    wilcoxon_p: pv(|h| h.rho),
                    wilcoxon_p_mae: pv(|h| h.mae),
                    wilcoxon_p_image_error: pv(|h| h.image_error),
                    a_better: pairs.clone().filter(|(x, y)| x.rho < y.rho).count(),
                    b_better: pairs.filter(|(x, y)| x.rho > y.rho).count(),
                });
            }
        }
    }
    Ok(CvResult {
        folds: folds
            .iter()
            .map(|f| f.iter().map(|&i| names[i].clone()).collect())
            .collect(),
        seed: p.seed,
        results,
        tests,
        mask: p.objective.mask.to_string(),
        weighting: p.objective.weighting.to_string(),
    })
}

/// MAE of fitted combinations on the grid (SPEC 5) over the objective's cells: one
/// multiply-add per cell from separable tables when every material is analytic, else the
/// f64 values of every column.
struct GridEval<'a> {
    coll: &'a Collection,
    cells: CellSet,
    moments: Option<CellMoments>,
    tables: GridTables,
    cpu: CpuBackend,
}

impl<'a> GridEval<'a> {
    fn new(coll: &'a Collection, fp: &FitParams) -> Self {
        let all: Vec<usize> = (0..coll.len()).collect();
        let cells = fit_cells(coll, &all, fp)
            .expect("the stride of checked objective parameters is at least 1");
        let tables = GridTables::new();
        let moments = (fp.gram == GramMode::Auto && coll.all_analytic())
            .then(|| CellMoments::new(&tables, &cells));
        Self {
            coll,
            cells,
            moments,
            tables,
            cpu: CpuBackend::new(),
        }
    }

    fn lobe(&self, col: Option<usize>, c: usize) -> Lobe {
        match col {
            None => LAMBERTIAN,
            Some(i) => channel_lobe(&self.coll.materials()[i].data, c),
        }
    }

    /// Weighted mean of |fit - target| over the cells, averaged over channels.
    fn mae(&self, basis: &[usize], t: usize, coef: &[[f64; 3]]) -> f64 {
        let cols: Vec<Option<usize>> = std::iter::once(None)
            .chain(basis.iter().map(|&b| Some(b)))
            .collect();
        let mut mae = 0.0;
        for c in 0..3 {
            let x: Vec<f64> = coef.iter().map(|a| a[c]).collect();
            let sep = |l: Lobe| match l {
                Lobe::Analytic(p) => Some(SeparableLobe::new(&self.tables, &p)),
                Lobe::Measured { .. } => None,
            };
            let analytic = self.moments.as_ref().and_then(|mom| {
                let lobes: Vec<SeparableLobe> = cols
                    .iter()
                    .map(|&i| sep(self.lobe(i, c)))
                    .collect::<Option<_>>()?;
                let refs: Vec<&SeparableLobe> = lobes.iter().collect();
                let target = sep(self.lobe(Some(t), c))?;
                Some(
                    mom.errors(&SeparableLobe::combination(&refs, &x), &target)
                        .1,
                )
            });
            mae += match analytic {
                Some(ab) => ab,
                None => {
                    let cells = &self.cells.cells;
                    let mut fitv = vec![0.0; cells.len()];
                    for (&i, &a) in cols.iter().zip(&x) {
                        if a != 0.0 {
                            let v = self.cpu.values_f64(&self.lobe(i, c), cells);
                            fitv.iter_mut().zip(v).for_each(|(o, v)| *o += a * v);
                        }
                    }
                    let b = self.cpu.values_f64(&self.lobe(Some(t), c), cells);
                    fitv.iter()
                        .zip(&b)
                        .zip(&self.cells.weights)
                        .map(|((f, b), w)| w * (f - b).abs())
                        .sum()
                }
            } / 3.0;
        }
        mae
    }
}

fn missing_distances() -> SelectionError {
    SelectionError::InvalidParam {
        name: "distances",
        value: "none".into(),
        expected: "a distance matrix for the clustering methods",
    }
}

/// Contributions counted by the leave-one-out fits of `train` (index into `train`).
fn empirical_counts(obj: &Objective, train: &[usize]) -> Vec<usize> {
    let used: Vec<Vec<bool>> = train
        .par_iter()
        .map(|&t| {
            let others: Vec<usize> = train.iter().copied().filter(|&j| j != t).collect();
            let u = obj.contributors(&others, t);
            // Back to positions in `train` (t's own position stays false).
            let mut row = vec![false; train.len()];
            let mut it = u.into_iter();
            for (pos, &j) in train.iter().enumerate() {
                if j != t {
                    row[pos] = it.next().unwrap_or(false);
                }
            }
            row
        })
        .collect();
    (0..train.len())
        .map(|j| used.iter().filter(|r| r[j]).count())
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        f64::NAN
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => f64::NAN,
        l if l % 2 == 1 => s[l / 2],
        l => 0.5 * (s[l / 2 - 1] + s[l / 2]),
    }
}

impl CvResult {
    /// The summary as Markdown: per method and k, mean and median held-out rho, MAE and
    /// image error; then the paired Wilcoxon tests.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let n: usize = self.folds.iter().map(Vec::len).sum();
        let _ = writeln!(
            s,
            "Cross-validation over materials: {} folds, {n} held-out materials, seed {}, {} mask, {} weights.\n",
            self.folds.len(),
            self.seed,
            self.mask,
            self.weighting
        );
        s.push_str(&self.table_markdown());
        s.push_str("\nPaired Wilcoxon signed-rank tests (two-sided p) on the held-out values:\n\n");
        s.push_str("| a | b | k | p (rho) | p (MAE) | p (image error) | a better / b better (rho) |\n|---|---|---|---|---|---|---|\n");
        for t in &self.tests {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.3e} | {:.3e} | {:.3e} | {} / {} |",
                t.a,
                t.b,
                t.k,
                t.wilcoxon_p,
                t.wilcoxon_p_mae,
                t.wilcoxon_p_image_error,
                t.a_better,
                t.b_better
            );
        }
        s
    }

    /// Only the method x k table of [`CvResult::markdown`].
    pub fn table_markdown(&self) -> String {
        let mut s = String::from(
            "| method | k | mean rho | median rho | mean MAE | median MAE | mean image error | median image error |\n|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.results {
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {:.4} | {:.4e} | {:.4e} | {:.4} | {:.4} |",
                r.method,
                r.k,
                r.mean_rho,
                r.median_rho,
                r.mean_mae,
                r.median_mae,
                r.mean_image_error,
                r.median_image_error
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folds_partition_the_collection_evenly() {
        let f = make_folds(23, 5, 7);
        let sizes: Vec<usize> = f.iter().map(Vec::len).collect();
        assert_eq!(sizes, vec![5, 5, 5, 4, 4]);
        let mut all: Vec<usize> = f.concat();
        all.sort_unstable();
        assert_eq!(all, (0..23).collect::<Vec<_>>());
        assert_eq!(f, make_folds(23, 5, 7));
        assert_ne!(f, make_folds(23, 5, 8));
    }

    #[test]
    fn median_of_even_and_odd() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
    }
}
