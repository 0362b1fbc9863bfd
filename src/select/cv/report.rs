//! The cross-validation summary as Markdown.

use super::CvResult;
use std::fmt::Write as _;

/// A value in at least four significant digits, fixed-point between 1e-3 and 1e5,
/// scientific (`1.234e-5`) outside; `n/a` when not finite.
pub fn num(v: f64) -> String {
    if !v.is_finite() {
        return "n/a".into();
    }
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&a) {
        let digits = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.3e}")
    }
}

/// A p-value: three significant digits, scientific below 1e-3.
pub fn p_value(v: f64) -> String {
    if !v.is_finite() {
        "n/a".into()
    } else if v >= 1e-3 {
        format!("{v:.3}")
    } else {
        format!("{v:.2e}")
    }
}

impl CvResult {
    /// The summary as Markdown: per method and k, mean and median held-out rho, MAE and
    /// image error; then the paired Wilcoxon tests.
    pub fn markdown(&self) -> String {
        let mut s = String::new();
        let n: usize = self.folds.iter().map(Vec::len).sum();
        let _ = writeln!(
            s,
            "Cross-validation over materials: {} folds, {n} held-out materials, seed {}, {} mask, {} weights.\n",
            self.folds.len(),
            self.seed,
            self.mask,
            self.weighting
        );
        s.push_str(&self.table_markdown());
        s.push_str("\nPaired Wilcoxon signed-rank tests (two-sided p) on the held-out values:\n\n");
        s.push_str("| a | b | k | p (rho) | p (MAE) | p (image error) | a better / b better (rho) |\n|---|---|---|---|---|---|---|\n");
        for t in &self.tests {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} / {} |",
                t.a,
                t.b,
                t.k,
                p_value(t.wilcoxon_p),
                p_value(t.wilcoxon_p_mae),
                p_value(t.wilcoxon_p_image_error),
                t.a_better,
                t.b_better
            );
        }
        s
    }

    /// Only the method x k table of [`CvResult::markdown`].
    pub fn table_markdown(&self) -> String {
        let mut s = String::from(
            "| method | k | mean rho | median rho | mean MAE | median MAE | mean image error | median image error |\n|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.results {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                r.method,
                r.k,
                num(r.mean_rho),
                num(r.median_rho),
                num(r.mean_mae),
                num(r.median_mae),
                num(r.mean_image_error),
                num(r.median_image_error)
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_readable() {
        assert_eq!(num(24.0753), "24.08");
        assert_eq!(num(6.6871), "6.687");
        assert_eq!(num(0.012346), "0.01235");
        assert_eq!(num(1234.56), "1235");
        assert_eq!(num(2.5e-5), "2.500e-5");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(f64::NAN), "n/a");
        assert_eq!(p_value(0.5), "0.500");
        assert_eq!(p_value(1e-5), "1.00e-5");
    }
}
