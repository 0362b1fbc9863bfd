//! Neural BRDFs (Sztrajman et al. 2021, SPEC 9): a 6-21-21-3 network per material,
//! `f = max(exp(a2 . fc3 + b3) - 1, 0)`, `a2 = relu(a1 . fc2 + b2)`,
//! `a1 = relu(x . fc1 + b1)`, `x = (sin th, 0, cos th, sin td cos pd, sin td sin pd, cos td)`.
//!
//! Two evaluations: [`Nbrdf::eval_f64`], the f64 reference, and the fast f32 twin
//! [`Nbrdf::eval_cells`] that every back-end tabulates with. The twin runs blocks of 64
//! cells, [`LANES`] at a time in struct-of-arrays layout, and leaves out the hidden units
//! that are provably 0 on the whole block (relu: about half of them in the trained
//! networks), which changes no value: it gives the dense f32 pass bit for bit (see
//! `forward`). On x86-64 with AVX2 and FMA, detected at run time, the block kernel is
//! written with intrinsics (`avx2`: twelve chains of 8-wide fused multiply-adds); elsewhere
//! it is portable code with the same operations. `exp(z) - 1` is an accurate `expm1` (a
//! few ulps), so the cancellation of `exp(z) - 1` near `z = 0` costs no accuracy: SPEC 9
//! asks 5e-4 relative where the value exceeds 1e-3, 1e-6 absolute below.
//!
//! Where the last layer's sum cancels, the f32 rounding of the hidden units can reach that
//! tolerance. Each block therefore carries an estimate of the pass's rounding error
//! (magnitude sums of its live units, a few hundred operations per block), each cell in
//! the block's doubtful range one of its own, and a cell whose own estimate is not within
//! half of SPEC 9's tolerance is recomputed with the f64 network (0.016% of the cells of
//! the 100 MERL networks). A value depends on its cell alone, not on the block it ran in
//! (`recheck_windows` and `recheck_cell` in the source).

mod forward;
mod range;
mod recheck;
use forward::*;
use recheck::*;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

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
/// The rows of `fc1` that the five inputs of [`features`] multiply (row 1's input, the
/// dropped one, is always 0).
const FC1_ROWS: [usize; 5] = [0, 2, 3, 4, 5];
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
    features_f64(th, td, pd).map(|v| v as f32)
}

/// [`features`] in f64 (the inputs of [`Nbrdf::eval_raw_f64`], bit for bit).
fn features_f64(th: f64, td: f64, pd: f64) -> [f64; 5] {
    let (sh, ch) = th.sin_cos();
    let (sd, cd) = td.sin_cos();
    let (sp, cp) = pd.sin_cos();
    [sh, ch, sd * cp, sd * sp, cd]
}

/// [`features`] of every cell of the MERL grid, from per-row tables (the cell centres of
/// SPEC 2): `(sin th, cos th)` per `i`, the three `d` inputs per `(j, k)` (one table each,
/// so that a run of consecutive cells reads each input as one vector).
struct GridFeatures {
    h: Vec<[f32; 2]>,
    d: [Vec<f32>; 3],
    /// The same in f64 (for the cells recomputed in f64), per `i` and per `(j, k)`.
    h64: Vec<[f64; 2]>,
    d64: Vec<[f64; 3]>,
}

fn grid_features() -> &'static GridFeatures {
    use crate::merl::{phi_d, theta_d, theta_h, N_PD, N_TD, N_TH};
    static G: std::sync::OnceLock<GridFeatures> = std::sync::OnceLock::new();
    G.get_or_init(|| {
        let h64: Vec<[f64; 2]> = (0..N_TH)
            .map(|i| {
                let f = features_f64(theta_h(i), 0.0, 0.0);
                [f[0], f[1]]
            })
            .collect();
        let d64: Vec<[f64; 3]> = (0..N_TD * N_PD)
            .map(|jk| {
                let f = features_f64(0.0, theta_d(jk / N_PD), phi_d(jk % N_PD));
                [f[2], f[3], f[4]]
            })
            .collect();
        let h = h64.iter().map(|f| f.map(|v| v as f32)).collect();
        let d = [0, 1, 2].map(|i| d64.iter().map(|f| f[i] as f32).collect());
        GridFeatures { h, d, h64, d64 }
    })
}

