//! Neural BRDFs (Sztrajman et al. 2021, SPEC 9): a 6-21-21-3 network per material,
//! `f = max(exp(a2 . fc3 + b3) - 1, 0)`, `a2 = relu(a1 . fc2 + b2)`,
//! `a1 = relu(x . fc1 + b1)`, `x = (sin th, 0, cos th, sin td cos pd, sin td sin pd, cos td)`.
//!
//! Two evaluations: [`Nbrdf::eval_f64`], the f64 reference, and the fast f32 twin
//! [`Nbrdf::eval_cells`] that every back-end tabulates with. The twin runs
//! [`LANES`] cells at once in struct-of-arrays layout (every loop over the lanes is a
//! fixed-length array loop that LLVM turns into vector code; on x86-64 with AVX2 and FMA,
//! detected at run time, into 8-wide fused multiply-adds), and computes `exp(z) - 1` as an
//! accurate `expm1` (a few ulps), so the cancellation of `exp(z) - 1` near `z = 0` costs no
//! accuracy: SPEC 9 asks 5e-4 relative where the value exceeds 1e-3, 1e-6 absolute below.

/// Weights of one network (f32): `fc1` 6 x 21, `b1` 21, `fc2` 21 x 21, `b2` 21, `fc3`
/// 21 x 3, `b3` 3.
pub const NBRDF_WEIGHTS: usize = 675;

/// Hidden units per layer.
pub const HIDDEN: usize = 21;

/// The six parts of a network: (file suffix, shape, offset in the flat layout), in the
/// order of the flat layout.
pub const NBRDF_PARTS: [(&str, &[usize], usize); 6] = [
    ("fc1", &[6, HIDDEN], 0),
    ("b1", &[HIDDEN], 126),
    ("fc2", &[HIDDEN, HIDDEN], 147),
    ("b2", &[HIDDEN], 588),
    ("fc3", &[HIDDEN, 3], 609),
    ("b3", &[3], 672),
];

const FC1: usize = 0;
const B1: usize = 126;
const FC2: usize = 147;
const B2: usize = 588;
const FC3: usize = 609;
const B3: usize = 672;

/// One neural BRDF: its weights in the flat layout of [`NBRDF_PARTS`].
#[derive(Clone, PartialEq)]
pub struct Nbrdf {
    w: Vec<f32>,
}

impl std::fmt::Debug for Nbrdf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Nbrdf {{ {} weights }}", self.w.len())
    }
}

/// Cells evaluated together by the f32 twin (one AVX2 register of f32).
pub const LANES: usize = 8;
type V = [f32; LANES];

/// Network inputs of one cell in f32 (the zero input dropped):
/// `(sin th, cos th, sin td cos pd, sin td sin pd, cos td)`, computed in f64, rounded once.
pub fn features(th: f64, td: f64, pd: f64) -> [f32; 5] {
    let (sh, ch) = th.sin_cos();
    let (sd, cd) = td.sin_cos();
    let (sp, cp) = pd.sin_cos();
    [sh, ch, sd * cp, sd * sp, cd].map(|v| v as f32)
}

/// [`features`] of every cell of the MERL grid, from per-row tables (the cell centres of
/// SPEC 2): `(sin th, cos th)` per `i`, the three `d` inputs per `(j, k)`.
struct GridFeatures {
    h: Vec<[f32; 2]>,
    d: Vec<[f32; 3]>,
}

fn grid_features() -> &'static GridFeatures {
    use crate::merl::grid::{phi_d, theta_d, theta_h, N_PD, N_TD, N_TH};
    static G: std::sync::OnceLock<GridFeatures> = std::sync::OnceLock::new();
    G.get_or_init(|| {
        let h = (0..N_TH)
            .map(|i| {
                let f = features(theta_h(i), 0.0, 0.0);
                [f[0], f[1]]
            })
            .collect();
        let d = (0..N_TD * N_PD)
            .map(|jk| {
                let f = features(0.0, theta_d(jk / N_PD), phi_d(jk % N_PD));
                [f[2], f[3], f[4]]
            })
            .collect();
        GridFeatures { h, d }
    })
}

