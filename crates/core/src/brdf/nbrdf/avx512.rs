//! The AVX-512 copy of [`super::forward`]: sixteen cells per register (two of the
//! block's eight-cell vectors side by side), the same f32 operations per cell in the same
//! order as the AVX2 and portable kernels, so the same values bit for bit. The block, its
//! live units (the same exact maxima and minima, whatever the lanes) and everything after
//! the pass (the recheck windows, the flags, the store) are those of the AVX2 kernel.
//!
//! Chosen at run time where the processor has AVX-512F (see `super::avx512_available`):
//! layer 2 runs as the whole block (four registers of sixteen cells) x [`RU`] units per
//! weight broadcast, half the instructions of the AVX2 kernel.
//!
//! Every function here is an `unsafe fn` with the features it needs: its caller must
//! have checked that the processor has AVX-512F, AVX2 and FMA.
//!
//! The AVX-512 intrinsics are stable since Rust 1.89, the crate's `rust-version`.

use super::avx2;
use super::{
    Kernel, Scratch, B1, B2, B3, BLOCK_VECS, EXPM1_C, FC1, FC2, FC3, HIDDEN, LANES, LN2_HI, LN2_LO,
    LOG2E, NBRDF_WEIGHTS, PRUNE_MARGIN, ROUND, RV, V,
};
use std::arch::x86_64::*;

/// Cells per AVX-512 register.
const L16: usize = 2 * LANES;
/// Registers of sixteen cells in a block.
const BLOCK_V16: usize = BLOCK_VECS / 2;
/// Layer-2 units per register block (whole block x `RU` accumulator chains).
const RU: usize = 4;

/// The AVX-512 block kernel; a value of it is a proof that the processor has AVX-512F,
/// AVX2 and FMA.
#[derive(Clone, Copy)]
pub(super) struct Avx512(avx2::Avx2);

impl Avx512 {
    /// # Safety
    /// The processor must support AVX-512F, AVX2 and FMA.
    pub(super) unsafe fn new() -> Self {
        // SAFETY: this function's contract covers AVX2 and FMA.
        Self(unsafe { avx2::Avx2::new() })
    }
}

impl Kernel for Avx512 {
    #[inline(always)]
    fn forward(self, w: &[f32; NBRDF_WEIGHTS], x: &[[V; 5]], y: &mut [[V; 3]], s: &mut Scratch) {
        // SAFETY: `self` exists, so AVX-512F, AVX2 and FMA were detected.
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
        self.0.windows(w, x, s, clamp)
    }
    #[inline(always)]
    fn flags(self, y: &[[V; 3]], win: &[(f32, f32); 3], clamp: bool) -> u64 {
        self.0.flags(y, win, clamp)
    }
    #[inline(always)]
    fn store(self, y: &[[V; 3]], out: [&mut [f32]; 3], clamp: bool) {
        self.0.store(y, out, clamp)
    }
}

/// Two eight-cell vectors as one register (`a` the low lanes).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn join(a: &V, b: &V) -> __m512 {
    let lo = _mm512_castps_pd(_mm512_castps256_ps512(_mm256_loadu_ps(a.as_ptr())));
    let hi = _mm256_castps_pd(_mm256_loadu_ps(b.as_ptr()));
    _mm512_castpd_ps(_mm512_insertf64x4::<1>(lo, hi))
}

/// A register into two eight-cell vectors (the low lanes into `a`).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn split(v: __m512, a: &mut V, b: &mut V) {
    _mm256_storeu_ps(a.as_mut_ptr(), _mm512_castps512_ps256(v));
    let hi = _mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v));
    _mm256_storeu_ps(b.as_mut_ptr(), _mm256_castpd_ps(hi));
}

