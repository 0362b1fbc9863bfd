//! Fitting a material from its samples (SPEC 10): per channel c, with weights
//! `w_s = (sigma_min / sigma_s)^2` (the SPEC's `1 / sigma_s^2` scaled by the smallest
//! sigma of the set, so that they neither underflow nor overflow; 1 without sigma),
//!
//! ```text
//! minimise  sum_s w_s (a0 / pi + sum_b a_b f_b,c(s) - y_c(s))^2   subject to a >= 0
//! ```
//!
//! section 5's problem on the samples instead of the grid, solved by the crate's exact
//! Lawson-Hanson solver on its Gram form (`G = A^T W A`, `h = A^T W y`). The basis is
//! evaluated at the exact sample directions ([`super::material_at`]). With fewer samples
//! than columns, or a rank-deficient or ill-conditioned sampled design, the fit is not
//! determined by the samples: NNLS still returns a non-negative solution closest to them
//! (often a good one), so that is a warning, never a refusal.

use super::eval::material_at;
use super::linalg::singular_values;
use super::samples::Sample;
use super::AcquireError;
use crate::backend::weighted::TargetWeight;
use crate::collection::Collection;
use crate::error::plural;
use crate::fit::TargetFit;
use crate::nnls::{lawson_hanson, GramProblem, NnlsError, NnlsSolution};
use std::f64::consts::FRAC_1_PI;

/// Condition number of the column-scaled sampled design above which `fit --samples` warns:
/// a relative error of 1e-4 in the samples (a good gonioreflectometer) may then move the
/// coefficients by 10% or more.
pub const WARN_CONDITION: f64 = 1e3;

/// Singular values below `RANK_TOL x` the largest count as zero in the rank of the
/// column-scaled sampled design (they come from the eigenvalues of its Gram matrix, whose
/// rounding puts a floor of about `sqrt(1e-16) = 1e-8` under the ratio).
pub const RANK_TOL: f64 = 1e-6;

/// The sampled design: per channel, one row `[1/pi, f_1,c(s), .., f_k,c(s)]` per sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Design {
    /// Columns: the Lambertian term and the basis.
    pub m: usize,
    /// Per channel, `n x m` row-major.
    pub rows: [Vec<f64>; 3],
}

impl Design {
    /// The basis (collection indices) evaluated at the samples' exact directions.
    pub fn at_samples(
        coll: &Collection,
        basis: &[usize],
        samples: &[Sample],
    ) -> Result<Self, AcquireError> {
        let m = basis.len() + 1;
        let mut rows: [Vec<f64>; 3] = Default::default();
        for r in rows.iter_mut() {
            r.reserve(samples.len() * m);
        }
        for s in samples {
            for r in rows.iter_mut() {
                r.push(FRAC_1_PI);
            }
            for &b in basis {
                let v = material_at(&coll.materials()[b], s.wi, s.wo)?;
                for (c, r) in rows.iter_mut().enumerate() {
                    r.push(v[c]);
                }
            }
        }
        Ok(Self { m, rows })
    }

    /// Number of samples (rows).
    pub fn n(&self) -> usize {
        self.rows[0].len() / self.m.max(1)
    }

    /// The mean over channels of the rows (`n x m`): the design of SPEC 10's condition
    /// criterion.
    pub fn mean_rows(&self) -> Vec<f64> {
        (0..self.rows[0].len())
            .map(|i| (self.rows[0][i] + self.rows[1][i] + self.rows[2][i]) / 3.0)
            .collect()
    }
}

/// The weighted NNLS of one channel: rows `n x m`, values `y` and weights `w` (one per
/// row), through the Gram form and the crate's Lawson-Hanson solver.
pub(crate) fn solve_rows(
    m: usize,
    rows: &[f64],
    y: &[f64],
    w: &[f64],
) -> Result<NnlsSolution, NnlsError> {
    solve_rows_toward(m, rows, y, w, None)
}

