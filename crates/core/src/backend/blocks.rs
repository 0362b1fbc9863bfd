//! Block-pair reductions shared by the back-ends: which `BLOCK x BLOCK` blocks of lobe
//! pairs to reduce, and how their sums land in the output.

/// Rows and columns of a block of lobe pairs (both back-ends; the GPU kernels hold the
/// four rows of a block in the lanes of one `vec4<f32>`, so this cannot change alone).
pub const BLOCK: usize = 4;

/// The per-cell operation reduced over the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairOp {
    /// `sum_s |w_s a_s - w_s b_s|` (rows pre-multiplied by `w_s`): BRDF_it.
    L1,
    /// `sum_s (sqrt(w_s) a_s)(sqrt(w_s) b_s)` (rows pre-multiplied by `sqrt(w_s)`): Gram
    /// matrices.
    Dot,
}

impl PairOp {
    /// The factor each row is multiplied by at a cell of weight `w`.
    #[inline]
    pub fn row_scale(self, w: f64) -> f64 {
        match self {
            PairOp::L1 => w,
            PairOp::Dot => w.sqrt(),
        }
    }
}

/// Every block pair `(bi <= bj)` of `n` lobes: all pairs `i < j` (and the diagonal).
pub fn all_blocks(n: usize) -> Vec<[u32; 2]> {
    let nb = n.div_ceil(BLOCK) as u32;
    (0..nb)
        .flat_map(|bi| (bi..nb).map(move |bj| [bi, bj]))
        .collect()
}

/// The block pairs a Gram computation needs when the first `basis` lobes are the basis
/// columns and the rest are targets: every pair with a basis lobe, and each target's
/// diagonal (for `b^T W b`).
pub fn gram_blocks(n: usize, basis: usize) -> Vec<[u32; 2]> {
    let nb = n.div_ceil(BLOCK) as u32;
    let basis_blocks = basis.div_ceil(BLOCK) as u32;
    let mut v: Vec<[u32; 2]> = (0..basis_blocks)
        .flat_map(|bi| (bi..nb).map(move |bj| [bi, bj]))
        .collect();
    v.extend((basis_blocks..nb).map(|b| [b, b]));
    v
}

/// Adds one block's sums `acc[r][q]` (rows `bi*BLOCK + r`, columns `bj*BLOCK + q`) into
/// the full symmetric `n x n` output, skipping padding.
#[inline]
pub fn add_block(out: &mut [f64], n: usize, [bi, bj]: [u32; 2], acc: impl Fn(usize, usize) -> f64) {
    for r in 0..BLOCK {
        for q in 0..BLOCK {
            let (i, j) = (bi as usize * BLOCK + r, bj as usize * BLOCK + q);
            if i < n && j < n && (bi != bj || i <= j) {
                let v = acc(r, q);
                out[i * n + j] += v;
                if i != j {
                    out[j * n + i] += v;
                }
            }
        }
    }
}

/// The condensed upper triangle of a full symmetric matrix.
pub(crate) fn condensed_of(full: &[f64], n: usize) -> Vec<f64> {
    let mut v = Vec::with_capacity(n * n.saturating_sub(1) / 2);
    for i in 0..n {
        v.extend_from_slice(&full[i * n + i + 1..(i + 1) * n]);
    }
    v
}
