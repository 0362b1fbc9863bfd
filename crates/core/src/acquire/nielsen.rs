//! The `nielsen` baseline of `cv --acquisition`: the published method of Nielsen, Jensen &
//! Ramamoorthi 2015 ("On Optimal, Minimal BRDF Sampling for Reflectance Acquisition", ACM
//! TOG 34(6)), with its own mapping, PCA, plan and reconstructor (no basis of ours).
//!
//! * **Observations**: each channel of each training material, tabulated on the model's
//!   cells (the evaluation-mask cell centres of the cross-validation).
//! * **Mapping**: a value `f` at a cell is weighted by the cosine map
//!   `w = clamp(cos theta_i cos theta_o, 0.01, 1)` of the cell centre and mapped to
//!   `log((f w + 0.001) / (m + 0.001))`, `m` the per-cell median of `f w` over the training
//!   observations.
//! * **PCA**: mean-centred, thin, through the eigendecomposition of the observations' Gram
//!   matrix `X_c X_c^T` (observations x observations, observations << cells): with
//!   `X_c = U S V^T`, the principal components scaled by their singular values are
//!   `Q = V S = X_c^T U` (cells x components). The first `k` are kept.
//! * **Plan**: the first direction is the cell whose row of `Q` (all components) has the
//!   largest norm; each
//!   further step examines a seeded random subset of 500 cells not yet chosen and adds the
//!   one minimising the condition number of `Q` restricted to the chosen rows and to as
//!   many components as samples; the added sample is then moved on the MERL grid by steps of
//!   +-3, then +-1 indices along theta_h, theta_d and phi_d while a move lowers that
//!   condition number (best move first). Only the new sample moves, so the first `n'`
//!   samples of an `n`-plan are the `n'`-plan.
//! * **Reconstruction**: the mapped, centred samples are regressed on the sampled rows of the
//!   first `n` components (as many as samples) by ridge regression with `eta = 40`, the
//!   components' combination is added to the mean and unmapped on every cell:
//!   `f = ((m + 0.001) e^x - 0.001) / w`. The one liberty taken: a negative unmapped value
//!   (which no BRDF has) is set to 0, which can only bring the reconstruction closer to any
//!   material, so it favours the baseline.

use super::linalg::{condition_number, sym_eigen};
use super::AcquireError;
use crate::backend::cpu::CpuBackend;
use crate::collection::{Collection, MaterialData};
use crate::fit::channel_lobe;
use crate::merl::{cell_directions, flat, lookup, unflat, N_CELLS, N_PD, N_TD, N_TH};
use rand::SeedableRng;
use rayon::prelude::*;

/// The offset of the log mapping.
pub const EPSILON: f64 = 0.001;
/// The ridge parameter of the reconstruction.
pub const ETA: f64 = 40.0;
/// Random candidate cells examined per plan step.
pub const CANDIDATES_PER_STEP: usize = 500;
/// Lower bound of the cosine map.
pub const COS_MIN: f64 = 0.01;
/// Local moves after each addition (grid steps, in order).
pub const LOCAL_STEPS: [usize; 2] = [3, 1];

/// Cells per block of the streamed passes over the cells.
const BLOCK: usize = 2048;

/// The cosine map `clamp(cos theta_i cos theta_o, 0.01, 1)` at a cell centre.
pub(crate) fn cos_map(cell: u32) -> f64 {
    let (wi, wo) = cell_directions(cell as usize);
    (wi[2] * wo[2]).clamp(COS_MIN, 1.0)
}

/// The mapping `log((f w + eps) / (m + eps))`.
pub(crate) fn map_value(f: f64, w: f64, m: f64) -> f64 {
    ((f * w + EPSILON).max(f64::MIN_POSITIVE) / (m + EPSILON)).ln()
}

/// The inverse of [`map_value`], `((m + eps) e^x - eps) / w`, negative values set to 0.
pub(crate) fn unmap_value(x: f64, w: f64, m: f64) -> f64 {
    (((m + EPSILON) * x.exp() - EPSILON) / w).max(0.0)
}

