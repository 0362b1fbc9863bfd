//! FasterPAM against the `kmedoids` package, against PAM, and the clustering flags of
//! `select`.

use crate::common::*;
use brdf_basis::backend::cpu::CpuBackend;
use brdf_basis::cluster::{KMedoidsAlgorithm, KMedoidsInit, KMedoidsOrder, KMedoidsParams};
use brdf_basis::distance::{distance_matrix, DistanceMatrix, DistanceParams};

/// The synthetic matrix of the reference below: points
/// `((1 + i % 7) frac(i G), frac(i S))`, Euclidean, f64.
fn synthetic(n: usize) -> DistanceMatrix {
    let (g, s) = (0.6180339887498949f64, 0.41421356237309503f64);
    let p: Vec<(f64, f64)> = (0..n)
        .map(|i| {
            let (x, y) = (i as f64 * g, i as f64 * s);
            ((1 + i % 7) as f64 * (x - x.floor()), y - y.floor())
        })
        .collect();
    let data = (0..n * n)
        .map(|ij| {
            let (a, b) = (p[ij / n], p[ij % n]);
            let (dx, dy) = (a.0 - b.0, a.1 - b.1);
            (dx * dx + dy * dy).sqrt()
        })
        .collect();
    DistanceMatrix::from_full((0..n).map(|i| format!("m{i}")).collect(), data).expect("matrix")
}

/// Start `r` of the reference: items `(r 7919 + i 104729) mod n`, `i < k`.
fn start(n: usize, k: usize, r: usize) -> Vec<usize> {
    (0..k).map(|i| (r * 7919 + i * 104_729) % n).collect()
}

/// `(k, start, loss, sorted medoids, swaps)` from the `kmedoids` Python package 0.5.5
/// (GPL-3.0; run once outside the project, never a dependency):
/// `kmedoids.fasterpam(D, start(200, k, r), max_iter=100, n_cpu=1)` on `synthetic(200)`
/// built in NumPy with the same formula (`-> res.loss, sorted(res.medoids), res.n_swap`).
#[rustfmt::skip]
const REFERENCE: [(usize, usize, f64, &[usize], usize); 12] = [
    (3, 0, 112.86865452663051, &[11, 52, 117], 12),
    (3, 1, 112.86865452663051, &[11, 52, 117], 10),
    (3, 2, 112.86865452663051, &[11, 52, 117], 12),
    (3, 3, 112.86865452663051, &[11, 52, 117], 11),
    (5, 0, 85.04328648082553, &[73, 110, 117, 124, 161], 19),
    (5, 1, 85.04328648082553, &[73, 110, 117, 124, 161], 21),
    (5, 2, 81.95591802826381, &[100, 110, 122, 182, 199], 20),
    (5, 3, 81.95591802826381, &[100, 110, 122, 182, 199], 22),
    (12, 0, 50.160179632479704, &[4, 6, 9, 11, 21, 26, 85, 102, 109, 119, 139, 158], 37),
    (12, 1, 51.05952030286291, &[9, 11, 26, 33, 42, 49, 76, 110, 155, 158, 165, 184], 26),
    (12, 2, 50.498838628543716, &[6, 9, 11, 14, 25, 49, 79, 138, 139, 148, 149, 158], 33),
    (12, 3, 50.160179632479704, &[4, 6, 9, 11, 21, 26, 85, 102, 109, 119, 139, 158], 28),
];

#[test]
fn fasterpam_matches_the_kmedoids_package() {
    let d = synthetic(200);
    for &(k, r, loss, medoids, swaps) in &REFERENCE {
        // Strict comparisons and candidates in item order, as the package's `fasterpam`
        // with given medoids: the same swaps, medoids and loss, bit for bit.
        let strict = KMedoidsParams::new(k)
            .order(KMedoidsOrder::Sequential)
            .tolerance(0.0)
            .check()
            .expect("params");
        let got = strict.fit_from(&d, &start(200, k, r)).expect("fit");
        assert_eq!(
            (got.loss, got.medoids.as_slice(), got.iterations),
            (loss, medoids, swaps),
            "k {k} start {r}"
        );
        // The default tie margin ends at the same local optimum here.
        let def = KMedoidsParams::new(k)
            .order(KMedoidsOrder::Sequential)
            .check()
            .expect("params");
        let got = def.fit_from(&d, &start(200, k, r)).expect("fit");
        assert_eq!((got.loss, got.medoids.as_slice()), (loss, medoids));
    }
}

