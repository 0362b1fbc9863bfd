//! Empirical basis selection (the paper's Algorithm 1, leave-one-out): every material is
//! fitted by all the others; each material that contributes (a coefficient > 0 in some
//! channel) gets a count; the basis is the materials counted more than a threshold.

use crate::backend::weighted::TargetWeight;
use crate::backend::{Backend, Progress};
use crate::collection::Collection;
use crate::fit::{
    collection_lobes, fit_cells, separable_lobes, CollectionGrams, FitError, FitParams,
};
use crate::merl::GridTables;
use crate::nnls::lawson_hanson::{self, LeaveOneOut};
use crate::nnls::NnlsError;
use crate::separable::{CellMoments, SeparableLobe};

use super::objective::shared_weight_grams;
use super::SelectionError;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Parameters of the empirical selection.
#[derive(Clone, Debug)]
pub struct EmpiricalParams {
    /// Fit settings (mask, weighting, stride, objective; the solver is always exact here).
    pub fit: FitParams,
    /// A material enters the basis when it contributes to more than this many fits
    /// (paper: 5).
    pub more_than: usize,
}

impl Default for EmpiricalParams {
    fn default() -> Self {
        Self {
            fit: FitParams::default(),
            more_than: 5,
        }
    }
}

/// Result of the empirical selection.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Empirical {
    /// Contributions of each material (collection order).
    pub histogram: BTreeMap<String, usize>,
    /// For each target, the materials that contributed to its fit (collection order).
    pub contributors: BTreeMap<String, Vec<String>>,
    /// Materials counted more than the threshold, most frequent first (ties: collection
    /// order).
    pub basis: Vec<String>,
    /// Counts in collection order.
    pub counts: Vec<usize>,
}

/// Runs Algorithm 1 on `coll`: the Gram matrices of all materials, then one exact
/// rank-deficiency-safe NNLS per target and channel, all sharing the channel's scaled Gram
/// matrix ([`LeaveOneOut`]). A failed solve is an error naming the material.
///
/// Under `l2` (SPEC 5, the paper's) the Gram matrices are the closed form of an analytic
/// collection, else one grid pass of the back-end for the three channels. Under
/// `relative` or `log` (`p.fit.objective`, SPEC 11) they carry the selection's shared
/// weights (the median material's weight per cell and channel, as greedy, swap and ga
/// score): one back-end pass per channel, and the leave-one-out fits cost what they cost
/// under `l2`.
pub fn empirical(
    backend: &dyn Backend,
    coll: &Collection,
    p: &EmpiricalParams,
    progress: Progress<'_>,
) -> Result<Empirical, SelectionError> {
    let n = coll.len();
    if n < 2 {
        return Err(FitError::EmptyBasis.into());
    }
    let objective = p.fit.objective;
    if objective != TargetWeight::L2 {
        let all: Vec<usize> = (0..n).collect();
        let cells = fit_cells(coll, &all, &p.fit)?;
        if cells.is_empty() {
            return Err(FitError::NoCells {
                mask: p.fit.mask,
                stride: p.fit.stride,
            }
            .into());
        }
        let grams = shared_weight_grams(backend, coll, &cells, objective, progress)?;
        return Ok(empirical_from_grams(coll, p, &grams)?);
    }
    if CollectionGrams::needed(coll, p.fit.gram) {
        let g = CollectionGrams::grid(backend, coll, &p.fit, progress)?;
        return Ok(empirical_from_grams(coll, p, &g.grams)?);
    }
    let all: Vec<usize> = (0..n).collect();
    let cells = fit_cells(coll, &all, &p.fit)?;
    let mom = CellMoments::new(&GridTables::new(), &cells);
    let fulls = collection_lobes(coll).map(|lobes| {
        let sep = separable_lobes(&lobes).expect("every lobe of an analytic collection");
        separable_gram_all(&mom, &sep)
    });
    Ok(empirical_from_grams(coll, p, &fulls)?)
}

