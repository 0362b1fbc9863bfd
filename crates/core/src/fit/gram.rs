//! Gram quantities of fits (SPEC 5): `A^T W A`, `A^T W b` and `b^T W b` per channel, in
//! closed form from separable tables when every lobe is analytic, else from one pass of
//! the back-end over the grid; the Gram matrices of a whole collection, reused by fits
//! and selection.

use super::*;

/// Lobes in separable form when every one is analytic.
pub(crate) fn separable_lobes(lobes: &[Lobe]) -> Option<Vec<SeparableLobe>> {
    let t = GridTables::new();
    lobes
        .iter()
        .map(|l| match l {
            Lobe::Analytic(p) => Some(SeparableLobe::new(&t, p)),
            Lobe::Measured { .. } | Lobe::Neural { .. } => None,
        })
        .collect()
}

/// The full Gram matrix of `lobes` with the first `basis` as columns (layout of
/// [`Backend::gram`]): the separable closed form in f64 when `mode` is `Auto` and every
/// lobe is analytic, else the back-end's grid pass.
pub(crate) fn gram_full(
    backend: &dyn Backend,
    lobes: &[Lobe],
    cells: &CellSet,
    basis: usize,
    mode: GramMode,
    progress: Progress<'_>,
) -> Result<Vec<f64>, FitError> {
    if mode == GramMode::Auto {
        if let Some(sep) = separable_lobes(lobes) {
            let mom = CellMoments::new(&GridTables::new(), cells);
            return Ok(mom.gram(&sep, basis));
        }
    }
    Ok(backend.gram(lobes, cells, basis, progress)?)
}

/// Lobes (three channels side by side) above which `gram_grid_rgb` makes one pass per
/// channel instead of one for all three: the back-end returns the full square matrix of
/// every lobe it is given, `(3 n)^2` entries (4,096 lobes: 128 MiB), against `3 n^2` for
/// three passes.
pub const RGB_PASS_MAX_LOBES: usize = 4096;

/// Per channel `c`, the back-end's Gram pass ([`Backend::gram`], as `gram_full` makes it
/// with [`GramMode::Grid`]) of `lobes[c]` (each `n` lobes, the first `basis` of them the
/// basis columns): in one pass over the cells for the three channels together, so that a
/// material's three lobes are filled together (a network runs once per cell for its three
/// channels, not once per channel), each channel's lobes padded to whole blocks and only
/// each channel's own block pairs reduced. A pair's sum depends only on its two rows and
/// the cells (the canonical summation order of both back-ends), so every matrix is bit for
/// bit the one a pass over its channel alone gives (tested); above
/// [`RGB_PASS_MAX_LOBES`] lobes it is made that way, one pass per channel.
pub(crate) fn gram_grid_rgb(
    backend: &dyn Backend,
    lobes: [Vec<Lobe>; 3],
    cells: &CellSet,
    basis: usize,
    progress: Progress<'_>,
) -> Result<[Vec<f64>; 3], FitError> {
    use crate::backend::{gram_blocks, BLOCK};
    let n = lobes[0].len();
    if lobes.iter().any(|l| l.len() != n) {
        return Err(FitError::Backend(BackendError::Invalid(
            "gram_grid_rgb: the channels have different numbers of lobes".into(),
        )));
    }
    let n_pad = n.div_ceil(BLOCK) * BLOCK;
    if 3 * n_pad > RGB_PASS_MAX_LOBES {
        let mut out: [Vec<f64>; 3] = Default::default();
        for (o, l) in out.iter_mut().zip(&lobes) {
            *o = backend.gram(l, cells, basis, progress)?;
        }
        return Ok(out);
    }
    let mut all: Vec<Lobe> = Vec::with_capacity(3 * n_pad);
    let mut blocks = Vec::new();
    let per = gram_blocks(n, basis);
    for (c, l) in lobes.into_iter().enumerate() {
        all.extend(l);
        // Padding: a cheap analytic lobe whose sums are never read.
        all.resize((c + 1) * n_pad, LAMBERTIAN);
        let off = (c * n_pad / BLOCK) as u32;
        blocks.extend(per.iter().map(|&[bi, bj]| [bi + off, bj + off]));
    }
    let big = backend.reduce_pairs(&all, cells, &blocks, crate::backend::PairOp::Dot, progress)?;
    let w = 3 * n_pad;
    Ok(std::array::from_fn(|c| {
        let o = c * n_pad;
        let mut g = vec![0.0; n * n];
        for i in 0..n {
            g[i * n..(i + 1) * n].copy_from_slice(&big[(o + i) * w + o..(o + i) * w + o + n]);
        }
        g
    }))
}

/// The Gram matrices of a whole collection over `cells`, per channel, with the columns
/// `[1/pi, material 0, .., material N-1]` (`(N + 1)^2`, row-major), from one grid pass
/// (`gram_grid_rgb`): what the stages of an experiment on a measured or neural collection
/// share (the empirical selection, the objective of SPEC 8 and the fits) instead of each
/// making its own passes. Analytic collections have closed forms instead.
#[derive(Clone, Debug)]
pub struct CollectionGrams {
    /// The cells, as [`fit_cells`] gives them for the whole collection.
    pub cells: CellSet,
    /// Per channel, the `(N + 1)^2` Gram matrix.
    pub grams: [Vec<f64>; 3],
}

