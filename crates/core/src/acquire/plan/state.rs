//! The dense state of a plan: the full-mask Gram quantities of the basis and the training
//! materials ([`Dense`]), and the sampled state of the error criterion ([`State`]) with the
//! order and bounds of its abandoning exact fits ([`Bound`]).

use super::*;

/// The weight of a cell no appearance render looks at, beside the renders' looks of mean
/// 1 ([`crate::eval::appearance::render_looks`]), in the plans' weights under an objective
/// (docs/acquisition.md: held out, floors of 1, 0.1, 0.01 and 0 gave images better in
/// that order, but at 0 the plans leave the grid the four renders do not see to chance
/// and the whole grid's log-RMSE and median rho rose two to four times; 0.01 kept them).
pub const LOOK_FLOOR: f64 = 0.01;

/// Full-mask Gram quantities of the basis and the training materials, per channel.
pub(crate) struct Dense {
    /// Columns (Lambertian + basis).
    pub m: usize,
    /// Per channel.
    pub g: [ChannelGram; 3],
}

impl Dense {
    /// One back-end pass (or the separable closed form) per channel.
    ///
    /// Under an objective other than `l2` (SPEC 11) the cells carry its shared weights
    /// per channel: the objective's weight at the median over the basis and the targets
    /// ([`crate::select::shared_weights`] of those materials), so that `rho` is `rho_W`
    /// with the weights a plan can know before the material is measured, each times how
    /// much the appearance renders look at the cell plus [`LOOK_FLOOR`]
    /// ([`crate::eval::appearance::render_looks`]: the plans lower what the renders
    /// judge); one back-end pass per channel (the weights are not separable). `progress` is the back-end
    /// passes' (a caller's cancel).
    pub(crate) fn new(
        backend: &dyn Backend,
        coll: &Collection,
        basis: &[usize],
        targets: &[usize],
        fit: &FitParams,
        progress: crate::backend::Progress<'_>,
    ) -> Result<Self, AcquireError> {
        let mut all = basis.to_vec();
        all.extend_from_slice(targets);
        let cells = fit_cells(coll, &all, fit)?;
        let shared;
        let (per_channel, mode) = if fit.objective == crate::backend::weighted::TargetWeight::L2 {
            ([&cells; 3], fit.gram)
        } else {
            let mut sw = crate::select::shared_weights(
                backend,
                &coll.subset(&all),
                &cells,
                fit.objective,
                progress,
            )?;
            // What the plans lower is what is judged (issue 50): each cell's shared weight
            // times how much the appearance renders look at it, plus a floor for the cells
            // no render sees.
            let looks = crate::eval::appearance::render_looks(&cells)
                .map_err(|e| AcquireError::Render(e.to_string()))?;
            for sc in sw.iter_mut() {
                for (w, l) in sc.weights.iter_mut().zip(&looks) {
                    *w *= l + LOOK_FLOOR;
                }
            }
            shared = sw;
            (
                [&shared[0], &shared[1], &shared[2]],
                crate::fit::GramMode::Grid,
            )
        };
        let g = [0, 1, 2].map(|c| {
            channel_gram(
                backend,
                coll,
                basis,
                targets,
                per_channel[c],
                c,
                mode,
                progress,
            )
        });
        let [a, b, c] = g;
        Ok(Self {
            m: basis.len() + 1,
            g: [a?, b?, c?],
        })
    }

