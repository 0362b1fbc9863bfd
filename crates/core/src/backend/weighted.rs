//! Per-target weighted normal equations (SPEC 11): for each target `t` of a fit by a basis
//! of `k` lobes plus the Lambertian column `1 / pi` (SPEC 5), the `m x m` Gram matrix
//! `G_t[i][j] = sum_s W_t(s) f_i(s) f_j(s)`, the right-hand side
//! `r_t[i] = sum_s W_t(s) f_i(s) y_t(s)` and `yy_t = sum_s W_t(s) y_t(s)^2`, `m = k + 1`,
//! over a cell set with weights `w_s`, where `W_t(s) = w_s phi(y_t(s), s)` is the
//! objective's weight ([`TargetWeight`]). One pass gives every target's system; an NNLS
//! solve per target (SPEC 5's exact criterion with `W` in place of `w`) then fits it.
//!
//! [`reference()`] is the CPU twin and the f64 reference: rows tabulated by a back-end in
//! f32, every product and sum in f64, as matrix products (`G = W P`, `r = (W o Y) F`, each
//! value one fused multiply-add chain over the cells in order: the same bits on any
//! processor and thread count; within a few units in the last place of the plain scalar
//! loop, which the unit tests keep as the oracle). The GPU kernel (`weighted.wgsl` of the GPU crate) sums runs of
//! at most 1,024 cells in f32 and adds the runs in f64: its systems agree with the
//! reference within [`WEIGHTED_TOLERANCE`].

use super::{Backend, Lobe};
use crate::error::BackendError;
use crate::merl::CellSet;
use gemm::accumulate_chunk;

mod gemm;

/// The GPU kernel's agreement with [`reference()`], relative, per value: f32 sums of at most
/// 1,024 non-negative terms (error below `1024 x 2^-24`, about 6.1e-5, in the worst case;
/// about 1e-6 in practice) added in f64.
pub const WEIGHTED_TOLERANCE: f64 = 1e-4;

/// The objective's per-cell weight factor `phi` (SPEC 11), times the cell weight `w_s`.
///
/// Valid when built: `relative` is made by [`TargetWeight::relative`] (or
/// [`ObjectiveKind::weight`]), the one place its `eps` is checked. Its variant is
/// `#[non_exhaustive]`, so that no other crate can build it with an unchecked `eps`; the
/// back-ends and algorithms take a `TargetWeight` as valid:
///
/// ```
/// use brdf_basis_core::backend::weighted::TargetWeight;
/// let w = TargetWeight::relative(0.02).unwrap();
/// assert_eq!(w.eps(), Some(0.02));
/// assert!(TargetWeight::relative(0.0).is_err());
/// ```
///
/// ```compile_fail
/// use brdf_basis_core::backend::weighted::TargetWeight;
/// // Not outside the core crate: `eps` would go unchecked.
/// let w = TargetWeight::Relative { eps: 0.0 };
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TargetWeight {
    /// `l2`: `phi = 1` (SPEC 5).
    L2,
    /// `relative`: `phi = 1 / (max(y, 0) + eps)^2`. Built by [`TargetWeight::relative`].
    #[non_exhaustive]
    Relative {
        /// `eps` in the reflectance units of SPEC 2 (SPEC 11's default 0.01).
        eps: f64,
    },
    /// `log`: `phi = (c / (1 + max(y, 0) c))^2`, `c = max(cos theta_i, 0)` at the cell
    /// (the first-order form of an L2 in `log(1 + f cos theta_i)`).
    Log,
}

/// The objectives by name (SPEC 11), as the command line and Python give them; `eps` is
/// given apart ([`ObjectiveKind::weight`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ObjectiveKind {
    /// L2 on raw reflectance (SPEC 5, the paper's).
    L2,
    /// Relative: weights `1 / (f + eps)^2`.
    Relative,
    /// Log: weights `(c / (1 + f c))^2`.
    Log,
}

impl ObjectiveKind {
    /// Every objective.
    pub const ALL: [ObjectiveKind; 3] = [
        ObjectiveKind::L2,
        ObjectiveKind::Relative,
        ObjectiveKind::Log,
    ];

    /// The objective with `eps` (used by `relative` only, checked by
    /// [`TargetWeight::relative`]).
    ///
    /// # Errors
    /// [`BackendError::Invalid`] for `relative` with an `eps` outside its range.
    pub fn weight(self, eps: f64) -> Result<TargetWeight, BackendError> {
        match self {
            ObjectiveKind::L2 => Ok(TargetWeight::L2),
            ObjectiveKind::Relative => TargetWeight::relative(eps),
            ObjectiveKind::Log => Ok(TargetWeight::Log),
        }
    }