/// Cells of one theta_h row of the grid.
const ROW_CELLS: usize = crate::merl::N_TD * crate::merl::N_PD;

/// [`features`] of a flat grid cell (at its centre, SPEC 2).
#[inline]
pub(crate) fn cell_features(cell: usize) -> [f32; 5] {
    let g = grid_features();
    let h = g.h[cell / ROW_CELLS];
    let jk = cell % ROW_CELLS;
    [h[0], h[1], g.d[0][jk], g.d[1][jk], g.d[2][jk]]
}

/// [`cell_features`] in f64 (those of [`Nbrdf::eval_raw_f64`] at the cell's angles).
fn cell_features_f64(cell: usize) -> [f64; 5] {
    let g = grid_features();
    let h = g.h64[cell / ROW_CELLS];
    let d = g.d64[cell % ROW_CELLS];
    [h[0], h[1], d[0], d[1], d[2]]
}

/// The inputs of a block of grid cells (at most [`BLOCK_CELLS`]) into `x`, padded to
/// `x.len()` vectors with the last cell. A vector of eight consecutive cells of one theta_h
/// row (the common case: tabulations and masks run in cell order) is read as slices.
/// Inlined, so that the copies are as wide as the kernel's loads that read them.
#[inline(always)]
fn fill_cells(cells: &[u32], x: &mut [[V; 5]]) {
    let g = grid_features();
    let m = cells.len();
    for (v, xv) in x.iter_mut().enumerate() {
        let at = v * LANES;
        if at + LANES <= m {
            let (c0, c7) = (cells[at] as usize, cells[at + LANES - 1] as usize);
            let jk = c0 % ROW_CELLS;
            if c7 == c0 + LANES - 1 && jk + LANES <= ROW_CELLS {
                let h = g.h[c0 / ROW_CELLS];
                xv[0] = [h[0]; LANES];
                xv[1] = [h[1]; LANES];
                for (xi, d) in xv[2..].iter_mut().zip(&g.d) {
                    xi.copy_from_slice(&d[jk..jk + LANES]);
                }
                continue;
            }
        }
        for l in 0..LANES {
            let f = cell_features(cells[(at + l).min(m - 1)] as usize);
            for (xi, fi) in xv.iter_mut().zip(f) {
                xi[l] = fi;
            }
        }
    }
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
        self.eval_inputs_f64(&Self::inputs_f64(theta_h, theta_d, phi_d))
    }

    /// The network's six inputs at half/difference angles, in f64 (the first step of
    /// [`Self::eval_raw_f64`]; they depend on the angles only, so that many networks at
    /// the same angles share them).
    pub fn inputs_f64(theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 6] {
        [
            theta_h.sin(),
            0.0,
            theta_h.cos(),
            theta_d.sin() * phi_d.cos(),
            theta_d.sin() * phi_d.sin(),
            theta_d.cos(),
        ]
    }

    /// [`Self::eval_raw_f64`] from the inputs ([`Self::inputs_f64`]).
    pub fn eval_inputs_f64(&self, x: &[f64; 6]) -> [f64; 3] {
        let w = |k: usize| self.w[k] as f64;
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

    /// [`Self::eval_inputs_f64`] clamped at 0 ([`Self::eval_f64`]) at every input of `xs`,
    /// into `out`: the same bits, four inputs at a time (one per f64 vector lane, each
    /// lane doing its input's products and sums in the scalar order: no fusing), AVX2 where
    /// the processor has it.
    pub fn eval_inputs_f64_batch(&self, xs: &[[f64; 6]], out: &mut [[f64; 3]]) {
        assert_eq!(
            xs.len(),
            out.len(),
            "eval_inputs_f64_batch: one output per input"
        );
        let w: Vec<f64> = self.w.iter().map(|&v| v as f64).collect();
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the processor has AVX2 (checked).
                unsafe { eval_f64_lanes_avx2(&w, xs, out) };
                return;
            }
        }
        eval_f64_lanes(&w, xs, out);
    }

    /// RGB reflectance at half/difference angles (SPEC 9), f64 reference, clamped at 0.
    pub fn eval_f64(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3] {
        self.eval_raw_f64(theta_h, theta_d, phi_d)
            .map(|v| v.max(0.0))
    }

    /// RGB reflectance at a direction pair (unit vectors, local frame): the angles of
    /// `crate::merl::half_diff`, then [`Self::eval_f64`]. Below the horizon
    /// (`wi.z <= 0` or `wo.z <= 0`) a BRDF is 0, and so is this (the network's raw output
    /// there means nothing).
    pub fn eval_dirs(&self, wi: [f64; 3], wo: [f64; 3]) -> [f64; 3] {
        if wi[2] <= 0.0 || wo[2] <= 0.0 {
            return [0.0; 3];
        }
        let (th, td, pd) = crate::merl::half_diff(wi, wo);
        self.eval_f64(th, td, pd)
    }

    /// The f32 twin at the flat grid cells `cells`: RGB into `out[c][n]` (`out` rows of at
    /// least `cells.len()`), clamped at 0 (`clamp`) or raw.
    pub fn eval_cells(&self, cells: &[u32], clamp: bool, out: [&mut [f32]; 3]) {
        self.eval_with(&GridCells(cells), clamp, out)
    }

    /// The f32 twin at given features ([`features`]); as [`Self::eval_cells`] (a value
    /// recomputed in f64 starts from the f32 features, the only inputs there are).
    pub fn eval_features(&self, feats: &[[f32; 5]], clamp: bool, out: [&mut [f32]; 3]) {
        self.eval_with(&Features(feats), clamp, out)
    }

    /// Runs the network on blocks of [`BLOCK_CELLS`] of the cells of `src`, with the
    /// kernel of the processor.
    fn eval_with(&self, src: &impl Source, clamp: bool, out: [&mut [f32]; 3]) {
        let w: &[f32; NBRDF_WEIGHTS] = self.w[..].try_into().expect("675 weights");
        let fast = fma_available();
        #[cfg(target_arch = "x86_64")]
        {
            if fast && avx512_available() {
                // SAFETY: AVX-512F, AVX2 and FMA were detected on this processor.
                return unsafe { eval_blocks_avx512(w, src, clamp, out) };
            }
            if fast {
                // SAFETY: AVX2 and FMA were detected on this processor.
                return unsafe { eval_blocks_avx2(w, src, clamp, out) };
            }
        }
        let _ = fast;
        eval_blocks(Portable::<false>, w, src, clamp, out)
    }
}

