//! `distance`: the pairwise distance matrix of a collection, whole or one tile of it.

use super::refuse;
use crate::backend::{Backend, Progress};
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

impl DistanceRequest {
    /// The rules that need no collection: band rows a positive multiple of 4, a tile
    /// `1 <= I <= N`.
    ///
    /// # Errors
    /// [`crate::error::DistanceError`] or [`crate::error::RequestError`] naming the
    /// setting.
    pub fn check(&self) -> Result<()> {
        check_band_rows(self.band_rows)?;
        if let Some((i, n)) = self.tile {
            if i == 0 || i > n {
                refuse!("--tile `{i}/{n}`: expected I/N with 1 <= I <= N (e.g. --tile 3/8)");
            }
        }
        Ok(())
    }

    /// The distance parameters checked against `coll` (and the tile against its size).
    ///
    /// # Errors
    /// [`crate::error::DistanceError`] for settings that do not fit the collection (a
    /// stride that leaves no cell, the euclidean metric on measured materials, more tiles
    /// than materials).
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

    /// Computes the matrix (or the tile) of `coll` on `backend` with the checked `p`
    /// ([`Self::params`]).
    ///
    /// # Errors
    /// A failed reduction.
    pub fn run(
        &self,
        backend: &dyn Backend,
        coll: &Collection,
        p: &ValidDistanceParams,
        progress: Progress<'_>,
    ) -> Result<DistanceOutput> {
        Ok(match self.tile {
            Some((i, n)) => DistanceOutput::Tile(distance_tile(
                backend,
                coll,
                p,
                self.band_rows,
                i,
                n,
                progress,
            )?),
            None => DistanceOutput::Matrix(distance_matrix_banded(
                backend,
                coll,
                p,
                self.band_rows,
                progress,
            )?),
        })
    }
}