/// `n` points drawn uniformly in the unit square by SplitMix64 (Steele, Lea & Flood 2014,
/// doi:10.1145/2714064.2660195) from `seed` (`x`, then `y`, each `(z >> 11) 2^-53`),
/// listed as drawn or, with `by_x`, in increasing `x` (as a collection lists similar
/// materials together); Euclidean, f64: a matrix NumPy rebuilds bit for bit.
fn uniform_points(n: usize, seed: u64, by_x: bool) -> DistanceMatrix {
    let mut s = seed;
    let mut next = || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 * (-53f64).exp2()
    };
    let mut p: Vec<(f64, f64)> = (0..n).map(|_| (next(), next())).collect();
    if by_x {
        p.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let data = (0..n * n)
        .map(|ij| {
            let (a, b) = (p[ij / n], p[ij % n]);
            let (dx, dy) = (a.0 - b.0, a.1 - b.1);
            (dx * dx + dy * dy).sqrt()
        })
        .collect();
    DistanceMatrix::from_full((0..n).map(|i| format!("p{i}")).collect(), data).expect("matrix")
}

/// As [`REFERENCE`], on `uniform_points(400, 400, false)` (rebuilt in NumPy), k = 15, starts
/// `start(400, 15, r)`: `kmedoids.fasterpam(D, start, max_iter=100, n_cpu=1)`.
#[rustfmt::skip]
const UNIFORM_REFERENCE: [(usize, usize, f64, &[usize], usize); 4] = [
    (15, 0, 36.355995376474624, &[27, 31, 88, 124, 138, 150, 194, 207, 250, 252, 273, 287, 298, 315, 355], 54),
    (15, 1, 36.48515062135612, &[27, 31, 124, 129, 138, 150, 187, 194, 250, 273, 292, 315, 318, 355, 396], 61),
    (15, 2, 36.355995376474624, &[27, 31, 88, 124, 138, 150, 194, 207, 250, 252, 273, 287, 298, 315, 355], 62),
    (15, 3, 36.854022255749015, &[23, 47, 85, 88, 90, 124, 148, 150, 194, 250, 252, 273, 287, 355, 397], 57),
];

/// `(k, loss)`: the best of the `kmedoids` package's 30 runs
/// `kmedoids.fasterpam(D, k, random_state=s, max_iter=100, n_cpu=1)`, `s = 0..30` (random
/// starts and shuffled candidate orders), on `uniform_points(400, 400, true)`; same
/// version.
const SORTED_BEST_OF_30: [(usize, f64); 4] = [
    (5, 67.94705580450126),
    (10, 47.009764382104784),
    (15, 36.35494723599605),
    (20, 30.443194481542996),
];

#[test]
fn fasterpam_matches_the_kmedoids_package_on_uniform_points() {
    let d = uniform_points(400, 400, false);
    for &(k, r, loss, medoids, swaps) in &UNIFORM_REFERENCE {
        let strict = KMedoidsParams::new(k)
            .order(KMedoidsOrder::Sequential)
            .tolerance(0.0)
            .check()
            .expect("params");
        let got = strict.fit_from(&d, &start(400, k, r)).expect("fit");
        assert_eq!(
            (got.loss, got.medoids.as_slice(), got.iterations),
            (loss, medoids, swaps),
            "k {k} start {r}"
        );
    }
}