/// The cells of an evaluation. Its methods are inlined into the kernel's loop (compiled
/// with the kernel's features: the inputs are written as wide as they are read).
trait Source {
    /// Number of cells.
    fn len(&self) -> usize;
    /// Writes the inputs of cells `start..start + m` into `x` (whole vectors; padding
    /// lanes repeat the last cell, so that they neither wake a hidden unit nor hide a
    /// shared theta_h).
    fn fill(&self, start: usize, m: usize, x: &mut [[V; 5]]);
    /// Cell `n`'s inputs in f64, for a value recomputed in f64.
    fn exact(&self, n: usize) -> [f64; 5];
}

/// Flat grid cells ([`cell_features`]).
struct GridCells<'a>(&'a [u32]);

impl Source for GridCells<'_> {
    #[inline(always)]
    fn len(&self) -> usize {
        self.0.len()
    }
    #[inline(always)]
    fn fill(&self, start: usize, m: usize, x: &mut [[V; 5]]) {
        fill_cells(&self.0[start..start + m], x)
    }
    #[inline(always)]
    fn exact(&self, n: usize) -> [f64; 5] {
        cell_features_f64(self.0[n] as usize)
    }
}

/// Given features ([`features`]; in f64, the same values).
struct Features<'a>(&'a [[f32; 5]]);

