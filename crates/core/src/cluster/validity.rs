//! Medoids, nearest-medoid assignment, k-medoids loss and the medoid Davies-Bouldin index.
//!
//! Conventions (SPEC section 6), for items `0..n`, medoids `m_0..m_{k-1}` and labels
//! `l(x)` in `0..k`:
//!
//! * medoid of a cluster `C`: `argmin_{y in C} sum_{x in C} D[x][y]`, ties to the lowest
//!   item index;
//! * assignment: `l(x) = argmin_i D[x][m_i]`, ties to the lowest cluster index `i`;
//! * loss: `sum_x D[x][m_{l(x)}]`;
//! * medoid Davies-Bouldin index (Davies & Bouldin 1979, doi:10.1109/TPAMI.1979.4766909,
//!   with medoids in place of centroids):
//!
//! ```text
//! S_i  = mean_{x : l(x) = i} D[x][m_i]              (0 for a singleton or empty cluster)
//! R_ij = (S_i + S_j) / D[m_i][m_j]                  (+inf when D[m_i][m_j] = 0)
//! DB   = (1/k) sum_i max_{j != i} R_ij              (lower is better)
//! ```
//!
//! The public functions validate their inputs; the crate-internal `*_unchecked` twins
//! are called by the algorithms, which keep the invariants themselves.

use super::ClusterError;
use crate::distance::{entry_fault, Distances, EntryFault};

/// Checks that every off-diagonal distance `D[i][j]`, `i < j`, is finite and
/// non-negative, by the crate's one entry validator, [`entry_fault`] (a [`Distances`] is
/// symmetric by construction and its diagonal is 0, so only these two faults can occur;
/// whole matrices read from files go through `distance::check_entries`). The algorithms
/// call this once before they start.
pub(crate) fn check_distances<D: Distances + ?Sized>(d: &D) -> Result<(), ClusterError> {
    let n = d.len();
    for i in 0..n {
        for j in i + 1..n {
            let value = d.dist(i, j);
            match entry_fault(i, j, value) {
                None => {}
                Some(EntryFault::Negative) => {
                    return Err(ClusterError::NegativeDistance { i, j, value })
                }
                // `NotFinite`; `Diagonal` and `Asymmetric` cannot arise for `i < j`.
                Some(_) => return Err(ClusterError::NonFiniteDistance { i, j, value }),
            }
        }
    }
    Ok(())
}

fn check_index(index: usize, n: usize) -> Result<(), ClusterError> {
    if index < n {
        Ok(())
    } else {
        Err(ClusterError::IndexOutOfRange { index, n })
    }
}

/// The medoid of a cluster: the member minimising the sum of distances to the other
/// members, ties to the lowest item index (whatever the order of `members`).
pub fn medoid_of<D: Distances + ?Sized>(d: &D, members: &[usize]) -> Result<usize, ClusterError> {
    if members.is_empty() {
        return Err(ClusterError::EmptyCluster);
    }
    for &m in members {
        check_index(m, d.len())?;
    }
    Ok(medoid_unchecked(d, members))
}

pub(crate) fn medoid_unchecked<D: Distances + ?Sized>(d: &D, members: &[usize]) -> usize {
    let mut best = (f64::INFINITY, usize::MAX);
    for &y in members {
        let cost: f64 = members.iter().map(|&x| d.dist(x, y)).sum();
        if cost < best.0 || (cost == best.0 && y < best.1) {
            best = (cost, y);
        }
    }
    best.1
}

/// Assigns every item to its nearest medoid: `labels[x]` is the position in `medoids` of
/// the medoid closest to `x`, ties to the lowest position.
pub fn assign<D: Distances + ?Sized>(d: &D, medoids: &[usize]) -> Result<Vec<usize>, ClusterError> {
    if medoids.is_empty() {
        return Err(ClusterError::NoMedoids);
    }
    for &m in medoids {
        check_index(m, d.len())?;
    }
    Ok(assign_unchecked(d, medoids))
}