    /// The name on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            ObjectiveKind::L2 => "l2",
            ObjectiveKind::Relative => "relative",
            ObjectiveKind::Log => "log",
        }
    }
}

impl std::str::FromStr for ObjectiveKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        ObjectiveKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| format!("objective `{s}`: give l2, relative or log"))
    }
}

impl TargetWeight {
    /// SPEC 11's default `eps` of `relative`, in the reflectance units of SPEC 2.
    pub const DEFAULT_EPS: f64 = 0.01;

    /// The objective's kind.
    pub fn kind(self) -> ObjectiveKind {
        match self {
            TargetWeight::L2 => ObjectiveKind::L2,
            TargetWeight::Relative { .. } => ObjectiveKind::Relative,
            TargetWeight::Log => ObjectiveKind::Log,
        }
    }

    /// `eps` of `relative` (`None` for the others).
    pub fn eps(self) -> Option<f64> {
        match self {
            TargetWeight::Relative { eps } => Some(eps),
            _ => None,
        }
    }

    /// `phi(y)` at a cell whose incoming cosine is `cos_i`, in f64.
    pub fn phi(self, y: f64, cos_i: f64) -> f64 {
        let y = y.max(0.0);
        match self {
            TargetWeight::L2 => 1.0,
            TargetWeight::Relative { eps } => 1.0 / ((y + eps) * (y + eps)),
            TargetWeight::Log => {
                let c = cos_i.max(0.0);
                let q = c / (1.0 + y * c);
                q * q
            }
        }
    }

    /// The GPU kernel's code and parameter (`weighted.wgsl` of `brdf-basis-gpu`, part of
    /// the back-end contract): 0 = l2, 1 = relative (eps), 2 = log.
    pub fn code(self) -> (u32, f32) {
        match self {
            TargetWeight::L2 => (0, 0.0),
            TargetWeight::Relative { eps } => (1, eps as f32),
            TargetWeight::Log => (2, 0.0),
        }
    }

    /// The smallest `eps` of `relative` ([`Self::relative`]): the weight `1 / eps^2` of a
    /// zero reflectance stays at most 1e200.
    pub const MIN_EPS: f64 = 1e-100;
    /// The largest `eps` of `relative` ([`Self::relative`]): the weight `1 / (f + eps)^2`
    /// of the largest reflectance a fit carries (1e100, the samples files' bound; tabulated
    /// rows are f32, below 3.5e38) stays at least 2.5e-201.
    pub const MAX_EPS: f64 = 1e100;

    /// `relative` with `eps`, the one place `eps` is checked: a number from
    /// [`Self::MIN_EPS`] to [`Self::MAX_EPS`]. In that range the weights `1 / (f + eps)^2`
    /// of every reflectance `f` from 0 to 1e100 lie between 2.5e-201 and 1e200, so that
    /// neither they nor their products with cell weights and values underflow to 0 or
    /// overflow in f64 where they are formed (the GPU kernel forms them in f32 and hands the
    /// targets whose weights leave f32's range to the f64 reference). Beyond it an `eps`
    /// can make every weight 0 (a fit of nothing, all black, whose objective residual of 0
    /// would read as perfect) or infinite.
    ///
    /// # Errors
    /// [`BackendError::Invalid`] naming the relative objective's `eps` and its range.
    pub fn relative(eps: f64) -> Result<Self, BackendError> {
        if !(eps.is_finite() && eps > 0.0) {
            return Err(BackendError::Invalid(format!(
                "the relative objective's eps must be a positive number, not {eps}"
            )));
        }
        if !(Self::MIN_EPS..=Self::MAX_EPS).contains(&eps) {
            return Err(BackendError::Invalid(format!(
                "the relative objective's eps must lie between 1e-100 and 1e100, not {eps:e}: beyond that range its weights 1/(f + eps)^2 {} in f64 (inside it they stay between 1e-201 and 1e200 for every reflectance from 0 to 1e100)",
                match eps < Self::MIN_EPS {
                    true => "overflow where f is small",
                    false => "underflow to 0, which would fit nothing and read as a perfect fit",
                }
            )));
        }
        Ok(TargetWeight::Relative { eps })
    }
}

