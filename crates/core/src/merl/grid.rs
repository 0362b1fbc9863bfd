//! The 90 x 90 x 180 half/difference grid (Rusinkiewicz 1998, doi:10.1007/978-3-7091-6453-2_2)
//! of Matusik et al.: cell angles, directions, the MERL lookup, validity, the evaluation
//! mask and sample weights (SPEC 2-3).
//!
//! Cell `(i, j, k)` has flat index `k + 180 (j + 90 i)` and is sampled at its centre in
//! index space: `theta_h = ((i + 0.5) / 90)^2 pi / 2`, `theta_d = (j + 0.5) pi / 180`,
//! `phi_d = (k + 0.5) pi / 180`.

use std::f64::consts::{FRAC_PI_2, PI};

/// Cells along theta_h.
pub const N_TH: usize = 90;
/// Cells along theta_d.
pub const N_TD: usize = 90;
/// Cells along phi_d (folded into [0, pi) by reciprocity).
pub const N_PD: usize = 180;
/// Cells in the grid.
pub const N_CELLS: usize = N_TH * N_TD * N_PD;
/// Tolerance (radians) of the angle tests, in favour of inclusion (SPEC 3).
pub const ANGLE_TOL: f64 = 1e-9;

/// Flat index of cell `(i, j, k)`.
#[inline]
pub fn flat(i: usize, j: usize, k: usize) -> usize {
    k + N_PD * (j + N_TD * i)
}

/// `(i, j, k)` of a flat index.
#[inline]
pub fn unflat(idx: usize) -> (usize, usize, usize) {
    (idx / (N_TD * N_PD), (idx / N_PD) % N_TD, idx % N_PD)
}

/// Sample angle theta_h of row `i`.
#[inline]
pub fn theta_h(i: usize) -> f64 {
    let t = (i as f64 + 0.5) / N_TH as f64;
    t * t * FRAC_PI_2
}

/// Sample angle theta_d of row `j`.
#[inline]
pub fn theta_d(j: usize) -> f64 {
    (j as f64 + 0.5) * PI / 180.0
}

/// Sample angle phi_d of row `k`.
#[inline]
pub fn phi_d(k: usize) -> f64 {
    (k as f64 + 0.5) * PI / 180.0
}

/// `(theta_h, theta_d, phi_d)` of a flat cell index.
pub fn cell_angles(idx: usize) -> (f64, f64, f64) {
    let (i, j, k) = unflat(idx);
    (theta_h(i), theta_d(j), phi_d(k))
}

/// Incoming and outgoing directions of half/difference angles (phi_h = 0), SPEC 2.
pub fn directions(th: f64, td: f64, pd: f64) -> ([f64; 3], [f64; 3]) {
    let (sh, ch) = th.sin_cos();
    directions_of(sh, ch, td.sin(), td.cos(), pd.sin(), pd.cos())
}

/// [`directions`] from the sines and cosines of its angles (the same arithmetic, so the
/// same bits when they are the same values).
#[inline]
fn directions_of(s: f64, c: f64, sd: f64, cd: f64, sp: f64, cp: f64) -> ([f64; 3], [f64; 3]) {
    let d = [sd * cp, sd * sp, cd];
    // wi = R_y(theta_h) d
    let wi = [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]];
    let h = [s, 0.0, c];
    let wh = wi[0] * h[0] + wi[1] * h[1] + wi[2] * h[2];
    let wo = [
        2.0 * wh * h[0] - wi[0],
        2.0 * wh * h[1] - wi[1],
        2.0 * wh * h[2] - wi[2],
    ];
    (wi, wo)
}

/// Directions of a flat cell index.
pub fn cell_directions(idx: usize) -> ([f64; 3], [f64; 3]) {
    let (th, td, pd) = cell_angles(idx);
    directions(th, td, pd)
}

fn rot_z(v: [f64; 3], a: f64) -> [f64; 3] {
    let (s, c) = a.sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
}