/// [`super::expm1f`] on sixteen lanes, operation for operation.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn expm1(z: __m512) -> __m512 {
    let z = _mm512_min_ps(
        _mm512_max_ps(z, _mm512_set1_ps(-88.0)),
        _mm512_set1_ps(88.0),
    );
    let round = _mm512_set1_ps(ROUND);
    let n = _mm512_sub_ps(
        _mm512_add_ps(_mm512_mul_ps(z, _mm512_set1_ps(LOG2E)), round),
        round,
    );
    // (-n) LN2 + z, rounded once: the negated product is exact.
    let r = _mm512_fnmadd_ps(n, _mm512_set1_ps(LN2_HI), z);
    let r = _mm512_fnmadd_ps(n, _mm512_set1_ps(LN2_LO), r);
    let mut p = _mm512_set1_ps(EXPM1_C[0]);
    for &c in &EXPM1_C[1..] {
        p = _mm512_fmadd_ps(p, r, _mm512_set1_ps(c));
    }
    let p = _mm512_fmadd_ps(_mm512_mul_ps(r, r), p, r);
    let e = _mm512_add_epi32(_mm512_cvtps_epi32(n), _mm512_set1_epi32(127));
    let s = _mm512_castsi512_ps(_mm512_slli_epi32::<23>(e));
    _mm512_fmadd_ps(s, p, _mm512_sub_ps(s, _mm512_set1_ps(1.0)))
}

/// Sixteen weights from `w[at..]` (`at + 16 <= NBRDF_WEIGHTS`).
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn load16(w: &[f32; NBRDF_WEIGHTS], at: usize) -> __m512 {
    let s: &[f32; 16] = w[at..at + 16].try_into().expect("16 weights");
    // `s` is 16 f32 (unaligned load).
    _mm512_loadu_ps(s.as_ptr())
}

/// [`super::forward`] with AVX-512 (same contract, same values).
///
/// # Safety
/// The processor must support AVX-512F, AVX2 and FMA.
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn forward(w: &[f32; NBRDF_WEIGHTS], x: &[[V; 5]], y: &mut [[V; 3]], s: &mut Scratch) {
    let nv = x.len();
    assert!(nv.is_multiple_of(RV) && nv <= BLOCK_VECS && y.len() == nv);
    match nv / 2 {
        2 => forward_n::<2>(w, x, y, s),
        _ => forward_n::<BLOCK_V16>(w, x, y, s),
    }
}

