//! `distance`: the pairwise distance matrix of a collection, whole or one tile of it.

use super::{refuse, Ctx, Refusal, Request};
use crate::collection::Collection;
use crate::distance::{check_band_rows, tile_rows};
use crate::distance::{
    distance_matrix_banded, distance_tile, DistanceMatrix, DistanceParams, LobeKind, Metric, Tile,
    ValidDistanceParams, DEFAULT_BAND_ROWS,
};
use crate::merl::GridSpec;
use crate::Result;

/// `brdf-basis distance`: its settings, with the defaults of `distance --help`.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct DistanceRequest {
    /// `--metric`: brdf-it (the paper's Eq. 5) or euclidean (on F0, n).
    pub metric: Metric,
    /// `--mask`, `--weighting`, `--stride`.
    pub grid: GridSpec,
    /// `--lobe`: specular or full (`None`: specular when every material is analytic).
    pub lobe: Option<LobeKind>,
    /// `--band-rows`: materials per back-end call (a multiple of 4; changes no value).
    pub band_rows: usize,
    /// `--tile I/N`: only band `I` of `N` (1-based), for `merge`.
    pub tile: Option<(usize, usize)>,
}

impl Default for DistanceRequest {
    fn default() -> Self {
        Self {
            metric: Metric::BrdfIt,
            grid: GridSpec::default(),
            lobe: None,
            band_rows: DEFAULT_BAND_ROWS,
            tile: None,
        }
    }
}

/// What `distance` computes.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub enum DistanceOutput {
    /// The whole matrix.
    Matrix(DistanceMatrix),
    /// One tile (`--tile I/N`).
    Tile(Tile),
}

impl Request for DistanceRequest {
    type Output = DistanceOutput;

    /// The rules that need no collection: band rows a positive multiple of 4, a tile
    /// `1 <= I <= N`.
    fn check(&self) -> Result<(), Refusal> {
        if let Err(e) = check_band_rows(self.band_rows) {
            refuse!(Refusal::Rule {
                setting: "--band-rows",
                message: e.to_string(),
            });
        }
        if let Some((i, n)) = self.tile {
            if i == 0 || i > n {
                refuse!(Refusal::OutOfRange {
                    setting: "--tile",
                    value: Some(format!("`{i}/{n}`")),
                    rule: "expected I/N with 1 <= I <= N (e.g. --tile 3/8)".into(),
                });
            }
        }
        Ok(())
    }

    /// Computes the matrix (or the tile) of the collection on the back-end, with the
    /// parameters of [`DistanceRequest::params`].
    fn run(&self, ctx: &Ctx<'_>) -> Result<DistanceOutput> {
        let (backend, coll) = (ctx.need_backend()?, ctx.need_collection()?);
        let p = self.params(coll)?;
        let progress = ctx.progress;
        Ok(match self.tile {
            Some((i, n)) => DistanceOutput::Tile(distance_tile(
                backend,
                coll,
                &p,
                self.band_rows,
                i,
                n,
                progress,
            )?),
            None => DistanceOutput::Matrix(distance_matrix_banded(
                backend,
                coll,
                &p,
                self.band_rows,
                progress,
            )?),
        })
    }
}

impl DistanceRequest {
    /// The distance parameters checked against `coll` (and the tile against its size):
    /// what [`Request::run`] computes with (the command line records them beside the
    /// matrix).
    ///
    /// # Errors
    /// The request's [`Refusal`]; [`crate::error::DistanceError`] for settings that do
    /// not fit the collection (a stride that leaves no cell, the euclidean metric on
    /// measured materials, more tiles than materials).
    pub fn params(&self, coll: &Collection) -> Result<ValidDistanceParams> {
        self.check()?;
        let mut p = DistanceParams::default()
            .metric(self.metric)
            .grid(self.grid);
        p.lobe = self.lobe;
        let p = p.check(coll)?;
        if let Some((i, n)) = self.tile {
            tile_rows(coll.len(), i, n)?;
        }
        Ok(p)
    }
}