impl Source for Features<'_> {
    #[inline(always)]
    fn len(&self) -> usize {
        self.0.len()
    }
    #[inline(always)]
    fn fill(&self, start: usize, m: usize, x: &mut [[V; 5]]) {
        for n in 0..x.len() * LANES {
            let f = self.0[start + n.min(m - 1)];
            for (xi, fi) in x[n / LANES].iter_mut().zip(f) {
                xi[n % LANES] = fi;
            }
        }
    }
    #[inline(always)]
    fn exact(&self, n: usize) -> [f64; 5] {
        self.0[n].map(f64::from)
    }
}

/// The parts of the block loop that run per block, by instruction set: [`Portable`]
/// (`FMA`: fused multiply-adds, as the AVX2 kernel) and `avx2::Avx2`. Every
/// implementation gives the same values bit for bit: the same f32 operations in the same
/// order per cell (`forward`) or per unit (`windows`), or exact ones (`flags`, `store`).
trait Kernel: Copy {
    /// [`forward`].
    fn forward(self, w: &[f32; NBRDF_WEIGHTS], x: &[[V; 5]], y: &mut [[V; 3]], s: &mut Scratch);
    /// [`recheck_windows`].
    fn windows(
        self,
        w: &[f32; NBRDF_WEIGHTS],
        x: &[[V; 5]],
        s: &Scratch,
        clamp: bool,
    ) -> [(f32, f32); 3];
    /// [`window_flags`].
    fn flags(self, y: &[[V; 3]], win: &[(f32, f32); 3], clamp: bool) -> u64;
    /// [`store_block`].
    fn store(self, y: &[[V; 3]], out: [&mut [f32]; 3], clamp: bool);
}

/// The portable block kernel (`FMA`: with fused multiply-adds, which is a library call
/// unless compiled with the FMA feature).
#[derive(Clone, Copy)]
struct Portable<const FMA: bool>;

impl<const FMA: bool> Kernel for Portable<FMA> {
    #[inline(always)]
    fn forward(self, w: &[f32; NBRDF_WEIGHTS], x: &[[V; 5]], y: &mut [[V; 3]], s: &mut Scratch) {
        forward::<FMA>(w, x, y, s)
    }
    #[inline(always)]
    fn windows(
        self,
        w: &[f32; NBRDF_WEIGHTS],
        x: &[[V; 5]],
        s: &Scratch,
        clamp: bool,
    ) -> [(f32, f32); 3] {
        recheck_windows(w, x, s, clamp)
    }
    #[inline(always)]
    fn flags(self, y: &[[V; 3]], win: &[(f32, f32); 3], clamp: bool) -> u64 {
        window_flags(y, win, clamp)
    }
    #[inline(always)]
    fn store(self, y: &[[V; 3]], out: [&mut [f32]; 3], clamp: bool) {
        store_block(y, out, clamp)
    }
}

/// The cells of a block (bit `v * LANES + l` for lane `l` of vector `v`, over `y`'s
/// vectors, at most 64 cells) whose raw value of some channel lies in its window
/// (`in_windows`).
#[inline(always)]
fn window_flags(y: &[[V; 3]], win: &[(f32, f32); 3], clamp: bool) -> u64 {
    let mut bits = 0u64;
    for (v, [r, g, b]) in y.iter().enumerate() {
        for (l, ((&r, &g), &b)) in r.iter().zip(g).zip(b).enumerate() {
            bits |= u64::from(in_windows([r, g, b], win, clamp)) << (v * LANES + l);
        }
    }
    bits
}

/// The block's values `y` into `out` (rows of the block's `m` cells), clamped at 0 with
/// `clamp` (NaN cannot arise from finite weights; `> 0` keeps 0 for it anyway).
#[inline(always)]
fn store_block(y: &[[V; 3]], out: [&mut [f32]; 3], clamp: bool) {
    for (c, o) in out.into_iter().enumerate() {
        for (o, yv) in o.chunks_mut(LANES).zip(y) {
            for (o, &v) in o.iter_mut().zip(&yv[c]) {
                *o = if !clamp || v > 0.0 { v } else { 0.0 };
            }
        }
    }
}

