//! Evaluation of every held-out material by every fold basis, and the paired tests.

use rayon::prelude::*;

use super::super::objective::Objective;
use super::super::SelectionError;
use super::{AppearanceMeans, CvMethodResult, CvTest, HeldOut};
use crate::backend::cpu::CpuBackend;
use crate::backend::weighted::TargetWeight;
use crate::backend::{Backend, Lobe};
use crate::collection::{Collection, MaterialData};
use crate::eval::appearance::{
    light_scores, render_params, Appearance, LogSums, Reference, LIGHTS,
};
use crate::eval::image_error::{normalized_image_error, DisplayParams};
use crate::eval::render::{Image, RenderParams};
use crate::eval::shade::PixelBrdfs;
use crate::fit::{channel_lobe, fit_cells, FitParams, GramMode, LAMBERTIAN};
use crate::merl::{CellSet, GridTables};
use crate::separable::{CellMoments, SeparableLobe};
use crate::stats::{mean, median, StatsError};

/// The renders of the appearance metrics (SPEC 11): per light, the pixel table of every
/// material and the render of every material.
pub(crate) struct LightRenders {
    pixels: PixelBrdfs,
    originals: Vec<Image>,
}

impl LightRenders {
    /// Every material of `coll` rendered under each of the four lights ([`LIGHTS`], SPEC
    /// 11's size), with the pixel tables of the fits' renders.
    pub(crate) fn all(coll: &Collection) -> Result<Vec<Self>, crate::eval::render::RenderError> {
        Self::all_ticking(coll, &|| {})
    }

    /// [`Self::all`], calling `tick` once per render (a caller's cancel).
    pub(crate) fn all_ticking(
        coll: &Collection,
        tick: Tick<'_>,
    ) -> Result<Vec<Self>, crate::eval::render::RenderError> {
        LIGHTS
            .iter()
            .map(|&(th, ph)| {
                // Every material's render from the table of its values at the render's
                // pixels (the values `material_brdf` gives there: the same bits, each
                // network run once).
                let rp = render_params((th, ph));
                let pixels = PixelBrdfs::new(coll, &rp)?;
                let originals = (0..coll.len())
                    .map(|t| {
                        tick();
                        pixels.render_material(t)
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Ok(Self { pixels, originals })
            })
            .collect()
    }

    /// The image metrics under each light of `lights` of material `t` fitted by `basis`
    /// with `coefficients` (log-RMSE left at 0).
    pub(crate) fn scores(
        lights: &[Self],
        t: usize,
        basis: &[usize],
        coefficients: &[[f64; 3]],
    ) -> Result<Appearance, crate::eval::render::RenderError> {
        Self::scores_of(lights, t, |l| {
            l.pixels.render_combination(basis, coefficients)
        })
    }

    /// The image metrics under each light of material `t` against the renders `render`
    /// makes of a reconstruction (log-RMSE left at 0).
    pub(crate) fn scores_of(
        lights: &[Self],
        t: usize,
        render: impl Fn(&Self) -> Result<Image, crate::eval::render::RenderError>,
    ) -> Result<Appearance, crate::eval::render::RenderError> {
        let scores = lights
            .iter()
            .zip(LIGHTS)
            .map(|(l, light)| light_scores(&l.originals[t], &render(l)?, light))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Appearance::new(0.0, scores))
    }

    /// [`Self::scores_of`] of `count` reconstructions of material `t` at once, `render(l,
    /// k)` the render of the k-th under light `l`: each light's reference prepared once
    /// for all of them (the same values: [`light_scores`] prepares it per call). `tick`
    /// is called before each render.
    pub(crate) fn scores_of_each(
        lights: &[Self],
        t: usize,
        count: usize,
        render: impl Fn(&Self, usize) -> Result<Image, crate::eval::render::RenderError>,
        tick: &dyn Fn(),
    ) -> Result<Vec<Appearance>, crate::eval::render::RenderError> {
        let mut per = vec![Vec::with_capacity(lights.len()); count];
        for (l, light) in lights.iter().zip(LIGHTS) {
            let reference = Reference::new(&l.originals[t])?;
            for (k, scores) in per.iter_mut().enumerate() {
                tick();
                scores.push(reference.scores(&render(l, k)?, light)?);
            }
        }
        Ok(per.into_iter().map(|s| Appearance::new(0.0, s)).collect())
    }

    /// The light's pixel table.
    pub(crate) fn pixels(&self) -> &PixelBrdfs {
        &self.pixels
    }
}

/// What the held-out materials are evaluated with: the objective, the grid MAE and
/// log-RMSE, renders of every material (SPEC 7: light (45, 45)) and, with appearance
/// metrics, renders under SPEC 11's four lights.
pub(crate) struct Evaluator<'a> {
    backend: &'a dyn Backend,
    coll: &'a Collection,
    obj: &'a Objective,
    fp: FitParams,
    grid: GridEval<'a>,
    pixels: PixelBrdfs,
    display: DisplayParams,
    originals: Vec<Image>,
    lights: Vec<LightRenders>,
}