/// [`forward`] on `NZ` registers of sixteen cells (`x.len() == 2 NZ`).
///
/// Long function: the block kernel, operation for operation the portable `forward` with
/// intrinsics; its register blocks are unrolled in place so that the accumulator chains
/// stay in registers.
#[inline]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn forward_n<const NZ: usize>(
    w: &[f32; NBRDF_WEIGHTS],
    x: &[[V; 5]],
    y: &mut [[V; 3]],
    s: &mut Scratch,
) {
    assert!(x.len() == 2 * NZ && y.len() == 2 * NZ && NZ <= BLOCK_V16);
    let zero = _mm512_setzero_ps();
    let mut xs = [[zero; 5]; NZ];
    for (v, xv) in xs.iter_mut().enumerate() {
        for (i, xi) in xv.iter_mut().enumerate() {
            *xi = join(&x[2 * v][i], &x[2 * v + 1][i]);
        }
    }
    // Layer 1, and each unit's range over the block.
    let (h0, h1) = (x[0][0][0], x[0][1][0]);
    // Every lane has the first one's theta_h inputs (bit for bit).
    let (b0, b1) = (
        _mm512_set1_epi32(h0.to_bits() as i32),
        _mm512_set1_epi32(h1.to_bits() as i32),
    );
    let mut same = u16::MAX;
    for xv in &xs {
        same &= _mm512_cmpeq_epi32_mask(_mm512_castps_si512(xv[0]), b0);
        same &= _mm512_cmpeq_epi32_mask(_mm512_castps_si512(xv[1]), b1);
    }
    let shared = same == u16::MAX;
    // The hidden activations in sixteen-cell layout, in the scratch arrays' memory:
    // a1 at `(v HIDDEN + unit) 16`, a2 at `(v (HIDDEN + 3) + slot) 16` (the sizes of the
    // eight-cell layouts: `BLOCK_VECS / 2` registers of 16 for `BLOCK_VECS` of 8).
    const A2_STRIDE: usize = HIDDEN + super::RU;
    let a1 = s.a1.as_mut_ptr().cast::<f32>();
    let a2 = s.a2.as_mut_ptr().cast::<f32>();
    let mut hv = [zero; 32];
    let mut mv = [zero; 32];
    for j in 0..HIDDEN {
        let w0 = _mm512_set1_ps(w[FC1 + j]);
        let w1 = _mm512_set1_ps(w[FC1 + 2 * HIDDEN + j]);
        let w2 = _mm512_set1_ps(w[FC1 + 3 * HIDDEN + j]);
        let w3 = _mm512_set1_ps(w[FC1 + 4 * HIDDEN + j]);
        let w4 = _mm512_set1_ps(w[FC1 + 5 * HIDDEN + j]);
        let b = _mm512_set1_ps(w[B1 + j]);
        let a0 =
            _mm512_set1_ps(h1.mul_add(w[FC1 + 2 * HIDDEN + j], h0.mul_add(w[FC1 + j], w[B1 + j])));
        let (mut h, mut m) = (_mm512_set1_ps(f32::MIN), _mm512_set1_ps(f32::MAX));
        for (v, xv) in xs.iter().enumerate() {
            let mut acc = if shared {
                a0
            } else {
                let acc = _mm512_fmadd_ps(xv[0], w0, b);
                _mm512_fmadd_ps(xv[1], w1, acc)
            };
            acc = _mm512_fmadd_ps(xv[2], w2, acc);
            acc = _mm512_fmadd_ps(xv[3], w3, acc);
            acc = _mm512_fmadd_ps(xv[4], w4, acc);
            h = _mm512_max_ps(h, acc);
            m = _mm512_min_ps(m, acc);
            // `v < NZ <= BLOCK_V16`, `j < HIDDEN`: inside `s.a1`.
            _mm512_storeu_ps(a1.add((v * HIDDEN + j) * L16), _mm512_max_ps(acc, zero));
        }
        (hv[j], mv[j]) = (h, m);
    }
    // Each unit's maximum and minimum over the block, sixteen units at a time (units
    // 21..32: zeros, dropped): exact, so the same as the AVX2 kernel's whatever the order
    // (a live unit's maximum is positive; its minimum is taken with +0 below).
    let mut hmax = [0f32; 32];
    let mut hmin = [0f32; 32];
    for (g, (hg, mg)) in hv.chunks_exact(16).zip(mv.chunks_exact(16)).enumerate() {
        let hg: &[__m512; 16] = hg.try_into().expect("16");
        let mg: &[__m512; 16] = mg.try_into().expect("16");
        _mm512_storeu_ps(hmax.as_mut_ptr().add(16 * g), reduce16::<true>(hg));
        _mm512_storeu_ps(hmin.as_mut_ptr().add(16 * g), reduce16::<false>(mg));
    }
    let mut live1 = [0usize; HIDDEN];
    let (mut hs, mut ls) = ([0f32; HIDDEN], [0f32; HIDDEN]);
    let mut n1 = 0;
    for j in 0..HIDDEN {
        live1[n1] = j;
        hs[n1] = hmax[j];
        ls[n1] = if hmin[j] > 0.0 { hmin[j] } else { 0.0 };
        n1 += usize::from(hmax[j] > 0.0);
    }
    // Layer-2 units not provably dead (sixteen, then five, at a time; lanes 21..32 read
    // past the matrix into the next weights and are dropped): as the AVX2 kernel, the
    // same operations per unit.
    let mut ub = [load16(w, B2), load16(w, B2 + 16)];
    let mut mag = [_mm512_abs_ps(ub[0]), _mm512_abs_ps(ub[1])];
    for t in 0..n1 {
        let row = FC2 + live1[t] * HIDDEN;
        let (hb, lb) = (_mm512_set1_ps(hs[t]), _mm512_set1_ps(ls[t]));
        for g in 0..2 {
            let wv = load16(w, row + 16 * g);
            let (p, q) = (_mm512_mul_ps(wv, hb), _mm512_mul_ps(wv, lb));
            ub[g] = _mm512_add_ps(ub[g], _mm512_max_ps(p, q));
            mag[g] = _mm512_add_ps(mag[g], _mm512_abs_ps(p));
        }
    }
    let mut bits = 0u32;
    for g in 0..2 {
        let limit = _mm512_mul_ps(_mm512_set1_ps(-PRUNE_MARGIN), mag[g]);
        bits |= (_mm512_cmp_ps_mask::<_CMP_GT_OQ>(ub[g], limit) as u32) << (16 * g);
    }
    bits &= (1 << HIDDEN) - 1;
    let mut live2 = [0usize; HIDDEN + super::RU];
    let mut n2 = 0;
    while bits != 0 {
        live2[n2] = bits.trailing_zeros() as usize;
        n2 += 1;
        bits &= bits - 1;
    }
    // The live lists for `recheck_windows` (the AVX2 and portable kernels pad `live2`
    // to a multiple of 3 by repeating the last; only `live2[..n2]` is read).
    (s.live1, s.n1, s.live2, s.n2) = (live1, n1, live2, n2);
    s.hi1 = hs;
    // Layer 2 on the live units, `RU` at a time, then the rest.
    let mut g = 0;
    while g + RU <= n2 {
        layer2::<NZ, RU>(w, &live1[..n1], &live2[g..g + RU], g, a1, a2);
        g += RU;
    }
    match n2 - g {
        1 => layer2::<NZ, 1>(w, &live1[..n1], &live2[g..g + 1], g, a1, a2),
        2 => layer2::<NZ, 2>(w, &live1[..n1], &live2[g..g + 2], g, a1, a2),
        3 => layer2::<NZ, 3>(w, &live1[..n1], &live2[g..g + 3], g, a1, a2),
        _ => {}
    }
    // Layer 3 on the live layer-2 units, then expm1.
    let mut z = [[
        _mm512_set1_ps(w[B3]),
        _mm512_set1_ps(w[B3 + 1]),
        _mm512_set1_ps(w[B3 + 2]),
    ]; NZ];
    for (t, &u) in live2[..n2].iter().enumerate() {
        let wc = [
            _mm512_set1_ps(w[FC3 + u * 3]),
            _mm512_set1_ps(w[FC3 + u * 3 + 1]),
            _mm512_set1_ps(w[FC3 + u * 3 + 2]),
        ];
        for (v, zv) in z.iter_mut().enumerate() {
            // `v < NZ`, `t < n2 <= HIDDEN`: inside `s.a2`.
            let a = _mm512_loadu_ps(a2.add((v * A2_STRIDE + t) * L16));
            for c in 0..3 {
                zv[c] = _mm512_fmadd_ps(a, wc[c], zv[c]);
            }
        }
    }
    for (v, zv) in z.iter().enumerate() {
        let (ya, yb) = y.split_at_mut(2 * v + 1);
        for c in 0..3 {
            split(expm1(zv[c]), &mut ya[2 * v][c], &mut yb[0][c]);
        }
    }
}

