//! Where the f32 pass may miss SPEC 9's tolerance: the rounding-error estimate of a block
//! ([`recheck_windows`]), the windows of values recomputed, and the f64 network
//! ([`net_f64`], [`recheck_cell`]) that recomputes them.

use super::*;

/// Unit roundoff of f32 (round to nearest).
pub(super) const U32: f64 = f32::EPSILON as f64 / 2.0;

/// A value is recomputed in f64 unless its estimated rounding error is at most this
/// fraction of SPEC 9's tolerance.
pub(super) const RECHECK_SAFETY: f64 = 0.5;

/// Bound on the error of [`expm1f`] relative to its result (2^-21; measured: 4e-7).
pub(super) const EXPM1_REL: f64 = 4.76837158203125e-7;

/// Per channel, the window `(lo, hi)` of raw f32 outputs of the block just run by
/// [`forward`] that are recomputed in f64: a value `y` is when `lo < y < hi` (with `clamp`
/// unset, `|y|`). Empty (`lo >= hi`) on most blocks.
///
/// The estimate. To first order, the f32 pass's error in `z = a2 . fc3 + b3` sums one
/// term per rounding: the roundings of the inputs and of the fused multiply-adds of the
/// three layers, each at most `u = 2^-24` of the partial sum it rounds, carried to `z`
/// by the absolute weights downstream (a relu passes an error on at most 1:1 and stops
/// it at a unit that is 0 on both sides). With round-to-nearest those roundings are
/// independent and centred, and a partial sum is at most its magnitude sum `sum |terms|`;
/// the estimate charges one `u` per magnitude sum, summed (not in quadrature) over the
/// block's live units, with magnitudes taken at the block's maxima:
///
/// * layer 1, unit `j`: `M1_j = |b1_j| + sum_i |fc1_ij| max|x_i|` (inputs and
///   multiply-adds);
/// * layer 2, unit `k` (not proven dead on the block): `mag_k = |b2_k| + sum_j |fc2_jk|
///   hi1_j` over live layer-1 units (`hi1_j`: block maximum), charged twice: its own
///   roundings and the layer-3 roundings (`a2_k <= mag_k`), plus the layer-1 errors it
///   carries, `sum_j |fc2_jk| M1_j`;
/// * `E_c = u (|b3_c| + sum_k |fc3_kc| (2 mag_k + sum_j |fc2_jk| M1_j))`.
///
/// The error of `f = expm1(z)` is then `E_c (1 + f)` (positive `f`) plus [`EXPM1_REL`]
/// `|f|`; a value is kept when this is at most [`RECHECK_SAFETY`] of SPEC 9's tolerance
/// (5e-4 relative above 1e-3, 1e-6 below; within 0.1% of 1e-3, where the f32 value may
/// sit on the other side of it from the exact one, the smaller of the two).
///
/// Not a worst-case bound: that charges `n u` to a chain of `n` roundings, as if every
/// partial sum were as large as the magnitude sum and every rounding went the same way,
/// and would send tens of percent of the cells to f64. Checked rather than assumed: on
/// one block in 13 of the 100 MERL networks, where the f32 error exceeds 5% of the
/// tolerance it is at most 0.75 of `E_c (1 + f)`, so a kept value is expected within
/// 0.4 of the tolerance. Over every cell of the 100 networks (`crates/cli/tests/nbrdf.rs`) the
/// tabulated values are within 1.4e-4 relative and 2.2e-7 absolute of the f64 network;
/// 0.074% of the cells fall in a block window and 0.016% are recomputed
/// ([`recheck_cell`]).
///
/// The windows depend on the block's units only through `hi1`, `live1`, `live2` and the
/// block's inputs, which every pass shares bit for bit; the portable pass computes them
/// here, the SIMD ones with the same f32 operations in the same order per unit (about 200
/// operations per block of 64 cells).
pub(super) fn recheck_windows(
    w: &[f32; NBRDF_WEIGHTS],
    x: &[[V; 5]],
    s: &Scratch,
    clamp: bool,
) -> [(f32, f32); 3] {
    // f32 throughout, in one order (`a * b + c` unfused: the same values whether or not
    // the compiler vectorises); relative error of the estimate below 1e-5, allowed for.
    let max = |a: f32, b: f32| if a > b { a } else { b };
    let mut xm = [[0f32; LANES]; 5];
    for xv in x {
        for (m, xi) in xm.iter_mut().zip(xv) {
            for l in 0..LANES {
                m[l] = max(m[l], xi[l].abs());
            }
        }
    }
    let xmax = xm.map(|m| m.iter().fold(0f32, |a, &b| max(a, b)));
    // g_k = 2 |b2_k| + sum_j |fc2_jk| (2 hi1_j + M1_j) over the live layer-1 units.
    let mut g = [0f32; HIDDEN];
    for (k, g) in g.iter_mut().enumerate() {
        *g = 2.0 * w[B2 + k].abs();
    }
    for t in 0..s.n1 {
        let j = s.live1[t];
        let mut m1 = w[B1 + j].abs();
        for (i, &xm) in xmax.iter().enumerate() {
            m1 += w[FC1 + FC1_ROWS[i] * HIDDEN + j].abs() * xm;
        }
        let h = 2.0 * s.hi1[t] + m1;
        let row = &w[FC2 + j * HIDDEN..][..HIDDEN];
        for (g, &wv) in g.iter_mut().zip(row) {
            *g += wv.abs() * h;
        }
    }
    windows_from_g(w, s, &g, clamp)
}

