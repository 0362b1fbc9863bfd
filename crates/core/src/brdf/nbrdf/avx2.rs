//! The AVX2 + FMA copy of [`super::forward`]: the same f32 operations in the same order
//! (so the same values, bit for bit), written with intrinsics so that the register
//! blocking is the intended one ([`RV`] vectors of cells x [`RU`] units, twelve chains of
//! fused multiply-adds in registers, a weight broadcast serving four vectors); left to
//! itself, the auto-vectoriser vectorises layer 1 across units and transposes.
//!
//! Every function here is an `unsafe fn` with the features it needs: its caller must
//! have checked that the processor has AVX2 and FMA (`super::fma_available`).

use super::{
    windows_from_g, Kernel, Scratch, B1, B2, B3, BLOCK_VECS, EXPM1_C, FC1, FC1_ROWS, FC2, FC3,
    HIDDEN, LANES, LN2_HI, LN2_LO, LOG2E, NBRDF_WEIGHTS, PRUNE_MARGIN, ROUND, RU, RV, V,
};
use std::arch::x86_64::*;

/// The AVX2 + FMA block kernel; a value of it is a proof that the processor has both.
#[derive(Clone, Copy)]
pub(super) struct Avx2(());

impl Avx2 {
    /// # Safety
    /// The processor must support AVX2 and FMA.
    pub(super) unsafe fn new() -> Self {
        Self(())
    }
}

impl Kernel for Avx2 {
    #[inline(always)]
    fn forward(self, w: &[f32; NBRDF_WEIGHTS], x: &[[V; 5]], y: &mut [[V; 3]], s: &mut Scratch) {
        // SAFETY: `self` exists, so AVX2 and FMA were detected.
        unsafe { forward(w, x, y, s) }
    }
    #[inline(always)]
    fn windows(
        self,
        w: &[f32; NBRDF_WEIGHTS],
        x: &[[V; 5]],
        s: &Scratch,
        clamp: bool,
    ) -> [(f32, f32); 3] {
        // SAFETY: as above.
        unsafe { windows(w, x, s, clamp) }
    }
    #[inline(always)]
    fn flags(self, y: &[[V; 3]], win: &[(f32, f32); 3], clamp: bool) -> u64 {
        // SAFETY: as above.
        unsafe { flags(y, win, clamp) }
    }
    #[inline(always)]
    fn store(self, y: &[[V; 3]], out: [&mut [f32]; 3], clamp: bool) {
        // SAFETY: as above.
        unsafe { store_block(y, out, clamp) }
    }
}

/// [`super::recheck_windows`] with AVX2, the same values: the same f32 operations per
/// unit (multiplies and adds unfused, in the same order), eight units at a time, and
/// maxima (exact in any order).
#[target_feature(enable = "avx2")]
unsafe fn windows(
    w: &[f32; NBRDF_WEIGHTS],
    x: &[[V; 5]],
    s: &Scratch,
    clamp: bool,
) -> [(f32, f32); 3] {
    let mut xm = [_mm256_setzero_ps(); 5];
    for xv in x {
        for (m, xi) in xm.iter_mut().zip(xv) {
            *m = _mm256_max_ps(*m, abs(load(xi)));
        }
    }
    let mut xmax = xm;
    for m in xmax.iter_mut() {
        *m = hmax(*m);
    }
    // M1_j for every unit (lanes 21..24 read the next weights and are not used).
    let mut m1 = [0f32; 24];
    for grp in 0..3 {
        let mut m = abs(load8(w, B1 + 8 * grp));
        for (i, &xm) in xmax.iter().enumerate() {
            m = _mm256_add_ps(
                m,
                _mm256_mul_ps(abs(load8(w, FC1 + FC1_ROWS[i] * HIDDEN + 8 * grp)), xm),
            );
        }
        _mm256_storeu_ps(m1.as_mut_ptr().add(8 * grp), m);
    }
    let two = _mm256_set1_ps(2.0);
    let mut g = [
        _mm256_mul_ps(two, abs(load8(w, B2))),
        _mm256_mul_ps(two, abs(load8(w, B2 + 8))),
        _mm256_mul_ps(two, abs(load8(w, B2 + 16))),
    ];
    for t in 0..s.n1 {
        let j = s.live1[t];
        let h = _mm256_set1_ps(2.0 * s.hi1[t] + m1[j]);
        for (grp, g) in g.iter_mut().enumerate() {
            let row = abs(load8(w, FC2 + j * HIDDEN + 8 * grp));
            *g = _mm256_add_ps(*g, _mm256_mul_ps(row, h));
        }
    }
    let mut gs = [0f32; 24];
    for (grp, g) in g.iter().enumerate() {
        _mm256_storeu_ps(gs.as_mut_ptr().add(8 * grp), *g);
    }
    windows_from_g(w, s, &gs, clamp)
}