fn rot_y(v: [f64; 3], a: f64) -> [f64; 3] {
    let (s, c) = a.sin_cos();
    [c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]]
}

/// Half/difference angles `(theta_h, theta_d, phi_d)` of a pair of unit directions
/// (the classic MERL `std_coords_to_half_diff_coords`).
pub(crate) fn half_diff(wi: [f64; 3], wo: [f64; 3]) -> (f64, f64, f64) {
    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
    let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let h = [h[0] / l, h[1] / l, h[2] / l];
    let th = h[2].clamp(-1.0, 1.0).acos();
    let ph = h[1].atan2(h[0]);
    let d = rot_y(rot_z(wi, -ph), -th);
    let td = d[2].clamp(-1.0, 1.0).acos();
    let pd = d[1].atan2(d[0]);
    (th, td, pd)
}

/// The MERL lookup: the flat cell of half/difference angles (indices clamped, phi_d folded).
pub fn lookup_angles(th: f64, td: f64, pd: f64) -> usize {
    let ti = ((th / FRAC_PI_2).max(0.0).sqrt() * N_TH as f64).floor();
    let i = (ti.max(0.0) as usize).min(N_TH - 1);
    let tj = (td / FRAC_PI_2 * N_TD as f64).floor();
    let j = (tj.max(0.0) as usize).min(N_TD - 1);
    let pd = if pd < 0.0 { pd + PI } else { pd };
    let tk = (pd / PI * N_PD as f64).floor();
    let k = (tk.max(0.0) as usize).min(N_PD - 1);
    flat(i, j, k)
}

/// The MERL lookup of a pair of directions.
pub fn lookup(wi: [f64; 3], wo: [f64; 3]) -> usize {
    let (th, td, pd) = half_diff(wi, wo);
    lookup_angles(th, td, pd)
}

/// Geometry of one cell, all in f64.
#[derive(Clone, Copy, Debug)]
pub struct CellInfo {
    /// Both directions above the horizon.
    pub valid: bool,
    /// In the evaluation mask of SPEC 3.
    pub evaluation: bool,
    /// Exact measure of the cell's bin (unnormalised solid-angle weight).
    pub measure: f64,
}

/// Unnormalised solid-angle weight of cell `(i, j, k)`: the integral of
/// `4 sin theta_h cos theta_d sin theta_d` over its bin (SPEC 3).
pub fn bin_measure(i: usize, j: usize, _k: usize) -> f64 {
    let ah = (i as f64 / N_TH as f64).powi(2) * FRAC_PI_2;
    let bh = ((i + 1) as f64 / N_TH as f64).powi(2) * FRAC_PI_2;
    let ad = j as f64 * PI / 180.0;
    let bd = (j + 1) as f64 * PI / 180.0;
    let dp = PI / 180.0;
    4.0 * (ah.cos() - bh.cos()) * (bd.sin().powi(2) - ad.sin().powi(2)) / 2.0 * dp
}

/// Whether each cell's directions are both above the horizon (cached, computed once).
pub fn geometric_validity() -> &'static [bool] {
    &classes().valid
}

/// Whether each cell is in the evaluation mask of SPEC 3 (cached, computed once).
pub(crate) fn evaluation_mask() -> &'static [bool] {
    &classes().evaluation
}

/// Every cell's membership of the two masks, by flat index: [`cell_info`]'s `valid` and
/// `evaluation`, computed once per process.
struct Classes {
    valid: Vec<bool>,
    evaluation: Vec<bool>,
}

/// Distance from a threshold within which an angle test falls back to `acos` itself.
/// `acos` is accurate to an ulp or so; away from the thresholds the cosine decides the
/// test the same way (acos is decreasing), and 1e-12 is far beyond its rounding.
const COS_BAND: f64 = 1e-12;