/// Algorithm 1 from the Gram matrices of `coll` per channel (`(N + 1)^2`, the Lambertian
/// column then every material: [`CollectionGrams`], over the cells of `p.fit`).
pub(crate) fn empirical_from_grams(
    coll: &Collection,
    p: &EmpiricalParams,
    fulls: &[Vec<f64>; 3],
) -> Result<Empirical, FitError> {
    let n = coll.len();
    if n < 2 {
        return Err(FitError::EmptyBasis);
    }
    let names = coll.names();
    let mut contributes = vec![vec![false; n]; n];
    let lh = lawson_hanson::LhParams::default();
    for (c, full) in fulls.iter().enumerate() {
        let rows = leave_one_out_contributors(full, &names, c, &lh)?;
        for (t, r) in rows.into_iter().enumerate() {
            for (j, u) in r.into_iter().enumerate() {
                contributes[t][j] |= u;
            }
        }
    }
    let counts: Vec<usize> = (0..n)
        .map(|j| (0..n).filter(|&t| contributes[t][j]).count())
        .collect();
    let mut order: Vec<usize> = (0..n).filter(|&j| counts[j] > p.more_than).collect();
    order.sort_by_key(|&j| (std::cmp::Reverse(counts[j]), j));
    Ok(Empirical {
        histogram: names.iter().cloned().zip(counts.iter().copied()).collect(),
        contributors: (0..n)
            .map(|t| {
                (
                    names[t].clone(),
                    (0..n)
                        .filter(|&j| contributes[t][j])
                        .map(|j| names[j].clone())
                        .collect(),
                )
            })
            .collect(),
        basis: order.into_iter().map(|j| names[j].clone()).collect(),
        counts,
    })
}

/// One channel of Algorithm 1 from its full Gram matrix: `full` is `(n + 1) x (n + 1)`
/// over the Lambertian column then the `n` materials `names`; returns, for each target
/// `t`, which materials have a positive coefficient when `t` is fitted by the Lambertian
/// and all the others. A non-finite Gram entry, or a solve that stops at the outer-loop
/// cap without meeting the KKT conditions (violation above `1e-6`), is an error naming the
/// material.
pub(crate) fn leave_one_out_contributors(
    full: &[f64],
    names: &[String],
    channel: usize,
    lh: &lawson_hanson::LhParams,
) -> Result<Vec<Vec<bool>>, FitError> {
    let n = names.len();
    let m1 = n + 1;
    let loo = LeaveOneOut::new(m1, full, lh).map_err(|e| {
        // Name the material of the offending row (row 0 is the Lambertian column).
        let idx = match &e {
            NnlsError::NonFinite { row, col, .. } => Some(if *row > 0 { *row } else { *col }),
            NnlsError::NegativeDiagonal { index, .. } => Some(*index),
            _ => None,
        };
        let material = match idx {
            Some(i) if (1..m1).contains(&i) => names[i - 1].clone(),
            _ => "<Lambertian column>".into(),
        };
        FitError::Solve {
            material,
            channel,
            reason: e.to_string(),
        }
    })?;
    (0..n)
        .into_par_iter()
        .map(|t| {
            let sol = loo.solve(t + 1);
            let converged = sol.max_kkt_violation <= 1e-6;
            if sol.iterations >= loo.outer_cap() && !converged {
                return Err(FitError::Solve {
                    material: names[t].clone(),
                    channel,
                    reason: format!(
                        "Lawson-Hanson stopped at its cap of {} outer loops with KKT violation {:.3e}",
                        loo.outer_cap(),
                        sol.max_kkt_violation
                    ),
                });
            }
            Ok((0..n).map(|j| j != t && sol.x[j + 1] > 0.0).collect())
        })
        .collect()
}