/// `cos theta_i` at a MERL grid cell (its centre angles; incoming direction by the MERL
/// convention: the difference vector rotated about the binormal by `theta_h`):
/// `cos theta_h cos theta_d - sin theta_h sin theta_d cos phi_d`.
pub fn cos_theta_i(cell: usize) -> f64 {
    use crate::merl::{phi_d, theta_d, theta_h, N_PD, N_TD};
    let (i, j, k) = (cell / (N_TD * N_PD), (cell / N_PD) % N_TD, cell % N_PD);
    let (th, td, pd) = (theta_h(i), theta_d(j), phi_d(k));
    th.cos() * td.cos() - th.sin() * td.sin() * pd.cos()
}

/// Every target's weighted system: `values` holds, per target, the upper triangle of `G`
/// row by row (`i <= j`), then `r`, then `yy`.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightedSystems {
    /// Columns `m`: the Lambertian term and the basis lobes.
    pub columns: usize,
    /// The systems, [`Self::stride`] values per target.
    pub values: Vec<f64>,
}

impl WeightedSystems {
    /// Values per target for `m` columns: `m (m + 1) / 2 + m + 1`.
    pub fn stride_for(m: usize) -> usize {
        m * (m + 1) / 2 + m + 1
    }

    /// Values per target.
    pub fn stride(&self) -> usize {
        Self::stride_for(self.columns)
    }

    /// Targets.
    pub fn len(&self) -> usize {
        self.values.len() / self.stride().max(1)
    }

    /// Whether there is no target.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Target `t`'s Gram matrix, full `m x m`, row-major.
    pub fn gram(&self, t: usize) -> Vec<f64> {
        let m = self.columns;
        let v = &self.values[t * self.stride()..];
        let mut g = vec![0.0; m * m];
        let mut q = 0;
        for i in 0..m {
            for j in i..m {
                g[i * m + j] = v[q];
                g[j * m + i] = v[q];
                q += 1;
            }
        }
        g
    }

    /// Target `t`'s right-hand side (`m` values).
    pub fn rhs(&self, t: usize) -> &[f64] {
        let m = self.columns;
        let at = t * self.stride() + m * (m + 1) / 2;
        &self.values[at..at + m]
    }

    /// Target `t`'s weighted sum of squares `sum_s W y^2`.
    pub fn yy(&self, t: usize) -> f64 {
        self.values[(t + 1) * self.stride() - 1]
    }
}

/// Cells per chunk of the reference (rows of every lobe tabulated per chunk).
pub(crate) const REFERENCE_CHUNK: usize = 1 << 14;

/// The f64 reference of every target's system (the CPU twin of the GPU kernel): rows
/// tabulated by `backend` (f32), `W_t(s) = w_s phi(y)` and every product and sum in f64,
/// each value a fused multiply-add chain over the cells in order, as cache-blocked matrix
/// products with the targets in parallel (the module `gemm`: the same bits whatever the
/// thread count or processor; within 1e-12 relative of the scalar loop it replaced, which
/// the unit tests keep as the oracle).
pub fn reference<B: Backend + ?Sized>(
    backend: &B,
    basis: &[Lobe],
    targets: &[Lobe],
    cells: &CellSet,
    weight: TargetWeight,
    progress: super::Progress<'_>,
) -> Result<WeightedSystems, BackendError> {
    let m = basis.len() + 1;
    let mut values = vec![0f64; targets.len() * WeightedSystems::stride_for(m)];
    let mut done = 0usize;
    for (cc, cw) in cells
        .cells
        .chunks(REFERENCE_CHUNK)
        .zip(cells.weights.chunks(REFERENCE_CHUNK))
    {
        let b = backend.tabulate(basis, cc)?;
        let y = backend.tabulate(targets, cc)?;
        accumulate_chunk(&mut values, m, &b, &y, cc, cw, weight);
        done += cc.len();
        progress(done as u64, cells.cells.len() as u64);
    }
    Ok(WeightedSystems { columns: m, values })
}

/// [`reference()`] of three channels (`basis[c]`, `targets[c]`, the same counts each) in one
/// pass over `cells`: per chunk the three channels' lobes are tabulated by one call each
/// for the basis and the targets (a network then runs once per cell for its three
/// channels), then each channel is accumulated as [`reference()`] does it: the same bits.
pub fn reference_per_channel<B: Backend + ?Sized>(
    backend: &B,
    basis: [&[Lobe]; 3],
    targets: [&[Lobe]; 3],
    cells: &CellSet,
    weight: TargetWeight,
    progress: super::Progress<'_>,
) -> Result<[WeightedSystems; 3], BackendError> {
    let tabulate = |lobes: &[Lobe], cc: &[u32], _: usize| backend.tabulate(lobes, cc);
    reference_per_channel_by(&tabulate, basis, targets, cells, weight, progress)
}