/// The loop of [`Nbrdf::eval_with`] over blocks, with `k` the kernel of a block: the f32
/// pass ([`forward`]), then the cells whose rounding error the block's estimate
/// ([`recheck_windows`]) cannot show to be well within SPEC 9 rechecked one by one with
/// their own estimate, and recomputed with the f64 network where that fails too
/// ([`recheck_cell`]).
#[inline(always)]
fn eval_blocks(
    k: impl Kernel,
    w: &[f32; NBRDF_WEIGHTS],
    src: &impl Source,
    clamp: bool,
    out: [&mut [f32]; 3],
) {
    const _: () = assert!(BLOCK_CELLS <= 64, "a block's flags are one u64");
    let len = src.len();
    let [r, g, b] = out;
    let (r, g, b) = (&mut r[..len], &mut g[..len], &mut b[..len]);
    let mut x = [[[0f32; LANES]; 5]; BLOCK_VECS];
    let mut y = [[[0f32; LANES]; 3]; BLOCK_VECS];
    let mut scratch = Scratch::default();
    for start in (0..len).step_by(BLOCK_CELLS) {
        let m = (len - start).min(BLOCK_CELLS);
        let nv = m.div_ceil(LANES).next_multiple_of(RV);
        src.fill(start, m, &mut x[..nv]);
        k.forward(w, &x[..nv], &mut y[..nv], &mut scratch);
        let win = k.windows(w, &x[..nv], &scratch, clamp);
        if win.iter().any(|&(lo, hi)| lo < hi) {
            let mut bits = k.flags(&y[..nv], &win, clamp);
            if m < 64 {
                bits &= (1u64 << m) - 1;
            }
            while bits != 0 {
                let n = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let (v, l) = (n / LANES, n % LANES);
                let yv = &mut y[v];
                let yc = [yv[0][l], yv[1][l], yv[2][l]];
                let yc = recheck_cell(w, yc, src.exact(start + n), clamp);
                for (c, y) in yv.iter_mut().zip(yc) {
                    c[l] = y;
                }
            }
        }
        let end = start + m;
        k.store(
            &y[..nv],
            [&mut r[start..end], &mut g[start..end], &mut b[start..end]],
            clamp,
        );
    }
}

/// [`eval_blocks`] compiled for AVX2 and FMA, with `avx2::Avx2`.
///
/// # Safety
/// The processor must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn eval_blocks_avx2(
    w: &[f32; NBRDF_WEIGHTS],
    src: &impl Source,
    clamp: bool,
    out: [&mut [f32]; 3],
) {
    // SAFETY: this function's own contract.
    let k = unsafe { avx2::Avx2::new() };
    eval_blocks(k, w, src, clamp, out)
}

/// [`eval_blocks`] compiled for AVX-512F, AVX2 and FMA, with `avx512::Avx512`.
///
/// # Safety
/// The processor must support AVX-512F, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn eval_blocks_avx512(
    w: &[f32; NBRDF_WEIGHTS],
    src: &impl Source,
    clamp: bool,
    out: [&mut [f32]; 3],
) {
    // SAFETY: this function's own contract.
    let k = unsafe { avx512::Avx512::new() };
    eval_blocks(k, w, src, clamp, out)
}

/// The CPU kernel that evaluates the networks on this processor: `"avx512"`, `"avx2"` or
/// `"portable"` (the two SIMD kernels give the portable pass with FMA bit for bit;
/// benchmarks print which one ran).
pub fn cpu_kernel() -> &'static str {
    if fma_available() && avx512_available() {
        "avx512"
    } else if fma_available() {
        "avx2"
    } else {
        "portable"
    }
}

/// Whether the processor has AVX-512F (the AVX-512 kernel also needs AVX2 and FMA,
/// [`fma_available`]).
fn avx512_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// A network with seeded pseudo-random weights of about the trained networks' size (the
/// unit tests' networks, here and in the back-ends).
#[cfg(test)]
pub(crate) fn seeded_for_tests(seed: u64) -> Nbrdf {
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

/// Inputs per lane group of [`Nbrdf::eval_inputs_f64_batch`].
const F64_LANES: usize = 4;

/// [`Nbrdf::eval_inputs_f64_batch`]'s loop, compiled for AVX2.
///
/// # Safety
/// The processor has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn eval_f64_lanes_avx2(w: &[f64], xs: &[[f64; 6]], out: &mut [[f64; 3]]) {
    eval_f64_lanes(w, xs, out)
}