fn classes() -> &'static Classes {
    static CLASSES: std::sync::OnceLock<Classes> = std::sync::OnceLock::new();
    CLASSES.get_or_init(|| {
        use rayon::prelude::*;
        // The sines and cosines of every axis's angles, computed as `directions` computes
        // them: the directions below are bit for bit those of `cell_info`.
        let h: Vec<(f64, f64)> = (0..N_TH).map(|i| theta_h(i).sin_cos()).collect();
        let d: Vec<(f64, f64)> = (0..N_TD)
            .map(|j| (theta_d(j).sin(), theta_d(j).cos()))
            .collect();
        let p: Vec<(f64, f64)> = (0..N_PD)
            .map(|k| (phi_d(k).sin(), phi_d(k).cos()))
            .collect();
        let lim = 80f64.to_radians() + ANGLE_TOL;
        let retro_lim = 3f64.to_radians() - ANGLE_TOL;
        let (cos_lim, cos_retro) = (lim.cos(), retro_lim.cos());
        // `acos(x) <= lim` (resp. `< retro_lim`) as `cell_info` decides it: by the cosine
        // where it is clearly on one side, by `acos` itself near the threshold.
        let within = |x: f64| {
            if x > cos_lim + COS_BAND {
                true
            } else if x < cos_lim - COS_BAND {
                false
            } else {
                x.clamp(-1.0, 1.0).acos() <= lim
            }
        };
        let retro = |x: f64| {
            if x > cos_retro + COS_BAND {
                true
            } else if x < cos_retro - COS_BAND {
                false
            } else {
                x.clamp(-1.0, 1.0).acos() < retro_lim
            }
        };
        let rows: Vec<Vec<(bool, bool)>> = (0..N_TH)
            .into_par_iter()
            .map(|i| {
                let (sh, ch) = h[i];
                let mut out = Vec::with_capacity(N_TD * N_PD);
                for &(sd, cd) in &d {
                    for &(sp, cp) in &p {
                        let (wi, wo) = directions_of(sh, ch, sd, cd, sp, cp);
                        let valid = wi[2] > 0.0 && wo[2] > 0.0;
                        let cos_io =
                            (wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2]).clamp(-1.0, 1.0);
                        let evaluation = valid && within(wi[2]) && within(wo[2]) && !retro(cos_io);
                        out.push((valid, evaluation));
                    }
                }
                out
            })
            .collect();
        let (valid, evaluation) = rows.into_iter().flatten().unzip();
        Classes { valid, evaluation }
    })
}

/// Classifies one cell (SPEC 2-3): horizon, 80 deg and 3 deg tests in f64 with a
/// tolerance of [`ANGLE_TOL`] in favour of inclusion.
pub fn cell_info(idx: usize) -> CellInfo {
    let (i, j, k) = unflat(idx);
    let (wi, wo) = directions(theta_h(i), theta_d(j), phi_d(k));
    let ti = wi[2].clamp(-1.0, 1.0).acos();
    let to = wo[2].clamp(-1.0, 1.0).acos();
    let valid = wi[2] > 0.0 && wo[2] > 0.0;
    let lim = 80f64.to_radians() + ANGLE_TOL;
    let cos_io = (wi[0] * wo[0] + wi[1] * wo[1] + wi[2] * wo[2]).clamp(-1.0, 1.0);
    let retro = cos_io.acos() < 3f64.to_radians() - ANGLE_TOL;
    CellInfo {
        valid,
        evaluation: valid && ti <= lim && to <= lim && !retro,
        measure: bin_measure(i, j, k),
    }
}

/// Which cells a computation runs over. Spellings (`evaluation`, `valid`) come from one
/// table, [`Mask::as_str`], used by [`FromStr`] and [`Display`](std::fmt::Display) alike
/// (the command line's names are the same; a unit test of `brdf-basis-cli` checks it).
///
/// [`FromStr`]: std::str::FromStr
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mask {
    /// Valid cells with theta_i, theta_o <= 80 deg and 2 theta_d >= 3 deg (paper VI-E).
    Evaluation,
    /// Every valid cell (both directions above the horizon).
    Valid,
}