pub(crate) fn assign_unchecked<D: Distances + ?Sized>(d: &D, medoids: &[usize]) -> Vec<usize> {
    (0..d.len())
        .map(|x| {
            let mut best = (f64::INFINITY, 0);
            for (i, &m) in medoids.iter().enumerate() {
                let dx = d.dist(x, m);
                if dx < best.0 {
                    best = (dx, i);
                }
            }
            best.1
        })
        .collect()
}

fn check_partition<D: Distances + ?Sized>(
    d: &D,
    medoids: &[usize],
    labels: &[usize],
) -> Result<(), ClusterError> {
    let n = d.len();
    if labels.len() != n {
        return Err(ClusterError::LabelCountMismatch {
            expected: n,
            found: labels.len(),
        });
    }
    for &m in medoids {
        check_index(m, n)?;
    }
    let k = medoids.len();
    match labels.iter().position(|&l| l >= k) {
        Some(item) => Err(ClusterError::LabelOutOfRange {
            item,
            label: labels[item],
            k,
        }),
        None => Ok(()),
    }
}

/// The k-medoids loss `sum_x D[x][medoids[labels[x]]]`.
pub fn loss<D: Distances + ?Sized>(
    d: &D,
    medoids: &[usize],
    labels: &[usize],
) -> Result<f64, ClusterError> {
    check_partition(d, medoids, labels)?;
    Ok(loss_unchecked(d, medoids, labels))
}

pub(crate) fn loss_unchecked<D: Distances + ?Sized>(
    d: &D,
    medoids: &[usize],
    labels: &[usize],
) -> f64 {
    labels
        .iter()
        .enumerate()
        .map(|(x, &l)| d.dist(x, medoids[l]))
        .sum()
}

/// The medoid Davies-Bouldin index of a partition (module docs for the formula).
///
/// Needs `2 <= k <= n` medoids. Medoids need not be distinct: two medoids at distance 0
/// give `R_ij = +inf`, hence `DB = +inf`. An empty cluster has `S_i = 0`.
pub fn davies_bouldin<D: Distances + ?Sized>(
    d: &D,
    medoids: &[usize],
    labels: &[usize],
) -> Result<f64, ClusterError> {
    let (k, n) = (medoids.len(), d.len());
    if k < 2 || k > n {
        return Err(ClusterError::KOutOfRange { k, n });
    }
    check_partition(d, medoids, labels)?;
    Ok(db_unchecked(d, medoids, labels))
}

