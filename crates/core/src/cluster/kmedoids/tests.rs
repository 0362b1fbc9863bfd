use super::*;
use crate::cluster::tests::{Line, Matrix};
use rand::Rng;

fn random_points(n: usize, seed: u64) -> Matrix {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let p: Vec<[f64; 2]> = (0..n)
        .map(|_| [rng.random::<f64>(), rng.random::<f64>()])
        .collect();
    let data = (0..n * n)
        .map(|ij| {
            let (a, b) = (p[ij / n], p[ij % n]);
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
        })
        .collect();
    Matrix(n, data)
}

/// Minimum loss over all k-subsets, by enumeration (n <= 8).
fn brute_force(d: &Matrix, k: usize) -> f64 {
    let n = d.len();
    (0u32..1 << n)
        .filter(|mask| mask.count_ones() as usize == k)
        .map(|mask| {
            let medoids: Vec<usize> = (0..n).filter(|&i| mask & (1 << i) != 0).collect();
            loss_unchecked(d, &medoids, &assign_unchecked(d, &medoids))
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn two_separated_groups() {
    let d = Line(vec![100.0, 0.0, 101.0, 1.0, 102.0, 2.0]);
    let r = KMedoidsParams::new(2).fit(&d).unwrap();
    assert_eq!(r.medoids, vec![2, 3]);
    assert_eq!(r.labels, vec![0, 1, 0, 1, 0, 1]);
    assert_eq!(r.loss, 4.0);
    // S = (2/3, 2/3), medoids 101 and 1 at distance 100.
    assert!((r.db_index - (4.0 / 3.0) / 100.0).abs() < 1e-15);
}

#[test]
fn reaches_brute_force_optimum_on_tiny_sets() {
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        for seed in 0..6 {
            let d = random_points(8, seed);
            for k in 2..=5 {
                let r = KMedoidsParams::new(k)
                    .algorithm(algorithm)
                    .restarts(10)
                    .seed(seed)
                    .fit(&d)
                    .unwrap();
                let opt = brute_force(&d, k);
                assert!(
                    (r.loss - opt).abs() <= 1e-12 * opt,
                    "{algorithm} seed {seed} k {k}: {} vs {opt}",
                    r.loss
                );
            }
        }
    }
}

#[test]
fn fasterpam_from_every_start_of_a_tiny_set_is_a_pam_local_optimum() {
    // Every 3-subset of 9 points as a start: FasterPAM ends where no single swap
    // lowers the loss (PAM's SWAP from there makes no swap), and from some start it
    // reaches the enumerated optimum.
    let d = random_points(9, 5);
    let opt = brute_force(&d, 3);
    let fp = KMedoidsParams::new(3).check().unwrap();
    let pam = KMedoidsParams::new(3)
        .algorithm(KMedoidsAlgorithm::Pam)
        .check()
        .unwrap();
    let mut best = f64::INFINITY;
    for mask in (0u32..1 << 9).filter(|m| m.count_ones() == 3) {
        let start: Vec<usize> = (0..9).filter(|&i| mask & (1 << i) != 0).collect();
        let r = fp.fit_from(&d, &start).unwrap();
        let again = pam.fit_from(&d, &r.medoids).unwrap();
        assert_eq!(again.iterations, 0, "start {start:?}");
        assert_eq!(again.medoids, r.medoids);
        assert!(r.loss >= opt - 1e-12);
        best = best.min(r.loss);
    }
    assert_eq!(best, opt);
}

#[test]
fn algorithm_names_round_trip() {
    for a in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        assert_eq!(a.to_string().parse::<KMedoidsAlgorithm>(), Ok(a));
    }
    assert_eq!(
        "clara".parse::<KMedoidsAlgorithm>(),
        Err(ClusterError::UnknownAlgorithm("clara".into()))
    );
}

#[test]
fn rejects_bad_starts_and_tolerances() {
    let d = Line(vec![0.0, 1.0, 2.0, 3.0]);
    let p = KMedoidsParams::new(2).check().unwrap();
    assert_eq!(
        p.fit_from(&d, &[1, 1]),
        Err(ClusterError::DuplicateMedoid(1))
    );
    assert_eq!(
        p.fit_from(&d, &[1, 7]),
        Err(ClusterError::IndexOutOfRange { index: 7, n: 4 })
    );
    assert_eq!(
        p.fit_from(&d, &[1]),
        Err(ClusterError::MedoidCount {
            expected: 2,
            found: 1
        })
    );
    for t in [-1e-6, 1.0, f64::NAN] {
        assert!(matches!(
            KMedoidsParams::new(2).tolerance(t).check(),
            Err(ClusterError::BadTolerance(_))
        ));
    }
}

#[test]
fn a_gain_within_the_tolerance_is_not_a_swap() {
    // Item 0 far from the group {1, 2, 3}; as the group's medoid, item 1 costs 2 and
    // items 2 and 3 cost 2 + 1e-9.
    let e = 1e-9;
    #[rustfmt::skip]
    let d = Matrix(4, vec![
        0.0, 100.0, 100.0, 100.0,
        100.0, 0.0, 1.0, 1.0,
        100.0, 1.0, 0.0, 1.0 + e,
        100.0, 1.0, 1.0 + e, 0.0,
    ]);
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        let p = KMedoidsParams::new(2).algorithm(algorithm);
        // From {0, 2}: the swap 2 -> 1 gains 1e-9 (5e-10 of the loss).
        let strict = p.clone().tolerance(0.0).check().unwrap();
        assert_eq!(strict.fit_from(&d, &[0, 2]).unwrap().medoids, vec![0, 1]);
        let tol = p.check().unwrap().fit_from(&d, &[0, 2]).unwrap();
        assert_eq!((tol.medoids, tol.iterations), (vec![0, 2], 0));
    }
}