/// How cells are weighted (`uniform`, `solid-angle`; spellings as for [`Mask`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Weighting {
    /// Every cell of the mask weighs 1 (the paper's Eq. 5).
    Uniform,
    /// A cell weighs the exact measure of its bin (the paper's future work).
    SolidAngle,
}

impl Mask {
    /// Every mask, in the order of the spellings' list.
    pub const ALL: [Mask; 2] = [Mask::Evaluation, Mask::Valid];

    /// The spelling: `evaluation` or `valid`.
    pub fn as_str(self) -> &'static str {
        match self {
            Mask::Evaluation => "evaluation",
            Mask::Valid => "valid",
        }
    }
}

impl Weighting {
    /// Every weighting, in the order of the spellings' list.
    pub const ALL: [Weighting; 2] = [Weighting::Uniform, Weighting::SolidAngle];

    /// The spelling: `uniform` or `solid-angle`.
    pub fn as_str(self) -> &'static str {
        match self {
            Weighting::Uniform => "uniform",
            Weighting::SolidAngle => "solid-angle",
        }
    }
}

/// Which grid cells a command reduces over and how they are weighted: the `--mask`,
/// `--weighting` and `--stride` of `distance`, `select`, `fit`, `cv` and
/// `cv --acquisition`, one value checked when it is built ([`GridSpec::new`]): a
/// `GridSpec` holds a stride from 1 (the full grid) to [`GridSpec::MAX_STRIDE`]. The
/// requests, the command line and Python hold their grid as one; its [`Default`] is the
/// library's (evaluation mask, uniform weights, the full grid).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridSpec {
    mask: Mask,
    weighting: Weighting,
    stride: usize,
}

impl Default for GridSpec {
    fn default() -> Self {
        Self {
            mask: Mask::Evaluation,
            weighting: Weighting::Uniform,
            stride: 1,
        }
    }
}

impl GridSpec {
    /// The largest stride: one cell per `theta_h` row.
    pub const MAX_STRIDE: usize = N_TH;
    /// The rule of `--stride`, its one wording (the command line's parser, the requests,
    /// Python and the core's parameter checks).
    pub const STRIDE_RULE: &'static str = "expected a whole number from 1 (the full grid) to 90";

    /// The grid of `mask`, `weighting` and `stride`, checked: the stride's rule.
    ///
    /// # Errors
    /// [`crate::error::Refusal::OutOfRange`] naming `--stride` for a stride outside
    /// 1..=[`Self::MAX_STRIDE`].
    pub fn new(
        mask: Mask,
        weighting: Weighting,
        stride: usize,
    ) -> Result<Self, crate::error::Refusal> {
        if !Self::stride_ok(stride) {
            return Err(crate::error::Refusal::OutOfRange {
                setting: "--stride",
                value: Some(stride.to_string()),
                rule: Self::STRIDE_RULE.to_string(),
            });
        }
        Ok(Self {
            mask,
            weighting,
            stride,
        })
    }

    /// Whether `stride` keeps the rule ([`Self::STRIDE_RULE`]).
    pub fn stride_ok(stride: usize) -> bool {
        (1..=Self::MAX_STRIDE).contains(&stride)
    }

    /// This grid with another mask.
    pub fn with_mask(self, mask: Mask) -> Self {
        Self { mask, ..self }
    }

    /// This grid with another weighting.
    pub fn with_weighting(self, weighting: Weighting) -> Self {
        Self { weighting, ..self }
    }

    /// This grid with another stride, checked ([`Self::new`]).
    ///
    /// # Errors
    /// As [`Self::new`].
    pub fn with_stride(self, stride: usize) -> Result<Self, crate::error::Refusal> {
        Self::new(self.mask, self.weighting, stride)
    }

    /// Grid cells.
    pub fn mask(&self) -> Mask {
        self.mask
    }