/// [`features`] of a flat grid cell (at its centre, SPEC 2).
#[inline]
pub fn cell_features(cell: usize) -> [f32; 5] {
    use crate::merl::grid::{N_PD, N_TD};
    let g = grid_features();
    let h = g.h[cell / (N_TD * N_PD)];
    let d = g.d[cell % (N_TD * N_PD)];
    [h[0], h[1], d[0], d[1], d[2]]
}

impl Nbrdf {
    /// A network from its flat weights ([`NBRDF_PARTS`] layout): exactly
    /// [`NBRDF_WEIGHTS`] finite values.
    pub fn from_weights(flat: Vec<f32>) -> Result<Self, String> {
        if flat.len() != NBRDF_WEIGHTS {
            return Err(format!(
                "{} weights, a neural BRDF has {NBRDF_WEIGHTS} (6x21 + 21 + 21x21 + 21 + 21x3 + 3)",
                flat.len()
            ));
        }
        if let Some(i) = flat.iter().position(|v| !v.is_finite()) {
            let (part, _, off) = NBRDF_PARTS
                .iter()
                .rev()
                .find(|p| p.2 <= i)
                .expect("offset 0 starts the first part");
            return Err(format!(
                "weight {} of `{part}` is not a finite number ({})",
                i - off,
                flat[i]
            ));
        }
        Ok(Self { w: flat })
    }

    /// The flat weights ([`NBRDF_PARTS`] layout).
    pub fn weights(&self) -> &[f32] {
        &self.w
    }

    /// The network's raw RGB output `exp(z) - 1` (not clamped) in f64 from the f32
    /// weights: the reference of every evaluation.
    pub fn eval_raw_f64(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3] {
        let w = |k: usize| self.w[k] as f64;
        let x = [
            theta_h.sin(),
            0.0,
            theta_h.cos(),
            theta_d.sin() * phi_d.cos(),
            theta_d.sin() * phi_d.sin(),
            theta_d.cos(),
        ];
        let mut a1 = [0f64; HIDDEN];
        for (j, a) in a1.iter_mut().enumerate() {
            let z: f64 = w(B1 + j) + (0..6).map(|i| x[i] * w(FC1 + i * HIDDEN + j)).sum::<f64>();
            *a = z.max(0.0);
        }
        let mut a2 = [0f64; HIDDEN];
        for (j, a) in a2.iter_mut().enumerate() {
            let z: f64 = w(B2 + j)
                + (0..HIDDEN)
                    .map(|i| a1[i] * w(FC2 + i * HIDDEN + j))
                    .sum::<f64>();
            *a = z.max(0.0);
        }
        std::array::from_fn(|c| {
            let z: f64 = w(B3 + c) + (0..HIDDEN).map(|i| a2[i] * w(FC3 + i * 3 + c)).sum::<f64>();
            z.exp_m1()
        })
    }

    /// RGB reflectance at half/difference angles (SPEC 9), f64 reference, clamped at 0.
    pub fn eval_f64(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3] {
        self.eval_raw_f64(theta_h, theta_d, phi_d)
            .map(|v| v.max(0.0))
    }

    /// RGB reflectance at a direction pair (unit vectors, local frame): the angles of
    /// [`crate::merl::grid::half_diff`], then [`Self::eval_f64`]. Below the horizon
    /// (`wi.z <= 0` or `wo.z <= 0`) a BRDF is 0, and so is this (the network's raw output
    /// there means nothing).
    pub fn eval_dirs(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let (th, td, pd) = crate::merl::grid::half_diff(wi, wo);
        self.eval_f64(th, td, pd)
    }

    /// The f32 twin at the flat grid cells `cells`: RGB into `out[c][n]` (`out` rows of at
    /// least `cells.len()`), clamped at 0 (`clamp`) or raw.
    pub fn eval_cells(&self, cells: &[u32], clamp: bool, out: [&mut [f32]; 3]) {
        self.eval_with(
            cells.len(),
            |n| cell_features(cells[n] as usize),
            clamp,
            out,
        )
    }

    /// The f32 twin at given features ([`features`]); as [`Self::eval_cells`].
    pub fn eval_features(&self, feats: &[[f32; 5]], clamp: bool, out: [&mut [f32]; 3]) {
        self.eval_with(feats.len(), |n| feats[n], clamp, out)
    }

