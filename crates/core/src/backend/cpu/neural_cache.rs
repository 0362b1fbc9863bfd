//! The values of recent neural lobes on recent cell sets, for `CpuBackend::values_f64`:
//! the cell-by-cell error passes (fits' errors, cross-validation's held-out MAE) ask for
//! the same basis lobes once per target, and a network costs ~600 multiply-adds per cell,
//! so the last `NEURAL_CACHE_BYTES` of them are kept (least recently used first out),
//! keyed by the network (held, so its address cannot be reused), the channel and the
//! cells (length and XXH3). The reductions (`reduce_pairs`) never use it: they evaluate
//! per chunk and keep nothing.

use super::Nbrdf;
use std::sync::{Arc, Mutex};

/// Bytes of f32 values kept at most (about 150 lobes of the evaluation mask).
pub const NEURAL_CACHE_BYTES: usize = 512 << 20;

struct Entry {
    net: Arc<Nbrdf>,
    channel: Option<usize>,
    cells: (usize, u64),
    values: Arc<Vec<f32>>,
}

static CACHE: Mutex<Vec<Entry>> = Mutex::new(Vec::new());

/// The values of `(net, channel)` at `cells`, from the cache or from `compute`, which
/// returns `channel`'s values and may return other channels' beside them (all kept).
pub(super) fn get(
    net: &Arc<Nbrdf>,
    channel: Option<usize>,
    cells: &[u32],
    compute: impl FnOnce() -> Vec<(Option<usize>, Vec<f32>)>,
) -> Arc<Vec<f32>> {
    let mut h = crate::hash::Hasher::new();
    h.write(bytemuck::cast_slice(cells));
    let key = (cells.len(), h.finish());
    let found = |ch: Option<usize>| {
        move |e: &Entry| Arc::ptr_eq(&e.net, net) && e.channel == ch && e.cells == key
    };
    {
        let mut c = CACHE.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(i) = c.iter().position(found(channel)) {
            let e = c.remove(i);
            let v = e.values.clone();
            c.push(e);
            return v;
        }
    }
    let mut made: Vec<(Option<usize>, Arc<Vec<f32>>)> = compute()
        .into_iter()
        .map(|(ch, v)| (ch, Arc::new(v)))
        .collect();
    // The asked channel last: the most recently used.
    let at = made
        .iter()
        .position(|(ch, _)| *ch == channel)
        .expect("compute returns the asked channel");
    let asked = made.remove(at);
    let values = asked.1.clone();
    made.push(asked);
    let mut c = CACHE.lock().unwrap_or_else(|p| p.into_inner());
    for (ch, v) in made {
        let bytes = 4 * v.len();
        if bytes > NEURAL_CACHE_BYTES || c.iter().any(found(ch)) {
            continue;
        }
        let mut total: usize = c.iter().map(|e| 4 * e.values.len()).sum::<usize>() + bytes;
        while total > NEURAL_CACHE_BYTES && !c.is_empty() {
            total -= 4 * c.remove(0).values.len();
        }
        c.push(Entry {
            net: net.clone(),
            channel: ch,
            cells: key,
            values: v,
        });
    }
    values
}