#[test]
fn best_of_30_seeds_is_as_good_as_the_packages_best_of_30() {
    // 30 seeded runs from random starts (seeds 1..=30) against the package's 30 runs, on
    // points listed in x order. With one candidate order for every run (`Sequential`, what
    // every run used before) the eager swaps follow the listing, the runs fall into fewer
    // optima and the best of 30 misses the package's at k = 10 and 15; with an order drawn
    // per run (the default) it is the package's or lower. These seeds are one draw: over
    // 8 blocks of 30 seeds, the best of a block was above the package's best of 30 in 2
    // of 32 (k, block) pairs with shuffled orders (the package's own blocks vary alike),
    // in 19 of 32 with item order. The 1e-12 allows only the rounding of one medoid set's
    // loss summed in another order.
    let d = uniform_points(400, 400, true);
    let mut misses = 0;
    for &(k, want) in &SORTED_BEST_OF_30 {
        let mut distinct = Vec::new();
        let mut best = Vec::new();
        for order in [KMedoidsOrder::Shuffled, KMedoidsOrder::Sequential] {
            let p = KMedoidsParams::new(k)
                .init(KMedoidsInit::Random)
                .order(order);
            let mut losses: Vec<f64> = (1..=30u64)
                .map(|s| p.clone().seed(s).fit(&d).expect("fit").loss)
                .collect();
            losses.sort_by(f64::total_cmp);
            losses.dedup_by(|a, b| (*a - *b).abs() <= 1e-12 * *b);
            distinct.push(losses.len());
            best.push(losses[0]);
        }
        eprintln!(
            "k {k}: best of 30 shuffled {} ({} optima), item order {} ({} optima), package {want}",
            best[0], distinct[0], best[1], distinct[1]
        );
        assert!(
            best[0] <= want * (1.0 + 1e-12),
            "k {k}: {} vs the package's {want}",
            best[0]
        );
        misses += usize::from(best[1] > want * (1.0 + 1e-12));
        // The restarts of one call are the same runs: its best is the best of the 30 (or
        // an earlier run within the tie margin).
        let one = KMedoidsParams::new(k)
            .init(KMedoidsInit::Random)
            .restarts(30)
            .fit(&d)
            .expect("fit");
        assert!((one.loss - best[0]).abs() <= 1e-6 * best[0], "k {k}");
    }
    // The test sees the defect: in item order the best of 30 misses the package's.
    assert!(
        misses > 0,
        "item order reached the package's best at every k"
    );
}

/// BRDF_it of the Ngan table (defaults: specular lobe, evaluation mask, uniform weights) on
/// the CPU back-end, computed once; `None` (after printing SKIP for `test`) without the
/// shared data.
fn ngan_brdf_it(test: &str) -> Option<&'static DistanceMatrix> {
    static D: std::sync::OnceLock<DistanceMatrix> = std::sync::OnceLock::new();
    let coll = ngan_or_skip(test)?;
    Some(D.get_or_init(|| {
        let p = DistanceParams::default().check(&coll).expect("params");
        distance_matrix(&CpuBackend::new(), &coll, &p, &|_, _| {}).expect("distances")
    }))
}

/// As [`REFERENCE`], on `ngan_brdf_it()` written by `brdf-basis --backend cpu distance
/// ngan2005_ashikhmin_shirley.csv --out d.npy` (bit-identical on the GPU back-end, see
/// `crates/cli/tests/determinism.rs`), starts `start(100, k, r)`, same call and package version.
#[rustfmt::skip]
const NGAN_REFERENCE: [(usize, usize, f64, &[usize], usize); 9] = [
    (5, 0, 1721.4043565342545, &[10, 16, 17, 35, 67], 8),
    (5, 1, 1721.4043565342545, &[10, 16, 17, 35, 67], 13),
    (5, 2, 1721.4043565342545, &[10, 16, 17, 35, 67], 10),
    (8, 0, 1066.903845644776, &[6, 17, 22, 26, 29, 35, 60, 67], 14),
    (8, 1, 1077.5425293172043, &[10, 16, 17, 26, 35, 56, 60, 68], 18),
    (8, 2, 1066.903845644776, &[6, 17, 22, 26, 29, 35, 60, 67], 19),
    (12, 0, 658.5852422163515, &[6, 17, 18, 22, 26, 29, 35, 60, 69, 71, 76, 87], 27),
    (12, 1, 658.5852422163515, &[6, 17, 18, 22, 26, 29, 35, 60, 69, 71, 76, 87], 25),
    (12, 2, 658.5852422163515, &[6, 17, 18, 22, 26, 29, 35, 60, 69, 71, 76, 87], 23),
];