impl<'a> Evaluator<'a> {
    /// Renders every material once (`render_size` pixels), and with `appearance` under
    /// the four lights at SPEC 11's size.
    pub(crate) fn new(
        backend: &'a dyn Backend,
        coll: &'a Collection,
        obj: &'a Objective,
        fp: &FitParams,
        render_size: u32,
        appearance: bool,
    ) -> Result<Self, SelectionError> {
        // Every material's render from the table of its values at the render's pixels
        // (the values `material_brdf` gives there: the same bits, each network run once).
        let renders = |pixels: &PixelBrdfs| -> Result<Vec<Image>, SelectionError> {
            (0..coll.len())
                .map(|t| Ok(pixels.render_material(t)?))
                .collect()
        };
        let rp = RenderParams::default()
            .with_size(render_size)
            .with_light(45.0, 45.0);
        let pixels = PixelBrdfs::new(coll, &rp)?;
        let originals = renders(&pixels)?;
        let lights = if appearance {
            LightRenders::all(coll)?
        } else {
            Vec::new()
        };
        Ok(Self {
            backend,
            coll,
            obj,
            fp: fp.clone(),
            grid: GridEval::new(coll, fp),
            pixels,
            display: DisplayParams::default(),
            originals,
            lights,
        })
    }

    /// The held-out material `t` of fold `f` with its fit (`rho`, `objective_rho` and the
    /// coefficients; MAE and log-RMSE left at 0, see [`Self::methods`]): its renders.
    fn held_out(
        &self,
        basis: &[usize],
        f: usize,
        t: usize,
        rho: f64,
        objective_rho: f64,
        coefficients: &[[f64; 3]],
    ) -> Result<HeldOut, SelectionError> {
        let img = self.pixels.render_combination(basis, coefficients)?;
        let appearance = if self.lights.is_empty() {
            None
        } else {
            Some(LightRenders::scores(&self.lights, t, basis, coefficients)?)
        };
        Ok(HeldOut {
            material: self.obj.names()[t].clone(),
            fold: f,
            rho,
            mae: 0.0,
            image_error: normalized_image_error(&self.originals[t], &img, &self.display)?,
            objective_rho,
            log_rmse: 0.0,
            appearance,
        })
    }

    /// The coefficients, `rho` and `rho_W` of every run's fit (`runs`: (fold, method, k,
    /// target), the targets of one (fold, method, k) consecutive). `l2`: from the
    /// objective's Gram form, run by run. `relative` and `log`: the per-target weighted
    /// fits of [`crate::fit::fit`], one call (one weighted-systems pass of the back-end) per
    /// (fold, method, k), `rho` on the grid.
    #[allow(clippy::type_complexity)]
    fn fits(
        &self,
        runs: &[(usize, usize, usize, usize)],
        bases: &[Vec<Vec<Vec<usize>>>],
    ) -> Result<Vec<(f64, f64, Vec<[f64; 3]>)>, SelectionError> {
        if self.fp.objective == TargetWeight::L2 {
            return runs
                .par_iter()
                .map(|&(f, m, k, t)| {
                    let fit = self.obj.fit(&bases[m][k][f], t)?;
                    Ok((fit.rho, fit.rho, fit.coefficients))
                })
                .collect();
        }
        let mut out = Vec::with_capacity(runs.len());
        let mut i = 0;
        while i < runs.len() {
            let (f, m, k, _) = runs[i];
            let j = i + runs[i..]
                .iter()
                .take_while(|r| (r.0, r.1, r.2) == (f, m, k))
                .count();
            let targets: Vec<usize> = runs[i..j].iter().map(|r| r.3).collect();
            let fits = crate::fit::fit(
                self.backend,
                self.coll,
                &bases[m][k][f],
                &targets,
                &self.fp,
                &|_, _| {},
            )?;
            out.extend(
                fits.into_iter()
                    .map(|tf| (tf.relative_residual, tf.objective_residual, tf.coefficients)),
            );
            i = j;
        }
        Ok(out)
    }