    /// `sum_s w_s r^2` on the full mask of coefficients `x` (channel `c`, target `t`).
    ///
    /// `bb + sum_i x_i ((G x)_i - 2 h_i)` over the non-zero `x_i`, each `(G x)_i` summed
    /// over the non-zero `x_j` in column order: a zero `x_j` adds a zero product, which
    /// leaves a non-zero partial sum as it is, so this is the sum over every `j` bit for
    /// bit, but for the sign of a `(G x)_i` that is exactly zero (then multiplied by
    /// `x_i` and added to `q`, where it changes nothing unless `q` is zero too).
    pub(crate) fn r2(&self, c: usize, t: usize, x: &[f64]) -> f64 {
        let m = self.m;
        let g = &self.g[c];
        let h = &g.h[t * m..(t + 1) * m];
        let mut nz = [0usize; MAX_PLAN_COLUMNS];
        let mut p = 0;
        for (j, &xj) in x[..m].iter().enumerate() {
            if xj != 0.0 {
                nz[p] = j;
                p += 1;
            }
        }
        let nz = &nz[..p];
        let mut q = g.bb[t];
        for &i in nz {
            let row = &g.gram[i * m..(i + 1) * m];
            let gx: f64 = nz.iter().map(|&j| row[j] * x[j]).sum();
            q += x[i] * (gx - 2.0 * h[i]);
        }
        q.max(0.0)
    }

    /// rho of target `t` with per-channel coefficients `x[c]`.
    pub(crate) fn rho(&self, t: usize, x: &[Vec<f64>; 3]) -> f64 {
        self.rho_of(t, [&x[0], &x[1], &x[2]])
    }

    /// [`Dense::rho`] on borrowed coefficients.
    pub(super) fn rho_of(&self, t: usize, x: [&[f64]; 3]) -> f64 {
        let e: f64 = (0..3).map(|c| self.g[c].bb[t]).sum();
        let r: f64 = (0..3).map(|c| self.r2(c, t, x[c])).sum();
        if e > 0.0 {
            r / e
        } else {
            0.0
        }
    }

    /// Per target, a lower bound of its score whatever its coefficients: `FLOOR` times
    /// the score of its dense fit.
    ///
    /// The dense fit minimises each channel's full-mask residual over non-negative
    /// coefficients, which a fit from samples also is, so no sample fit scores below it
    /// (`rho` is a sum of those residuals over a constant). [`FLOOR`] leaves room for the
    /// rounding of the dense solve and of the Gram form (relative errors around 1e-12 at
    /// the scores of these fits). When a dense solve fails: zeros (no bound).
    pub(super) fn floors(&self, nt: usize) -> Vec<f64> {
        let m = self.m;
        let params = lawson_hanson::LhParams::default();
        let fits: Vec<Option<Vec<Vec<f64>>>> = (0..3)
            .map(|c| {
                let g = &self.g[c];
                crate::nnls::GramBatch::new(m, &g.gram, &g.h[..nt * m], &g.bb[..nt])
                    .and_then(|b| lawson_hanson::solve_batch(&b, &params))
                    .map(|v| v.into_iter().map(|s| s.x).collect())
                    .ok()
            })
            .collect();
        let [Some(r), Some(g), Some(b)] = [&fits[0], &fits[1], &fits[2]] else {
            return vec![0.0; nt];
        };
        (0..nt)
            .map(|t| FLOOR * self.rho_of(t, [&r[t], &g[t], &b[t]]))
            .collect()
    }
}

/// The order in which [`State::exact_mean_below`] fits the targets and, at each position,
/// a lower bound of the scores of the targets after it.
pub(super) struct Bound {
    pub(super) order: Vec<usize>,
    pub(super) rest: Vec<f64>,
}

impl Bound {
    /// `order` with `floors` per target.
    pub(super) fn new(order: Vec<usize>, floors: &[f64]) -> Self {
        let mut rest = vec![0.0; order.len()];
        let mut acc = 0.0;
        for (r, &t) in rest.iter_mut().zip(&order).rev() {
            *r = acc;
            acc += floors[t];
        }
        Self { order, rest }
    }

    /// The targets fitted first are those whose current sample fits exceed their floors
    /// most (`current[t]`: the score of target `t`'s current fit; ties: target order):
    /// where one more sample moves the score most, so a losing candidate shows soonest.
    pub(super) fn by_excess(current: &[f64], floors: &[f64]) -> Self {
        let mut order: Vec<usize> = (0..current.len()).collect();
        let excess = |t: usize| current[t] - floors[t];
        order.sort_by(|&a, &b| excess(b).total_cmp(&excess(a)).then(a.cmp(&b)));
        Self::new(order, floors)
    }
}

