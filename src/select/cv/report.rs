//! The cross-validation summary as Markdown.

use super::CvResult;
use crate::stats::{num, p_value};
use std::fmt::Write as _;

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