pub(crate) fn db_unchecked<D: Distances + ?Sized>(
    d: &D,
    medoids: &[usize],
    labels: &[usize],
) -> f64 {
    let k = medoids.len();
    let mut sum = vec![0.0; k];
    let mut count = vec![0usize; k];
    for (x, &l) in labels.iter().enumerate() {
        sum[l] += d.dist(x, medoids[l]);
        count[l] += 1;
    }
    let scatter: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(&s, &c)| if c > 1 { s / c as f64 } else { 0.0 })
        .collect();
    let mut total = 0.0;
    for i in 0..k {
        let mut worst = f64::NEG_INFINITY;
        for j in (0..k).filter(|&j| j != i) {
            let sep = d.dist(medoids[i], medoids[j]);
            let r = if sep == 0.0 {
                f64::INFINITY
            } else {
                (scatter[i] + scatter[j]) / sep
            };
            worst = worst.max(r);
        }
        total += worst;
    }
    total / k as f64
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Points on a line with `|x - y|` distances: a test-only [`Distances`].
    pub(crate) struct Line(pub Vec<f64>);

    impl Distances for Line {
        fn len(&self) -> usize {
            self.0.len()
        }
        fn dist(&self, i: usize, j: usize) -> f64 {
            (self.0[i] - self.0[j]).abs()
        }
    }

    /// A full row-major matrix: a test-only [`Distances`].
    pub(crate) struct Matrix(pub usize, pub Vec<f64>);

    impl Distances for Matrix {
        fn len(&self) -> usize {
            self.0
        }
        fn dist(&self, i: usize, j: usize) -> f64 {
            self.1[i * self.0 + j]
        }
    }

    /// Three clusters {0, 1, 2}, {10, 11}, {20}: items 0..6.
    fn three() -> (Line, Vec<usize>) {
        (
            Line(vec![0.0, 1.0, 2.0, 10.0, 11.0, 20.0]),
            vec![0, 0, 0, 1, 1, 2],
        )
    }

    #[test]
    fn medoid_minimises_sum_ties_to_lowest_index() {
        let (d, _) = three();
        assert_eq!(medoid_of(&d, &[0, 1, 2]), Ok(1));
        // {10, 11}: both sums are 1 -> lowest item index, whatever the order given.
        assert_eq!(medoid_of(&d, &[4, 3]), Ok(3));
        assert_eq!(medoid_of(&d, &[5]), Ok(5));
        assert_eq!(medoid_of(&d, &[]), Err(ClusterError::EmptyCluster));
        assert_eq!(
            medoid_of(&d, &[6]),
            Err(ClusterError::IndexOutOfRange { index: 6, n: 6 })
        );
    }

    #[test]
    fn assignment_ties_go_to_lowest_cluster_index() {
        let d = Line(vec![0.0, 2.0, 4.0]);
        // Item 1 is at distance 2 from both medoids: cluster 0 (medoid item 2) wins.
        assert_eq!(assign(&d, &[2, 0]), Ok(vec![1, 0, 0]));
        assert_eq!(assign(&d, &[]), Err(ClusterError::NoMedoids));
    }

    #[test]
    fn loss_and_db_by_hand() {
        let (d, labels) = three();
        let medoids = [1, 3, 5];
        assert_eq!(loss(&d, &medoids, &labels), Ok(3.0));
        // S = (2/3, 1/2, 0); R_01 = (7/6)/9 = 7/54, R_02 = (2/3)/19, R_12 = (1/2)/10.
        // DB = (7/54 + 7/54 + 1/20) / 3 = 167/1620.
        let db = davies_bouldin(&d, &medoids, &labels).unwrap();
        assert!((db - 167.0 / 1620.0).abs() < 1e-15, "{db}");
    }

    #[test]
    fn db_is_infinite_when_medoids_coincide() {
        let d = Line(vec![0.0, 0.0, 5.0]);
        let db = davies_bouldin(&d, &[0, 1, 2], &[0, 1, 2]).unwrap();
        assert_eq!(db, f64::INFINITY);
        // Singletons at positive separation: every S is 0, so DB is 0.
        let d = Line(vec![0.0, 1.0, 5.0]);
        assert_eq!(davies_bouldin(&d, &[0, 1, 2], &[0, 1, 2]), Ok(0.0));
    }

    #[test]
    fn rejects_bad_partitions() {
        let (d, labels) = three();
        assert_eq!(
            davies_bouldin(&d, &[1], &labels),
            Err(ClusterError::KOutOfRange { k: 1, n: 6 })
        );
        assert_eq!(
            loss(&d, &[1, 3], &labels),
            Err(ClusterError::LabelOutOfRange {
                item: 5,
                label: 2,
                k: 2
            })
        );
        assert_eq!(
            loss(&d, &[1, 3, 5], &labels[..5]),
            Err(ClusterError::LabelCountMismatch {
                expected: 6,
                found: 5
            })
        );
    }

    #[test]
    fn check_distances_finds_bad_entries() {
        assert_eq!(check_distances(&Line(vec![0.0, 1.0])), Ok(()));
        let err = check_distances(&Line(vec![0.0, f64::NAN])).unwrap_err();
        assert!(matches!(
            err,
            ClusterError::NonFiniteDistance { i: 0, j: 1, .. }
        ));
        let m = Matrix(3, vec![0.0, 1.0, 2.0, 1.0, 0.0, -1.0, 2.0, -1.0, 0.0]);
        let err = check_distances(&m).unwrap_err();
        assert!(matches!(
            err,
            ClusterError::NegativeDistance { i: 1, j: 2, .. }
        ));
    }
}
