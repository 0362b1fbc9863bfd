//! Distances between materials (SPEC 4): the paper's BRDF_it (Eq. 5) on the specular or
//! full lobe, over the evaluation mask or every valid cell, with uniform or solid-angle
//! weights, and the Euclidean (F0, n) baseline.

mod band;
mod matrix;

pub use band::*;

pub use matrix::*;
pub(crate) use matrix::{check_entries, entry_fault};

use crate::backend::{condensed_index, Backend, Lobe, Progress};
use crate::brdf::LobeParams;
use crate::collection::{Collection, MaterialData};
use crate::error::DistanceError;
use crate::merl::{CellSet, Mask, Weighting};
use std::num::NonZeroUsize;

/// Which distance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Metric {
    /// The paper's BRDF_it: weighted mean absolute difference of lobes over the grid.
    BrdfIt,
    /// Euclidean distance between raw (F0, n) vectors (the paper's baseline).
    Euclidean,
}

/// Which function of a material BRDF_it compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LobeKind {
    /// `rho_s(F0, n)`, colour-free (analytic materials only): the paper's choice.
    Specular,
    /// The mean over R, G, B of the full reflectance `f_c`.
    Full,
}

macro_rules! named_enum {
    ($t:ty, $what:literal, $expected:literal, $($s:literal => $v:expr),+) => {
        impl std::str::FromStr for $t {
            type Err = DistanceError;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                match s {
                    $($s => Ok($v),)+
                    _ => Err(DistanceError::UnknownOption { what: $what, found: s.into(), expected: $expected }),
                }
            }
        }
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                $(if *self == $v { return f.write_str($s); })+
                Ok(())
            }
        }
    };
}
named_enum!(Metric, "metric", "brdf-it, euclidean", "brdf-it" => Metric::BrdfIt, "euclidean" => Metric::Euclidean);
named_enum!(LobeKind, "lobe", "specular, full", "specular" => LobeKind::Specular, "full" => LobeKind::Full);

/// Distance parameters (builder). Defaults: BRDF_it, evaluation mask, uniform weights,
/// lobe chosen from the collection (specular when every material is analytic, else full),
/// full grid (stride 1).
#[derive(Clone, Debug)]
pub struct DistanceParams {
    /// Metric (default BRDF_it).
    pub metric: Metric,
    /// Mask (default evaluation).
    pub mask: Mask,
    /// Weighting (default uniform).
    pub weighting: Weighting,
    /// Lobe; `None` = SPEC 4 default.
    pub lobe: Option<LobeKind>,
    /// Grid sub-sampling stride (1 = full grid).
    pub stride: usize,
}

impl Default for DistanceParams {
    fn default() -> Self {
        Self {
            metric: Metric::BrdfIt,
            mask: Mask::Evaluation,
            weighting: Weighting::Uniform,
            lobe: None,
            stride: 1,
        }
    }
}

/// Parameters checked against a collection ([`DistanceParams::check`]); read them
/// through the accessors.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ValidDistanceParams {
    metric: Metric,
    mask: Mask,
    weighting: Weighting,
    lobe: LobeKind,
    stride: NonZeroUsize,
}

impl ValidDistanceParams {
    /// The metric.
    pub fn metric(&self) -> Metric {
        self.metric
    }
    /// The mask.
    pub fn mask(&self) -> Mask {
        self.mask
    }
    /// The weighting.
    pub fn weighting(&self) -> Weighting {
        self.weighting
    }
    /// The lobe actually used.
    pub fn lobe(&self) -> LobeKind {
        self.lobe
    }
    /// The grid stride (at least 1).
    pub fn stride(&self) -> usize {
        self.stride.get()
    }
}

impl DistanceParams {
    /// Sets the mask, weighting and stride of a checked grid.
    pub fn grid(self, g: crate::merl::GridSpec) -> Self {
        self.mask(g.mask())
            .weighting(g.weighting())
            .stride(g.stride())
    }
    /// Sets the metric.
    pub fn metric(mut self, m: Metric) -> Self {
        self.metric = m;
        self
    }
    /// Sets the mask.
    pub fn mask(mut self, m: Mask) -> Self {
        self.mask = m;
        self
    }
    /// Sets the weighting.
    pub fn weighting(mut self, w: Weighting) -> Self {
        self.weighting = w;
        self
    }
    /// Sets the lobe.
    pub fn lobe(mut self, l: LobeKind) -> Self {
        self.lobe = Some(l);
        self
    }
    /// Sets the grid stride.
    pub fn stride(mut self, s: usize) -> Self {
        self.stride = s;
        self
    }