/// The trained model: per-cell mapping, mean and scaled principal components.
#[derive(Clone, Debug)]
pub struct NielsenModel {
    /// The model's cells (flat MERL indices).
    pub cells: Vec<u32>,
    /// Index of each MERL cell in `cells` (`u32::MAX`: not a model cell).
    index: Vec<u32>,
    /// Cosine map per cell.
    w: Vec<f64>,
    /// Median of the weighted training values per cell.
    med: Vec<f64>,
    /// Mean of the mapped training values per cell.
    mean: Vec<f64>,
    /// Squared norm of each cell's row of all the scaled components (the centred mapped
    /// values' sum of squares over the observations, `U` being orthogonal).
    norm2: Vec<f64>,
    /// Components kept.
    pub k: usize,
    /// `cells x k`, row-major: principal components scaled by their singular values.
    q: Vec<f64>,
    /// Singular values of the centred mapped observations, decreasing (all of them).
    pub singular_values: Vec<f64>,
    /// The model cell nearest to every MERL cell (`nearest_model_cells`), built on the
    /// first render and shared by every later one.
    near: std::sync::OnceLock<Vec<u32>>,
}

/// The three channels of a material at `cells` in f64: each channel's lobe tabulated by
/// [`CpuBackend::values_f64`], a network run once for all three
/// ([`CpuBackend::neural_values_f64`], the same values).
pub(crate) fn channel_values(cpu: &CpuBackend, m: &MaterialData, cells: &[u32]) -> [Vec<f64>; 3] {
    match m {
        MaterialData::Neural(net) => cpu.neural_values_f64(net, cells),
        d => [0, 1, 2].map(|c| cpu.values_f64(&channel_lobe(d, c), cells)),
    }
}

/// Median of `v` (mean of the two middle values for an even count); `v` is reordered.
fn median_in_place(v: &mut [f64]) -> f64 {
    let n = v.len();
    let (_, &mut hi, _) = v.select_nth_unstable_by(n / 2, f64::total_cmp);
    if n % 2 == 1 {
        hi
    } else {
        let lo = v[..n / 2].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    }
}

/// `sum_i a_i b_i` with four accumulators (vectorised by the compiler).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..4 {
            acc[l] += x[l] * y[l];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    acc[0] + acc[1] + acc[2] + acc[3] + tail
}

/// [`dot`] of four rows `a` with one `b` at once, `b` read once for the four: each sum is
/// formed term by term and accumulator by accumulator as [`dot`] forms it (the same bits).
fn dot4(a: [&[f64]; 4], b: &[f64]) -> [f64; 4] {
    let n = b.len() / 4 * 4;
    let mut acc = [[0.0f64; 4]; 4];
    let rows = a.map(|r| &r[..n]);
    for (i, y) in b[..n].chunks_exact(4).enumerate() {
        let o = 4 * i;
        for (r, x) in rows.iter().enumerate() {
            let x = &x[o..o + 4];
            for l in 0..4 {
                acc[r][l] += x[l] * y[l];
            }
        }
    }
    [0, 1, 2, 3].map(|r| {
        let tail: f64 = a[r][n..].iter().zip(&b[n..]).map(|(x, y)| x * y).sum();
        acc[r][0] + acc[r][1] + acc[r][2] + acc[r][3] + tail
    })
}

impl NielsenModel {
    /// Trains on `train` (collection indices; each channel is one observation) over
    /// `cells` (valid in every training material), keeping `k` components (at most the
    /// rank of the centred observations).
    pub fn train(
        coll: &Collection,
        train: &[usize],
        cells: &[u32],
        k: usize,
    ) -> Result<Self, AcquireError> {
        if train.is_empty() {
            return Err(AcquireError::InvalidParam {
                name: "training materials",
                value: "none".into(),
                expected: "at least one training material for the nielsen baseline".into(),
            });
        }
        let cpu = CpuBackend::new();
        let values = |block: &[u32]| -> Vec<Vec<f64>> {
            train
                .iter()
                .flat_map(|&m| channel_values(&cpu, &coll.materials()[m].data, block))
                .collect()
        };
        Ok(Self::from_values(3 * train.len(), cells, k, &values))
    }

