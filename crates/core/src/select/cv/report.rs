//! The cross-validation summary as Markdown.

use super::CvResult;
use crate::stats::{num, p_value};
use std::fmt::Write as _;

/// The header of a column of image errors at `render_size` px (`what`: "mean" or
/// "median"), which names the size where it is known: beside the appearance tables' image
/// errors at 256 px, the two must not read as one (audit 3, U5).
pub(crate) fn image_error_header(what: &str, render_size: Option<u32>) -> String {
    match render_size {
        Some(n) => format!("{what} image error ({n} px)"),
        None => format!("{what} image error"),
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
            "Cross-validation over materials: {} folds, {n} held-out materials, seed {}, {} mask, {} weights, objective {}{}.\n",
            self.folds.len(),
            self.seed,
            self.mask,
            self.weighting,
            self.objective,
            self.eps.map(|e| format!(" (eps {})", num(e))).unwrap_or_default()
        );
        s.push_str(&self.table_markdown());
        if let Some(t) = self.appearance_markdown() {
            s.push_str("\nAppearance of the held-out fits (SPEC 11): log-RMSE on the grid; renders at 256 x 256, image error (exposure 0, gamma 2.2), CIEDE2000, ΔE_ITP (ITU-R BT.2124) and FLIP (67 ppd) averaged over the sphere, under the paper's light (45, 45) and averaged over the four lights:\n\n");
            s.push_str(&t);
        }
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

    /// The appearance table of [`CvResult::markdown`] (`None` without appearance metrics):
    /// per method and k, the means of log-RMSE and of the image metrics.
    pub fn appearance_markdown(&self) -> Option<String> {
        if self.results.iter().all(|r| r.appearance.is_none()) {
            return None;
        }
        let mut s = String::from(
            "| method | k | log-RMSE | image error (45, 45; 256 px) | image error (4 lights; 256 px) | median | CIEDE2000 (4 lights) | ΔE_ITP (4 lights) | FLIP (45, 45) | FLIP (4 lights) | median |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.results {
            let Some(a) = &r.appearance else { continue };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.method,
                r.k,
                num(r.mean_log_rmse),
                num(a.image_error_paper_light),
                num(a.image_error),
                num(a.median_image_error),
                num(a.ciede2000),
                num(a.delta_e_itp),
                num(a.flip_paper_light),
                num(a.flip),
                num(a.median_flip)
            );
        }
        Some(s)
    }

    /// Only the method x k table of [`CvResult::markdown`].
    pub fn table_markdown(&self) -> String {
        let mut s = format!(
            "| method | k | mean rho | median rho | mean MAE | median MAE | {} | {} |\n|---|---|---|---|---|---|---|---|\n",
            image_error_header("mean", self.render_size),
            image_error_header("median", self.render_size)
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