    /// Cell weights.
    pub fn weighting(&self) -> Weighting {
        self.weighting
    }

    /// Every `stride`-th cell on each grid axis (1: the full grid).
    pub fn stride(&self) -> usize {
        self.stride
    }
}

/// The value of `all` spelled exactly `s` (`as_str`); `what` names the option and
/// `expected` lists the spellings in the error.
fn parse_named<T: Copy>(
    s: &str,
    all: &[T],
    as_str: fn(T) -> &'static str,
    what: &'static str,
    expected: &'static str,
) -> Result<T, crate::error::DistanceError> {
    all.iter()
        .copied()
        .find(|&v| as_str(v) == s)
        .ok_or_else(|| crate::error::DistanceError::UnknownOption {
            what,
            found: s.into(),
            expected,
        })
}

impl std::str::FromStr for Mask {
    type Err = crate::error::DistanceError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse_named(s, &Mask::ALL, Mask::as_str, "mask", "evaluation, valid")
    }
}

impl std::str::FromStr for Weighting {
    type Err = crate::error::DistanceError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse_named(
            s,
            &Weighting::ALL,
            Weighting::as_str,
            "weighting",
            "uniform, solid-angle",
        )
    }
}

impl std::fmt::Display for Mask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::fmt::Display for Weighting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Why a cell set of `mask` at `stride` came out empty for `what` (e.g. "the
/// collection"), in words: either the sub-sampled grid itself has no cell in the mask
/// (the stride leaves too few cells: say so, with the largest stride that leaves some),
/// or the materials' valid cells have none in common.
pub fn no_cells_reason(mask: Mask, stride: usize, what: &str) -> String {
    let s = stride.max(1);
    let in_mask = CellSet::new(mask, Weighting::Uniform, s).cells.len();
    if in_mask > 0 {
        return format!(
            "no cell of the {mask} mask ({in_mask} cells at stride {s}) is valid in every material of {what}: their measured cells have none in common; use --mask valid or materials measured over common cells"
        );
    }
    let (a, b, c) = (N_TH.div_ceil(s), N_TD.div_ceil(s), N_PD.div_ceil(s));
    let largest = (1..s)
        .rev()
        .find(|&t| !CellSet::new(mask, Weighting::Uniform, t).cells.is_empty())
        .unwrap_or(1);
    format!(
        "--stride {s} leaves too few cells: the grid sampled every {s} cells has {a} x {b} x {c} = {} cells, none of them in the {mask} mask; use --stride {largest} or less",
        a * b * c
    )
}

/// An ordered list of grid cells with weights normalised to sum 1: what every reduction
/// over the grid (distances, Gram matrices, errors) iterates over.
#[derive(Clone, Debug)]
pub struct CellSet {
    /// Flat cell indices, increasing.
    pub cells: Vec<u32>,
    /// Weight of each cell, summing to 1.
    pub weights: Vec<f64>,
    /// The mask used.
    pub mask: Mask,
    /// The weighting used.
    pub weighting: Weighting,
    /// Sub-sampling stride on each axis (1 = full grid).
    pub stride: usize,
}

impl CellSet {
    /// Cells of `mask` on the grid sub-sampled every `stride` cells on each axis
    /// (`stride = 1`: the full grid), weighted by `weighting`.
    pub fn new(mask: Mask, weighting: Weighting, stride: usize) -> Self {
        use rayon::prelude::*;
        let stride = stride.max(1);
        // One theta_h row of cells per task, concatenated in grid order: the same cells
        // and weights as a sequential pass.
        // Membership from the cached classification of every cell (`cell_info`'s, bit
        // for bit); the solid-angle weight depends on (i, j) only (`bin_measure`).
        let member = match mask {
            Mask::Evaluation => evaluation_mask(),
            Mask::Valid => geometric_validity(),
        };
        let rows: Vec<usize> = (0..N_TH).step_by(stride).collect();
        let parts: Vec<(Vec<u32>, Vec<f64>)> = rows
            .par_iter()
            .map(|&i| {
                let mut cells = Vec::new();
                let mut weights = Vec::new();
                for j in (0..N_TD).step_by(stride) {
                    let w = match weighting {
                        Weighting::Uniform => 1.0,
                        Weighting::SolidAngle => bin_measure(i, j, 0),
                    };
                    for k in (0..N_PD).step_by(stride) {
                        let idx = flat(i, j, k);
                        if member[idx] {
                            cells.push(idx as u32);
                            weights.push(w);
                        }
                    }
                }
                (cells, weights)
            })
            .collect();
        let mut cells = Vec::with_capacity(parts.iter().map(|p| p.0.len()).sum());
        let mut weights = Vec::with_capacity(cells.capacity());
        for (c, w) in parts {
            cells.extend(c);
            weights.extend(w);
        }
        let total: f64 = weights.iter().sum();
        for w in &mut weights {
            *w /= total;
        }
        Self {
            cells,
            weights,
            mask,
            weighting,
            stride,
        }
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// True when the set has no cell.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
}

/// Per-axis f64 geometry tables from which the model is evaluated on any cell: every
/// quantity of rho_s on the grid factors into per-axis terms.
#[derive(Clone, Debug)]
pub struct GridTables {
    /// cos theta_h per i.
    pub cos_h: [f64; N_TH],
    /// sin theta_h per i.
    pub sin_h: [f64; N_TH],
    /// ln cos theta_h = log1p(-2 sin^2(theta_h / 2)) per i.
    pub ln_cos_h: [f64; N_TH],
    /// cos theta_d per j.
    pub cos_d: [f64; N_TD],
    /// sin theta_d per j.
    pub sin_d: [f64; N_TD],
    /// Schlick weight (1 - cos theta_d)^5 per j.
    pub schlick_d: [f64; N_TD],
    /// |cos phi_d| per k.
    pub abs_cos_p: [f64; N_PD],
}

impl Default for GridTables {
    fn default() -> Self {
        Self::new()
    }
}

impl GridTables {
    /// Builds the tables.
    pub fn new() -> Self {
        let mut t = Self {
            cos_h: [0.0; N_TH],
            sin_h: [0.0; N_TH],
            ln_cos_h: [0.0; N_TH],
            cos_d: [0.0; N_TD],
            sin_d: [0.0; N_TD],
            schlick_d: [0.0; N_TD],
            abs_cos_p: [0.0; N_PD],
        };
        for i in 0..N_TH {
            let th = theta_h(i);
            t.cos_h[i] = th.cos();
            t.sin_h[i] = th.sin();
            let s = (0.5 * th).sin();
            t.ln_cos_h[i] = (-2.0 * s * s).ln_1p();
        }
        for j in 0..N_TD {
            let td = theta_d(j);
            t.cos_d[j] = td.cos();
            t.sin_d[j] = td.sin();
            // 1 - cos = 2 sin^2(t/2), exact near 0.
            let s = (0.5 * td).sin();
            t.schlick_d[j] = (2.0 * s * s).powi(5);
        }
        for k in 0..N_PD {
            t.abs_cos_p[k] = phi_d(k).cos().abs();
        }
        t
    }

    /// `max(N.wi, N.wo) = cos th cos td + sin th sin td |cos pd|` of cell `(i, j, k)`.
    #[inline]
    pub fn max_cos(&self, i: usize, j: usize, k: usize) -> f64 {
        self.cos_h[i] * self.cos_d[j] + self.sin_h[i] * self.sin_d[j] * self.abs_cos_p[k]
    }

    /// The separable form's cell factor (src/separable.rs): `(i * 90 + j, 1 / (cos theta_d
    /// max(N.wi, N.wo)))` of `cell`, so that an analytic lobe is
    /// `alpha + factor * beta[i * 90 + j]`.
    #[inline]
    pub fn cell_factor(&self, cell: usize) -> (usize, f64) {
        let (i, j, k) = (cell / (N_TD * N_PD), (cell / N_PD) % N_TD, cell % N_PD);
        (i * N_TD + j, 1.0 / (self.cos_d[j] * self.max_cos(i, j, k)))
    }

    /// `rho_s` of `(F0, n)` at cell `(i, j, k)`, in f64.
    #[inline]
    pub fn rho_s(&self, i: usize, j: usize, k: usize, f0: f64, n: f64) -> f64 {
        let f = f0 + (1.0 - f0) * self.schlick_d[j];
        (n + 1.0) * (n * self.ln_cos_h[i]).exp() * f
            / (8.0 * PI * self.cos_d[j] * self.max_cos(i, j, k))
    }
}

#[cfg(test)]
mod spelling_tests {
    use super::*;

    #[test]
    fn spellings_round_trip_and_unknown_ones_are_named() {
        for m in Mask::ALL {
            assert_eq!(m.to_string().parse::<Mask>().unwrap(), m);
        }
        for w in Weighting::ALL {
            assert_eq!(w.to_string().parse::<Weighting>().unwrap(), w);
        }
        assert_eq!(
            "solid-angle".parse::<Weighting>().unwrap(),
            Weighting::SolidAngle
        );
        let e = "Valid".parse::<Mask>().unwrap_err().to_string();
        assert!(
            e.contains("`Valid`") && e.contains("evaluation, valid"),
            "{e}"
        );
        let e = "solid_angle".parse::<Weighting>().unwrap_err().to_string();
        assert!(e.contains("uniform, solid-angle"), "{e}");
    }
}

#[cfg(test)]
mod cell_set_tests {
    use super::*;

    /// The cell set as it was built before the classification was cached: `cell_info` of
    /// every cell, in grid order, its `measure` as the solid-angle weight.
    fn reference(mask: Mask, weighting: Weighting, stride: usize) -> (Vec<u32>, Vec<f64>) {
        let mut cells = Vec::new();
        let mut weights = Vec::new();
        for i in (0..N_TH).step_by(stride) {
            for j in (0..N_TD).step_by(stride) {
                for k in (0..N_PD).step_by(stride) {
                    let idx = flat(i, j, k);
                    let info = cell_info(idx);
                    let keep = match mask {
                        Mask::Evaluation => info.evaluation,
                        Mask::Valid => info.valid,
                    };
                    if keep {
                        cells.push(idx as u32);
                        weights.push(match weighting {
                            Weighting::Uniform => 1.0,
                            Weighting::SolidAngle => info.measure,
                        });
                    }
                }
            }
        }
        let total: f64 = weights.iter().sum();
        for w in &mut weights {
            *w /= total;
        }
        (cells, weights)
    }

    #[test]
    fn cached_classification_is_cell_info_for_every_cell() {
        let (valid, evaluation) = (geometric_validity(), evaluation_mask());
        let mut near = 0;
        for c in 0..N_CELLS {
            let info = cell_info(c);
            assert_eq!(valid[c], info.valid, "valid, cell {c}");
            assert_eq!(evaluation[c], info.evaluation, "evaluation, cell {c}");
            near += usize::from(info.valid != info.evaluation);
        }
        // Both masks are exercised: cells in one and not the other exist.
        assert!(near > 0 && evaluation.iter().any(|&e| e));
    }

    #[test]
    fn cell_sets_are_the_cell_info_ones_bit_for_bit() {
        for mask in Mask::ALL {
            for weighting in Weighting::ALL {
                for stride in [1, 2, 3, 4, 7, 45] {
                    let cs = CellSet::new(mask, weighting, stride);
                    let (cells, weights) = reference(mask, weighting, stride);
                    let what = format!("{mask} {weighting} stride {stride}");
                    assert_eq!(cs.cells, cells, "{what}");
                    let bits = |w: &[f64]| w.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&cs.weights), bits(&weights), "{what}");
                }
            }
        }
    }
}
