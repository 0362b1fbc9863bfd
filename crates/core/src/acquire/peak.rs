//! Whether the samples of a fit pin its peak (issue 50, item 2): a fit from a few samples
//! away from the specular peak extrapolates the peak from the basis, and a user who
//! measured five points must not receive a wild material in silence.

use super::eval::angles_deg;
use super::plan::{cell_candidates, values_at};
use super::{AcquireError, Sample, SampleFit, HIGHLIGHT_DEG};
use crate::collection::Collection;
use crate::fit::FitParams;
use std::f64::consts::FRAC_1_PI;

/// The reconstruction's peak over the largest measured value (mean over channels) above
/// which `fit --samples` warns that the samples do not pin the peak.
pub const PEAK_RATIO: f64 = 10.0;

/// The grid stride of the search for the reconstruction's peak (every second cell along
/// each axis of the evaluation mask, cell index 0 of `theta_h` included: the mirror
/// direction of every `theta_d`).
const PEAK_STRIDE: usize = 2;

/// A sample looks at the highlight when its half vector is within [`HIGHLIGHT_DEG`] of
/// the normal. Without a sample at the highlight, the reconstruction's peak over the largest measured
/// value above which the peak is the basis's guess.
const UNSEEN_RATIO: f64 = 2.0;

/// Directions a warning suggests (the peak and the next brightest cells at least
/// [`APART_DEG`] of `theta_i` from those already named).
const SUGGESTED: usize = 3;
/// See [`SUGGESTED`].
const APART_DEG: f64 = 10.0;

/// The warning of a fit from samples whose peak the samples do not pin: its
/// reconstruction (the fit's combination of the basis on the evaluation mask) peaks more
/// than [`PEAK_RATIO`] times above the largest measured value (the basis extrapolates
/// it), or no sample looks at the highlight (half vector within [`HIGHLIGHT_DEG`] of the
/// normal) while the reconstruction peaks above twice the largest measured value (the
/// peak is the basis's guess). It names the reconstruction's brightest direction pairs
/// near the mirror direction (`theta_i, phi_i, theta_o, phi_o` in degrees, `theta_h`
/// below [`HIGHLIGHT_DEG`], at least 10 degrees of `theta_i` apart), where a
/// measurement would pin it. `None` when the peak is pinned or no sample is positive.
pub fn peak_warning(
    coll: &Collection,
    basis: &[usize],
    fit: &SampleFit,
    samples: &[Sample],
) -> Result<Option<String>, AcquireError> {
    let mean = |v: [f64; 3]| (v[0] + v[1] + v[2]) / 3.0;
    let measured = samples.iter().map(|s| mean(s.rgb)).fold(0.0f64, f64::max);
    if measured.is_nan() || measured <= 0.0 {
        return Ok(None);
    }
    let fp = FitParams {
        stride: PEAK_STRIDE,
        ..FitParams::default()
    };
    let cands = cell_candidates(coll, basis, &fp)?;
    let vals = values_at(coll, basis, &cands)?;
    let a = &fit.coefficients;
    let value = |k: usize| -> f64 {
        mean([0, 1, 2].map(|c| {
            a[0][c] * FRAC_1_PI
                + (0..basis.len())
                    .map(|b| a[b + 1][c] * vals[c][b][k])
                    .sum::<f64>()
        }))
    };
    let mut order: Vec<(f64, usize)> = (0..cands.len()).map(|k| (value(k), k)).collect();
    order.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let Some(&(peak, _)) = order.first() else {
        return Ok(None);
    };
    let ratio = peak / measured;
    let theta_h = |wi: [f64; 3], wo: [f64; 3]| {
        let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        (h[2] / n).clamp(-1.0, 1.0).acos().to_degrees()
    };
    let seen = samples.iter().any(|s| theta_h(s.wi, s.wo) < HIGHLIGHT_DEG);
    let wild = ratio > PEAK_RATIO;
    // Without a sample at the highlight: the basis material that peaks most above its
    // values at the samples, when one peaks above [`UNSEEN_RATIO`] times them.
    let unseen = if wild || seen {
        None
    } else {
        let at = super::fit::Design::at_samples(coll, basis, samples)?;
        let m = basis.len() + 1;
        (0..basis.len())
            .map(|b| {
                let top = (0..cands.len())
                    .map(|k| mean([0, 1, 2].map(|c| vals[c][b][k])))
                    .fold(0.0f64, f64::max);
                let at_samples = (0..samples.len())
                    .map(|s| mean([0, 1, 2].map(|c| at.rows[c][s * m + b + 1])))
                    .fold(0.0f64, f64::max);
                (top / at_samples.max(f64::MIN_POSITIVE), b)
            })
            .filter(|x| x.0 > UNSEEN_RATIO)
            .max_by(|x, y| x.0.total_cmp(&y.0))
    };
    if !wild && unseen.is_none() {
        return Ok(None);
    }
    // Ordered by the reconstruction, or by the unseen basis material's peak.
    if let Some((_, b)) = unseen {
        order = (0..cands.len())
            .map(|k| (mean([0, 1, 2].map(|c| vals[c][b][k])), k))
            .collect();
        order.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    }
    let mut named: Vec<(f64, String)> = Vec::new();
    for &(_, k) in &order {
        if theta_h(cands[k].wi, cands[k].wo) >= HIGHLIGHT_DEG {
            continue;
        }
        let (ti, pi) = angles_deg(cands[k].wi);
        if named.iter().any(|(t, _)| (t - ti).abs() < APART_DEG) {
            continue;
        }
        let (to, po) = angles_deg(cands[k].wo);
        named.push((ti, format!("({ti:.1}, {pi:.1}, {to:.1}, {po:.1})")));
        if named.len() == SUGGESTED {
            break;
        }
    }
    let head = match unseen {
        None => format!(
            "the reconstruction peaks at {} times the largest measured value ({} against {}, mean over channels): the samples do not pin its peak, which the basis extrapolates; measure near its brightest directions",
            crate::stats::num(ratio),
            crate::stats::num(peak),
            crate::stats::num(measured)
        ),
        Some((r, b)) => format!(
            "no sample looks at the highlight (half vector within {HIGHLIGHT_DEG} degrees of the normal), where the basis material `{}` peaks {} times above its values at the samples: the samples cannot tell whether the material has a peak there, and the reconstruction's (peak {} times the largest measured value) is the basis's guess; measure near the mirror directions",
            coll.materials()[basis[b]].name,
            crate::stats::num(r),
            crate::stats::num(ratio)
        ),
    };
    Ok(Some(format!(
        "{head} (theta_i, phi_i, theta_o, phi_o in degrees) {}",
        named
            .iter()
            .map(|x| x.1.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    )))
}