/// `|v|` (the sign bits cleared).
#[inline]
#[target_feature(enable = "avx")]
unsafe fn abs(v: __m256) -> __m256 {
    _mm256_andnot_ps(_mm256_set1_ps(-0.0), v)
}

/// [`super::window_flags`] with AVX2 (exact comparisons).
#[target_feature(enable = "avx2")]
unsafe fn flags(y: &[[V; 3]], win: &[(f32, f32); 3], clamp: bool) -> u64 {
    let sign = _mm256_set1_ps(if clamp { 0.0 } else { -0.0 });
    let (mut lo, mut hi) = ([_mm256_setzero_ps(); 3], [_mm256_setzero_ps(); 3]);
    for c in 0..3 {
        (lo[c], hi[c]) = (_mm256_set1_ps(win[c].0), _mm256_set1_ps(win[c].1));
    }
    let mut bits = 0u64;
    for (v, yv) in y.iter().enumerate() {
        let mut f = _mm256_setzero_ps();
        for c in 0..3 {
            // |y| unless `clamp` (and-not with 0 keeps y).
            let t = _mm256_andnot_ps(sign, load(&yv[c]));
            let inside = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(t, lo[c]),
                _mm256_cmp_ps::<_CMP_LT_OQ>(t, hi[c]),
            );
            f = _mm256_or_ps(f, inside);
        }
        bits |= (_mm256_movemask_ps(f) as u32 as u64) << (v * LANES);
    }
    bits
}

/// [`super::store_block`] with AVX2: `max(v, +0)` is `v` when `v > 0`, else +0, as there.
#[target_feature(enable = "avx2")]
unsafe fn store_block(y: &[[V; 3]], out: [&mut [f32]; 3], clamp: bool) {
    let zero = _mm256_setzero_ps();
    for (c, o) in out.into_iter().enumerate() {
        let full = o.len() / LANES;
        for (v, yv) in y[..full].iter().enumerate() {
            let a = load(&yv[c]);
            let a = if clamp { _mm256_max_ps(a, zero) } else { a };
            // `v * LANES + 8 <= o.len()`.
            _mm256_storeu_ps(o.as_mut_ptr().add(v * LANES), a);
        }
        for (k, o) in o[full * LANES..].iter_mut().enumerate() {
            let v = y[full][c][k];
            *o = if !clamp || v > 0.0 { v } else { 0.0 };
        }
    }
}

/// Horizontal maximum of `v`, broadcast to every lane.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn hmax(v: __m256) -> __m256 {
    let m = _mm256_max_ps(v, _mm256_permute2f128_ps::<1>(v, v));
    let m = _mm256_max_ps(m, _mm256_permute_ps::<0b0100_1110>(m));
    _mm256_max_ps(m, _mm256_permute_ps::<0b1011_0001>(m))
}

/// Horizontal minimum of `v`, broadcast to every lane.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn hmin(v: __m256) -> __m256 {
    let m = _mm256_min_ps(v, _mm256_permute2f128_ps::<1>(v, v));
    let m = _mm256_min_ps(m, _mm256_permute_ps::<0b0100_1110>(m));
    _mm256_min_ps(m, _mm256_permute_ps::<0b1011_0001>(m))
}

/// [`super::expm1f`] on eight lanes, operation for operation.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn expm1(z: __m256) -> __m256 {
    let z = _mm256_min_ps(
        _mm256_max_ps(z, _mm256_set1_ps(-88.0)),
        _mm256_set1_ps(88.0),
    );
    let round = _mm256_set1_ps(ROUND);
    let n = _mm256_sub_ps(
        _mm256_add_ps(_mm256_mul_ps(z, _mm256_set1_ps(LOG2E)), round),
        round,
    );
    // (-n) LN2 + z, rounded once: the negated product is exact.
    let r = _mm256_fnmadd_ps(n, _mm256_set1_ps(LN2_HI), z);
    let r = _mm256_fnmadd_ps(n, _mm256_set1_ps(LN2_LO), r);
    let mut p = _mm256_set1_ps(EXPM1_C[0]);
    for &c in &EXPM1_C[1..] {
        p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(c));
    }
    let p = _mm256_fmadd_ps(_mm256_mul_ps(r, r), p, r);
    let e = _mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127));
    let s = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(e));
    _mm256_fmadd_ps(s, p, _mm256_sub_ps(s, _mm256_set1_ps(1.0)))
}

