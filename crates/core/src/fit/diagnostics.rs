//! Diagnostics of a fit that ran but whose numbers may mean little: a target in the
//! basis, an unphysical albedo, a fit about as far from its target as a black material,
//! or one that explains little of it.

use super::{TargetFit, TargetWeight};
use crate::collection::Collection;
use crate::error::short_name;
use crate::stats::num;

/// Relative residual above which a fit is reported as meaningless: the basis explains
/// less than half of the target's weighted energy.
pub const WARN_RELATIVE_RESIDUAL: f64 = 0.5;

/// Relative MAE above which a fit is reported as meaningless: its mean absolute error is
/// close to the target's own mean (a black material would do about as well).
pub const WARN_RELATIVE_MAE: f64 = 0.75;

/// Warnings printed one per line; the rest are counted.
pub const MAX_WARNINGS: usize = 8;

/// Diffuse albedo above which a fitted combination is reported as unphysical.
pub const WARN_ALBEDO: f64 = 1.0;

/// Warnings about a fit that ran but whose numbers may mean little. A fit is judged by
/// its own objective: `l2` fits by their relative MAE and relative residual, `relative`
/// and `log` fits by their relative residual under the objective's weights (`rho_W`).
pub fn fit_warnings(
    coll: &Collection,
    basis: &[usize],
    targets: &[usize],
    fits: &[TargetFit],
    objective: TargetWeight,
) -> Vec<String> {
    let mut w = Vec::new();
    for &t in targets {
        if basis.contains(&t) {
            w.push(format!(
                "target `{}` is in the basis: its fit is exact and says nothing about the basis",
                short_name(&coll.materials()[t].name)
            ));
        }
    }
    for f in fits {
        // Diffuse albedo of the combination (analytic basis): above 1 it reflects more
        // light than it receives, a sign that the basis was stretched to mimic the target.
        let analytic: Option<Vec<_>> = basis
            .iter()
            .map(|&b| coll.materials()[b].analytic())
            .collect();
        if let Some(ps) = analytic {
            let albedo: Vec<f64> = (0..3)
                .map(|c| {
                    f.coefficients[0][c]
                        + ps.iter()
                            .zip(&f.coefficients[1..])
                            .map(|(p, a)| a[c] * p.d[c])
                            .sum::<f64>()
                })
                .collect();
            let worst = albedo.iter().cloned().fold(0.0, f64::max);
            if worst > WARN_ALBEDO {
                w.push(format!(
                    "the fit of `{}` has a diffuse albedo of {} (above 1: it reflects more light than it receives); the basis cannot represent it and its numbers mean little",
                    short_name(&f.material), num(worst)
                ));
                continue;
            }
        }
        if objective != TargetWeight::L2 {
            if f.objective_residual > WARN_RELATIVE_RESIDUAL {
                w.push(format!(
                    "the fit of `{}` explains little of it under the `{}` objective (relative residual under its weights {}; 0 is a perfect fit, 1 explains nothing): this basis cannot represent it",
                    short_name(&f.material), objective.kind().name(), num(f.objective_residual)
                ));
            }
        } else if f.relative_mae > WARN_RELATIVE_MAE {
            w.push(format!(
                "the fit of `{}` is almost as far from it as a black material (relative MAE {}, relative residual {}): this basis cannot represent it",
                short_name(&f.material), num(f.relative_mae), num(f.relative_residual)
            ));
        } else if f.relative_residual > WARN_RELATIVE_RESIDUAL {
            w.push(format!(
                "the fit of `{}` explains little of it (relative residual {}; 0 is a perfect fit, 1 explains nothing): this basis cannot represent it",
                short_name(&f.material), num(f.relative_residual)
            ));
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    fn target(name: &str, relative_residual: f64, relative_mae: f64) -> TargetFit {
        TargetFit {
            material: name.into(),
            coefficients: vec![[0.0; 3]; 2],
            residual: [0.0; 3],
            mae: 0.0,
            relative_residual,
            relative_mae,
            objective_residual: relative_residual,
            kkt: [0.0; 3],
            iterations: [0; 3],
        }
    }

    #[test]
    fn warnings_follow_the_thresholds_in_the_crate_number_format() {
        let coll = Collection::embedded_default();
        let names = coll.names();
        let fits = [
            target(&names[1], 0.1, 0.2),
            target(&names[2], 0.61234, 0.3),
            target(&names[3], 0.9, 0.812345),
        ];
        let w = fit_warnings(&coll, &[0], &[0, 1, 2, 3], &fits, TargetWeight::L2);
        assert_eq!(w.len(), 3, "{w:?}");
        assert!(w[0].contains("is in the basis"), "{}", w[0]);
        assert!(w[1].contains("relative residual 0.6123;"), "{}", w[1]);
        assert!(
            w[2].contains("relative MAE 0.8123, relative residual 0.9000)"),
            "{}",
            w[2]
        );
    }
}
