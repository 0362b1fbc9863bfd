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
    use crate::merl::grid::{phi_d, theta_d, theta_h, N_PD, N_TD, N_TH};
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
const ROW_CELLS: usize = crate::merl::grid::N_TD * crate::merl::grid::N_PD;

/// [`features`] of a flat grid cell (at its centre, SPEC 2).
#[inline]
pub fn cell_features(cell: usize) -> [f32; 5] {
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
#[inline(always)]
fn forward<const FMA: bool>(
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

/// Unit roundoff of f32 (round to nearest).
const U32: f64 = f32::EPSILON as f64 / 2.0;

/// A value is recomputed in f64 unless its estimated rounding error is at most this
/// fraction of SPEC 9's tolerance.
const RECHECK_SAFETY: f64 = 0.5;

/// Bound on the error of [`expm1f`] relative to its result (2^-21; measured: 4e-7).
const EXPM1_REL: f64 = 4.76837158203125e-7;

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
/// 0.4 of the tolerance. Over every cell of the 100 networks (`tests/nbrdf.rs`) the
/// tabulated values are within 1.4e-4 relative and 2.2e-7 absolute of the f64 network;
/// 0.074% of the cells fall in a block window and 0.016% are recomputed
/// ([`recheck_cell`]).
///
/// The windows depend on the block's units only through `hi1`, `live1`, `live2` and the
/// block's inputs, which every pass shares bit for bit; the portable pass computes them
/// here, the SIMD ones with the same f32 operations in the same order per unit (about 200
/// operations per block of 64 cells).
fn recheck_windows(
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
fn windows_from_g(
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
fn window(e: f64, clamp: bool) -> (f32, f32) {
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
fn in_windows(y: [f32; 3], win: &[(f32, f32); 3], clamp: bool) -> bool {
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
fn recheck_cell(w: &[f32; NBRDF_WEIGHTS], y: [f32; 3], x: [f64; 5], clamp: bool) -> [f32; 3] {
    let (z, e) = net_f64(w, x);
    let win = e.map(|e| window(e * (1.0 - 1e-4), clamp));
    if in_windows(y, &win, clamp) {
        z.map(|z| z.exp_m1() as f32)
    } else {
        y
    }
}

/// An f32 at most `v` (`v` lowered by 1e-6 of itself, 16 f32 ulps, then rounded).
fn f32_below(v: f64) -> f32 {
    (v - v.abs() * 1e-6) as f32
}

/// An f32 at least `v` (infinity above f32's range).
fn f32_above(v: f64) -> f32 {
    (v + v.abs() * 1e-6) as f32
}

/// The network in f64 from the f32 weights at inputs `x` (as [`features`], in f64): the
/// last layer's sums `z` (the raw outputs are `exp(z) - 1`, taken only for the values
/// kept), and per channel the cell's own error estimate of the f32 pass's `z`
/// ([`recheck_windows`]'s, with the units live at the cell and its own magnitudes: a
/// layer-1 unit counts when clearly positive, `z1 > 2^-20 M1`, so that the f32 pass has
/// it positive too). A dense pass (a unit that is 0 adds nothing and is skipped), loops
/// over units innermost so that they vectorise.
fn net_f64(w: &[f32; NBRDF_WEIGHTS], x: [f64; 5]) -> ([f64; 3], [f64; 3]) {
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

/// Layer 1 of [`forward`]: `a1 = relu(x . fc1 + b1)` per vector of `x`, and each unit's
/// per-lane maximum and minimum over the vectors into `hi`, `lo`. `SHARED`: every lane of
/// `x` has the first vector's theta_h inputs, and the chain's first two steps are done once.
#[inline(always)]
fn layer1<const FMA: bool, const SHARED: bool>(
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
pub fn expm1f<const FMA: bool>(z: f32) -> f32 {
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

const LOG2E: f32 = std::f32::consts::LOG2_E;
/// ln 2 = LN2_HI + LN2_LO, LN2_HI with 9 significant bits (n LN2_HI exact).
const LN2_HI: f32 = 0.693_359_4;
const LN2_LO: f32 = -2.121_944_4e-4;
/// 1.5 x 2^23: adding and subtracting it rounds to the nearest integer.
const ROUND: f32 = 12_582_912.0;
/// Taylor coefficients of `(expm1(r) - r) / r^2`, highest degree first.
const EXPM1_C: [f32; 6] = [
    1.0 / 5040.0,
    1.0 / 720.0,
    1.0 / 120.0,
    1.0 / 24.0,
    1.0 / 6.0,
    0.5,
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::merl::grid::N_CELLS;

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

    /// The dense f32 pass, cell by cell, in the order [`forward`] documents (`acc = b`,
    /// then `acc = x_i w_i + acc` for `i` ascending; fused when `fma`): what the pruned
    /// block kernels must give bit for bit.
    fn dense(w: &[f32], x: [f32; 5], fma: bool) -> [f32; 3] {
        let madd = |a: f32, b: f32, c: f32| if fma { a.mul_add(b, c) } else { a * b + c };
        let xs = [x[0], 0.0, x[1], x[2], x[3], x[4]];
        let mut a1 = [0f32; HIDDEN];
        for (j, a) in a1.iter_mut().enumerate() {
            let mut acc = w[B1 + j];
            for i in [0, 2, 3, 4, 5] {
                acc = madd(xs[i], w[FC1 + i * HIDDEN + j], acc);
            }
            *a = if acc > 0.0 { acc } else { 0.0 };
        }
        let mut a2 = [0f32; HIDDEN];
        for (j, a) in a2.iter_mut().enumerate() {
            let mut acc = w[B2 + j];
            for (i, &v) in a1.iter().enumerate() {
                acc = madd(v, w[FC2 + i * HIDDEN + j], acc);
            }
            *a = if acc > 0.0 { acc } else { 0.0 };
        }
        std::array::from_fn(|c| {
            let mut z = w[B3 + c];
            for (i, &v) in a2.iter().enumerate() {
                z = madd(v, w[FC3 + i * 3 + c], z);
            }
            if fma {
                expm1f::<true>(z)
            } else {
                expm1f::<false>(z)
            }
        })
    }

    fn rows(r: &mut [Vec<f32>]) -> [&mut [f32]; 3] {
        let [x, y, z] = r else { unreachable!() };
        [&mut x[..], &mut y[..], &mut z[..]]
    }

    /// Networks with many dead units (biases pushed down), so that blocks prune.
    fn sparse_net(seed: u64) -> Nbrdf {
        let mut w = net(seed).weights().to_vec();
        for k in (B1..B1 + HIDDEN).chain(B2..B2 + HIDDEN) {
            w[k] -= 0.3 + 0.1 * (seed % 4) as f32;
        }
        Nbrdf::from_weights(w).expect("finite")
    }

    /// The values are those of the dense f32 pass followed by the cell's own recheck
    /// (`recheck_cell`: the f64 network's where its estimate says so), bit for bit, on
    /// every path: pruning and the blocks change no value.
    #[test]
    fn pruned_blocks_give_the_dense_pass_bit_for_bit() {
        // Grid runs (shared theta_h), a row boundary inside a block, scattered cells and
        // a short tail.
        let mut cells: Vec<u32> = (0..3000u32).chain(16_150..16_290).collect();
        cells.extend((0..500u32).map(|k| k * 2903 % N_CELLS as u32));
        cells.extend(700_001..700_013);
        let feats: Vec<[f32; 5]> = cells.iter().map(|&c| cell_features(c as usize)).collect();
        let fma = fma_available();
        let mut rechecked = 0;
        for seed in 0..8 {
            for n in [net(seed), sparse_net(seed)] {
                let w: &[f32; NBRDF_WEIGHTS] = n.weights().try_into().expect("675");
                let mut got = vec![vec![0f32; cells.len()]; 4 * 3];
                let (a, rest) = got.split_at_mut(3);
                let (b, rest) = rest.split_at_mut(3);
                let (c, d) = rest.split_at_mut(3);
                n.eval_cells(&cells, false, rows(a));
                n.eval_features(&feats, false, rows(b));
                eval_blocks(Portable::<true>, w, &GridCells(&cells), false, rows(c));
                eval_blocks(Portable::<false>, w, &GridCells(&cells), false, rows(d));
                // Each SIMD kernel the processor has (`eval_cells` picks one), bit for bit.
                #[cfg(target_arch = "x86_64")]
                for avx512 in [false, true] {
                    if !fma || (avx512 && !avx512_available()) {
                        continue;
                    }
                    let mut e = vec![vec![0f32; cells.len()]; 3];
                    // SAFETY: checked just before.
                    unsafe {
                        if avx512 {
                            eval_blocks_avx512(w, &GridCells(&cells), false, rows(&mut e))
                        } else {
                            eval_blocks_avx2(w, &GridCells(&cells), false, rows(&mut e))
                        }
                    }
                    for (e, a) in e.iter().zip(&got[..3]) {
                        let bits = |r: &[f32]| r.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                        assert!(bits(e) == bits(a), "seed {seed}: avx512 {avx512}");
                    }
                }
                for (k, f) in feats.iter().enumerate() {
                    // The dense pass, then the cell's own recheck (from the cell's f64
                    // inputs, or, features given in f32, from those).
                    let x64 = cell_features_f64(cells[k] as usize);
                    let f64in = f.map(f64::from);
                    let want = [
                        recheck_cell(w, dense(w, *f, fma), x64, false),
                        recheck_cell(w, dense(w, *f, fma), f64in, false),
                        recheck_cell(w, dense(w, *f, true), x64, false),
                        recheck_cell(w, dense(w, *f, false), x64, false),
                    ];
                    rechecked += usize::from(want[0] != dense(w, *f, fma));
                    for ch in 0..3 {
                        let seen = [got[ch][k], got[3 + ch][k], got[6 + ch][k], got[9 + ch][k]];
                        let expect = want.map(|v| v[ch]);
                        // `==`: an exact zero may carry either sign.
                        assert!(
                            seen.iter().zip(&expect).all(|(a, b)| a == b),
                            "seed {seed} cell {} ch {ch}: {seen:?} vs {expect:?}",
                            cells[k]
                        );
                    }
                }
            }
        }
        // The rechecked values were exercised (the pruned nets give small values).
        assert!(rechecked > 0);
    }

    /// The MERL networks of `dir` by name, read part by part (not through `collection`,
    /// which depends on this module).
    fn merl100_nets(dir: &std::path::Path) -> Vec<(String, Nbrdf)> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .expect("merl100")
            .filter_map(|e| {
                let n = e.ok()?.file_name().into_string().ok()?;
                n.strip_suffix("_fc1.npy").map(str::to_string)
            })
            .collect();
        names.sort();
        names
            .into_iter()
            .map(|name| {
                let mut flat = Vec::with_capacity(NBRDF_WEIGHTS);
                for (part, _, _) in NBRDF_PARTS {
                    let f = dir.join(format!("{name}_{part}.npy"));
                    let a = crate::npy_format::read_npy_f32(&f, 4096).expect("weights");
                    flat.extend(a.data);
                }
                let n = Nbrdf::from_weights(flat).expect("network");
                (name, n)
            })
            .collect()
    }

    /// Hashes of every tabulated value of the 100 MERL networks on the full grid, per
    /// path (AVX-512 where the CPU has it, AVX2 clamped and raw, the portable pass with and
    /// without FMA), written to `$BRDF_BASIS_NBRDF_GOLDEN` when that file is missing, else
    /// compared with it: a kernel change must leave every bit as it was. A tool for kernel
    /// changes, not a check of the current code (it needs the hashes of the code before the
    /// change, and minutes of CPU):
    /// `BRDF_BASIS_NBRDF_GOLDEN=/tmp/nb_golden.txt cargo test --release --lib golden -- --ignored`.
    /// The tests that always run check every kernel against the f64 network and the SIMD
    /// kernels against the portable pass bit for bit.
    #[test]
    #[ignore = "a tool for kernel changes: compares with hashes written before the change (BRDF_BASIS_NBRDF_GOLDEN), minutes of CPU"]
    fn golden_hashes_of_the_merl100_tabulation() {
        use rayon::prelude::*;
        let Ok(file) = std::env::var("BRDF_BASIS_NBRDF_GOLDEN") else {
            return;
        };
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/real/nbrdf/merl100");
        let nets = merl100_nets(&dir);
        assert_eq!(nets.len(), 100);
        let cells: Vec<u32> = (0..N_CELLS as u32).collect();
        let hash = |rows: &[Vec<f32>]| {
            let mut h = 0xcbf2_9ce4_8422_2325u64;
            for r in rows {
                for v in r {
                    h = (h ^ v.to_bits() as u64).wrapping_mul(0x0000_0100_0000_01b3);
                }
            }
            h
        };
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn port_fma(
            w: &[f32; NBRDF_WEIGHTS],
            cells: &[u32],
            clamp: bool,
            out: [&mut [f32]; 3],
        ) {
            eval_blocks(Portable::<true>, w, &GridCells(cells), clamp, out);
        }
        // The AVX2 and AVX-512 kernels, explicitly (`eval_cells` picks one).
        let simd = |avx512: bool, w: &[f32; NBRDF_WEIGHTS], clamp: bool, out: [&mut [f32]; 3]| {
            // SAFETY: checked just before.
            assert!(fma_available() && (!avx512 || avx512_available()));
            unsafe {
                if avx512 {
                    eval_blocks_avx512(w, &GridCells(&cells), clamp, out)
                } else {
                    eval_blocks_avx2(w, &GridCells(&cells), clamp, out)
                }
            }
        };
        let paths = [
            "avx2-clamp",
            "avx2-raw",
            "port-fma-clamp",
            "port-nofma-clamp",
        ];
        let t = std::time::Instant::now();
        let lines: Vec<String> = nets
            .par_iter()
            .map(|(name, n)| {
                let w: &[f32; NBRDF_WEIGHTS] = n.weights().try_into().expect("675");
                let mut line = name.clone();
                for p in paths {
                    let mut out = vec![vec![0f32; cells.len()]; 3];
                    match p {
                        "avx2-clamp" | "avx2-raw" => {
                            let clamp = p == "avx2-clamp";
                            simd(false, w, clamp, rows(&mut out));
                            // The AVX-512 kernel and `eval_cells` give the same bits.
                            let mut more = vec![vec![0f32; cells.len()]; 3];
                            if avx512_available() {
                                simd(true, w, clamp, rows(&mut more));
                                assert_eq!(hash(&more), hash(&out), "{name} {p}: avx512");
                            }
                            n.eval_cells(&cells, clamp, rows(&mut more));
                            assert_eq!(hash(&more), hash(&out), "{name} {p}: eval_cells");
                        }
                        // SAFETY: the test machine has AVX2 and FMA (x86-64 CI).
                        "port-fma-clamp" => unsafe { port_fma(w, &cells, true, rows(&mut out)) },
                        _ => {
                            eval_blocks(
                                Portable::<false>,
                                w,
                                &GridCells(&cells),
                                true,
                                rows(&mut out),
                            );
                        }
                    }
                    line += &format!(" {p}={:016x}", hash(&out));
                }
                line
            })
            .collect();
        let text = lines.join("\n") + "\n";
        eprintln!("golden: {:.1} s", t.elapsed().as_secs_f64());
        match std::fs::read_to_string(&file) {
            Ok(want) => {
                let bad: Vec<_> = text
                    .lines()
                    .zip(want.lines())
                    .filter(|(a, b)| a != b)
                    .collect();
                assert!(
                    bad.is_empty() && text.lines().count() == want.lines().count(),
                    "{} networks differ: {bad:?}",
                    bad.len()
                );
                eprintln!("golden: all {} networks bit for bit", lines.len());
            }
            Err(_) => std::fs::write(&file, text).expect("write golden"),
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
