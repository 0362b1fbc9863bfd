//! Separable reductions for analytic lobes.
//!
//! On the MERL grid every analytic lobe is `L(c) = alpha + G(c) beta[i][j]` with
//! `alpha = kd / pi`, `beta[i][j] = ks (n + 1) / (8 pi) (cos theta_h_i)^n F(F0, cos theta_d_j)`
//! and the lobe-free cell factor `G(c) = 1 / (cos theta_d max(N.wi, N.wo))`. Weighted sums of
//! products of two lobes over any cell set therefore reduce to three per-(i, j) moment
//! tables of the cell set, `M_p[i][j] = sum_k w G^p` (p = 0, 1, 2):
//!
//! ```text
//! sum_c w L_a L_b = alpha_a alpha_b sum M_0 + alpha_a <beta_b, M_1> + alpha_b <beta_a, M_1>
//!                 + <beta_a beta_b, M_2>
//! ```
//!
//! so a Gram matrix over 894,396 cells costs 8,100 multiply-adds per entry, exactly in f64.
//! Residuals and absolute errors still run over the cells (no separation for |r|), but each
//! cell costs one multiply-add from the per-(i, j) tables of the fit and of the target.

use crate::brdf::LobeParams;
use crate::merl::{CellSet, GridTables};
use crate::merl::{N_TD, N_TH};
use rayon::prelude::*;

const NIJ: usize = N_TH * N_TD;

/// An analytic lobe in separable form.
#[derive(Clone, Debug)]
pub struct SeparableLobe {
    /// The constant term `kd / pi`.
    pub alpha: f64,
    /// `beta[i * 90 + j]`.
    pub beta: Vec<f64>,
}

impl SeparableLobe {
    /// The separable form of `l` (f64 from the f32 parameters).
    pub fn new(t: &GridTables, l: &LobeParams) -> Self {
        let (f0, n) = (l.f0 as f64, l.n as f64);
        let coef = l.ks as f64 * (n + 1.0) / (8.0 * std::f64::consts::PI);
        let mut beta = vec![0.0; NIJ];
        for i in 0..N_TH {
            let p = coef * (n * t.ln_cos_h[i]).exp();
            for j in 0..N_TD {
                beta[i * N_TD + j] = p * (f0 + (1.0 - f0) * t.schlick_d[j]);
            }
        }
        Self {
            alpha: l.kd as f64 * std::f64::consts::FRAC_1_PI,
            beta,
        }
    }

    /// `sum_k x_k lobe_k`.
    pub fn combination(lobes: &[&SeparableLobe], x: &[f64]) -> Self {
        let mut out = Self {
            alpha: 0.0,
            beta: vec![0.0; NIJ],
        };
        for (l, &a) in lobes.iter().zip(x) {
            if a != 0.0 {
                out.alpha += a * l.alpha;
                out.beta
                    .iter_mut()
                    .zip(&l.beta)
                    .for_each(|(o, b)| *o += a * b);
            }
        }
        out
    }
}

/// Per-cell factors and per-(i, j) moments of a cell set.
#[derive(Clone, Debug)]
pub struct CellMoments {
    /// `sum_c w`.
    pub total: f64,
    /// `M_1[i * 90 + j] = sum_k w G`.
    pub m1: Vec<f64>,
    /// `M_2[i * 90 + j] = sum_k w G^2`.
    pub m2: Vec<f64>,
    /// `G` of each cell of the set, in order.
    pub g: Vec<f64>,
    /// `i * 90 + j` of each cell.
    pub ij: Vec<u16>,
    /// Weight of each cell.
    pub w: Vec<f64>,
}

impl CellMoments {
    /// Moments of `cells` (weights as given, normalised or not).
    pub fn new(t: &GridTables, cells: &CellSet) -> Self {
        let mut m1 = vec![0.0; NIJ];
        let mut m2 = vec![0.0; NIJ];
        let mut g = Vec::with_capacity(cells.len());
        let mut ij = Vec::with_capacity(cells.len());
        for (&c, &w) in cells.cells.iter().zip(&cells.weights) {
            let (e, gc) = t.cell_factor(c as usize);
            m1[e] += w * gc;
            m2[e] += w * gc * gc;
            g.push(gc);
            ij.push(e as u16);
        }
        Self {
            total: cells.weights.iter().sum(),
            m1,
            m2,
            g,
            ij,
            w: cells.weights.clone(),
        }
    }

    /// `sum_c w L_a L_b`.
    pub fn dot(&self, a: &SeparableLobe, b: &SeparableLobe) -> f64 {
        let (mut s1a, mut s1b, mut s2) = (0.0, 0.0, 0.0);
        for e in 0..NIJ {
            s1a += a.beta[e] * self.m1[e];
            s1b += b.beta[e] * self.m1[e];
            s2 += a.beta[e] * b.beta[e] * self.m2[e];
        }
        a.alpha * b.alpha * self.total + a.alpha * s1b + b.alpha * s1a + s2
    }

    /// The full symmetric Gram matrix of `lobes` for every pair with `i < basis` or
    /// `j < basis`, and the diagonal (the layout of `Backend::gram`).
    pub fn gram(&self, lobes: &[SeparableLobe], basis: usize) -> Vec<f64> {
        let n = lobes.len();
        let pairs: Vec<(usize, usize)> = (0..n)
            .flat_map(|i| (i..n).map(move |j| (i, j)))
            .filter(|&(i, j)| i < basis || i == j)
            .collect();
        let vals: Vec<f64> = pairs
            .par_iter()
            .map(|&(i, j)| self.dot(&lobes[i], &lobes[j]))
            .collect();
        let mut out = vec![0.0; n * n];
        for (&(i, j), v) in pairs.iter().zip(vals) {
            out[i * n + j] = v;
            out[j * n + i] = v;
        }
        out
    }

    /// The weighted errors of `r = fit - target` over the cells.
    pub fn errors(&self, fit: &SeparableLobe, target: &SeparableLobe) -> CellErrors {
        let da = fit.alpha - target.alpha;
        let db: Vec<f64> = fit
            .beta
            .iter()
            .zip(&target.beta)
            .map(|(a, b)| a - b)
            .collect();
        let (mut sq, mut ab) = (0.0, 0.0);
        for ((&g, &e), &w) in self.g.iter().zip(&self.ij).zip(&self.w) {
            let r = da + g * db[e as usize];
            sq += w * r * r;
            ab += w * r.abs();
        }
        CellErrors {
            squared: sq,
            absolute: ab,
        }
    }
}

/// Weighted errors over a cell set ([`CellMoments::errors`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellErrors {
    /// `sum_s w_s r(s)^2`.
    pub squared: f64,
    /// `sum_s w_s |r(s)|`.
    pub absolute: f64,
}