    /// Every method at every k (`bases[m][k][f]`: the basis of method `methods[m]` at
    /// `ks[k]` in fold `f`): every held-out material of every fold, with means and
    /// medians; results in method order, then k order. The grid MAE and log-RMSE of all
    /// the fits (every fold, method and k, every held-out material) come from one pass
    /// over the grid ([`GridEval::sums`]: each material tabulated once per block of cells,
    /// however many folds it serves in).
    pub(crate) fn methods(
        &self,
        methods: &[&str],
        ks: &[usize],
        folds: &[Vec<usize>],
        bases: &[Vec<Vec<Vec<usize>>>],
    ) -> Result<Vec<CvMethodResult>, SelectionError> {
        let mut held: Vec<Vec<Vec<HeldOut>>> = vec![vec![Vec::new(); ks.len()]; methods.len()];
        let runs: Vec<(usize, usize, usize, usize)> = folds
            .iter()
            .enumerate()
            .flat_map(|(f, fold)| {
                (0..methods.len()).flat_map(move |m| {
                    (0..ks.len()).flat_map(move |k| fold.iter().map(move |&t| (f, m, k, t)))
                })
            })
            .collect();
        let coefs = self.fits(&runs, bases)?;
        let fits: Vec<HeldOut> = runs
            .par_iter()
            .zip(&coefs)
            .map(|(&(f, m, k, t), (rho, rho_w, coef))| {
                self.held_out(&bases[m][k][f], f, t, *rho, *rho_w, coef)
            })
            .collect::<Result<_, _>>()?;
        let jobs: Vec<MaeJob<'_>> = runs
            .iter()
            .zip(&coefs)
            .map(|(&(f, m, k, t), (_, _, coef))| MaeJob {
                basis: &bases[m][k][f],
                target: t,
                coef,
            })
            .collect();
        let sums = self.grid.sums(&jobs, &|| {});
        drop(jobs);
        for ((&(_, m, k, _), mut h), (mae, log_rmse)) in runs.iter().zip(fits).zip(sums) {
            h.mae = mae;
            h.log_rmse = log_rmse;
            if let Some(a) = &mut h.appearance {
                a.log_rmse = log_rmse;
            }
            held[m][k].push(h);
        }
        let names = self.obj.names();
        let mut out = Vec::new();
        for (m, per_k) in held.into_iter().enumerate() {
            for (k, held_out) in per_k.into_iter().enumerate() {
                let col = |g: fn(&HeldOut) -> f64| held_out.iter().map(g).collect::<Vec<f64>>();
                let (rho, mae, img) = (col(|h| h.rho), col(|h| h.mae), col(|h| h.image_error));
                let appearance = appearance_means(&held_out);
                out.push(CvMethodResult {
                    method: methods[m].into(),
                    k: ks[k],
                    fold_bases: bases[m][k]
                        .iter()
                        .map(|b| b.iter().map(|&i| names[i].clone()).collect())
                        .collect(),
                    mean_rho: mean(&rho),
                    median_rho: median(&rho),
                    mean_mae: mean(&mae),
                    median_mae: median(&mae),
                    mean_image_error: mean(&img),
                    median_image_error: median(&img),
                    mean_log_rmse: mean(&col(|h| h.log_rmse)),
                    appearance,
                    held_out,
                });
            }
        }
        Ok(out)
    }
}