    fn eval_with(
        &self,
        len: usize,
        feat: impl Fn(usize) -> [f32; 5],
        clamp: bool,
        out: [&mut [f32]; 3],
    ) {
        let fast = fma_available();
        let [r, g, b] = out;
        for start in (0..len).step_by(LANES) {
            let m = (len - start).min(LANES);
            let mut x = [[0f32; LANES]; 5];
            for l in 0..m {
                let f = feat(start + l);
                for (xi, fi) in x.iter_mut().zip(f) {
                    xi[l] = fi;
                }
            }
            let y = forward_dispatch(&self.w, &x, fast);
            for (o, yc) in [&mut *r, &mut *g, &mut *b].into_iter().zip(y) {
                for l in 0..m {
                    // NaN cannot arise from finite weights; `> 0` keeps 0 for it anyway.
                    let keep = !clamp || yc[l] > 0.0;
                    o[start + l] = if keep { yc[l] } else { 0.0 };
                }
            }
        }
    }
}

fn fma_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[inline(always)]
fn forward_dispatch(w: &[f32], x: &[V; 5], fast: bool) -> [V; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        if fast {
            // SAFETY: AVX2 and FMA were detected on this processor (`fma_available`).
            return unsafe { forward_avx2(w, x) };
        }
    }
    let _ = fast;
    forward::<false>(w, x)
}

/// [`forward`] compiled for AVX2 with fused multiply-adds.
///
/// # Safety
/// The processor must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn forward_avx2(w: &[f32], x: &[V; 5]) -> [V; 3] {
    forward::<true>(w, x)
}

/// `a b + c`, fused when `FMA` (only in code compiled with the FMA feature: elsewhere
/// `mul_add` would be a library call).
#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

#[inline(always)]
fn relu(v: V) -> V {
    v.map(|x| if x > 0.0 { x } else { 0.0 })
}

/// Output units of layer 2 accumulated together (7 x 8 lanes: seven independent chains of
/// fused multiply-adds in registers; 21 = 3 x 7).
const J_BLOCK: usize = 7;

/// The network on [`LANES`] cells at once: inputs `x` (struct of arrays, the five
/// non-zero inputs), raw outputs `exp(z) - 1` per channel.
#[inline(always)]
fn forward<const FMA: bool>(w: &[f32], x: &[V; 5]) -> [V; 3] {
    let w = &w[..NBRDF_WEIGHTS];
    // Input rows of fc1 for the five non-zero inputs (row 1 multiplies the zero input).
    const ROWS: [usize; 5] = [0, 2, 3, 4, 5];
    let mut a1 = [[0f32; LANES]; HIDDEN];
    for (j, a) in a1.iter_mut().enumerate() {
        let mut acc = [w[B1 + j]; LANES];
        for (xi, &row) in x.iter().zip(&ROWS) {
            let wv = w[FC1 + row * HIDDEN + j];
            for l in 0..LANES {
                acc[l] = madd::<FMA>(xi[l], wv, acc[l]);
            }
        }
        *a = relu(acc);
    }
    let mut a2 = [[0f32; LANES]; HIDDEN];
    for jb in (0..HIDDEN).step_by(J_BLOCK) {
        let mut acc: [V; J_BLOCK] = std::array::from_fn(|jj| [w[B2 + jb + jj]; LANES]);
        for (i, a) in a1.iter().enumerate() {
            for (jj, acc) in acc.iter_mut().enumerate() {
                let wv = w[FC2 + i * HIDDEN + jb + jj];
                for l in 0..LANES {
                    acc[l] = madd::<FMA>(a[l], wv, acc[l]);
                }
            }
        }
        for (jj, acc) in acc.into_iter().enumerate() {
            a2[jb + jj] = relu(acc);
        }
    }
    let mut z: [V; 3] = std::array::from_fn(|c| [w[B3 + c]; LANES]);
    for (i, a) in a2.iter().enumerate() {
        for (c, z) in z.iter_mut().enumerate() {
            let wv = w[FC3 + i * 3 + c];
            for l in 0..LANES {
                z[l] = madd::<FMA>(a[l], wv, z[l]);
            }
        }
    }
    z.map(|zc| zc.map(expm1f::<FMA>))
}