    /// Trains on `nobs` observations given by `values(block)`: the value of each
    /// observation at each cell of `block` (`values(block)[o][j]`).
    ///
    /// Long function: two passes over the cells in blocks (medians, means and the Gram
    /// matrix of the centred observations; then the components) that share the block
    /// closure and whose loop order fixes the bits (comments inside).
    pub fn from_values(
        nobs: usize,
        cells: &[u32],
        k: usize,
        values: &(dyn Fn(&[u32]) -> Vec<Vec<f64>> + Sync),
    ) -> Self {
        let nc = cells.len();
        let w: Vec<f64> = cells.par_iter().map(|&c| cos_map(c)).collect();
        let mut med = vec![0.0; nc];
        let mut mean = vec![0.0; nc];
        let mut norm2 = vec![0.0; nc];
        // The centred mapped observations of a block (observation-major), with the block's
        // medians and means written on the way.
        let centred = |block: &[u32], wb: &[f64], md: &mut [f64], mu: &mut [f64], fill: bool| {
            let v = values(block);
            let mut x = vec![vec![0.0; block.len()]; nobs];
            let mut col = vec![0.0; nobs];
            for j in 0..block.len() {
                if fill {
                    for o in 0..nobs {
                        col[o] = v[o][j] * wb[j];
                    }
                    md[j] = if nobs > 0 {
                        median_in_place(&mut col)
                    } else {
                        0.0
                    };
                }
                let mut s = 0.0;
                for o in 0..nobs {
                    let y = map_value(v[o][j], wb[j], md[j]);
                    x[o][j] = y;
                    s += y;
                }
                if fill {
                    mu[j] = s / nobs.max(1) as f64;
                }
                for xo in x.iter_mut() {
                    xo[j] -= mu[j];
                }
            }
            x
        };
        // Pass 1: medians, means and the Gram matrix of the centred observations. The
        // blocks' Gram matrices are added in block order (groups of GROUP blocks run in
        // parallel, then summed sequentially): the same bits on every run and back-end,
        // whatever rayon's splitting.
        const GROUP: usize = 16;
        let mut gram = vec![0.0; nobs * nobs];
        let mut blocks: Vec<_> = med
            .chunks_mut(BLOCK)
            .zip(mean.chunks_mut(BLOCK))
            .zip(cells.chunks(BLOCK).zip(w.chunks(BLOCK)))
            .zip(norm2.chunks_mut(BLOCK))
            .collect();
        for group in blocks.chunks_mut(GROUP) {
            let parts: Vec<Vec<f64>> = group
                .par_iter_mut()
                .map(|(((md, mu), (block, wb)), n2)| {
                    let x = centred(block, wb, md, mu, true);
                    for (j, v) in n2.iter_mut().enumerate() {
                        *v = x.iter().map(|xo| xo[j] * xo[j]).sum();
                    }
                    // The lower triangle, four rows at a time.
                    let mut g = vec![0.0; nobs * nobs];
                    let quads = nobs / 4 * 4;
                    for a0 in (0..quads).step_by(4) {
                        let rows = [&x[a0][..], &x[a0 + 1], &x[a0 + 2], &x[a0 + 3]];
                        for b in 0..a0 + 4 {
                            let d = dot4(rows, &x[b]);
                            for (r, v) in d.into_iter().enumerate() {
                                if b <= a0 + r {
                                    g[(a0 + r) * nobs + b] = v;
                                }
                            }
                        }
                    }
                    for a in quads..nobs {
                        for b in 0..=a {
                            g[a * nobs + b] = dot(&x[a], &x[b]);
                        }
                    }
                    g
                })
                .collect();
            for g in parts {
                gram.iter_mut().zip(&g).for_each(|(x, y)| *x += y);
            }
        }
        for a in 0..nobs {
            for b in 0..a {
                gram[b * nobs + a] = gram[a * nobs + b];
            }
        }
        let (lam, u) = sym_eigen(nobs, &gram);
        let top = lam.first().copied().unwrap_or(0.0);
        let rank = lam.iter().filter(|&&l| l > 1e-12 * top && l > 0.0).count();
        let k = k.min(rank);
        // Pass 2: Q = X_c^T U (the first k columns).
        let mut q = vec![0.0; nc * k];
        if k > 0 {
            q.par_chunks_mut(BLOCK * k)
                .zip(cells.par_chunks(BLOCK).zip(w.par_chunks(BLOCK)))
                .zip(med.par_chunks(BLOCK).zip(mean.par_chunks(BLOCK)))
                .for_each(|((qb, (block, wb)), (md, mu))| {
                    let mut md = md.to_vec();
                    let mut mu = mu.to_vec();
                    let x = centred(block, wb, &mut md, &mut mu, false);
                    for j in 0..block.len() {
                        for r in 0..k {
                            qb[j * k + r] = (0..nobs).map(|o| x[o][j] * u[o * nobs + r]).sum();
                        }
                    }
                });
        }
        let mut index = vec![u32::MAX; N_CELLS];
        for (i, &c) in cells.iter().enumerate() {
            index[c as usize] = i as u32;
        }
        Self {
            cells: cells.to_vec(),
            index,
            w,
            med,
            mean,
            norm2,
            k,
            q,
            singular_values: lam.iter().map(|l| l.max(0.0).sqrt()).collect(),
            near: std::sync::OnceLock::new(),
        }
    }