/// `max(a, b)` (`MAX`) or `min(a, b)`, lane by lane.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn op<const MAX: bool>(a: __m512, b: __m512) -> __m512 {
    if MAX {
        _mm512_max_ps(a, b)
    } else {
        _mm512_min_ps(a, b)
    }
}

/// The maxima (`MAX`) or minima of the sixteen registers `v`, lane `u` that of `v[u]`:
/// a tree of fifteen pairwise `max` (or `min`) over lane halves, quarters, pairs and
/// single lanes, each unit's lanes only with its own.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn reduce16<const MAX: bool>(v: &[__m512; 16]) -> __m512 {
    // Halves: c[a] = (v[2a] over 8 lanes, v[2a + 1] over 8 lanes).
    let mut c = [_mm512_setzero_ps(); 8];
    for (a, c) in c.iter_mut().enumerate() {
        let (x, y) = (v[2 * a], v[2 * a + 1]);
        *c = op::<MAX>(
            _mm512_shuffle_f32x4::<0x44>(x, y),
            _mm512_shuffle_f32x4::<0xEE>(x, y),
        );
    }
    // Quarters: 128-bit lane q of e[b] holds unit 4b + q over 4 lanes.
    let mut e = [_mm512_setzero_ps(); 4];
    for (b, e) in e.iter_mut().enumerate() {
        let (x, y) = (c[2 * b], c[2 * b + 1]);
        *e = op::<MAX>(
            _mm512_shuffle_f32x4::<0x88>(x, y),
            _mm512_shuffle_f32x4::<0xDD>(x, y),
        );
    }
    // Pairs: in 128-bit lane q of g[c], lanes 0-1 unit 8c + q, lanes 2-3 unit 8c + 4 + q.
    let mut g = [_mm512_setzero_ps(); 2];
    for (c, g) in g.iter_mut().enumerate() {
        let (x, y) = (e[2 * c], e[2 * c + 1]);
        *g = op::<MAX>(
            _mm512_shuffle_ps::<0x88>(x, y),
            _mm512_shuffle_ps::<0xDD>(x, y),
        );
    }
    // Single lanes: lane 4q + r holds unit 4r + q.
    let h = op::<MAX>(
        _mm512_shuffle_ps::<0x88>(g[0], g[1]),
        _mm512_shuffle_ps::<0xDD>(g[0], g[1]),
    );
    let idx = _mm512_setr_epi32(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15);
    _mm512_permutexvar_ps(idx, h)
}