/// Fraction of a target's dense score that bounds its score from samples from below in
/// [`State::exact_mean_below`] (the bound holds at 1 in exact arithmetic; this is margin
/// for rounding, about 1e9 times the relative error of the scores).
pub(super) const FLOOR: f64 = 0.999;

/// A candidate's rows (per channel, padded to [`MAX_PLAN_COLUMNS`]) and the training
/// values there (per target, RGB).
pub(super) type Added<'a> = (&'a [[f64; 16]; 3], &'a [[f64; 3]]);

/// Sampled state of the error criterion: per channel the rows so far; per target and
/// channel the exact sample fit.
pub(super) struct State {
    pub(super) m: usize,
    pub(super) rows: [Vec<f64>; 3],
    pub(super) y: [Vec<Vec<f64>>; 3],
    pub(super) x: Vec<[Vec<f64>; 3]>,
    /// Per channel the sampled Gram's lower triangle (`m x m`, accumulated row by row as
    /// [`super::super::fit::solve_rows`] does, so that its fits are bit for bit the same); per channel and
    /// target `h = A^T y` and `y^T y`.
    pub(super) gl: [Vec<f64>; 3],
    pub(super) h: [Vec<Vec<f64>>; 3],
    pub(super) bb: [Vec<f64>; 3],
}

// Index loops over the triangle of a symmetric matrix read more plainly than iterators.
#[allow(clippy::needless_range_loop)]
impl State {
    pub(super) fn new(m: usize, nt: usize) -> Self {
        Self {
            m,
            rows: Default::default(),
            y: [0, 1, 2].map(|_| vec![Vec::new(); nt]),
            x: vec![[0, 1, 2].map(|_| vec![0.0; m]); nt],
            gl: [0, 1, 2].map(|_| vec![0.0; m * m]),
            h: [0, 1, 2].map(|_| vec![vec![0.0; m]; nt]),
            bb: [0, 1, 2].map(|_| vec![0.0; nt]),
        }
    }

    /// Adds the sample row `a[c]` with values `y[t][c]`: an exact rank-one update of every
    /// target's normal equations.
    pub(super) fn push(&mut self, a: &[[f64; 16]; 3], y: &[[f64; 3]]) {
        let m = self.m;
        for c in 0..3 {
            let r = &a[c][..m];
            self.rows[c].extend_from_slice(r);
            for i in 0..m {
                for j in 0..=i {
                    self.gl[c][i * m + j] += r[i] * r[j];
                }
            }
            for (t, yt) in y.iter().enumerate() {
                self.y[c][t].push(yt[c]);
                for i in 0..m {
                    self.h[c][t][i] += r[i] * yt[c];
                }
                self.bb[c][t] += yt[c] * yt[c];
            }
        }
    }

    /// Per channel `c`, the sampled normal equations after adding the candidate row
    /// `a[c]` with values `y[t][c]` (or with no addition): the full symmetric Gram
    /// matrix, `h` of every target (concatenated) and `y^T y` per target.
    pub(super) fn channel_equations(&self, c: usize, add: Option<Added<'_>>) -> [Vec<f64>; 3] {
        let m = self.m;
        let nt = self.x.len();
        let mut g = self.gl[c].clone();
        let mut hs: Vec<f64> = self.h[c].concat();
        let mut bbs = self.bb[c].clone();
        if let Some((a, yv)) = add {
            let r = &a[c][..m];
            for i in 0..m {
                for j in 0..=i {
                    g[i * m + j] += r[i] * r[j];
                }
            }
            for t in 0..nt {
                let yt = yv[t][c];
                for i in 0..m {
                    hs[t * m + i] += r[i] * yt;
                }
                bbs[t] += yt * yt;
            }
        }
        for i in 0..m {
            for j in 0..i {
                g[j * m + i] = g[i * m + j];
            }
        }
        [g, hs, bbs]
    }