/// Ridge strengths `solve_rows_toward` chooses among (`cv --acquisition` picks one per
/// fold, plan and n on the training materials; 0: plain NNLS).
pub const RIDGE_STRENGTHS: [f64; 7] = [0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1];

/// The prior of [`solve_rows_toward`] in one channel: the mean coefficients `mean` of the
/// training materials and the shape `S` of the penalty `(x - mean)^T S (x - mean)`, an
/// `m x m` symmetric positive-semidefinite matrix of trace `m` ([`function_shape`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Toward<'a> {
    /// Mean coefficients (Lambertian first).
    pub mean: &'a [f64],
    /// Shape of the penalty, row-major `m x m`, trace `m`.
    pub shape: &'a [f64],
    /// Strength relative to the sampled design ([`solve_rows_toward`]).
    pub lambda: f64,
    /// A second penalty toward the black material, `mu_e x^T E x`: `E` the shape
    /// ([`function_shape`]) of the basis columns' *unweighted* Gram matrix on the whole
    /// mask, so that `x^T E x` is the reconstruction's squared L2 norm (its energy, which
    /// the specular peak dominates), and `mu_e = energy_lambda tr(A^T W A) / m`. Among the
    /// fits the samples allow, it prefers the one with the least energy where the samples
    /// do not look: an unpinned peak is shrunk toward none, never blown up (a
    /// reconstruction shrunk all the way to black has rho 1). `None` or 0: no such term.
    pub energy: Option<(&'a [f64], f64)>,
}

/// The shape of the ridge's penalty in function space: the basis columns' Gram matrix `G`
/// on the whole mask under the objective's shared weights (`G_ij = sum_s W(s) f_i(s)
/// f_j(s)`, Lambertian first), scaled to trace `m`. Then `(x - mean)^T S (x - mean)` is the
/// weighted squared distance over the whole grid between the material the coefficients
/// `x` describe and the training materials' mean material: among the many fits that
/// fewer samples than unknowns allow, the ridge prefers the one that looks most like an
/// ordinary material everywhere, not only at the samples, which is what keeps the
/// unsampled specular peak from extrapolating. The identity when `G` has no trace.
pub(crate) fn function_shape(m: usize, gram: &[f64]) -> Vec<f64> {
    let tr: f64 = (0..m).map(|i| gram[i * m + i]).sum();
    if tr > 0.0 && tr.is_finite() {
        gram[..m * m].iter().map(|v| v * m as f64 / tr).collect()
    } else {
        (0..m * m)
            .map(|i| if i % (m + 1) == 0 { 1.0 } else { 0.0 })
            .collect()
    }
}