/// Means (and medians) over held-out materials of their appearance metrics; `None` when
/// they were not computed.
pub(crate) fn appearance_means(held: &[HeldOut]) -> Option<AppearanceMeans> {
    let a: Vec<&Appearance> = held.iter().filter_map(|h| h.appearance.as_ref()).collect();
    if a.len() != held.len() {
        return None;
    }
    means_of(&a)
}

/// Means (and medians) of the appearance metrics `a`; `None` when `a` is empty.
pub(crate) fn means_of(a: &[&Appearance]) -> Option<AppearanceMeans> {
    if a.is_empty() {
        return None;
    }
    let col = |g: &dyn Fn(&Appearance) -> f64| a.iter().map(|x| g(x)).collect::<Vec<f64>>();
    Some(AppearanceMeans {
        image_error_paper_light: mean(&col(&|x| x.paper_light().image_error)),
        image_error: mean(&col(&|x| x.mean_image_error)),
        median_image_error: median(&col(&|x| x.mean_image_error)),
        ciede2000: mean(&col(&|x| x.mean_ciede2000)),
        delta_e_itp: mean(&col(&|x| x.mean_delta_e_itp)),
        flip_paper_light: mean(&col(&|x| x.paper_light().flip)),
        flip: mean(&col(&|x| x.mean_flip)),
        median_flip: median(&col(&|x| x.mean_flip)),
    })
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

/// One fitted combination whose grid MAE is wanted: `target` fitted by `basis` (collection
/// indices) with `coef` (Lambertian first, then basis order; one `[r, g, b]` per column).
#[derive(Clone, Copy, Debug)]
pub(crate) struct MaeJob<'j> {
    /// Basis materials.
    pub basis: &'j [usize],
    /// Target material.
    pub target: usize,
    /// Coefficients.
    pub coef: &'j [[f64; 3]],
}

/// Most cells tabulated at once by [`GridEval::maes`] (100 materials: 37 MiB of f64 values
/// for their three channels).
const MAE_BLOCK: usize = 1 << 14;

/// Called while a long pass runs (once per block of cells and job): a caller's progress
/// pulse, through which it may cancel.
pub(crate) type Tick<'a> = &'a (dyn Fn() + Sync);
/// Bytes of tabulated values [`cell_sums`] keeps per block at most (its blocks shrink, down
/// to 1,024 cells, as the materials it needs grow: the sums do not depend on the blocks).
const MAE_BLOCK_BYTES: usize = 64 << 20;

