//! The portable f32 block kernel of the networks ([`forward`], with its layer 1 and
//! [`expm1f`]): the operations `avx2` and `avx512` copy with intrinsics.

use super::*;

/// The network on a block of cells (`x.len()` vectors of [`LANES`], a multiple of [`RV`],
/// at most [`BLOCK_VECS`]; struct of arrays, the five non-zero inputs): raw outputs
/// `exp(z) - 1` per channel into `y`.
///
/// The same f32 operations in the same order as a dense pass (`acc = b`, then
/// `acc = x_i w_i + acc` for `i` ascending, per unit and lane), minus those that cannot
/// change a result, so the values are those of the dense pass bit for bit (up to the sign
/// of an exact zero before the clamp):
/// * a layer-1 unit that is 0 at every cell of the block (relu) adds `0 x w` (exactly
///   nothing) to each layer-2 sum: it is left out;
/// * a layer-2 unit whose pre-activation is provably <= 0 at every cell of the block is
///   0 after its relu, neither computed nor read by layer 3. The proof: interval bounds
///   from the block's range `[lo_i, hi_i]` of each layer-1 unit, `ub = b + sum_i
///   max(w_i lo_i, w_i hi_i) <= -1e-5 (|b| + sum_i |w_i| hi_i)`; the f32 sums (21 roundings
///   of at most 2^-24 of that magnitude, the bound's own likewise) stay below 0;
/// * when the block shares theta_h (grid runs), `b1 + x0 w0 + x1 w2` is the same f32
///   chain at every lane: computed once per unit.
///
/// On the 100 MERL networks, a block of 64 grid cells has on average 11.2 live layer-1
/// units and 9.8 layer-2 units not proven dead (of 21), so layer 2 (441 multiply-adds per
/// cell dense) costs about a quarter. `avx2::forward` is the same with intrinsics.
///
/// Long function: the three layers of the block kernel in one inlined body (the SIMD
/// copies follow it line for line), so that the pruning of dead units and the register
/// blocks read as the operations they skip.
#[inline(always)]
pub(super) fn forward<const FMA: bool>(
    w: &[f32; NBRDF_WEIGHTS],
    x: &[[V; 5]],
    y: &mut [[V; 3]],
    scratch: &mut Scratch,
) {
    let nv = x.len();
    assert!(nv.is_multiple_of(RV) && nv <= BLOCK_VECS && y.len() == nv);
    let Scratch { a1, a2, .. } = scratch;
    // Layer 1: a1 = relu(x . fc1 + b1) per vector, and each unit's range over the block.
    let mut hi = [[0f32; LANES]; HIDDEN];
    let mut lo = [[f32::MAX; LANES]; HIDDEN];
    let (h0, h1) = (x[0][0][0], x[0][1][0]);
    let shared = x.iter().all(|xv| {
        (0..LANES).all(|l| xv[0][l].to_bits() == h0.to_bits() && xv[1][l].to_bits() == h1.to_bits())
    });
    if shared {
        layer1::<FMA, true>(w, x, a1, &mut hi, &mut lo);
    } else {
        layer1::<FMA, false>(w, x, a1, &mut hi, &mut lo);
    }
    // The live layer-1 units (ascending) and their ranges.
    let mut live1 = [0usize; HIDDEN];
    let (mut hi1, mut lo1) = ([0f32; HIDDEN], [0f32; HIDDEN]);
    let mut n1 = 0;
    for j in 0..HIDDEN {
        let h = hi[j].iter().fold(0f32, |m, &v| if v > m { v } else { m });
        if h > 0.0 {
            live1[n1] = j;
            hi1[n1] = h;
            lo1[n1] = lo[j]
                .iter()
                .fold(f32::MAX, |m, &v| if v < m { v } else { m });
            n1 += 1;
        }
    }
    // Layer-2 units not provably dead on the block (ascending), padded to a multiple of
    // RU by repeating the last (computed twice, read once).
    let mut ub = [0f32; HIDDEN];
    let mut mag = [0f32; HIDDEN];
    for u in 0..HIDDEN {
        ub[u] = w[B2 + u];
        mag[u] = w[B2 + u].abs();
    }
    for s in 0..n1 {
        let row = &w[FC2 + live1[s] * HIDDEN..][..HIDDEN];
        for u in 0..HIDDEN {
            let (p, q) = (row[u] * hi1[s], row[u] * lo1[s]);
            ub[u] += p.max(q);
            mag[u] += p.abs();
        }
    }
    let mut live2 = [0usize; HIDDEN + RU];
    let mut n2 = 0;
    for u in 0..HIDDEN {
        if ub[u] > -PRUNE_MARGIN * mag[u] {
            live2[n2] = u;
            n2 += 1;
        }
    }
    let n2_pad = n2.next_multiple_of(RU);
    for s in n2..n2_pad {
        live2[s] = live2[n2 - 1];
    }
    (scratch.live1, scratch.hi1, scratch.n1) = (live1, hi1, n1);
    (scratch.live2, scratch.n2) = (live2, n2);
    // Layer 2 on the live units: a2[v][s] for unit live2[s].
    for g in (0..n2_pad).step_by(RU) {
        let u: [usize; RU] = std::array::from_fn(|t| live2[g + t]);
        for v0 in (0..nv).step_by(RV) {
            let mut acc = [[[0f32; LANES]; RU]; RV];
            for accv in acc.iter_mut() {
                for (t, acc) in accv.iter_mut().enumerate() {
                    *acc = [w[B2 + u[t]]; LANES];
                }
            }
            for &k in &live1[..n1] {
                let row = &w[FC2 + k * HIDDEN..][..HIDDEN];
                let wv: [f32; RU] = std::array::from_fn(|t| row[u[t]]);
                for (r, accv) in acc.iter_mut().enumerate() {
                    let a = &a1[v0 + r][k];
                    for (t, acc) in accv.iter_mut().enumerate() {
                        for l in 0..LANES {
                            acc[l] = madd::<FMA>(a[l], wv[t], acc[l]);
                        }
                    }
                }
            }
            for (r, accv) in acc.iter_mut().enumerate() {
                for (t, acc) in accv.iter_mut().enumerate() {
                    relu(acc);
                    a2[v0 + r][g + t] = *acc;
                }
            }
        }
    }
    // Layer 3 on the live layer-2 units, then expm1.
    for v0 in (0..nv).step_by(RV) {
        let mut z = [[[0f32; LANES]; 3]; RV];
        for zv in z.iter_mut() {
            for (c, z) in zv.iter_mut().enumerate() {
                *z = [w[B3 + c]; LANES];
            }
        }
        for s in 0..n2 {
            let wrow = &w[FC3 + live2[s] * 3..][..3];
            for (r, zv) in z.iter_mut().enumerate() {
                let a = &a2[v0 + r][s];
                for (c, z) in zv.iter_mut().enumerate() {
                    for l in 0..LANES {
                        z[l] = madd::<FMA>(a[l], wrow[c], z[l]);
                    }
                }
            }
        }
        for (r, zv) in z.iter().enumerate() {
            for (c, z) in zv.iter().enumerate() {
                for l in 0..LANES {
                    y[v0 + r][c][l] = expm1f::<FMA>(z[l]);
                }
            }
        }
    }
}