/// [`solve_rows`] with an optional ridge toward a prior ([`Toward`]: SPEC 10's choice among
/// the solutions when the samples do not determine the fit):
///
/// ```text
/// minimise  sum_s w_s (row_s . x - y_s)^2 + mu (x - mean)^T S (x - mean)   subject to x >= 0,
/// mu = lambda tr(G) / m
/// ```
///
/// `G = A^T W A` the sampled Gram matrix, so `lambda` is relative to the mean squared
/// (weighted) column norm and does not depend on the units or on the number of samples;
/// `S` has trace `m` (the identity is the plain ridge). With fewer samples than columns the
/// sampled problem has many exact solutions; the ridge picks the one most probable under
/// the prior, and with enough samples a small `lambda` leaves the fit as it was.
/// `lambda = 0` or no prior is [`solve_rows`], bit for bit.
pub(crate) fn solve_rows_toward(
    m: usize,
    rows: &[f64],
    y: &[f64],
    w: &[f64],
    prior: Option<Toward<'_>>,
) -> Result<NnlsSolution, NnlsError> {
    let mut g = vec![0.0; m * m];
    let mut h = vec![0.0; m];
    let mut bb = 0.0;
    for ((row, &yv), &wv) in rows.chunks_exact(m).zip(y).zip(w) {
        for i in 0..m {
            let wi = wv * row[i];
            h[i] += wi * yv;
            for j in 0..=i {
                g[i * m + j] += wi * row[j];
            }
        }
        bb += wv * yv * yv;
    }
    for i in 0..m {
        for j in 0..i {
            g[j * m + i] = g[i * m + j];
        }
    }
    if let Some(t) = prior {
        // Both strengths are relative to the sampled design before any penalty.
        let tr = (0..m).map(|i| g[i * m + i]).sum::<f64>();
        if t.lambda > 0.0 {
            let mu = t.lambda * tr / m as f64;
            for i in 0..m {
                let sm: f64 = (0..m).map(|j| t.shape[i * m + j] * t.mean[j]).sum();
                for j in 0..m {
                    g[i * m + j] += mu * t.shape[i * m + j];
                }
                h[i] += mu * sm;
                bb += mu * t.mean[i] * sm;
            }
        }
        if let Some((e, le)) = t.energy.filter(|e| e.1 > 0.0) {
            let mu = le * tr / m as f64;
            for (gv, ev) in g.iter_mut().zip(&e[..m * m]) {
                *gv += mu * ev;
            }
        }
    }
    let p = GramProblem::new(m, &g, &h, bb)?;
    lawson_hanson::solve(&p, &lawson_hanson::LhParams::default())
}

/// What a sample set can determine: rank and condition number of the column-scaled design
/// (mean over channels; every non-zero column scaled to unit norm).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Determination {
    /// Samples.
    pub samples: usize,
    /// Columns (Lambertian + basis).
    pub columns: usize,
    /// Numerical rank ([`RANK_TOL`]).
    pub rank: usize,
    /// Largest over smallest of its `min(samples, columns)` singular values (infinite when
    /// rank-deficient).
    pub condition: f64,
}

/// Rank and condition of the column-scaled `n x m` design `d`.
pub fn determination(n: usize, m: usize, d: &[f64]) -> Determination {
    let mut d = d.to_vec();
    for j in 0..m {
        let norm = (0..n)
            .map(|r| d[r * m + j] * d[r * m + j])
            .sum::<f64>()
            .sqrt();
        if norm > 0.0 {
            (0..n).for_each(|r| d[r * m + j] /= norm);
        }
    }
    let s = singular_values(n, m, &d);
    let hi = s.first().copied().unwrap_or(0.0);
    let rank = s.iter().filter(|&&v| v > RANK_TOL * hi && v > 0.0).count();
    let lo = s.last().copied().unwrap_or(0.0);
    Determination {
        samples: n,
        columns: m,
        rank,
        condition: if rank == m && lo > 0.0 {
            hi / lo
        } else {
            f64::INFINITY
        },
    }
}

/// The fit of one material from its samples.
#[derive(Clone, Debug, PartialEq)]
pub struct SampleFit {
    /// Coefficients per column (0 = Lambertian, then the basis), RGB.
    pub coefficients: Vec<[f64; 3]>,
    /// `sqrt(sum_s w_s r_s^2)` per channel, on the samples (`w_s` the sigma weights).
    pub residual: [f64; 3],
    /// Weighted mean of |fit - y| over the samples, averaged over channels.
    pub mae: f64,
    /// `sum_c residual_c^2 / sum_c sum_s w_s y_c(s)^2` on the samples.
    pub relative_residual: f64,
    /// The same ratio with the objective's weights (SPEC 11; equal to
    /// `relative_residual` under `l2`): what the fit minimised, on the samples.
    pub objective_residual: f64,
    /// Largest scaled KKT violation per channel.
    pub kkt: [f64; 3],
    /// Solver iterations per channel.
    pub iterations: [usize; 3],
    /// Rank and condition of the sampled design.
    pub determination: Determination,
}