#[inline]
#[target_feature(enable = "avx")]
unsafe fn load(v: &V) -> __m256 {
    // `v` is 8 f32 (unaligned load).
    _mm256_loadu_ps(v.as_ptr())
}

#[inline]
#[target_feature(enable = "avx")]
unsafe fn store(v: &mut V, x: __m256) {
    // `v` is 8 f32 (unaligned store).
    _mm256_storeu_ps(v.as_mut_ptr(), x)
}

/// Eight weights from `w[at..]` (`at + 8 <= NBRDF_WEIGHTS`).
#[inline]
#[target_feature(enable = "avx")]
unsafe fn load8(w: &[f32; NBRDF_WEIGHTS], at: usize) -> __m256 {
    let s: &[f32; 8] = w[at..at + 8].try_into().expect("8 weights");
    // `s` is 8 f32 (unaligned load).
    _mm256_loadu_ps(s.as_ptr())
}

/// [`super::forward`] with AVX2 and FMA (same contract, same values).
///
/// # Safety
/// The processor must support AVX2 and FMA.
///
/// Long function: the block kernel, operation for operation the portable `forward` with
/// intrinsics; its register blocks are unrolled in place so that the accumulator chains
/// stay in registers.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn forward(
    w: &[f32; NBRDF_WEIGHTS],
    x: &[[V; 5]],
    y: &mut [[V; 3]],
    s: &mut Scratch,
) {
    let nv = x.len();
    assert!(nv.is_multiple_of(RV) && nv <= BLOCK_VECS && y.len() == nv);
    let zero = _mm256_setzero_ps();
    // Layer 1, and each unit's per-lane range over the block.
    let (h0, h1) = (x[0][0][0], x[0][1][0]);
    let shared = x.iter().all(|xv| {
        (0..LANES).all(|l| xv[0][l].to_bits() == h0.to_bits() && xv[1][l].to_bits() == h1.to_bits())
    });
    let mut start = [0f32; HIDDEN];
    for (j, s) in start.iter_mut().enumerate() {
        *s = h1.mul_add(w[FC1 + 2 * HIDDEN + j], h0.mul_add(w[FC1 + j], w[B1 + j]));
    }
    // Unit by unit over the block's vectors: each unit's range stays in registers, and
    // the live units (positive somewhere) are listed with their range (broadcast).
    let mut live1 = [0usize; HIDDEN];
    let (mut hb, mut lb) = ([zero; HIDDEN], [zero; HIDDEN]);
    let mut n1 = 0;
    for j in 0..HIDDEN {
        let w0 = _mm256_set1_ps(w[FC1 + j]);
        let w1 = _mm256_set1_ps(w[FC1 + 2 * HIDDEN + j]);
        let w2 = _mm256_set1_ps(w[FC1 + 3 * HIDDEN + j]);
        let w3 = _mm256_set1_ps(w[FC1 + 4 * HIDDEN + j]);
        let w4 = _mm256_set1_ps(w[FC1 + 5 * HIDDEN + j]);
        let (b, a0) = (_mm256_set1_ps(w[B1 + j]), _mm256_set1_ps(start[j]));
        let (mut h, mut m) = (_mm256_set1_ps(f32::MIN), _mm256_set1_ps(f32::MAX));
        for (xv, a1v) in x.iter().zip(s.a1.iter_mut()) {
            let mut acc = if shared {
                a0
            } else {
                let acc = _mm256_fmadd_ps(load(&xv[0]), w0, b);
                _mm256_fmadd_ps(load(&xv[1]), w1, acc)
            };
            acc = _mm256_fmadd_ps(load(&xv[2]), w2, acc);
            acc = _mm256_fmadd_ps(load(&xv[3]), w3, acc);
            acc = _mm256_fmadd_ps(load(&xv[4]), w4, acc);
            // The range before the relu (the relu of the range is the range after it).
            h = _mm256_max_ps(h, acc);
            m = _mm256_min_ps(m, acc);
            // max(acc, +0) is +0 unless acc > 0, as `relu`.
            store(&mut a1v[j], _mm256_max_ps(acc, zero));
        }
        let h = hmax(h);
        live1[n1] = j;
        hb[n1] = h;
        lb[n1] = _mm256_max_ps(hmin(m), zero);
        n1 += usize::from(_mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(h, zero)) != 0);
    }
    // Layer-2 units not provably dead (eight at a time; lanes 21..24 read past the
    // matrix into the next weights and are dropped).
    let sign = _mm256_set1_ps(-0.0);
    let mut ub = [load8(w, B2), load8(w, B2 + 8), load8(w, B2 + 16)];
    let mut mag = [
        _mm256_andnot_ps(sign, ub[0]),
        _mm256_andnot_ps(sign, ub[1]),
        _mm256_andnot_ps(sign, ub[2]),
    ];
    for t in 0..n1 {
        let row = FC2 + live1[t] * HIDDEN;
        for g in 0..3 {
            let wv = load8(w, row + 8 * g);
            let (p, q) = (_mm256_mul_ps(wv, hb[t]), _mm256_mul_ps(wv, lb[t]));
            ub[g] = _mm256_add_ps(ub[g], _mm256_max_ps(p, q));
            mag[g] = _mm256_add_ps(mag[g], _mm256_andnot_ps(sign, p));
        }
    }
    let mut bits = 0u32;
    for g in 0..3 {
        let limit = _mm256_mul_ps(_mm256_set1_ps(-PRUNE_MARGIN), mag[g]);
        bits |= (_mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(ub[g], limit)) as u32) << (8 * g);
    }
    bits &= (1 << HIDDEN) - 1;
    let mut live2 = [0usize; HIDDEN + RU];
    let mut n2 = 0;
    while bits != 0 {
        live2[n2] = bits.trailing_zeros() as usize;
        n2 += 1;
        bits &= bits - 1;
    }
    let n2_pad = n2.next_multiple_of(RU);
    for t in n2..n2_pad {
        live2[t] = live2[n2 - 1];
    }
    // The live lists for `super::recheck_windows` (hb[t] holds hi1 in every lane).
    (s.live1, s.n1, s.live2, s.n2) = (live1, n1, live2, n2);
    for (h, b) in s.hi1.iter_mut().zip(&hb).take(n1) {
        *h = _mm256_cvtss_f32(*b);
    }
    // Layer 2 on the live units.
    for g in (0..n2_pad).step_by(RU) {
        let u = [live2[g], live2[g + 1], live2[g + 2]];
        for v0 in (0..nv).step_by(RV) {
            let b = [
                _mm256_set1_ps(w[B2 + u[0]]),
                _mm256_set1_ps(w[B2 + u[1]]),
                _mm256_set1_ps(w[B2 + u[2]]),
            ];
            let mut acc = [b; RV];
            // The hot loop, without bounds checks: `k` and `u[t]` are units (< HIDDEN,
            // from the live lists) and `v0 + r < nv <= BLOCK_VECS` (asserted above).
            let a1 = s.a1[v0..v0 + RV].as_ptr().cast::<f32>();
            for &k in &live1[..n1] {
                let row = w.as_ptr().add(FC2 + k * HIDDEN);
                let wv = [
                    _mm256_broadcast_ss(&*row.add(u[0])),
                    _mm256_broadcast_ss(&*row.add(u[1])),
                    _mm256_broadcast_ss(&*row.add(u[2])),
                ];
                for (r, accv) in acc.iter_mut().enumerate() {
                    let a = _mm256_loadu_ps(a1.add((r * HIDDEN + k) * LANES));
                    for t in 0..RU {
                        accv[t] = _mm256_fmadd_ps(a, wv[t], accv[t]);
                    }
                }
            }
            for (r, accv) in acc.iter().enumerate() {
                for (t, &a) in accv.iter().enumerate() {
                    store(&mut s.a2[v0 + r][g + t], _mm256_max_ps(a, zero));
                }
            }
        }
    }
    // Layer 3 on the live layer-2 units, then expm1.
    for v0 in (0..nv).step_by(RV) {
        let mut z = [[
            _mm256_set1_ps(w[B3]),
            _mm256_set1_ps(w[B3 + 1]),
            _mm256_set1_ps(w[B3 + 2]),
        ]; RV];
        // As layer 2: `u < HIDDEN`, `t < n2 <= HIDDEN`, `v0 + r < nv`.
        let a2 = s.a2[v0..v0 + RV].as_ptr().cast::<f32>();
        for (t, &u) in live2[..n2].iter().enumerate() {
            let row = w.as_ptr().add(FC3 + u * 3);
            let wc = [
                _mm256_broadcast_ss(&*row),
                _mm256_broadcast_ss(&*row.add(1)),
                _mm256_broadcast_ss(&*row.add(2)),
            ];
            for (r, zv) in z.iter_mut().enumerate() {
                let a = _mm256_loadu_ps(a2.add((r * (HIDDEN + RU) + t) * LANES));
                for c in 0..3 {
                    zv[c] = _mm256_fmadd_ps(a, wc[c], zv[c]);
                }
            }
        }
        for (r, zv) in z.iter().enumerate() {
            for c in 0..3 {
                store(&mut y[v0 + r][c], expm1(zv[c]));
            }
        }
    }
}
