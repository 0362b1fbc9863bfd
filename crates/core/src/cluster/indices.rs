//! Validity indices beyond Davies-Bouldin (the paper's future work, VII: "different
//! clustering validation metrics"), on any distance matrix and any partition.
//!
//! For items `0..n` with labels `l(x)` (cluster indices; clusters with no member are
//! ignored), SPEC section 6:
//!
//! * **Silhouette** (Rousseeuw 1987, doi:10.1016/0377-0427(87)90125-7): for `x` in cluster
//!   `A`, `a(x)` = mean distance to the other members of `A`, `b(x)` = min over the other
//!   clusters `B` of the mean distance to the members of `B`; `s(x) = (b - a) / max(a, b)`
//!   (0 when `A = {x}` or when `a = b = 0`); the index is the mean of `s(x)` over all
//!   items, in `[-1, 1]`. Higher is better.
//! * **Dunn index** (Dunn 1974, doi:10.1080/01969727408546059): the smallest distance
//!   between members of two different clusters divided by the largest distance between two
//!   members of one cluster. Higher is better; `None` when every cluster is a singleton
//!   (the denominator is 0; SPEC: reported as null).
//!
//! Both need at least two non-empty clusters.

use super::validity::check_distances;
use super::ClusterError;
use crate::distance::Distances;

fn check_labels<D: Distances + ?Sized>(d: &D, labels: &[usize]) -> Result<usize, ClusterError> {
    if labels.len() != d.len() {
        return Err(ClusterError::LabelCountMismatch {
            expected: d.len(),
            found: labels.len(),
        });
    }
    check_distances(d)?;
    let k = labels.iter().max().map_or(0, |&m| m + 1);
    let mut seen = vec![false; k];
    labels.iter().for_each(|&l| seen[l] = true);
    let nonempty = seen.iter().filter(|&&s| s).count();
    if nonempty < 2 {
        return Err(ClusterError::OneNonEmptyCluster { n: d.len() });
    }
    Ok(k)
}

/// Mean silhouette width of the partition `labels` (module docs for the formula).
pub fn silhouette<D: Distances + ?Sized>(d: &D, labels: &[usize]) -> Result<f64, ClusterError> {
    let k = check_labels(d, labels)?;
    let n = d.len();
    let mut size = vec![0usize; k];
    labels.iter().for_each(|&l| size[l] += 1);
    let mut total = 0.0;
    let mut sums = vec![0.0; k];
    for x in 0..n {
        sums.iter_mut().for_each(|s| *s = 0.0);
        for y in (0..n).filter(|&y| y != x) {
            sums[labels[y]] += d.dist(x, y);
        }
        let own = labels[x];
        if size[own] == 1 {
            continue; // s(x) = 0
        }
        let a = sums[own] / (size[own] - 1) as f64;
        let b = (0..k)
            .filter(|&c| c != own && size[c] > 0)
            .map(|c| sums[c] / size[c] as f64)
            .fold(f64::INFINITY, f64::min);
        let m = a.max(b);
        if m > 0.0 {
            total += (b - a) / m;
        }
    }
    Ok(total / n as f64)
}

/// Dunn index of the partition `labels` (module docs); `None` when every cluster is a
/// singleton.
pub fn dunn<D: Distances + ?Sized>(d: &D, labels: &[usize]) -> Result<Option<f64>, ClusterError> {
    check_labels(d, labels)?;
    let n = d.len();
    let (mut separation, mut diameter) = (f64::INFINITY, 0.0f64);
    for x in 0..n {
        for y in x + 1..n {
            let v = d.dist(x, y);
            if labels[x] == labels[y] {
                diameter = diameter.max(v);
            } else {
                separation = separation.min(v);
            }
        }
    }
    Ok((diameter > 0.0).then(|| separation / diameter))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a line: D = |p_i - p_j|.
    struct Line(Vec<f64>);
    impl Distances for Line {
        fn len(&self) -> usize {
            self.0.len()
        }
        fn dist(&self, i: usize, j: usize) -> f64 {
            (self.0[i] - self.0[j]).abs()
        }
    }

    /// Points 0, 1, 5, 7 in clusters {0, 1}, {5, 7}, by hand:
    /// x=0: a = 1, b = (5 + 7) / 2 = 6, s = 5/6; x=1: a = 1, b = (4 + 6) / 2 = 5, s = 4/5;
    /// x=5: a = 2, b = (5 + 4) / 2 = 4.5, s = 2.5/4.5 = 5/9; x=7: a = 2, b = 6.5, s = 9/13.
    #[test]
    fn silhouette_by_hand() {
        let d = Line(vec![0.0, 1.0, 5.0, 7.0]);
        let s = silhouette(&d, &[0, 0, 1, 1]).unwrap();
        let expected = (5.0 / 6.0 + 4.0 / 5.0 + 5.0 / 9.0 + 9.0 / 13.0) / 4.0;
        assert!((s - expected).abs() < 1e-15, "{s} vs {expected}");
        // A singleton contributes 0: {0}, {1, 5, 7}.
        // x=1: a = (4 + 6) / 2 = 5, b = 1, s = -4/5; x=5: a = (4 + 2) / 2 = 3, b = 5,
        // s = 2/5; x=7: a = (6 + 2) / 2 = 4, b = 7, s = 3/7.
        let s = silhouette(&d, &[0, 1, 1, 1]).unwrap();
        let expected = (0.0 - 4.0 / 5.0 + 2.0 / 5.0 + 3.0 / 7.0) / 4.0;
        assert!((s - expected).abs() < 1e-15, "{s} vs {expected}");
        // Empty cluster indices are ignored: labels 0 and 2.
        assert_eq!(
            silhouette(&d, &[0, 0, 2, 2]).unwrap(),
            silhouette(&d, &[0, 0, 1, 1]).unwrap()
        );
    }

    /// Dunn of {0, 1}, {5, 7}: separation 4 (1 to 5), diameter 2 (5 to 7): 2.
    #[test]
    fn dunn_by_hand() {
        let d = Line(vec![0.0, 1.0, 5.0, 7.0]);
        assert_eq!(dunn(&d, &[0, 0, 1, 1]).unwrap(), Some(2.0));
        // {0}, {1, 5}, {7}: separation min(1, 5, 7, 6, 2) = 1, diameter 4: 0.25.
        assert_eq!(dunn(&d, &[0, 1, 1, 2]).unwrap(), Some(0.25));
        // All singletons: undefined.
        assert_eq!(dunn(&d, &[0, 1, 2, 3]).unwrap(), None);
    }

    #[test]
    fn indices_reject_bad_partitions() {
        let d = Line(vec![0.0, 1.0, 5.0]);
        assert_eq!(
            silhouette(&d, &[0, 0]),
            Err(ClusterError::LabelCountMismatch {
                expected: 3,
                found: 2
            })
        );
        assert_eq!(
            dunn(&d, &[1, 1, 1]),
            Err(ClusterError::OneNonEmptyCluster { n: 3 })
        );
    }
}