    /// Row `j` of the scaled components (its first `cols`).
    fn row(&self, j: usize, cols: usize) -> &[f64] {
        &self.q[j * self.k..j * self.k + cols]
    }

    /// Condition number of the components restricted to rows `rows` and to as many
    /// components as rows (at most `k`).
    pub fn condition(&self, rows: &[usize]) -> f64 {
        let cols = rows.len().min(self.k);
        if cols == 0 {
            return f64::INFINITY;
        }
        let d: Vec<f64> = rows
            .iter()
            .flat_map(|&j| self.row(j, cols).iter().copied())
            .collect();
        condition_number(rows.len(), cols, &d)
    }

    /// Plans `n` samples (indices into `cells`) as the module docs say, examining
    /// `candidates_per_step` random cells per step (0: all), seeded.
    pub fn plan(&self, n: usize, candidates_per_step: usize, seed: u64) -> Vec<usize> {
        let nc = self.cells.len();
        let n = n.min(nc);
        if n == 0 || self.k == 0 {
            return Vec::new();
        }
        let mut first = 0;
        for j in 1..nc {
            if self.norm2[j] > self.norm2[first] {
                first = j;
            }
        }
        let mut chosen = vec![first];
        let mut taken = vec![false; nc];
        taken[first] = true;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for _step in 1..n {
            let free: Vec<usize> = (0..nc).filter(|&j| !taken[j]).collect();
            let per = if candidates_per_step == 0 {
                free.len()
            } else {
                candidates_per_step.min(free.len())
            };
            let mut pool: Vec<usize> = rand::seq::index::sample(&mut rng, free.len(), per)
                .into_iter()
                .map(|i| free[i])
                .collect();
            pool.sort_unstable();
            let with = |j: usize| -> f64 {
                let mut rows = chosen.clone();
                rows.push(j);
                let c = self.condition(&rows);
                if c.is_nan() {
                    f64::INFINITY
                } else {
                    c
                }
            };
            let scores: Vec<f64> = pool.par_iter().map(|&j| with(j)).collect();
            let mut best = 0;
            for i in 1..pool.len() {
                if scores[i] < scores[best] {
                    best = i;
                }
            }
            let (mut cur, mut cur_score) = (pool[best], scores[best]);
            for step in LOCAL_STEPS {
                loop {
                    let moves: Vec<usize> = self
                        .neighbours(cur, step)
                        .into_iter()
                        .filter(|&j| !taken[j])
                        .collect();
                    let s: Vec<f64> = moves.par_iter().map(|&j| with(j)).collect();
                    let mut bi = None;
                    for (i, &v) in s.iter().enumerate() {
                        if v < cur_score && bi.is_none_or(|b: usize| v < s[b]) {
                            bi = Some(i);
                        }
                    }
                    match bi {
                        Some(i) => {
                            cur = moves[i];
                            cur_score = s[i];
                        }
                        None => break,
                    }
                }
            }
            taken[cur] = true;
            chosen.push(cur);
        }
        chosen
    }