#[test]
fn fasterpam_matches_the_kmedoids_package_on_the_ngan_matrix() {
    // With strict comparisons (as the package): the same medoids and loss, bit for bit,
    // from every start. Some swaps change the loss by 0 in exact arithmetic (e.g. the two
    // members of a two-item cluster are equally good medoids) and by +-1 ulp in floating
    // point: strictly, such a swap may be taken (and others undone: k = 8, start 1 makes
    // 212 swaps here, 18 in the package, before both stop at the same medoids). With the
    // default tie margin none is taken: at most the package's swaps, the same loss, and at
    // k = 8, start 1 the other member of the tied cluster (item 18, chrome, for item 56,
    // red-metallic-paint; loss 1077.542529317204 vs 1077.5425293172043).
    let Some(d) = ngan_brdf_it("fasterpam_matches_the_kmedoids_package_on_the_ngan_matrix") else {
        return;
    };
    for &(k, r, loss, medoids, swaps) in &NGAN_REFERENCE {
        let strict = KMedoidsParams::new(k)
            .order(KMedoidsOrder::Sequential)
            .tolerance(0.0)
            .check()
            .expect("params");
        let got = strict.fit_from(d, &start(100, k, r)).expect("fit");
        assert_eq!(
            (got.loss, got.medoids.as_slice()),
            (loss, medoids),
            "k {k} start {r}"
        );
        // Default margin: the same loss (to rounding) and medoids, or an exactly tied
        // alternative (at most one medoid differs, at the same loss).
        let def = KMedoidsParams::new(k)
            .order(KMedoidsOrder::Sequential)
            .check()
            .expect("params");
        let got = def.fit_from(d, &start(100, k, r)).expect("fit");
        assert!((got.loss - loss).abs() <= 1e-12 * loss, "k {k} start {r}");
        let differ = medoids.iter().filter(|m| !got.medoids.contains(m)).count();
        assert!(differ <= 1, "k {k} start {r}: {:?}", got.medoids);
        assert!(
            got.iterations <= swaps,
            "k {k} start {r}: {} swaps",
            got.iterations
        );
        eprintln!("k {k} start {r}: {} swaps, package {swaps}", got.iterations);
    }
}

#[test]
fn fasterpam_and_pam_on_seeded_starts_of_the_ngan_matrix() {
    // 30 seeded random starts x k = 5..12 (the paper's protocol) on BRDF_it of the Ngan
    // table: from every start FasterPAM ends where PAM's SWAP finds no improving swap, and
    // the best of the 30 runs has the same loss for both algorithms at every k. FasterPAM
    // may end lower or higher than PAM from one start (another neighbourhood order).
    let Some(d) = ngan_brdf_it("fasterpam_and_pam_on_seeded_starts_of_the_ngan_matrix") else {
        return;
    };
    let (mut lower, mut higher, mut same) = (0, 0, 0);
    for k in 5..=12 {
        let fp = KMedoidsParams::new(k).check().expect("params");
        let pam = KMedoidsParams::new(k)
            .algorithm(KMedoidsAlgorithm::Pam)
            .check()
            .expect("params");
        let (mut best_fp, mut best_pam) = (f64::INFINITY, f64::INFINITY);
        for seed in 0..30u64 {
            let init = KMedoidsParams::new(k)
                .seed(seed)
                .init(KMedoidsInit::Random)
                .max_iter(0)
                .fit(d)
                .expect("start");
            let a = fp.fit_from(d, &init.medoids).expect("fasterpam");
            let b = pam.fit_from(d, &init.medoids).expect("pam");
            let again = pam.fit_from(d, &a.medoids).expect("pam after fasterpam");
            assert_eq!(again.iterations, 0, "k {k} seed {seed}");
            assert_eq!(again.medoids, a.medoids);
            let rel = (a.loss - b.loss) / b.loss;
            if rel < -1e-12 {
                lower += 1;
            } else if rel > 1e-12 {
                higher += 1;
            } else {
                same += 1;
            }
            best_fp = best_fp.min(a.loss);
            best_pam = best_pam.min(b.loss);
        }
        assert!(
            (best_fp - best_pam).abs() <= 1e-12 * best_pam,
            "k {k}: best FasterPAM {best_fp}, best PAM {best_pam}"
        );
    }
    eprintln!(
        "FasterPAM vs PAM from the same 240 starts: {lower} lower, {same} equal, {higher} higher"
    );
}