/// `exp(z) - 1` in f32 to a few ulps, branch-free (vectorises): `z = n ln 2 + r`,
/// `|r| <= ln 2 / 2`, `expm1(r)` by its Taylor polynomial to degree 7 (truncation
/// < 2e-8 relative), then `expm1(z) = 2^n expm1(r) + (2^n - 1)`, where `2^n - 1` is exact
/// and the sum never cancels. `z` is clamped to [-88, 88] (beyond: -1, or ~2.4e38).
#[inline(always)]
pub fn expm1f<const FMA: bool>(z: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    // ln 2 = LN2_HI + LN2_LO, LN2_HI with 9 significant bits (n LN2_HI exact).
    const LN2_HI: f32 = 0.693_359_4;
    const LN2_LO: f32 = -2.121_944_4e-4;
    // 1.5 x 2^23: adding and subtracting it rounds to the nearest integer.
    const ROUND: f32 = 12_582_912.0;
    let z = z.clamp(-88.0, 88.0);
    let n = (z * LOG2E + ROUND) - ROUND;
    let r = madd::<FMA>(-n, LN2_HI, z);
    let r = madd::<FMA>(-n, LN2_LO, r);
    let mut p = 1.0 / 5040.0;
    for c in [1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5] {
        p = madd::<FMA>(p, r, c);
    }
    let p = madd::<FMA>(r * r, p, r);
    let s = f32::from_bits(((n as i32 + 127) as u32) << 23);
    madd::<FMA>(s, p, s - 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A network with seeded pseudo-random weights of about the trained networks' size.
    fn net(seed: u64) -> Nbrdf {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let w = (0..NBRDF_WEIGHTS)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 1.2
            })
            .collect();
        Nbrdf::from_weights(w).expect("finite")
    }

    #[test]
    fn expm1f_is_accurate_against_f64_over_its_range() {
        let mut worst = 0f64;
        for k in -200_000..=200_000 {
            let z = k as f32 * 1e-4 * (1.0 + (k as f32).abs() * 1e-5);
            let want = (z as f64).exp_m1();
            for got in [expm1f::<false>(z) as f64, expm1f::<true>(z) as f64] {
                worst = worst.max(((got - want) / want.abs().max(1e-30)).abs());
            }
        }
        assert!(worst < 4e-7, "worst relative error {worst}");
        assert_eq!(expm1f::<false>(0.0), 0.0);
        assert_eq!(expm1f::<false>(-1000.0), -1.0);
        assert!(expm1f::<false>(1000.0).is_finite());
    }

    #[test]
    fn f32_twin_matches_the_f64_network_within_spec_9() {
        let cells: Vec<u32> = (0..20_000u32).map(|k| k * 72 + k % 71).collect();
        for seed in 0..6 {
            let n = net(seed);
            let mut out = vec![vec![0f32; cells.len()]; 3];
            let [r, g, b] = &mut out[..] else {
                unreachable!()
            };
            n.eval_cells(&cells, false, [r, g, b]);
            for (k, &c) in cells.iter().enumerate() {
                let (th, td, pd) = crate::merl::grid::cell_angles(c as usize);
                let want = n.eval_raw_f64(th, td, pd);
                for ch in 0..3 {
                    let (got, want) = (out[ch][k] as f64, want[ch]);
                    let tol = if want.abs() > 1e-3 {
                        5e-4 * want.abs()
                    } else {
                        1e-6
                    };
                    assert!(
                        (got - want).abs() <= tol,
                        "seed {seed} cell {c} ch {ch}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn bad_weights_are_refused_with_the_part_named() {
        assert!(Nbrdf::from_weights(vec![0.0; 674])
            .unwrap_err()
            .contains("674"));
        let mut w = vec![0.0; NBRDF_WEIGHTS];
        w[600] = f32::NAN;
        let e = Nbrdf::from_weights(w).unwrap_err();
        assert!(e.contains("`b2`") && e.contains("weight 12"), "{e}");
    }

    #[test]
    fn directions_and_angles_agree_and_below_the_horizon_is_zero() {
        let n = net(3);
        for cell in [0usize, 12345, 700_000, 1_000_001] {
            let (th, td, pd) = crate::merl::grid::cell_angles(cell);
            let (wi, wo) = crate::merl::grid::cell_directions(cell);
            if wi[2] <= 0.0 || wo[2] <= 0.0 {
                assert_eq!(n.eval_dirs(wi, wo), [0.0; 3]);
                continue;
            }
            let a = n.eval_f64(th, td, pd);
            let b = n.eval_dirs(wi, wo);
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-9 * a[c].abs().max(1e-9), "{cell}");
            }
        }
    }
}