/// MAE of fitted combinations on the grid (SPEC 5) over the objective's cells: one
/// multiply-add per cell from separable tables when every material is analytic, else the
/// f64 values of every column, cell by cell.
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

    /// The MAE of every job (job order). Analytic collections: from the separable cell
    /// moments, job by job. Otherwise one pass over the cells for all jobs at once: block
    /// after block of [`MAE_BLOCK`] cells, every material the jobs need (their targets and
    /// the basis materials with a non-zero coefficient) is tabulated once per block, all
    /// three channels together (a network runs once per cell), and each job adds the
    /// block's cells to its running sums in cell order. The sums are those of
    /// `fit::cell_error_sums` term by term, in the same order, so every MAE is the same to the
    /// bit as a pass over all cells per job.
    pub(crate) fn maes(&self, jobs: &[MaeJob<'_>], tick: Tick<'_>) -> Vec<f64> {
        if let Some(mom) = &self.moments {
            return jobs.par_iter().map(|j| self.analytic_mae(mom, j)).collect();
        }
        cell_sums::<false, false>(&self.cpu, self.coll, &self.cells, jobs, tick)
            .iter()
            .map(|s| s.iter().fold(0.0, |mae, e| mae + e.absolute / 3.0))
            .collect()
    }

    /// The MAE ([`Self::maes`], the same bits) and the log-RMSE (SPEC 11) of every job, in
    /// job order: one pass over the cells (the MAE of an analytic collection from its
    /// moments). `tick` is called once per block of cells and job (a caller's cancel).
    pub(crate) fn sums(&self, jobs: &[MaeJob<'_>], tick: Tick<'_>) -> Vec<(f64, f64)> {
        let cells = cell_sums::<false, true>(&self.cpu, self.coll, &self.cells, jobs, tick);
        let logs = cells.iter().map(|s| {
            let mut l = LogSums::default();
            s.iter().for_each(|e| l.merge(&e.log));
            l.value()
        });
        match &self.moments {
            Some(mom) => jobs
                .par_iter()
                .map(|j| self.analytic_mae(mom, j))
                .collect::<Vec<f64>>()
                .into_iter()
                .zip(logs)
                .collect(),
            None => cells
                .iter()
                .map(|s| s.iter().fold(0.0, |mae, e| mae + e.absolute / 3.0))
                .zip(logs)
                .collect(),
        }
    }

    /// [`Self::mae`] from the separable cell moments (every material analytic).
    fn analytic_mae(&self, mom: &CellMoments, j: &MaeJob<'_>) -> f64 {
        let sep = |l: Lobe| match l {
            Lobe::Analytic(p) => SeparableLobe::new(&self.tables, &p),
            Lobe::Measured { .. } | Lobe::Neural { .. } => {
                unreachable!("moments exist only when every material is analytic")
            }
        };
        let mut mae = 0.0;
        for c in 0..3 {
            let x: Vec<f64> = j.coef.iter().map(|a| a[c]).collect();
            let lobes: Vec<SeparableLobe> = std::iter::once(None)
                .chain(j.basis.iter().map(|&b| Some(b)))
                .map(|i| sep(self.lobe(i, c)))
                .collect();
            let refs: Vec<&SeparableLobe> = lobes.iter().collect();
            let target = sep(self.lobe(Some(j.target), c));
            mae += mom
                .errors(&SeparableLobe::combination(&refs, &x), &target)
                .absolute
                / 3.0;
        }
        mae
    }
}

/// Sums of one channel of one job over the cells (`fit::cell_error_sums`'s): `sum w r^2`,
/// `sum w |r|` and `sum w |b|`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CellSums {
    /// `sum_s w_s r_s^2`.
    pub squared: f64,
    /// `sum_s w_s |r_s|`.
    pub absolute: f64,
    /// `sum_s w_s |b_s|`.
    pub target: f64,
    /// The log-RMSE's sums (SPEC 11), when asked for.
    pub log: LogSums,
}

/// The three channels of material `m` at `cells`, in f64: the values
/// [`CpuBackend::values_f64`] gives each channel's lobe (a network runs once for all three,
/// past the back-end's cache).
fn material_values(cpu: &CpuBackend, coll: &Collection, m: usize, cells: &[u32]) -> [Vec<f64>; 3] {
    match &coll.materials()[m].data {
        MaterialData::Neural(net) => cpu.neural_values_f64(net, cells),
        d => [0, 1, 2].map(|c| cpu.values_f64(&channel_lobe(d, c), cells)),
    }
}