#[test]
fn same_seed_same_result() {
    let d = random_points(40, 7);
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        let p = KMedoidsParams::new(5)
            .algorithm(algorithm)
            .restarts(4)
            .seed(11)
            .init(KMedoidsInit::Random);
        let a = p.fit(&d).unwrap();
        assert_eq!(a, p.fit(&d).unwrap());
        // Restarts never do worse than run 0 alone (same seed for run 0).
        assert!(a.loss <= p.clone().restarts(1).fit(&d).unwrap().loss);
    }
}

#[test]
fn candidate_orders() {
    assert_eq!(
        candidate_order(6, KMedoidsOrder::Sequential, 3),
        vec![0, 1, 2, 3, 4, 5]
    );
    let a = candidate_order(50, KMedoidsOrder::Shuffled, 3);
    let mut sorted = a.clone();
    sorted.sort_unstable();
    assert_eq!(sorted, (0..50).collect::<Vec<_>>());
    assert_eq!(a, candidate_order(50, KMedoidsOrder::Shuffled, 3));
    assert_ne!(a, candidate_order(50, KMedoidsOrder::Shuffled, 4));
    assert_ne!(a, sorted);
}

#[test]
fn fit_from_repeats_a_seeded_run() {
    // Run r of `fit` draws its start from stream 0 and its order from stream 1 of the
    // generator of seed + r: `fit_from` with that start and seed is the same run.
    let d = random_points(60, 2);
    for seed in [0, 5, u64::MAX] {
        let p = KMedoidsParams::new(6).init(KMedoidsInit::Random).seed(seed);
        let start = rand::seq::index::sample(&mut ChaCha8Rng::seed_from_u64(seed), 60, 6);
        let from = p.check().unwrap().fit_from(&d, &start.into_vec()).unwrap();
        assert_eq!(p.fit(&d).unwrap(), from, "seed {seed}");
    }
}