    /// Model cells one grid move of `step` indices away from cell `j` along theta_h,
    /// theta_d or phi_d (no wrap).
    fn neighbours(&self, j: usize, step: usize) -> Vec<usize> {
        let (a, b, c) = unflat(self.cells[j] as usize);
        let mut out = Vec::with_capacity(6);
        let dims = [(a, N_TH), (b, N_TD), (c, N_PD)];
        for (d, &(v, len)) in dims.iter().enumerate() {
            for nv in [v.checked_sub(step), Some(v + step).filter(|&x| x < len)]
                .into_iter()
                .flatten()
            {
                let mut idx = [a, b, c];
                idx[d] = nv;
                let i = self.index[flat(idx[0], idx[1], idx[2])];
                if i != u32::MAX {
                    out.push(i as usize);
                }
            }
        }
        out
    }

    /// Ridge coefficients of one channel from measured values `y` at the samples `chosen`
    /// (indices into `cells`), on as many components as samples.
    pub fn coefficients(&self, chosen: &[usize], y: &[f64], eta: f64) -> Vec<f64> {
        let kk = chosen.len().min(self.k);
        let mut a = vec![0.0; kk * kk];
        let mut rhs = vec![0.0; kk];
        for (&j, &yv) in chosen.iter().zip(y) {
            let t = map_value(yv, self.w[j], self.med[j]) - self.mean[j];
            let r = self.row(j, kk);
            for p in 0..kk {
                rhs[p] += r[p] * t;
                for s in 0..kk {
                    a[p * kk + s] += r[p] * r[s];
                }
            }
        }
        for p in 0..kk {
            a[p * kk + p] += eta;
        }
        cholesky_solve(kk, &mut a, &mut rhs);
        rhs
    }

    /// The reconstruction at model cell `j` of coefficients `coef`.
    pub fn value(&self, j: usize, coef: &[f64]) -> f64 {
        let x: f64 = self.mean[j]
            + self
                .row(j, coef.len())
                .iter()
                .zip(coef)
                .map(|(q, c)| q * c)
                .sum::<f64>();
        unmap_value(x, self.w[j], self.med[j])
    }

    /// Index in `cells` of a MERL cell, if it is a model cell.
    pub fn index_of(&self, cell: u32) -> Option<usize> {
        self.index
            .get(cell as usize)
            .filter(|&&i| i != u32::MAX)
            .map(|&i| i as usize)
    }

    /// The model cell nearest to every MERL cell (breadth-first over the grid's six index
    /// neighbours, no wrap; ties to the first reached): renders read the reconstruction at
    /// cells the model does not hold (outside the evaluation mask, or between the cells of
    /// a strided grid) from their nearest model cell, never as 0.
    fn nearest_model_cells(&self) -> Vec<u32> {
        let mut near = self.index.clone();
        let mut queue: std::collections::VecDeque<usize> =
            self.cells.iter().map(|&c| c as usize).collect();
        while let Some(cell) = queue.pop_front() {
            let (a, b, c) = unflat(cell);
            let m = near[cell];
            let dims = [(a, N_TH), (b, N_TD), (c, N_PD)];
            for (d, &(v, len)) in dims.iter().enumerate() {
                for nv in [v.checked_sub(1), Some(v + 1).filter(|&x| x < len)]
                    .into_iter()
                    .flatten()
                {
                    let mut idx = [a, b, c];
                    idx[d] = nv;
                    let f = flat(idx[0], idx[1], idx[2]);
                    if near[f] == u32::MAX {
                        near[f] = m;
                        queue.push_back(f);
                    }
                }
            }
        }
        near
    }