impl CollectionGrams {
    /// One grid pass of `backend` over the cells of `p` for every material of `coll`.
    pub fn grid(
        backend: &dyn Backend,
        coll: &Collection,
        p: &FitParams,
        progress: Progress<'_>,
    ) -> Result<Self, FitError> {
        let all: Vec<usize> = (0..coll.len()).collect();
        let cells = fit_cells(coll, &all, p)?;
        let grams = Self::over(backend, coll, &cells, progress)?;
        Ok(Self { cells, grams })
    }

    /// The Gram matrices alone, per channel, of every material of `coll` over `cells`
    /// (one grid pass for the three channels, `gram_grid_rgb`).
    pub fn over(
        backend: &dyn Backend,
        coll: &Collection,
        cells: &CellSet,
        progress: Progress<'_>,
    ) -> Result<[Vec<f64>; 3], FitError> {
        gram_grid_rgb(
            backend,
            collection_lobes(coll),
            cells,
            coll.len() + 1,
            progress,
        )
    }

    /// Whether [`CollectionGrams::grid`] is how the Gram matrices of `coll` are made with
    /// `mode` (else they come in closed form: every material analytic, mode auto).
    pub fn needed(coll: &Collection, mode: GramMode) -> bool {
        !(mode == GramMode::Auto && coll.all_analytic())
    }
}

/// Per channel, the Lambertian lobe then every material's lobe of that channel.
pub(crate) fn collection_lobes(coll: &Collection) -> [Vec<Lobe>; 3] {
    std::array::from_fn(|c| {
        std::iter::once(LAMBERTIAN)
            .chain(coll.materials().iter().map(|m| channel_lobe(&m.data, c)))
            .collect()
    })
}

/// The Gram quantities of one channel (section 5): what one batch of NNLS fits shares.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelGram {
    /// `(k+1)^2` Gram matrix of the Lambertian and basis columns, row-major.
    pub gram: Vec<f64>,
    /// Per target `t`, `h[t * (k+1) .. (t+1) * (k+1)]`: its products with the columns.
    pub h: Vec<f64>,
    /// Per target, its weighted squared norm `sum_s w_s b(s)^2`.
    pub bb: Vec<f64>,
}

/// Gram quantities of one channel: the `(k+1)^2` Gram of the Lambertian and basis
/// columns and, per target, its products with them and its squared norm.
#[allow(clippy::too_many_arguments)]
#[doc(hidden)]
pub fn channel_gram(
    backend: &dyn Backend,
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    cells: &CellSet,
    c: usize,
    mode: GramMode,
    progress: Progress<'_>,
) -> Result<ChannelGram, FitError> {
    let m = basis.len() + 1;
    let mut lobes = vec![LAMBERTIAN];
    lobes.extend(
        basis
            .iter()
            .map(|&i| channel_lobe(&coll.materials()[i].data, c)),
    );
    lobes.extend(
        targets
            .iter()
            .map(|&i| channel_lobe(&coll.materials()[i].data, c)),
    );
    let n = lobes.len();
    let full = gram_full(backend, &lobes, cells, m, mode, progress)?;
    gram_quantities(
        coll,
        basis,
        targets,
        c,
        |i, j| full[i * n + j],
        |a| a,
        |t| m + t,
    )
}

/// [`ChannelGram`] of `basis` and `targets` (channel `c`) read from a Gram matrix `at(i, j)`
/// in which basis column `a` (0: the Lambertian) is row `col(a)` and target `t` (its index
/// in `targets`) is row `row(t)`; a non-finite entry is an error naming its material.
fn gram_quantities(
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    c: usize,
    at: impl Fn(usize, usize) -> f64,
    col: impl Fn(usize) -> usize,
    row: impl Fn(usize) -> usize,
) -> Result<ChannelGram, FitError> {
    let m = basis.len() + 1;
    let mut g = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            g[i * m + j] = at(col(i), col(j));
        }
    }
    let mut hs = Vec::with_capacity(targets.len() * m);
    let mut bbs = Vec::with_capacity(targets.len());
    for (t, &ti) in targets.iter().enumerate() {
        let r = row(t);
        hs.extend((0..m).map(|i| at(col(i), r)));
        let bb = at(r, r);
        if !bb.is_finite() || hs[t * m..].iter().any(|v| !v.is_finite()) {
            return Err(FitError::NonFinite {
                material: coll.materials()[ti].name.clone(),
                channel: c,
            });
        }
        bbs.push(bb);
    }
    if let Some(i) = g.iter().position(|v| !v.is_finite()) {
        let k = (i / m).max(1) - 1;
        return Err(FitError::NonFinite {
            material: coll.materials()[basis[k]].name.clone(),
            channel: c,
        });
    }
    Ok(ChannelGram {
        gram: g,
        h: hs,
        bb: bbs,
    })
}

impl CollectionGrams {
    /// [`channel_gram`] of `basis` and `targets` of `coll` (the collection these Gram
    /// matrices were made of), channel `c`, read from the matrices: the same numbers, bit
    /// for bit, as a pass over these cells for those materials alone would give.
    pub fn channel_gram(
        &self,
        coll: &Collection,
        basis: &[usize],
        targets: &[usize],
        c: usize,
    ) -> Result<ChannelGram, FitError> {
        let n = coll.len() + 1;
        let full = &self.grams[c];
        gram_quantities(
            coll,
            basis,
            targets,
            c,
            |i, j| full[i * n + j],
            |a| if a == 0 { 0 } else { basis[a - 1] + 1 },
            |t| targets[t] + 1,
        )
    }

    /// Whether these are the Gram matrices over `cells` (same cells, same weights).
    pub fn covers(&self, cells: &CellSet) -> bool {
        self.cells.cells == cells.cells && self.cells.weights == cells.weights
    }
}