/// A chunk's rows: `(lobes, the chunk's cells, the chunk's offset in the cell set)` to the
/// lobe-major f32 rows of [`Backend::tabulate`].
pub(crate) type ChunkRows<'a> =
    dyn Fn(&[Lobe], &[u32], usize) -> Result<Vec<f32>, BackendError> + Sync + 'a;

/// [`reference_per_channel`] with each chunk's rows from `tabulate` (the same values as
/// the back-end's tabulation: the CPU back-end reads networks from tabulations it keeps).
pub(crate) fn reference_per_channel_by(
    tabulate: &ChunkRows<'_>,
    basis: [&[Lobe]; 3],
    targets: [&[Lobe]; 3],
    cells: &CellSet,
    weight: TargetWeight,
    progress: super::Progress<'_>,
) -> Result<[WeightedSystems; 3], BackendError> {
    let (k, t) = (basis[0].len(), targets[0].len());
    if basis.iter().any(|b| b.len() != k) || targets.iter().any(|y| y.len() != t) {
        return Err(BackendError::Invalid(
            "weighted systems per channel: the channels have different lobe counts".into(),
        ));
    }
    let m = k + 1;
    let all_basis: Vec<Lobe> = basis.iter().flat_map(|b| b.iter().cloned()).collect();
    let all_targets: Vec<Lobe> = targets.iter().flat_map(|y| y.iter().cloned()).collect();
    let mut values: [Vec<f64>; 3] =
        std::array::from_fn(|_| vec![0f64; t * WeightedSystems::stride_for(m)]);
    let mut done = 0usize;
    for (cc, cw) in cells
        .cells
        .chunks(REFERENCE_CHUNK)
        .zip(cells.weights.chunks(REFERENCE_CHUNK))
    {
        let n = cc.len();
        let b = tabulate(&all_basis, cc, done)?;
        let y = tabulate(&all_targets, cc, done)?;
        for (c, v) in values.iter_mut().enumerate() {
            let bc = &b[c * k * n..(c + 1) * k * n];
            let yc = &y[c * t * n..(c + 1) * t * n];
            accumulate_chunk(v, m, bc, yc, cc, cw, weight);
        }
        done += n;
        progress(done as u64, cells.cells.len() as u64);
    }
    Ok(values.map(|values| WeightedSystems { columns: m, values }))
}

/// [`reference`] one target and cell at a time, as first written: the oracle the blocked
/// version is held to, bit for bit.
#[cfg(test)]
pub(crate) fn reference_scalar<B: Backend + ?Sized>(
    backend: &B,
    basis: &[Lobe],
    targets: &[Lobe],
    cells: &CellSet,
    weight: TargetWeight,
    progress: super::Progress<'_>,
) -> Result<WeightedSystems, BackendError> {
    use rayon::prelude::*;
    let m = basis.len() + 1;
    let stride = WeightedSystems::stride_for(m);
    let mut values = vec![0f64; targets.len() * stride];
    let lambert = std::f32::consts::FRAC_1_PI as f64;
    let mut done = 0usize;
    for (cc, cw) in cells
        .cells
        .chunks(REFERENCE_CHUNK)
        .zip(cells.weights.chunks(REFERENCE_CHUNK))
    {
        let n = cc.len();
        let b = backend.tabulate(basis, cc)?;
        let y = backend.tabulate(targets, cc)?;
        let cos_i: Vec<f64> = cc.iter().map(|&c| cos_theta_i(c as usize)).collect();
        values
            .par_chunks_mut(stride)
            .zip(y.par_chunks(n.max(1)))
            .for_each(|(v, yt)| {
                let mut f = vec![0f64; m];
                f[0] = lambert;
                for (c, &yc) in yt.iter().enumerate() {
                    let yc = yc as f64;
                    let w = cw[c] * weight.phi(yc, cos_i[c]);
                    for (j, fj) in f.iter_mut().enumerate().skip(1) {
                        *fj = b[(j - 1) * n + c] as f64;
                    }
                    let mut q = 0;
                    for i in 0..m {
                        let wf = w * f[i];
                        for &fj in &f[i..] {
                            v[q] += wf * fj;
                            q += 1;
                        }
                    }
                    for (i, &fi) in f.iter().enumerate() {
                        v[q + i] += w * fi * yc;
                    }
                    v[q + m] += w * yc * yc;
                }
            });
        done += n;
        progress(done as u64, cells.cells.len() as u64);
    }
    Ok(WeightedSystems { columns: m, values })
}