    /// The reconstruction (per-channel coefficients) as a BRDF for renders: the value of
    /// the model cell nearest to the MERL cell a direction pair falls in (the model holds
    /// the evaluation-mask cells of its grid stride only; see
    /// `nearest_model_cells`); 0 below the horizon.
    pub fn brdf<'a>(
        &'a self,
        coef: &'a [Vec<f64>; 3],
    ) -> impl Fn([f64; 3], [f64; 3]) -> [f64; 3] + Sync + 'a {
        let at = self.at_cell(coef);
        move |wi, wo| {
            if wi[2] <= 0.0 || wo[2] <= 0.0 {
                return [0.0; 3];
            }
            at(lookup(wi, wo))
        }
    }

    /// [`Self::brdf`] on a MERL cell: the reconstruction at its nearest model cell (for
    /// [`crate::eval::shade::PixelBrdfs::render_cells`]).
    pub fn at_cell<'a>(&'a self, coef: &'a [Vec<f64>; 3]) -> impl Fn(usize) -> [f64; 3] + 'a {
        let near = self.near.get_or_init(|| self.nearest_model_cells());
        move |cell| match near[cell] {
            u32::MAX => [0.0; 3],
            j => [0, 1, 2].map(|c| self.value(j as usize, &coef[c])),
        }
    }
}

/// [`super::plan()`] with the `nielsen` criterion: the model trained on `basis` and
/// `targets` together (the peer has no basis: every training material is an observation)
/// over `cands` (cell centres only), keeping `p.n` components, and its plan of `p.n`
/// samples with [`CANDIDATES_PER_STEP`] candidates per step (`p.candidates_per_step` when
/// smaller). `history` holds the condition number after each sample.
pub(crate) fn plan_criterion(
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    cands: &[super::Candidate],
    p: &super::PlanParams,
) -> Result<super::Plan, AcquireError> {
    let cells: Vec<u32> = cands
        .iter()
        .map(|c| c.cell)
        .collect::<Option<_>>()
        .ok_or(AcquireError::InvalidParam {
        name: "candidates",
        value: "directions off the cell centres".into(),
        expected:
            "cell centres for the nielsen criterion (its PCA and local moves live on the MERL grid)"
                .into(),
    })?;
    if p.n == 0 || p.n > cells.len() {
        return Err(AcquireError::InvalidParam {
            name: "n",
            value: p.n.to_string(),
            expected: format!(
                "at least 1 and at most the number of candidates ({})",
                cells.len()
            ),
        });
    }
    let mut train = basis.to_vec();
    train.extend_from_slice(targets);
    let model = NielsenModel::train(coll, &train, &cells, p.n)?;
    let per = nielsen_per_step(p.candidates_per_step);
    let chosen = model.plan(p.n, per, p.seed);
    let history = (1..=chosen.len())
        .map(|i| model.condition(&chosen[..i]))
        .collect();
    Ok(super::Plan {
        basis: basis
            .iter()
            .map(|&b| coll.materials()[b].name.clone())
            .collect(),
        criterion: super::Criterion::Nielsen,
        n: chosen.len(),
        candidates_per_step: per.min(cells.len()),
        candidates: cells.len(),
        samples: chosen
            .iter()
            .map(|&j| super::PlannedSample::from(&cands[j]))
            .collect(),
        history,
        seed: p.seed,
        restarts: 1,
        objective: "l2".into(),
        chosen: chosen.iter().map(|&j| cands[j]).collect(),
    })
}

/// Candidates per step of the baseline: the published 500, fewer if asked (0: 500).
pub(crate) fn nielsen_per_step(requested: usize) -> usize {
    if requested == 0 {
        CANDIDATES_PER_STEP
    } else {
        requested.min(CANDIDATES_PER_STEP)
    }
}