impl SampleFit {
    /// As a [`TargetFit`] named `material` (residual and MAE on the samples), for the fit
    /// JSON and the export.
    pub fn target_fit(&self, material: &str) -> TargetFit {
        TargetFit {
            material: material.to_string(),
            coefficients: self.coefficients.clone(),
            residual: self.residual,
            mae: self.mae,
            relative_residual: self.relative_residual,
            relative_mae: 0.0,
            objective_residual: self.objective_residual,
            kkt: self.kkt,
            iterations: self.iterations,
        }
    }
}

/// Parameters of [`fit_samples`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleFitParams {
    /// Condition number above which the fit warns ([`WARN_CONDITION`]).
    pub warn_condition: f64,
}

impl Default for SampleFitParams {
    fn default() -> Self {
        Self {
            warn_condition: WARN_CONDITION,
        }
    }
}

/// Fits the samples by the basis (collection indices, each once): per channel the weighted
/// NNLS of SPEC 10. Refused: an empty basis, a duplicate, no sample, a basis value
/// undefined at a sample (a MERL cell without measurement).
pub fn fit_samples(
    coll: &Collection,
    basis: &[usize],
    samples: &[Sample],
    objective: TargetWeight,
) -> Result<SampleFit, AcquireError> {
    if basis.is_empty() {
        return Err(crate::fit::FitError::EmptyBasis.into());
    }
    for (i, &b) in basis.iter().enumerate() {
        if basis[..i].contains(&b) {
            return Err(
                crate::fit::FitError::DuplicateBasis(coll.materials()[b].name.clone()).into(),
            );
        }
    }
    if samples.is_empty() {
        return Err(AcquireError::NoSamples {
            what: "the samples".into(),
        });
    }
    let d = Design::at_samples(coll, basis, samples)?;
    fit_design(&d, samples, objective)
}

/// [`fit_samples`] on a given design (rows at the samples, in order). Samples validated
/// as a samples file is ([`super::samples`]: values at most `MAX_VALUE`, sigmas at most
/// `MAX_SIGMA_RATIO` apart) give a finite Gram problem; others may be refused by it.
///
/// Under an objective (SPEC 11) each sample's weight is the objective's weight at the
/// measured value, `phi(y_c(s), cos theta_i(s))`, times its sigma weight: the residual,
/// MAE and relative residual reported are then the objective's, on the samples.
/// `objective` is checked by the caller ([`fit_samples`]).
pub(crate) fn fit_design(
    d: &Design,
    samples: &[Sample],
    objective: TargetWeight,
) -> Result<SampleFit, AcquireError> {
    let m = d.m;
    let n = samples.len();
    let mut out = SampleFit {
        coefficients: vec![[0.0; 3]; m],
        residual: [0.0; 3],
        mae: 0.0,
        relative_residual: 0.0,
        objective_residual: 0.0,
        kkt: [0.0; 3],
        iterations: [0; 3],
        determination: determination(n, m, &d.mean_rows()),
    };
    let (mut sq, mut energy) = (0.0, 0.0);
    let (mut osq, mut oenergy) = (0.0, 0.0);
    let floor = super::samples::sigma_floor(samples);
    for c in 0..3 {
        let y: Vec<f64> = samples.iter().map(|s| s.rgb[c]).collect();
        let w: Vec<f64> = samples.iter().map(|s| s.weight(c, floor)).collect();
        let ow: Vec<f64> = samples
            .iter()
            .zip(&w)
            .map(|(s, &wv)| wv * objective.phi(s.rgb[c], s.wi[2]))
            .collect();
        vanishing_weights(&ow, objective, c)?;
        let sol = solve_rows(m, &d.rows[c], &y, &ow)?;
        let (mut r2, mut ab, mut wsum) = (0.0, 0.0, 0.0);
        for (((row, &yv), &wv), &owv) in d.rows[c].chunks_exact(m).zip(&y).zip(&w).zip(&ow) {
            let f: f64 = row.iter().zip(&sol.x).map(|(a, x)| a * x).sum();
            r2 += wv * (f - yv) * (f - yv);
            ab += wv * (f - yv).abs();
            wsum += wv;
            energy += wv * yv * yv;
            osq += owv * (f - yv) * (f - yv);
            oenergy += owv * yv * yv;
        }
        sq += r2;
        out.residual[c] = r2.sqrt();
        out.mae += ab / wsum / 3.0;
        out.kkt[c] = sol.max_kkt_violation;
        out.iterations[c] = sol.iterations;
        for (k, &a) in sol.x.iter().enumerate() {
            out.coefficients[k][c] = a;
        }
    }
    out.relative_residual = if energy > 0.0 { sq / energy } else { 0.0 };
    out.objective_residual = if oenergy > 0.0 { osq / oenergy } else { 0.0 };
    Ok(out)
}