    /// Checks the parameters against `coll`: at least 2 materials; Euclidean needs
    /// parameters; the specular lobe needs analytic materials.
    pub fn check(&self, coll: &Collection) -> Result<ValidDistanceParams, DistanceError> {
        if coll.len() < 2 {
            return Err(DistanceError::TooFew(coll.len()));
        }
        let measured = coll.materials().iter().find(|m| m.analytic().is_none());
        let lobe = self.lobe.unwrap_or(if measured.is_some() {
            LobeKind::Full
        } else {
            LobeKind::Specular
        });
        if let Some(m) = measured {
            if self.metric == Metric::Euclidean {
                return Err(DistanceError::NoParameters(m.name.clone()));
            }
            if lobe == LobeKind::Specular {
                return Err(DistanceError::SpecularOfMeasured(m.name.clone()));
            }
        }
        let stride = NonZeroUsize::new(self.stride)
            .filter(|_| crate::merl::GridSpec::stride_ok(self.stride))
            .ok_or(DistanceError::UnknownOption {
                what: "stride",
                found: self.stride.to_string(),
                expected: crate::merl::GridSpec::STRIDE_RULE,
            })?;
        Ok(ValidDistanceParams {
            metric: self.metric,
            mask: self.mask,
            weighting: self.weighting,
            lobe,
            stride,
        })
    }
}

/// The lobe of each material that BRDF_it compares.
pub fn lobes(coll: &Collection, kind: LobeKind) -> Vec<Lobe> {
    coll.materials()
        .iter()
        .map(|m| match (&m.data, kind) {
            (MaterialData::Analytic(a), LobeKind::Specular) => Lobe::Analytic(LobeParams {
                kd: 0.0,
                ks: 1.0,
                f0: a.f0 as f32,
                n: a.n as f32,
            }),
            (MaterialData::Analytic(a), LobeKind::Full) => Lobe::Analytic(LobeParams {
                kd: (a.d.iter().sum::<f64>() / 3.0) as f32,
                ks: (a.s.iter().sum::<f64>() / 3.0) as f32,
                f0: a.f0 as f32,
                n: a.n as f32,
            }),
            (MaterialData::Measured(t), _) => Lobe::Measured {
                table: t.clone(),
                channel: None,
            },
            (MaterialData::Rgl(t), _) => Lobe::Measured {
                table: t.table().clone(),
                channel: None,
            },
            (MaterialData::Neural(net), _) => Lobe::Neural {
                net: net.clone(),
                channel: None,
            },
        })
        .collect()
}

/// The cells a distance runs over: the mask, restricted to cells valid in every measured
/// material of the collection ([`CellSet::for_collection`]).
pub fn cell_set(coll: &Collection, p: &ValidDistanceParams) -> CellSet {
    CellSet::for_collection(coll, p.mask, p.weighting, p.stride)
}

/// Computes the distance matrix of `coll` on `backend`, in super-blocks of
/// [`DEFAULT_BAND_ROWS`] materials ([`distance_matrix_banded`]).
pub fn distance_matrix(
    backend: &dyn Backend,
    coll: &Collection,
    p: &ValidDistanceParams,
    progress: Progress<'_>,
) -> Result<DistanceMatrix, DistanceError> {
    distance_matrix_banded(backend, coll, p, DEFAULT_BAND_ROWS, progress)
}

/// f64 reference of BRDF_it (slow, single pass per pair over the cells; for tests).
#[doc(hidden)]
pub fn reference_pairwise_f64(lobes: &[Lobe], cells: &CellSet) -> Vec<f64> {
    use rayon::prelude::*;
    let t = crate::merl::GridTables::new();
    let n = lobes.len();
    let mut out = vec![0.0; crate::backend::condensed_len(n)];
    let chunk = 16_384;
    let mut buf = vec![0f64; n * chunk];
    for (cc, cw) in cells.cells.chunks(chunk).zip(cells.weights.chunks(chunk)) {
        let len = cc.len();
        buf[..n * len]
            .par_chunks_mut(len)
            .zip(lobes.par_iter())
            .for_each(|(row, l)| {
                for ((o, &c), &w) in row.iter_mut().zip(cc).zip(cw) {
                    *o = w * l.eval_f64(&t, c as usize);
                }
            });
        let rows: Vec<&[f64]> = buf[..n * len].chunks(len).collect();
        let add: Vec<(usize, f64)> = (0..n)
            .into_par_iter()
            .flat_map_iter(|i| {
                let rows = &rows;
                (i + 1..n).map(move |j| {
                    (
                        condensed_index(n, i, j),
                        rows[i]
                            .iter()
                            .zip(rows[j])
                            .map(|(a, b)| (a - b).abs())
                            .sum::<f64>(),
                    )
                })
            })
            .collect();
        for (k, v) in add {
            out[k] += v;
        }
    }
    out
}