/// Layer 2 for the `N` units `u` (slots `g..g + N` of `a2`): `a2 = relu(b2 + sum over
/// live1 ascending of a1 fc2)`, one chain per unit and register, fused, as the other
/// kernels.
#[inline]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn layer2<const NZ: usize, const N: usize>(
    w: &[f32; NBRDF_WEIGHTS],
    live1: &[usize],
    u: &[usize],
    g: usize,
    a1: *const f32,
    a2: *mut f32,
) {
    const A2_STRIDE: usize = HIDDEN + super::RU;
    let u: [usize; N] = u.try_into().expect("N units");
    let mut b = [_mm512_setzero_ps(); N];
    for t in 0..N {
        b[t] = _mm512_set1_ps(w[B2 + u[t]]);
    }
    let mut acc = [b; NZ];
    for &k in live1 {
        // `k` and `u[t]` are units (< HIDDEN); `v < NZ <= BLOCK_V16`.
        let row = w.as_ptr().add(FC2 + k * HIDDEN);
        let mut a = [_mm512_setzero_ps(); NZ];
        for (v, a) in a.iter_mut().enumerate() {
            *a = _mm512_loadu_ps(a1.add((v * HIDDEN + k) * L16));
        }
        for t in 0..N {
            let wv = _mm512_set1_ps(*row.add(u[t]));
            for v in 0..NZ {
                acc[v][t] = _mm512_fmadd_ps(a[v], wv, acc[v][t]);
            }
        }
    }
    let zero = _mm512_setzero_ps();
    for (v, accv) in acc.iter().enumerate() {
        for (t, &a) in accv.iter().enumerate() {
            // `g + t < n2 <= HIDDEN`: inside `s.a2`.
            _mm512_storeu_ps(
                a2.add((v * A2_STRIDE + g + t) * L16),
                _mm512_max_ps(a, zero),
            );
        }
    }
}