/// The full Gram matrix of separable lobes (every pair), bit for bit equal to
/// [`CellMoments::gram`] with all lobes as basis: the same products in the same order
/// per entry (`sum_e (beta_a[e] beta_b[e]) M_2[e]` sequentially over `e`), but computed
/// as register tiles of 4 x 32 entries over a transposed copy of the betas, so the
/// `O(n^2 x 8,100)` inner sums run in SIMD lanes (one lane per entry, no re-association)
/// instead of one entry at a time with its per-lobe sums recomputed for every pair.
pub(crate) fn separable_gram_all(mom: &CellMoments, lobes: &[SeparableLobe]) -> Vec<f64> {
    const R: usize = 4;
    const Q: usize = 32;
    let n = lobes.len();
    let nij = mom.m1.len();
    // <beta_x, M_1>, sequential over e as in `CellMoments::dot`.
    let s1: Vec<f64> = lobes
        .par_iter()
        .map(|l| {
            let mut s = 0.0;
            for e in 0..nij {
                s += l.beta[e] * mom.m1[e];
            }
            s
        })
        .collect();
    let np = n.div_ceil(Q) * Q;
    let mut bt = vec![0.0; nij * np];
    bt.par_chunks_mut(np).enumerate().for_each(|(e, row)| {
        for (o, l) in row.iter_mut().zip(lobes) {
            *o = l.beta[e];
        }
    });
    let zeros = vec![0.0; nij];
    let blocks: Vec<Vec<f64>> = (0..n.div_ceil(R))
        .into_par_iter()
        .map(|blk| {
            let ia = blk * R;
            let a: [&[f64]; R] = std::array::from_fn(|r| {
                lobes
                    .get(ia + r)
                    .map_or(zeros.as_slice(), |l| l.beta.as_slice())
            });
            let mut rows = vec![0.0; R * n];
            for jb in (ia / Q * Q..np).step_by(Q) {
                let acc = gram_tile::<R, Q>(a, &bt, np, jb, &mom.m2);
                for (r, acc_r) in acc.iter().enumerate() {
                    let i = ia + r;
                    for (q, &s2) in acc_r.iter().enumerate() {
                        let j = jb + q;
                        if i < n && j < n && j >= i {
                            let (li, lj) = (&lobes[i], &lobes[j]);
                            rows[r * n + j] = li.alpha * lj.alpha * mom.total
                                + li.alpha * s1[j]
                                + lj.alpha * s1[i]
                                + s2;
                        }
                    }
                }
            }
            rows
        })
        .collect();
    let mut out = vec![0.0; n * n];
    for (blk, rows) in blocks.iter().enumerate() {
        for r in 0..R {
            let i = blk * R + r;
            if i >= n {
                break;
            }
            for j in i..n {
                let v = rows[r * n + j];
                out[i * n + j] = v;
                out[j * n + i] = v;
            }
        }
    }
    out
}

/// `acc[r][q] = sum_e (a[r][e] bt[e][jb + q]) m2[e]`, sequential over `e`.
fn gram_tile<const R: usize, const Q: usize>(
    a: [&[f64]; R],
    bt: &[f64],
    np: usize,
    jb: usize,
    m2: &[f64],
) -> [[f64; Q]; R] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: AVX2 was detected on this processor.
            return unsafe { gram_tile_avx2::<R, Q>(a, bt, np, jb, m2) };
        }
    }
    gram_tile_portable::<R, Q>(a, bt, np, jb, m2)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn gram_tile_avx2<const R: usize, const Q: usize>(
    a: [&[f64]; R],
    bt: &[f64],
    np: usize,
    jb: usize,
    m2: &[f64],
) -> [[f64; Q]; R] {
    gram_tile_portable::<R, Q>(a, bt, np, jb, m2)
}