/// The end of [`recheck_windows`] from the `g_k` of the block's units (`g[..HIDDEN]`).
#[inline(always)]
pub(super) fn windows_from_g(
    w: &[f32; NBRDF_WEIGHTS],
    s: &Scratch,
    g: &[f32],
    clamp: bool,
) -> [(f32, f32); 3] {
    let mut e = [0f32; 3];
    for &k in &s.live2[..s.n2] {
        for (c, e) in e.iter_mut().enumerate() {
            *e += w[FC3 + k * 3 + c].abs() * g[k];
        }
    }
    std::array::from_fn(|c| {
        let e = U32 * (w[B3 + c].abs() as f64 + e[c] as f64) * (1.0 + 1e-5);
        window(e, clamp)
    })
}

/// The window of raw f32 values (or of `|y|`, with `clamp` unset) whose error estimate
/// `e` (of `z`) is not within [`RECHECK_SAFETY`] of SPEC 9's tolerance; it only grows
/// with `e`.
pub(super) fn window(e: f64, clamp: bool) -> (f32, f32) {
    let sf = RECHECK_SAFETY;
    // Values above 1e-3 (the f32 value above 1.001e-3): E (1 + f) + EXPM1_REL f <=
    // sf 4.995e-4 f from f = rel on.
    let den = sf * 4.995e-4 - EXPM1_REL - e;
    let rel = if den > 0.0 { e / den } else { f64::INFINITY };
    // Values up to 1e-3 (tolerance 1e-6), and within 0.1% of 1e-3 (4.99e-7).
    let small_ok = e * 1.001 + EXPM1_REL * 1e-3 <= sf * 1e-6;
    let band_ok = e * 1.002 + EXPM1_REL * 1.001e-3 <= sf * 4.99e-7;
    let (lo, hi) = if !small_ok {
        // Below 0 both sides clamp to 0 once the exact value is surely negative.
        (if clamp { -2.0 * e } else { -1.0 }, rel.max(1.001e-3))
    } else if !band_ok {
        (0.999e-3, rel.max(1.001e-3))
    } else {
        (1.001e-3, rel)
    };
    // Outward to f32 (a window only grows).
    (f32_below(lo), f32_above(hi))
}

/// Whether a cell's f32 values `y` fall in its windows `win`.
pub(super) fn in_windows(y: [f32; 3], win: &[(f32, f32); 3], clamp: bool) -> bool {
    y.iter().zip(win).any(|(&y, &(lo, hi))| {
        let y = if clamp { y } else { y.abs() };
        y > lo && y < hi
    })
}