/// The grid sums of every job's fit, per channel, over `cells`, cell by cell in f64, in one
/// pass for all jobs: block after block of [`MAE_BLOCK`] cells, every material the jobs
/// need (their targets and basis materials) is tabulated once per block, all three channels
/// together (a network runs once per cell), and each job adds the block's cells to its
/// running sums in cell order. The sums are `fit::cell_error_sums`'s term by term, in the same
/// order, so every sum is the same to the bit as a pass over all cells per job (the old
/// per-target passes). `ALL`: every column of the fit enters the combination and all three
/// sums are formed (the fits' errors, `fit::fit`); else only the columns with a non-zero
/// coefficient (the others add exact zeros: the same bits) and only `absolute` (the
/// cross-validation's MAE).
pub(crate) fn cell_sums<const ALL: bool, const LOG: bool>(
    cpu: &CpuBackend,
    coll: &Collection,
    cells: &CellSet,
    jobs: &[MaeJob<'_>],
    tick: Tick<'_>,
) -> Vec<[CellSums; 3]> {
    let mut slot: Vec<Option<usize>> = vec![None; coll.len()];
    let mut needed = Vec::new();
    let mut need = |m: usize| {
        if slot[m].is_none() {
            slot[m] = Some(needed.len());
            needed.push(m);
        }
    };
    for j in jobs {
        need(j.target);
        for (k, &b) in j.basis.iter().enumerate() {
            if ALL || j.coef[k + 1].iter().any(|&a| a != 0.0) {
                need(b);
            }
        }
    }
    let mut sums = vec![[CellSums::default(); 3]; jobs.len()];
    let per_cell = 3 * std::mem::size_of::<f64>() * needed.len().max(1);
    let block_cells = (MAE_BLOCK_BYTES / per_cell).clamp(1024, MAE_BLOCK);
    for (block, w) in cells
        .cells
        .chunks(block_cells)
        .zip(cells.weights.chunks(block_cells))
    {
        let lambert = cpu.values_f64(&LAMBERTIAN, block);
        let cos_i: Vec<f64> = if LOG {
            block
                .iter()
                .map(|&c| crate::backend::weighted::cos_theta_i(c as usize))
                .collect()
        } else {
            Vec::new()
        };
        let values: Vec<[Vec<f64>; 3]> = needed
            .par_iter()
            .map(|&m| material_values(cpu, coll, m, block))
            .collect();
        // The targets' terms of the log-RMSE, once per target and block (a target is
        // compared with many fits: its dense fit and every reconstruction).
        let target_logs: Vec<Option<[Vec<f64>; 3]>> = if LOG {
            let mut is_target = vec![false; needed.len()];
            for j in jobs {
                is_target[slot[j.target].expect("targets have slots")] = true;
            }
            values
                .par_iter()
                .zip(&is_target)
                .map(|(v, &t)| t.then(|| [0, 1, 2].map(|c| LogSums::logs(&v[c], &cos_i))))
                .collect()
        } else {
            Vec::new()
        };
        let len = block.len();
        sums.par_iter_mut().zip(jobs).for_each_init(
            || (vec![0.0f64; 3 * len], Vec::new(), Vec::new()),
            |(fit, fl, scratch), (sum, j)| {
                tick();
                fit.resize(3 * len, 0.0);
                // The fitted values of every cell, column by column (Lambertian first, then
                // basis order, as `cell_error_sums` is given them): per cell the same products
                // added in the same order as a sum over the columns, so the same bits; the
                // loops over cells vectorise.
                for (c, f) in fit.chunks_mut(len).enumerate() {
                    f.fill(-0.0);
                    let cols = std::iter::once(&lambert[..])
                        .chain(j.basis.iter().map(|&b| match slot[b] {
                            Some(s) => &values[s][c][..],
                            None => &[][..],
                        }))
                        .zip(j.coef.iter().map(|a| a[c]))
                        .filter(|&(_, a)| ALL || a != 0.0);
                    crate::fit::add_columns(f, cols);
                }
                // Then each channel's sums in cell order (the three channels are independent
                // sums, interleaved here).
                let ts = slot[j.target].expect("targets have slots");
                let b = &values[ts];
                let tl = if LOG { target_logs[ts].as_ref() } else { None };
                // The fit's terms of the log-RMSE, four cells at a time.
                if LOG {
                    fl.resize(3 * len, 0.0);
                    for (f, out) in fit.chunks(len).zip(fl.chunks_mut(len)) {
                        LogSums::logs_into(f, &cos_i, scratch, out);
                    }
                }
                for (i, &w) in w.iter().enumerate() {
                    for (c, e) in sum.iter_mut().enumerate() {
                        let bv = b[c][i];
                        let r = fit[c * len + i] - bv;
                        if ALL {
                            e.squared += w * r * r;
                        }
                        e.absolute += w * r.abs();
                        if ALL {
                            e.target += w * bv.abs();
                        }
                        if let Some(tl) = tl {
                            e.log.add_logs(fl[c * len + i], tl[c][i], w);
                        }
                    }
                }
            },
        );
    }
    sums
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
                    objective_rho: x,
                    log_rmse: x,
                    appearance: None,
                })
                .collect(),
            mean_rho: mean(v),
            median_rho: median(v),
            mean_mae: mean(v),
            median_mae: median(v),
            mean_image_error: mean(v),
            median_image_error: median(v),
            mean_log_rmse: mean(v),
            appearance: None,
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
