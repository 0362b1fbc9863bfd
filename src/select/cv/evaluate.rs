//! Evaluation of every held-out material by every fold basis, and the paired tests.

use rayon::prelude::*;

use super::super::objective::Objective;
use super::super::SelectionError;
use super::{CvMethodResult, CvTest, HeldOut};
use crate::backend::cpu::CpuBackend;
use crate::backend::Lobe;
use crate::collection::Collection;
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{render_sphere, Image, RenderParams};
use crate::eval::shade::{combination_brdf, material_brdf};
use crate::fit::{cell_errors, channel_lobe, fit_cells, FitParams, GramMode, LAMBERTIAN};
use crate::merl::{CellSet, GridTables};
use crate::separable::{CellMoments, SeparableLobe};
use crate::stats::{mean, median, StatsError};

/// What the held-out materials are evaluated with: the objective, the grid MAE and renders
/// of every material (SPEC 7: light (45, 45)).
pub(crate) struct Evaluator<'a> {
    coll: &'a Collection,
    obj: &'a Objective,
    grid: GridEval<'a>,
    rp: RenderParams,
    display: DisplayParams,
    originals: Vec<Image>,
}

impl<'a> Evaluator<'a> {
    /// Renders every material once (`render_size` pixels).
    pub fn new(
        coll: &'a Collection,
        obj: &'a Objective,
        fp: &FitParams,
        render_size: u32,
    ) -> Result<Self, SelectionError> {
        let rp = RenderParams::default()
            .with_size(render_size)
            .with_light(45.0, 45.0);
        let originals: Vec<Image> = (0..coll.len())
            .map(|t| render_sphere(&rp, &material_brdf(&coll.materials()[t].data)))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            coll,
            obj,
            grid: GridEval::new(coll, fp),
            rp,
            display: DisplayParams::default(),
            originals,
        })
    }

    /// The held-out material `t` of fold `f` fitted by `basis`.
    fn held_out(&self, basis: &[usize], f: usize, t: usize) -> Result<HeldOut, SelectionError> {
        let fit = self.obj.fit(basis, t)?;
        let img = render_sphere(
            &self.rp,
            &combination_brdf(self.coll, basis, &fit.coefficients),
        )?;
        Ok(HeldOut {
            material: self.obj.names()[t].clone(),
            fold: f,
            rho: fit.rho,
            mae: self.grid.mae(basis, t, &fit.coefficients),
            image_error: normalized_image_error(&self.originals[t], &img, &self.display)?,
        })
    }

    /// One method at one k: every held-out material of every fold (`bases[f]` the fold's
    /// basis), with means and medians.
    pub fn method(
        &self,
        method: &str,
        k: usize,
        folds: &[Vec<usize>],
        bases: &[Vec<usize>],
    ) -> Result<CvMethodResult, SelectionError> {
        let names = self.obj.names();
        let mut held_out = Vec::with_capacity(self.coll.len());
        for (f, (fold, basis)) in folds.iter().zip(bases).enumerate() {
            let rows: Vec<HeldOut> = fold
                .par_iter()
                .map(|&t| self.held_out(basis, f, t))
                .collect::<Result<_, _>>()?;
            held_out.extend(rows);
        }
        let col = |g: fn(&HeldOut) -> f64| held_out.iter().map(g).collect::<Vec<f64>>();
        let (rho, mae, img) = (col(|h| h.rho), col(|h| h.mae), col(|h| h.image_error));
        Ok(CvMethodResult {
            method: method.into(),
            k,
            fold_bases: bases
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
        })
    }
}