/// A cell's final values from its f32 ones `y` (in a block window) and its f64 inputs
/// `x`: the f64 network's, rounded once, when the cell's own estimate ([`net_f64`]) puts
/// `y` in its windows; else `y`. The cell's estimate is at most the block's (its live
/// units are among the block's, its magnitudes below the block's maxima; the factor
/// `1 - 1e-4` absorbs the rounding of both), so its windows lie in the block's: the
/// result depends on the cell alone, not on the block it was run in.
pub(super) fn recheck_cell(
    w: &[f32; NBRDF_WEIGHTS],
    y: [f32; 3],
    x: [f64; 5],
    clamp: bool,
) -> [f32; 3] {
    let (z, e) = net_f64(w, x);
    let win = e.map(|e| window(e * (1.0 - 1e-4), clamp));
    if in_windows(y, &win, clamp) {
        z.map(|z| z.exp_m1() as f32)
    } else {
        y
    }
}

/// An f32 at most `v` (`v` lowered by 1e-6 of itself, 16 f32 ulps, then rounded).
pub(super) fn f32_below(v: f64) -> f32 {
    (v - v.abs() * 1e-6) as f32
}

/// An f32 at least `v` (infinity above f32's range).
pub(super) fn f32_above(v: f64) -> f32 {
    (v + v.abs() * 1e-6) as f32
}

/// The network in f64 from the f32 weights at inputs `x` (as [`features`], in f64): the
/// last layer's sums `z` (the raw outputs are `exp(z) - 1`, taken only for the values
/// kept), and per channel the cell's own error estimate of the f32 pass's `z`
/// ([`recheck_windows`]'s, with the units live at the cell and its own magnitudes: a
/// layer-1 unit counts when clearly positive, `z1 > 2^-20 M1`, so that the f32 pass has
/// it positive too). A dense pass (a unit that is 0 adds nothing and is skipped), loops
/// over units innermost so that they vectorise.
pub(super) fn net_f64(w: &[f32; NBRDF_WEIGHTS], x: [f64; 5]) -> ([f64; 3], [f64; 3]) {
    let (mut a1, mut m1) = ([0f64; HIDDEN], [0f64; HIDDEN]);
    for j in 0..HIDDEN {
        a1[j] = w[B1 + j] as f64;
        m1[j] = (w[B1 + j] as f64).abs();
    }
    for (i, &xi) in x.iter().enumerate() {
        let row = &w[FC1 + FC1_ROWS[i] * HIDDEN..][..HIDDEN];
        for ((a, m), &wv) in a1.iter_mut().zip(&mut m1).zip(row) {
            *a += xi * wv as f64;
            *m += (xi * wv as f64).abs();
        }
    }
    // Layer 2 and, per unit, g_k = 2 |b2_k| + sum_j |fc2_jk| (2 a1_j + M1_j).
    let (mut a2, mut g) = ([0f64; HIDDEN], [0f64; HIDDEN]);
    for k in 0..HIDDEN {
        a2[k] = w[B2 + k] as f64;
        g[k] = 2.0 * (w[B2 + k] as f64).abs();
    }
    for j in 0..HIDDEN {
        let aj = a1[j];
        if aj > 0.0 {
            let h = if aj > m1[j] * 2f64.powi(-20) {
                2.0 * aj + m1[j]
            } else {
                0.0
            };
            let row = &w[FC2 + j * HIDDEN..][..HIDDEN];
            for ((a, g), &wv) in a2.iter_mut().zip(&mut g).zip(row) {
                *a += aj * wv as f64;
                *g += (wv as f64).abs() * h;
            }
        }
    }
    let (mut z, mut e) = ([0f64; 3], [0f64; 3]);
    for c in 0..3 {
        z[c] = w[B3 + c] as f64;
        e[c] = (w[B3 + c] as f64).abs();
    }
    for (k, &ak) in a2.iter().enumerate() {
        if ak > 0.0 {
            for c in 0..3 {
                let wv = w[FC3 + k * 3 + c] as f64;
                z[c] += ak * wv;
                e[c] += wv.abs() * g[k];
            }
        }
    }
    (z, e.map(|e| e * U32))
}