/// Solves the symmetric positive definite `a x = b` in place (`b` becomes `x`) by Cholesky.
fn cholesky_solve(n: usize, a: &mut [f64], b: &mut [f64]) {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        let d = d.max(f64::MIN_POSITIVE).sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mapping_round_trips() {
        for &(f, w, m) in &[(0.3, 0.5, 0.1), (12.0, 0.01, 0.4), (0.0, 1.0, 0.0)] {
            let x = map_value(f, w, m);
            assert!(
                (unmap_value(x, w, m) - f).abs() < 1e-12 * f.max(1.0),
                "{f} {w} {m}"
            );
        }
        // The median itself maps to 0.
        assert!(map_value(0.2 / 0.5, 0.5, 0.2).abs() < 1e-15);
        assert_eq!(median_in_place(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median_in_place(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert!((cos_map(flat(0, 0, 0) as u32) - 1.0).abs() < 1e-3);
    }

    #[test]
    fn dot4_is_dot_to_the_bit() {
        let v: Vec<Vec<f64>> = (0..5)
            .map(|r| {
                (0..23)
                    .map(|i| ((i * 7 + r * 3) as f64 * 0.37).sin())
                    .collect()
            })
            .collect();
        let d = dot4([&v[0], &v[1], &v[2], &v[3]], &v[4]);
        for r in 0..4 {
            assert_eq!(d[r].to_bits(), dot(&v[r], &v[4]).to_bits());
        }
    }

    #[test]
    fn cholesky_solves_a_hand_made_system() {
        let mut a = vec![4.0, 2.0, 2.0, 3.0];
        let mut b = vec![2.0, 1.0];
        cholesky_solve(2, &mut a, &mut b);
        assert!((b[0] - 0.5).abs() < 1e-14 && b[1].abs() < 1e-14, "{b:?}");
    }

    /// Observations that are, in the mapped space, the mean plus combinations of two fixed
    /// patterns: a new material of the same form is reconstructed exactly from two samples
    /// (eta = 0), and nearly so with the published ridge when the components are large.
    #[test]
    fn a_material_in_the_span_is_reconstructed_exactly() {
        let cells: Vec<u32> = (0..400)
            .map(|i| flat(10 + i % 20, 5 + i / 20, 7) as u32)
            .collect();
        let pat = |p: usize, c: u32| -> f64 {
            let (a, b, _) = unflat(c as usize);
            if p == 0 {
                (a as f64 * 0.3).sin()
            } else {
                (b as f64 * 0.2).cos() * 0.5
            }
        };
        let base = |c: u32| 0.05 + 0.001 * (c % 7) as f64;
        // f w + eps = exp(base + s0 p0 + s1 p1): mapped values are affine in the patterns
        // (the median is a constant offset per cell).
        let mat = |s: [f64; 2], c: u32| -> f64 {
            ((base(c).ln() + s[0] * pat(0, c) + s[1] * pat(1, c)).exp() - EPSILON) / cos_map(c)
        };
        let coeffs: Vec<[f64; 2]> = (0..9)
            .map(|i| [(i as f64 * 0.7).sin() * 3.0, (i as f64 * 1.3).cos() * 2.0])
            .collect();
        let values = |block: &[u32]| -> Vec<Vec<f64>> {
            coeffs
                .iter()
                .map(|s| block.iter().map(|&c| mat(*s, c)).collect())
                .collect()
        };
        let model = NielsenModel::from_values(coeffs.len(), &cells, 5, &values);
        assert_eq!(
            model.k, 2,
            "two patterns, rank 2: {:?}",
            model.singular_values
        );
        let target = [0.8, -1.1];
        let plan = model.plan(2, 0, 3);
        assert_eq!(plan.len(), 2);
        assert!(model.condition(&plan).is_finite());
        let y: Vec<f64> = plan.iter().map(|&j| mat(target, cells[j])).collect();
        let coef = model.coefficients(&plan, &y, 0.0);
        for (j, &c) in cells.iter().enumerate() {
            let want = mat(target, c);
            let got = model.value(j, &coef);
            assert!(
                (got - want).abs() < 1e-9 * want.max(1.0),
                "cell {c}: {got} vs {want}"
            );
        }
        // Training observations are in the span too: each is reconstructed from the plan.
        let y: Vec<f64> = plan.iter().map(|&j| mat(coeffs[4], cells[j])).collect();
        let coef = model.coefficients(&plan, &y, 0.0);
        assert!((model.value(100, &coef) - mat(coeffs[4], cells[100])).abs() < 1e-9);
        // The plan is deterministic for a seed and nested.
        assert_eq!(model.plan(2, 50, 9), model.plan(2, 50, 9));
        assert_eq!(model.plan(2, 50, 9)[..1], model.plan(1, 50, 9)[..]);
    }
}