/// Paired two-sided Wilcoxon signed-rank tests between every two methods at each k of
/// `ks`. p = 1 when every paired difference is zero (no evidence either way); any other
/// failure of the test is an error naming the pair.
pub(crate) fn paired_tests(
    ks: &[usize],
    results: &[CvMethodResult],
) -> Result<Vec<CvTest>, SelectionError> {
    let mut tests = Vec::new();
    for &k in ks {
        let at_k: Vec<&CvMethodResult> = results.iter().filter(|r| r.k == k).collect();
        for (i, a) in at_k.iter().enumerate() {
            for b in &at_k[i + 1..] {
                let pv = |what: &'static str, g: fn(&HeldOut) -> f64| {
                    let x: Vec<f64> = a.held_out.iter().map(g).collect();
                    let y: Vec<f64> = b.held_out.iter().map(g).collect();
                    match crate::stats::wilcoxon_signed_rank(&x, &y) {
                        Ok(w) => Ok(w.p_value),
                        Err(StatsError::AllZeroDifferences) => Ok(1.0),
                        Err(source) => Err(SelectionError::Test {
                            a: a.method.clone(),
                            b: b.method.clone(),
                            k,
                            what,
                            source,
                        }),
                    }
                };
                let pairs = a.held_out.iter().zip(&b.held_out);
                tests.push(CvTest {
                    a: a.method.clone(),
                    b: b.method.clone(),
                    k,
                    wilcoxon_p: pv("rho", |h| h.rho)?,
                    wilcoxon_p_mae: pv("MAE", |h| h.mae)?,
                    wilcoxon_p_image_error: pv("image error", |h| h.image_error)?,
                    a_better: pairs.clone().filter(|(x, y)| x.rho < y.rho).count(),
                    b_better: pairs.filter(|(x, y)| x.rho > y.rho).count(),
                });
            }
        }
    }
    Ok(tests)
}

/// MAE of fitted combinations on the grid (SPEC 5) over the objective's cells: one
/// multiply-add per cell from separable tables when every material is analytic, else the
/// f64 values of every column.
pub(crate) struct GridEval<'a> {
    coll: &'a Collection,
    cells: CellSet,
    moments: Option<CellMoments>,
    tables: GridTables,
    cpu: CpuBackend,
}

impl<'a> GridEval<'a> {
    pub(crate) fn new(coll: &'a Collection, fp: &FitParams) -> Self {
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
    pub(crate) fn mae(&self, basis: &[usize], t: usize, coef: &[[f64; 3]]) -> f64 {
        let cols: Vec<Option<usize>> = std::iter::once(None)
            .chain(basis.iter().map(|&b| Some(b)))
            .collect();
        let mut mae = 0.0;
        for c in 0..3 {
            let x: Vec<f64> = coef.iter().map(|a| a[c]).collect();
            let sep = |l: Lobe| match l {
                Lobe::Analytic(p) => Some(SeparableLobe::new(&self.tables, &p)),
                Lobe::Measured { .. } | Lobe::Neural { .. } => None,
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
                        .absolute,
                )
            });
            mae += match analytic {
                Some(ab) => ab,
                None => {
                    // The fits' cell-by-cell sum, on the columns with a non-zero
                    // coefficient (the others add exact zeros).
                    let cells = &self.cells.cells;
                    let (vals, xs): (Vec<Vec<f64>>, Vec<f64>) = cols
                        .iter()
                        .zip(&x)
                        .filter(|(_, &a)| a != 0.0)
                        .map(|(&i, &a)| (self.cpu.values_f64(&self.lobe(i, c), cells), a))
                        .unzip();
                    let refs: Vec<&[f64]> = vals.iter().map(Vec::as_slice).collect();
                    let b = self.cpu.values_f64(&self.lobe(Some(t), c), cells);
                    cell_errors(&refs, &xs, &b, &self.cells.weights).mae
                }
            } / 3.0;
        }
        mae
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result(method: &str, v: &[f64]) -> CvMethodResult {
        CvMethodResult {
            method: method.into(),
            k: 2,
            fold_bases: vec![],
            held_out: v
                .iter()
                .enumerate()
                .map(|(i, &x)| HeldOut {
                    material: format!("m{i}"),
                    fold: 0,
                    rho: x,
                    mae: x,
                    image_error: x,
                })
                .collect(),
            mean_rho: mean(v),
            median_rho: median(v),
            mean_mae: mean(v),
            median_mae: median(v),
            mean_image_error: mean(v),
            median_image_error: median(v),
        }
    }

    /// Before: any Wilcoxon error became p = 1.
    #[test]
    fn a_failed_wilcoxon_test_is_an_error_and_all_ties_give_p_1() {
        let a = result("greedy", &[0.1, 0.2, 0.3]);
        let same = result("swap", &[0.1, 0.2, 0.3]);
        let t = paired_tests(&[2], &[a.clone(), same]).unwrap();
        assert_eq!(t[0].wilcoxon_p, 1.0);
        let nan = result("random", &[0.1, f64::NAN, 0.3]);
        let e = paired_tests(&[2], &[a, nan]).unwrap_err().to_string();
        assert!(e.contains("greedy vs random at k = 2 on rho"), "{e}");
    }
}
