//! The CPU back-end's weighted systems (SPEC 11): [`weighted::reference_per_channel`]'s
//! pass, with each network's rows read from its tabulation over all the cells, kept in the
//! back-end's cache ([`CpuBackend::neural_f32`]) instead of tabulated per chunk. A fit asks
//! for its targets' and basis materials' values twice (the systems, then the grid errors
//! of `fit::fit`): with this, a network runs once per fit, not twice. The values are the
//! same f32 (the cache holds the back-end's tabulation: a unit test holds the systems to
//! the per-chunk pass's bits).

use super::CpuBackend;
use crate::backend::weighted::{self, TargetWeight, WeightedSystems};
use crate::backend::{Backend, Lobe, Progress};
use crate::error::BackendError;
use crate::merl::CellSet;
use std::sync::Arc;

/// [`Backend::weighted_systems_per_channel`] of the CPU back-end. When the networks'
/// tabulations over `cells` would not fit in the cache together, the per-chunk pass
/// (tabulating them there) instead: the cache would only churn. (A fit of 20 networks by
/// 12 on the evaluation mask keeps 96 lobes, 344 MB, of the cache's 512 MiB.)
pub(super) fn weighted_systems_per_channel(
    cpu: &CpuBackend,
    basis: [&[Lobe]; 3],
    targets: [&[Lobe]; 3],
    cells: &CellSet,
    weight: TargetWeight,
    progress: Progress<'_>,
) -> Result<[WeightedSystems; 3], BackendError> {
    let lobes = || basis.iter().chain(&targets).flat_map(|l| l.iter());
    let nets = lobes().filter(|l| matches!(l, Lobe::Neural { .. })).count();
    if nets == 0 || 4 * nets * cells.cells.len() > super::NEURAL_CACHE_BYTES {
        return weighted::reference_per_channel(cpu, basis, targets, cells, weight, progress);
    }
    // Every network lobe's values over all the cells, held for the pass (keyed by the
    // network's address: the lobes hold the networks, so no address is reused meanwhile).
    let mut held: Vec<(usize, Option<usize>, Arc<Vec<f32>>)> = Vec::new();
    for lobe in lobes() {
        if let Lobe::Neural { net, channel } = lobe {
            let key = (Arc::as_ptr(net) as usize, *channel);
            if !held.iter().any(|h| (h.0, h.1) == key) {
                let values = cpu.neural_f32(lobe, net, *channel, &cells.cells);
                held.push((key.0, key.1, values));
            }
        }
    }
    let find = |net: &Arc<crate::brdf::Nbrdf>, channel: Option<usize>| -> &[f32] {
        let key = (Arc::as_ptr(net) as usize, channel);
        let h = held.iter().find(|h| (h.0, h.1) == key);
        &h.expect("every network lobe is held").2
    };
    let rows = |lobes: &[Lobe], cc: &[u32], offset: usize| -> Result<Vec<f32>, BackendError> {
        let n = cc.len();
        let others: Vec<Lobe> = lobes
            .iter()
            .filter(|l| !matches!(l, Lobe::Neural { .. }))
            .cloned()
            .collect();
        let tabulated = cpu.tabulate(&others, cc)?;
        let mut next = tabulated.chunks_exact(n.max(1));
        let mut out = vec![0f32; lobes.len() * n];
        for (row, lobe) in out.chunks_exact_mut(n.max(1)).zip(lobes) {
            match lobe {
                Lobe::Neural { net, channel } => {
                    row.copy_from_slice(&find(net, *channel)[offset..offset + n]);
                }
                _ => row.copy_from_slice(next.next().expect("a row per other lobe")),
            }
        }
        Ok(out)
    };
    weighted::reference_per_channel_by(&rows, basis, targets, cells, weight, progress)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::LobeParams;

    /// Networks, an analytic and a measured-like lobe mixed: the systems from the kept
    /// tabulations are the per-chunk pass's to the bit, over more cells than one chunk.
    #[test]
    fn systems_from_kept_tabulations_are_the_per_chunk_pass_to_the_bit() {
        let cpu = CpuBackend::new();
        let cells = CellSet::new(
            crate::merl::Mask::Evaluation,
            crate::merl::Weighting::Uniform,
            2,
        );
        let nets: Vec<Arc<crate::brdf::Nbrdf>> = (0..4)
            .map(|s| Arc::new(crate::brdf::seeded_for_tests(70 + s)))
            .collect();
        let analytic = Lobe::Analytic(LobeParams {
            kd: 0.1,
            ks: 0.5,
            f0: 0.3,
            n: 40.0,
        });
        let per_channel = |ids: &[usize], c: usize| -> Vec<Lobe> {
            ids.iter()
                .map(|&i| match i {
                    9 => analytic.clone(),
                    i => Lobe::Neural {
                        net: nets[i].clone(),
                        channel: Some(c),
                    },
                })
                .collect()
        };
        let b: [Vec<Lobe>; 3] = std::array::from_fn(|c| per_channel(&[0, 9, 1], c));
        let t: [Vec<Lobe>; 3] = std::array::from_fn(|c| per_channel(&[2, 3, 9, 0], c));
        for weight in [TargetWeight::Relative { eps: 0.01 }, TargetWeight::Log] {
            let run = |kept: bool| {
                let args = ([&b[0][..], &b[1], &b[2]], [&t[0][..], &t[1], &t[2]]);
                if kept {
                    weighted_systems_per_channel(&cpu, args.0, args.1, &cells, weight, &|_, _| {})
                } else {
                    weighted::reference_per_channel(
                        &cpu,
                        args.0,
                        args.1,
                        &cells,
                        weight,
                        &|_, _| {},
                    )
                }
                .expect("systems")
            };
            let (kept, chunked) = (run(true), run(false));
            assert!(cells.cells.len() > 1 << 14, "more than one chunk");
            for c in 0..3 {
                assert_eq!(kept[c].values.len(), chunked[c].values.len());
                assert!(
                    kept[c]
                        .values
                        .iter()
                        .zip(&chunked[c].values)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{weight:?} channel {c}"
                );
            }
        }
    }
}