#[test]
fn the_order_changes_where_a_run_ends() {
    // From one start, the shuffled orders of a few seeds reach other local optima than
    // item order (each a PAM local optimum).
    let d = random_points(60, 9);
    let start = [0, 1, 2, 3, 4, 5];
    let seq = KMedoidsParams::new(6)
        .order(KMedoidsOrder::Sequential)
        .check()
        .unwrap()
        .fit_from(&d, &start)
        .unwrap();
    let pam = KMedoidsParams::new(6)
        .algorithm(KMedoidsAlgorithm::Pam)
        .check()
        .unwrap();
    let mut other = 0;
    for seed in 0..10 {
        let r = KMedoidsParams::new(6)
            .seed(seed)
            .check()
            .unwrap()
            .fit_from(&d, &start)
            .unwrap();
        assert_eq!(pam.fit_from(&d, &r.medoids).unwrap().iterations, 0);
        other += usize::from(r.medoids != seq.medoids);
    }
    assert!(other > 0, "every order ended at {:?}", seq.medoids);
}

#[test]
fn max_iter_zero_keeps_build() {
    let d = random_points(20, 3);
    let mut b = build(&d, 3);
    b.sort_unstable();
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        let r = KMedoidsParams::new(3)
            .algorithm(algorithm)
            .max_iter(0)
            .fit(&d)
            .unwrap();
        assert_eq!(r.iterations, 0);
        assert_eq!(r.medoids, b);
    }
}

#[test]
fn rejects_k_below_two() {
    assert_eq!(
        KMedoidsParams::new(1).check(),
        Err(ClusterError::KTooSmall { k: 1 })
    );
}

#[test]
fn rejects_k_above_n() {
    let d = Line(vec![0.0, 1.0, 2.0]);
    assert_eq!(
        KMedoidsParams::new(4).fit(&d),
        Err(ClusterError::KOutOfRange { k: 4, n: 3 })
    );
}

#[test]
fn rejects_zero_restarts() {
    assert_eq!(
        KMedoidsParams::new(2).restarts(0).check(),
        Err(ClusterError::ZeroRuns)
    );
}

#[test]
fn rejects_non_finite_distance() {
    let d = Line(vec![0.0, 1.0, f64::INFINITY]);
    let err = KMedoidsParams::new(2).fit(&d).unwrap_err();
    assert!(matches!(
        err,
        ClusterError::NonFiniteDistance { i: 0, j: 2, .. }
    ));
}

/// Distances whose values stop being intact after `after` checks (a mapped matrix file
/// truncated under the clustering, audit 3 M2).
struct Failing {
    inner: Matrix,
    after: usize,
    asked: std::sync::atomic::AtomicUsize,
}

impl Distances for Failing {
    fn len(&self) -> usize {
        self.inner.len()
    }
    fn dist(&self, i: usize, j: usize) -> f64 {
        self.inner.dist(i, j)
    }
    fn intact(&self) -> Result<(), String> {
        match self
            .asked
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            < self.after
        {
            true => Ok(()),
            false => Err("truncated".into()),
        }
    }
}

/// Audit 3, M2: the search asks whether the values are intact between runs and during a
/// run, and stops with the reason as soon as they are not (before: only at the end).
#[test]
fn a_search_stops_when_the_values_stop_being_intact() {
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        for after in [0, 1, 3] {
            let d = Failing {
                inner: random_points(300, 5),
                after,
                asked: Default::default(),
            };
            let e = KMedoidsParams::new(6)
                .algorithm(algorithm)
                .restarts(1000)
                .fit(&d)
                .expect_err("stops");
            assert!(
                matches!(e, ClusterError::SourceChanged(ref m) if m == "truncated"),
                "{e}"
            );
            // Far fewer checks than 1,000 runs would make.
            assert!(d.asked.load(std::sync::atomic::Ordering::Relaxed) == after + 1);
        }
        let ok = Failing {
            inner: random_points(60, 5),
            after: usize::MAX,
            asked: Default::default(),
        };
        let a = KMedoidsParams::new(4)
            .algorithm(algorithm)
            .restarts(3)
            .fit(&ok)
            .expect("intact");
        let b = KMedoidsParams::new(4)
            .algorithm(algorithm)
            .restarts(3)
            .fit(&ok.inner)
            .expect("plain");
        assert_eq!(a, b);
    }
}