#[test]
fn same_seed_gives_byte_identical_results() {
    let d = synthetic(300);
    for algorithm in [KMedoidsAlgorithm::FasterPam, KMedoidsAlgorithm::Pam] {
        let p = KMedoidsParams::new(8)
            .algorithm(algorithm)
            .restarts(3)
            .seed(42)
            .init(KMedoidsInit::Random);
        let a = serde_json::to_string(&p.fit(&d).expect("fit")).expect("json");
        let b = serde_json::to_string(&p.fit(&d).expect("fit")).expect("json");
        assert_eq!(a, b, "{algorithm}");
    }
}

fn select(args: &[&str]) -> (bool, String, Option<serde_json::Value>) {
    let dir = tmp();
    let out = dir.path().join("s.json");
    let o = bin()
        .args(["--quiet", "--backend", "cpu", "select"])
        .args(args)
        .args(["--stride", "8", "--json"])
        .arg(&out)
        .output()
        .expect("run");
    let json = std::fs::read_to_string(&out)
        .ok()
        .map(|s| serde_json::from_str(&s).expect("json"));
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        json,
    )
}

#[test]
fn select_rejects_zero_runs_and_empty_k_ranges() {
    for method in ["kmedoids", "gcuk"] {
        let (ok, err, json) = select(&["--method", method, "--runs", "0"]);
        assert!(!ok && json.is_none(), "{method} --runs 0 succeeded");
        assert!(err.contains("runs"), "{err}");
        let (ok, err, json) = select(&["--method", method, "--k-min", "10", "--k-max", "5"]);
        assert!(
            !ok && json.is_none(),
            "{method} --k-min 10 --k-max 5 succeeded"
        );
        assert!(
            err.contains("--k-min 10") && err.contains("--k-max 5"),
            "{err}"
        );
    }
    let (ok, err, _) = select(&["--method", "kmedoids", "-k", "1"]);
    assert!(!ok && err.contains("k = 1"), "{err}");
    let (ok, err, _) = select(&["--method", "kmedoids", "-k", "500"]);
    assert!(
        !ok && err.contains("500") && err.contains("58 materials"),
        "{err}"
    );
    let (ok, err, _) = select(&["--method", "kmedoids", "--algorithm", "clara"]);
    assert!(!ok && err.contains("clara"), "{err}");
}

#[test]
fn select_runs_pam_and_fasterpam() {
    let mut best = Vec::new();
    for algorithm in ["pam", "fasterpam"] {
        let (ok, err, json) = select(&[
            "--method",
            "kmedoids",
            "--algorithm",
            algorithm,
            "--k-min",
            "4",
            "--k-max",
            "5",
            "--runs",
            "3",
        ]);
        assert!(ok, "{err}");
        let v = json.expect("json");
        assert_eq!(v["algorithm"], algorithm);
        assert_eq!(v["runs"].as_array().expect("runs").len(), 6);
        assert_eq!(v["runs"][3]["k"], 5);
        best.push(v["best"]["db_index"].as_f64().expect("db"));
    }
    assert!(best.iter().all(|b| b.is_finite() && *b > 0.0));
}