/// [`Nbrdf::eval_inputs_f64_batch`]'s loop: `w` the weights in f64; per group of
/// [`F64_LANES`] inputs, each lane's sums in [`Nbrdf::eval_inputs_f64`]'s order (a sum
/// from `-0.0`, as `Iterator::sum` of f64 starts, then the bias plus the sum).
#[inline(always)]
fn eval_f64_lanes(w: &[f64], xs: &[[f64; 6]], out: &mut [[f64; 3]]) {
    const L: usize = F64_LANES;
    for (xg, og) in xs.chunks(L).zip(out.chunks_mut(L)) {
        let n = xg.len();
        let x: [[f64; L]; 6] =
            std::array::from_fn(|i| std::array::from_fn(|l| xg[l.min(n - 1)][i]));
        let mut a1 = [[0f64; L]; HIDDEN];
        for (j, a) in a1.iter_mut().enumerate() {
            let mut s = [-0.0f64; L];
            for (i, xi) in x.iter().enumerate() {
                let wv = w[FC1 + i * HIDDEN + j];
                for l in 0..L {
                    s[l] += xi[l] * wv;
                }
            }
            for l in 0..L {
                a[l] = (w[B1 + j] + s[l]).max(0.0);
            }
        }
        let mut a2 = [[0f64; L]; HIDDEN];
        for (j, a) in a2.iter_mut().enumerate() {
            let mut s = [-0.0f64; L];
            for (i, ai) in a1.iter().enumerate() {
                let wv = w[FC2 + i * HIDDEN + j];
                for l in 0..L {
                    s[l] += ai[l] * wv;
                }
            }
            for l in 0..L {
                a[l] = (w[B2 + j] + s[l]).max(0.0);
            }
        }
        for c in 0..3 {
            let mut s = [-0.0f64; L];
            for (i, ai) in a2.iter().enumerate() {
                let wv = w[FC3 + i * 3 + c];
                for l in 0..L {
                    s[l] += ai[l] * wv;
                }
            }
            for (l, o) in og.iter_mut().enumerate() {
                o[c] = (w[B3 + c] + s[l]).exp_m1().max(0.0);
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

/// `max(v, 0)` in place.
#[inline(always)]
fn relu(v: &mut V) {
    for x in v.iter_mut() {
        *x = if *x > 0.0 { *x } else { 0.0 };
    }
}

/// Hidden activations of a block, kept between blocks (not re-zeroed per block), and the
/// block's live units (for [`recheck_windows`]).
#[derive(Default)]
#[repr(align(32))]
struct Scratch {
    /// Layer 1, per vector and unit.
    a1: [[V; HIDDEN]; BLOCK_VECS],
    /// Layer 2, per vector and live unit (in the order of the live list).
    a2: [[V; HIDDEN + RU]; BLOCK_VECS],
    /// The layer-1 units positive somewhere on the block (`live1[..n1]`, ascending) and
    /// their maxima there.
    live1: [usize; HIDDEN],
    hi1: [f32; HIDDEN],
    n1: usize,
    /// The layer-2 units not proven dead on the block (`live2[..n2]`, ascending).
    live2: [usize; HIDDEN + RU],
    n2: usize,
}

/// A layer-2 unit is skipped on a block when its interval bound is below `-PRUNE_MARGIN`
/// times its magnitude ([`forward`]).
const PRUNE_MARGIN: f32 = 1e-5;

/// Vectors of [`LANES`] cells whose dead hidden units are skipped together.
const BLOCK_VECS: usize = 8;
/// Cells of such a block.
const BLOCK_CELLS: usize = BLOCK_VECS * LANES;
/// Vectors of cells per register block (each weight broadcast serves all of them).
const RV: usize = 4;
/// Layer-2 output units per register block (`RV` x `RU` accumulator chains).
const RU: usize = 3;

#[cfg(test)]
mod tests;