/// Same operations in every lane: `(a * b) * m`, then `+=` (Rust never fuses them).
#[inline(always)]
fn gram_tile_portable<const R: usize, const Q: usize>(
    a: [&[f64]; R],
    bt: &[f64],
    np: usize,
    jb: usize,
    m2: &[f64],
) -> [[f64; Q]; R] {
    let mut acc = [[0.0f64; Q]; R];
    for (e, &m) in m2.iter().enumerate() {
        let o = e * np + jb;
        let Some(brow) = bt.get(o..o + Q) else { break };
        for r in 0..R {
            let av = a[r][e];
            for q in 0..Q {
                acc[r][q] += av * brow[q] * m;
            }
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collection::{parse_csv, Collection};
    use crate::nnls::GramProblem;

    /// 45 analytic materials, several near-duplicates (rank-deficient Gram matrices).
    fn collection() -> Collection {
        let mut csv = String::from("material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\n");
        for i in 0..45usize {
            let f = |k: usize| ((i * 37 + k * 11) % 17) as f64 / 17.0;
            let n = 2f64.powf(1.0 + (i % 15) as f64);
            csv.push_str(&format!(
                "m{i},{},{},{},{},{},{},{},{n}\n",
                0.3 * f(0),
                0.3 * f(1),
                0.3 * f(2),
                f(3),
                f(4),
                f(5),
                0.02 + 0.9 * f(6)
            ));
        }
        parse_csv(csv.as_bytes(), std::path::Path::new("t.csv")).expect("csv")
    }

    fn full_gram(coll: &Collection, c: usize, stride: usize) -> (Vec<f64>, Vec<SeparableLobe>) {
        let all: Vec<usize> = (0..coll.len()).collect();
        let fp = FitParams {
            stride,
            ..Default::default()
        };
        let cells = fit_cells(coll, &all, &fp).expect("stride >= 1");
        let lobes = collection_lobes(coll);
        let sep = separable_lobes(&lobes[c]).expect("analytic");
        let mom = CellMoments::new(&GridTables::new(), &cells);
        (mom.gram(&sep, sep.len()), sep)
    }

    #[test]
    fn tiled_separable_gram_is_bit_identical_to_the_entrywise_one() {
        let coll = collection();
        for stride in [3, 5] {
            let all: Vec<usize> = (0..coll.len()).collect();
            let fp = FitParams {
                stride,
                ..Default::default()
            };
            let cells = fit_cells(&coll, &all, &fp).expect("stride >= 1");
            let mom = CellMoments::new(&GridTables::new(), &cells);
            for c in 0..3 {
                let (want, sep) = full_gram(&coll, c, stride);
                // Sizes around the 4 x 32 tile: partial row and column tiles.
                for n in [1, 5, 33, sep.len()] {
                    let got = separable_gram_all(&mom, &sep[..n]);
                    let m = sep.len();
                    for i in 0..n {
                        for j in 0..n {
                            assert_eq!(
                                got[i * n + j].to_bits(),
                                want[i * m + j].to_bits(),
                                "stride {stride} channel {c} n {n} ({i}, {j})"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn shared_gram_leave_one_out_equals_solving_each_sub_problem() {
        let coll = collection();
        let names = coll.names();
        let n = names.len();
        let m1 = n + 1;
        let lh = lawson_hanson::LhParams::default();
        for c in 0..3 {
            let (full, _) = full_gram(&coll, c, 4);
            let loo = LeaveOneOut::new(m1, &full, &lh).expect("loo");
            let fast = leave_one_out_contributors(&full, &names, c, &lh).expect("fast");
            for t in 0..n {
                // The sub-problem as the paper states it: G without row/column t + 1.
                let cols: Vec<usize> = std::iter::once(0)
                    .chain((0..n).filter(|&j| j != t).map(|j| j + 1))
                    .collect();
                let m = cols.len();
                let g: Vec<f64> = cols
                    .iter()
                    .flat_map(|&a| cols.iter().map(move |&b| (a, b)))
                    .map(|(a, b)| full[a * m1 + b])
                    .collect();
                let h: Vec<f64> = cols.iter().map(|&a| full[a * m1 + t + 1]).collect();
                let bb = full[(t + 1) * m1 + t + 1];
                let want = lawson_hanson::solve(&GramProblem::new(m, &g, &h, bb).expect("p"), &lh)
                    .expect("solve");
                let got = loo.solve(t + 1);
                for (k, &col) in cols.iter().enumerate() {
                    assert_eq!(got.x[col].to_bits(), want.x[k].to_bits(), "c {c} t {t}");
                }
                assert_eq!(got.x[t + 1], 0.0);
                assert_eq!(got.iterations, want.iterations);
                assert!((got.objective - want.objective).abs() <= 1e-12 * bb.max(1e-300));
                assert!((got.max_kkt_violation - want.max_kkt_violation).abs() <= 1e-12);
                let used: Vec<bool> = (0..n)
                    .map(|j| j != t && want.x[k_of(&cols, j)] > 0.0)
                    .collect();
                assert_eq!(fast[t], used, "c {c} t {t}");
            }
        }
        fn k_of(cols: &[usize], j: usize) -> usize {
            cols.iter().position(|&c| c == j + 1).unwrap_or(0)
        }
    }

    #[test]
    fn a_failed_solve_is_an_error_naming_the_material() {
        let coll = collection();
        let names = coll.names();
        let lh = lawson_hanson::LhParams::default();
        let (mut full, _) = full_gram(&coll, 1, 4);
        let m1 = names.len() + 1;
        // Material 7's data is NaN: its Gram row and column are.
        for k in 0..m1 {
            full[8 * m1 + k] = f64::NAN;
            full[k * m1 + 8] = f64::NAN;
        }
        let e = leave_one_out_contributors(&full, &names, 1, &lh).expect_err("NaN");
        let msg = e.to_string();
        assert!(
            matches!(&e, FitError::Solve { material, channel: 1, .. } if material == "m7"),
            "{msg}"
        );
        assert!(msg.contains("`m7`"), "{msg}");
        // A solver stopped at its cap before meeting the KKT conditions.
        let (full, _) = full_gram(&coll, 0, 4);
        let capped = lawson_hanson::LhParams {
            max_outer: Some(1),
            ..lh
        };
        let e = leave_one_out_contributors(&full, &names, 0, &capped).expect_err("cap");
        assert!(
            matches!(&e, FitError::Solve { material, channel: 0, reason }
                if names.contains(material) && reason.contains("cap")),
            "{e}"
        );
    }
}