/// Layer 1 of [`forward`]: `a1 = relu(x . fc1 + b1)` per vector of `x`, and each unit's
/// per-lane maximum and minimum over the vectors into `hi`, `lo`. `SHARED`: every lane of
/// `x` has the first vector's theta_h inputs, and the chain's first two steps are done once.
#[inline(always)]
pub(super) fn layer1<const FMA: bool, const SHARED: bool>(
    w: &[f32; NBRDF_WEIGHTS],
    x: &[[V; 5]],
    a1: &mut [[V; HIDDEN]; BLOCK_VECS],
    hi: &mut [V; HIDDEN],
    lo: &mut [V; HIDDEN],
) {
    // Input rows of fc1 for the five non-zero inputs (row 1 multiplies the zero input).
    let (h0, h1) = (x[0][0][0], x[0][1][0]);
    let mut start = [0f32; HIDDEN];
    for (j, s) in start.iter_mut().enumerate() {
        *s = madd::<FMA>(
            h1,
            w[FC1 + 2 * HIDDEN + j],
            madd::<FMA>(h0, w[FC1 + j], w[B1 + j]),
        );
    }
    for (xv, a1v) in x.iter().zip(a1.iter_mut()) {
        for j in 0..HIDDEN {
            let mut acc = [if SHARED { start[j] } else { w[B1 + j] }; LANES];
            for i in if SHARED { 2 } else { 0 }..5 {
                let wv = w[FC1 + FC1_ROWS[i] * HIDDEN + j];
                for l in 0..LANES {
                    acc[l] = madd::<FMA>(xv[i][l], wv, acc[l]);
                }
            }
            relu(&mut acc);
            a1v[j] = acc;
        }
    }
    for j in 0..HIDDEN {
        let (mut h, mut m) = (a1[0][j], a1[0][j]);
        for a in &a1[1..x.len()] {
            for l in 0..LANES {
                h[l] = if a[j][l] > h[l] { a[j][l] } else { h[l] };
                m[l] = if a[j][l] < m[l] { a[j][l] } else { m[l] };
            }
        }
        (hi[j], lo[j]) = (h, m);
    }
}

/// `exp(z) - 1` in f32 to a few ulps, branch-free (vectorises): `z = n ln 2 + r`,
/// `|r| <= ln 2 / 2`, `expm1(r)` by its Taylor polynomial to degree 7 (truncation
/// < 2e-8 relative), then `expm1(z) = 2^n expm1(r) + (2^n - 1)`, where `2^n - 1` is exact
/// and the sum never cancels. `z` is clamped to [-88, 88] (beyond: -1, or ~2.4e38).
#[inline(always)]
pub(super) fn expm1f<const FMA: bool>(z: f32) -> f32 {
    let z = z.clamp(-88.0, 88.0);
    let n = (z * LOG2E + ROUND) - ROUND;
    let r = madd::<FMA>(-n, LN2_HI, z);
    let r = madd::<FMA>(-n, LN2_LO, r);
    let mut p = EXPM1_C[0];
    for &c in &EXPM1_C[1..] {
        p = madd::<FMA>(p, r, c);
    }
    let p = madd::<FMA>(r * r, p, r);
    let s = f32::from_bits(((n as i32 + 127) as u32) << 23);
    madd::<FMA>(s, p, s - 1.0)
}

pub(super) const LOG2E: f32 = std::f32::consts::LOG2_E;
/// ln 2 = LN2_HI + LN2_LO, LN2_HI with 9 significant bits (n LN2_HI exact).
pub(super) const LN2_HI: f32 = 0.693_359_4;
pub(super) const LN2_LO: f32 = -2.121_944_4e-4;
/// 1.5 x 2^23: adding and subtracting it rounds to the nearest integer.
pub(super) const ROUND: f32 = 12_582_912.0;
/// Taylor coefficients of `(expm1(r) - r) / r^2`, highest degree first.
pub(super) const EXPM1_C: [f32; 6] = [
    1.0 / 5040.0,
    1.0 / 720.0,
    1.0 / 120.0,
    1.0 / 24.0,
    1.0 / 6.0,
    0.5,
];