/// Refuses sample weights (sigma weights times the objective's, channel `c`) that are 0 or
/// not normal on every sample: the fit would fit nothing, and its objective residual of 0
/// would read as perfect.
fn vanishing_weights(ow: &[f64], objective: TargetWeight, c: usize) -> Result<(), AcquireError> {
    if ow.iter().any(|w| w.is_normal()) {
        return Ok(());
    }
    let what = match objective.eps() {
        Some(eps) => format!("the relative objective's weights 1/(f + eps)^2 at eps {eps:e}"),
        None => format!("the {} objective's weights", objective.kind().name()),
    };
    Err(crate::fit::FitError::Weights {
        material: "the samples".into(),
        channel: c,
        detail: format!("{what} vanish on every sample: it would fit nothing, and an objective residual of 0 would read as a perfect fit"),
    }
    .into())
}

/// Warnings of a fit whose samples cannot determine it: fewer samples than columns, a
/// rank-deficient sampled design, or a condition number above `bound`; each says how many
/// more samples would help (`where_` lists suggested directions, e.g. from
/// [`super::plan::suggest`]).
pub fn determination_warnings(d: &Determination, bound: f64, where_: &str) -> Vec<String> {
    let mut w = Vec::new();
    let at = if where_.is_empty() {
        String::new()
    } else {
        format!(", e.g. at {where_}")
    };
    // Samples that repeat what others tell (rank below the sample count) add nothing: the
    // missing count is that of the rank.
    if d.samples < d.columns {
        w.push(format!(
            "{} for {} unknowns per channel (the Lambertian term and {}): the samples cannot determine the fit; NNLS returns the non-negative combination closest to them, often a good one, but {} would determine it{at}",
            plural(d.samples, "sample", "samples"),
            d.columns,
            plural(d.columns - 1, "basis material", "basis materials"),
            plural(d.columns - d.rank.min(d.samples), "more sample", "more samples")
        ));
    } else if d.rank < d.columns {
        w.push(format!(
            "the sampled design has rank {} of {} (some basis materials look alike at these directions): the samples cannot tell them apart; at least {} more samples at other directions would help{at}",
            d.rank,
            d.columns,
            d.columns - d.rank
        ));
    } else if d.condition > bound {
        w.push(format!(
            "the sampled design is ill-conditioned (condition number {} > {}): noise in the samples is amplified that much in the coefficients; a few more samples at other directions would help{at}",
            crate::stats::num(d.condition),
            crate::stats::num(bound)
        ));
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two rows, two columns: `[1 0; 0 2] x = [3, 4]` has the exact solution (3, 2).
    #[test]
    fn an_exactly_determined_hand_made_system() {
        let s = solve_rows(2, &[1.0, 0.0, 0.0, 2.0], &[3.0, 4.0], &[1.0, 1.0]).unwrap();
        assert!(
            (s.x[0] - 3.0).abs() < 1e-14 && (s.x[1] - 2.0).abs() < 1e-14,
            "{:?}",
            s.x
        );
        let d = determination(2, 2, &[1.0, 0.0, 0.0, 2.0]);
        assert_eq!(d.rank, 2);
        assert!((d.condition - 1.0).abs() < 1e-12);
        let dep = determination(3, 2, &[1.0, 2.0, 2.0, 4.0, 3.0, 6.0]);
        assert_eq!(dep.rank, 1);
        assert!(dep.condition.is_infinite());
        let w = determination_warnings(&dep, WARN_CONDITION, "");
        assert!(w[0].contains("rank 1 of 2"), "{w:?}");
    }

    /// `A x = b` by Gaussian elimination with partial pivoting (the tests' reference,
    /// independent of the crate's Cholesky); `None` when singular.
    fn gauss(n: usize, a: &[f64], b: &[f64]) -> Option<Vec<f64>> {
        let mut m: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                let mut r = a[i * n..(i + 1) * n].to_vec();
                r.push(b[i]);
                r
            })
            .collect();
        for c in 0..n {
            let p = (c..n).max_by(|&i, &j| m[i][c].abs().total_cmp(&m[j][c].abs()))?;
            if m[p][c].abs() < 1e-300 {
                return None;
            }
            m.swap(c, p);
            let pivot = m[c].clone();
            for (r, row) in m.iter_mut().enumerate() {
                if r != c {
                    let f = row[c] / pivot[c];
                    for (v, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                        *v -= f * p;
                    }
                }
            }
        }
        Some((0..n).map(|i| m[i][n] / m[i][i]).collect())
    }

    /// The shape is the Gram matrix scaled to trace m; the identity without a trace.
    #[test]
    fn the_function_shape_is_the_gram_matrix_of_trace_m() {
        let g = [2.0, 1.0, 0.5, 1.0, 4.0, 0.0, 0.5, 0.0, 0.0];
        let s = function_shape(3, &g);
        for (a, b) in s.iter().zip(&g) {
            assert!((a - b * 0.5).abs() < 1e-15, "{s:?}");
        }
        assert_eq!(function_shape(2, &[0.0; 4]), vec![1.0, 0.0, 0.0, 1.0]);
    }

    /// The identity shape gives the plain ridge's normal equations bit for bit.
    #[test]
    fn the_identity_shape_is_the_plain_ridge() {
        let m = 4;
        let rows = [0.3, 1.0, 0.2, 0.7, 0.3, 0.1, 0.9, 0.4];
        let (y, w) = ([0.8, 0.5], [1.0, 2.5]);
        let mean = [0.2, 0.3, 0.2, 0.2];
        let lambda = 0.05;
        // Identity shape: the plain ridge (diagonal mu, h + mu mean) bit for bit.
        let eye: Vec<f64> = (0..m * m)
            .map(|i| if i % (m + 1) == 0 { 1.0 } else { 0.0 })
            .collect();
        let shaped = solve_rows_toward(
            m,
            &rows,
            &y,
            &w,
            Some(Toward {
                mean: &mean,
                shape: &eye,
                lambda,
                energy: None,
            }),
        )
        .unwrap();
        let mut g = vec![0.0; m * m];
        let mut h = vec![0.0; m];
        let mut bb = 0.0;
        for ((row, &yv), &wv) in rows.chunks_exact(m).zip(&y).zip(&w) {
            for i in 0..m {
                let wi = wv * row[i];
                h[i] += wi * yv;
                for j in 0..=i {
                    g[i * m + j] += wi * row[j];
                }
            }
            bb += wv * yv * yv;
        }
        for i in 0..m {
            for j in 0..i {
                g[j * m + i] = g[i * m + j];
            }
        }
        let mu = lambda * (0..m).map(|i| g[i * m + i]).sum::<f64>() / m as f64;
        for i in 0..m {
            g[i * m + i] += mu;
            h[i] += mu * mean[i];
            bb += mu * mean[i] * mean[i];
        }
        let plain = lawson_hanson::solve(
            &GramProblem::new(m, &g, &h, bb).unwrap(),
            &lawson_hanson::LhParams::default(),
        )
        .unwrap();
        assert_eq!(shaped.x, plain.x);
        assert_eq!(shaped.objective.to_bits(), plain.objective.to_bits());
    }

    /// With fewer samples than columns, the ridge's solution is the exact optimum of the
    /// penalised problem (every active set enumerated in f64).
    #[test]
    fn the_shaped_ridge_reaches_the_penalised_optimum() {
        let m = 4;
        let rows = [0.3, 1.0, 0.2, 0.7, 0.3, 0.1, 0.9, 0.4];
        let (y, w) = ([0.8, 0.5], [1.0, 2.5]);
        let mean = [0.2, 0.3, 0.2, 0.2];
        // A positive-definite shape with off-diagonal terms (a Gram matrix of 5 rows).
        let f: [[f64; 4]; 5] = [
            [0.1, 0.5, 0.0, 0.2],
            [0.2, 0.1, 0.4, 0.0],
            [0.0, 0.3, 0.3, 0.6],
            [0.4, 0.0, 0.1, 0.1],
            [0.3, 0.6, 0.2, 0.1],
        ];
        let mut gram = vec![0.0; m * m];
        for r in &f {
            for i in 0..m {
                for j in 0..m {
                    gram[i * m + j] += r[i] * r[j];
                }
            }
        }
        let shape = function_shape(m, &gram);
        let lambda = 0.05;
        let got = solve_rows_toward(
            m,
            &rows,
            &y,
            &w,
            Some(Toward {
                mean: &mean,
                shape: &shape,
                lambda,
                energy: None,
            }),
        )
        .unwrap()
        .x;
        // The quadratic x^T Q x - 2 b^T x of the penalised problem, built here.
        let mut q = vec![0.0; m * m];
        let mut b = vec![0.0; m];
        for (r, (yv, wv)) in rows.chunks(m).zip(y.iter().zip(w)) {
            for i in 0..m {
                b[i] += wv * r[i] * yv;
                for j in 0..m {
                    q[i * m + j] += wv * r[i] * r[j];
                }
            }
        }
        let mu = lambda * (0..m).map(|i| q[i * m + i]).sum::<f64>() / m as f64;
        for i in 0..m {
            for j in 0..m {
                q[i * m + j] += mu * shape[i * m + j];
                b[i] += mu * shape[i * m + j] * mean[j];
            }
        }
        let f = |x: &[f64]| -> f64 {
            let mut v = 0.0;
            for i in 0..m {
                v -= 2.0 * b[i] * x[i];
                for j in 0..m {
                    v += x[i] * q[i * m + j] * x[j];
                }
            }
            v
        };
        let mut best: Option<(f64, Vec<f64>)> = None;
        for set in 0u32..(1 << m) {
            let p: Vec<usize> = (0..m).filter(|i| set >> i & 1 == 1).collect();
            let qp: Vec<f64> = p
                .iter()
                .flat_map(|&i| p.iter().map(move |&j| (i, j)))
                .map(|(i, j)| q[i * m + j])
                .collect();
            let bp: Vec<f64> = p.iter().map(|&i| b[i]).collect();
            let Some(xp) = gauss(p.len(), &qp, &bp) else {
                continue;
            };
            if xp.iter().any(|&v| v < 0.0) {
                continue;
            }
            let mut x = vec![0.0; m];
            p.iter().zip(&xp).for_each(|(&i, &v)| x[i] = v);
            if best.as_ref().is_none_or(|(fb, _)| f(&x) < *fb) {
                best = Some((f(&x), x));
            }
        }
        let (_, want) = best.unwrap();
        for (g, e) in got.iter().zip(&want) {
            assert!((g - e).abs() < 1e-10, "{got:?} vs {want:?}");
        }
    }
}