    /// Exact fits of every target after adding the candidate row `a[c]` and values
    /// `y[t][c]` (or with no addition): per channel one sampled Gram matrix, updated by the
    /// candidate's row, shared by every target ([`lawson_hanson::solve_batch`]).
    pub(super) fn exact(&self, add: Option<Added<'_>>) -> Vec<[Vec<f64>; 3]> {
        let m = self.m;
        let nt = self.x.len();
        if self.rows[0].is_empty() && add.is_none() {
            return vec![[0, 1, 2].map(|_| vec![0.0; m]); nt];
        }
        let per_c = [0, 1, 2].map(|c| {
            let [g, hs, bbs] = self.channel_equations(c, add);
            crate::nnls::GramBatch::new(m, &g, &hs, &bbs)
                .and_then(|b| lawson_hanson::solve_batch(&b, &lawson_hanson::LhParams::default()))
                .map(|v| v.into_iter().map(|s| s.x).collect::<Vec<_>>())
                .unwrap_or_else(|_| vec![vec![0.0; m]; nt])
        });
        let [mut r, mut g, mut b] = per_c;
        (0..nt)
            .map(|t| {
                [
                    std::mem::take(&mut r[t]),
                    std::mem::take(&mut g[t]),
                    std::mem::take(&mut b[t]),
                ]
            })
            .collect()
    }

    /// `mean_rho(d, &self.exact(Some(add)))`, bit for bit, or `None` once the candidate
    /// provably cannot have a mean at most `beat`: the targets are fitted in the order of
    /// `bound`, and the candidate abandoned as soon as the sum of the scores fitted so far
    /// plus the bound on the others (times `1 - 1e-12`, the rounding of a different
    /// summation order) exceeds `beat` times the target count. Scores are non-negative,
    /// so the whole mean would exceed `beat` too, and the candidate could neither win
    /// against a mean of `beat` nor tie it. A complete candidate's mean is summed in
    /// target order and compared with `beat` as it is.
    pub(super) fn exact_mean_below(
        &self,
        d: &Dense,
        add: Added<'_>,
        beat: f64,
        bound: &Bound,
    ) -> Option<f64> {
        let m = self.m;
        let nt = self.x.len();
        let eqs = [0, 1, 2].map(|c| self.channel_equations(c, Some(add)));
        let batches = eqs
            .each_ref()
            .map(|[g, hs, bbs]| crate::nnls::GramBatch::new(m, g, hs, bbs).ok());
        let params = lawson_hanson::LhParams::default();
        let solvers = batches.each_ref().map(|b| {
            b.as_ref()
                .and_then(|b| lawson_hanson::PreparedBatch::new(b, &params).ok())
        });
        let div = nt.max(1) as f64;
        let mut ws = lawson_hanson::Workspace::default();
        let mut x = [[0.0f64; MAX_PLAN_COLUMNS]; 3];
        let mut rho = vec![0.0; nt];
        let mut partial = 0.0;
        for (&t, &rest) in bound.order.iter().zip(&bound.rest) {
            for (xc, s) in x.iter_mut().zip(&solvers) {
                let xc = &mut xc[..m];
                if !s.as_ref().is_some_and(|s| s.solve_x(t, &mut ws, xc)) {
                    xc.fill(0.0);
                }
            }
            rho[t] = d.rho_of(t, [&x[0][..m], &x[1][..m], &x[2][..m]]);
            partial += rho[t];
            if (partial + rest) * (1.0 - 1e-12) / div > beat {
                return None;
            }
        }
        let mut sum = 0.0;
        for r in &rho {
            sum += r;
        }
        if sum / div > beat {
            return None;
        }
        Some(sum / div)
    }
}
