"""The library against independent peers: SciPy, scikit-learn, the kmedoids package."""

import numpy as np
import pytest

import brdf_basis as bb


@pytest.fixture(scope="module")
def brdf_it():
    """The BRDF_it matrix of the embedded collection (every 6th cell per axis)."""
    return bb.distance_matrix(bb.Collection.default(), stride=6, backend="cpu")


def test_nnls_matches_scipy(peer):
    opt = peer("scipy.optimize")
    rng = np.random.default_rng(7)
    active = 0
    for trial in range(40):
        m, n = rng.integers(5, 40), rng.integers(1, 12)
        a = rng.normal(size=(m, n))
        b = rng.normal(size=m)
        x = bb.nnls(a, b)
        ref, _ = opt.nnls(a, b)
        active += int((x == 0).sum())
        assert x.shape == (n,) and (x >= 0).all()
        np.testing.assert_allclose(x, ref, rtol=1e-8, atol=1e-10, err_msg=f"trial {trial}")
        # The same objective value (a peer-independent check of optimality).
        assert np.linalg.norm(a @ x - b) <= np.linalg.norm(a @ ref - b) * (1 + 1e-12) + 1e-14
    assert active > 0, "no bound was active: the test would not see a wrong active set"


def test_silhouette_matches_scikit_learn(peer, brdf_it):
    metrics = peer("sklearn.metrics")
    for k in (2, 3, 5, 8):
        km = bb.kmedoids(brdf_it, k, seed=3)
        ours = bb.silhouette(brdf_it, km.labels)
        ref = metrics.silhouette_score(brdf_it, km.labels, metric="precomputed")
        assert ours == pytest.approx(ref, rel=1e-12, abs=1e-14), k


def test_kmedoids_loss_matches_the_kmedoids_package(peer, brdf_it):
    km = peer("kmedoids")
    for k in (2, 4, 6, 9):
        ours = bb.kmedoids(brdf_it, k, init="build", algorithm="pam")
        ref = km.pam(brdf_it, k, init="build", max_iter=1000)
        # The loss of our medoids, computed independently.
        own = brdf_it[:, ours.medoids].min(axis=1).sum()
        assert ours.loss == pytest.approx(own, rel=1e-12)
        assert ours.loss == pytest.approx(float(ref.loss), rel=1e-9), k
        assert sorted(ours.medoids) == sorted(int(m) for m in ref.medoids), k
        # FasterPAM from the same start reaches a loss no worse than PAM's by more than ties.
        fast = bb.kmedoids(brdf_it, k, init="build", algorithm="fasterpam")
        ref_fast = km.fasterpam(brdf_it, np.array(ref.medoids), max_iter=1000)
        assert fast.loss == pytest.approx(brdf_it[:, fast.medoids].min(axis=1).sum(), rel=1e-12)
        assert float(ref_fast.loss) == pytest.approx(brdf_it[:, list(ref_fast.medoids)].min(axis=1).sum(), rel=1e-6)


def test_wilcoxon_matches_scipy(peer):
    stats = peer("scipy.stats")
    rng = np.random.default_rng(11)
    exact = normal = 0
    for trial in range(30):
        n = int(rng.integers(6, 70))
        x = rng.normal(size=n)
        y = x + rng.normal(0.2, 1.0, size=n)
        if trial % 3 == 0:  # ties and zeros: the normal approximation
            x, y = np.round(x, 1), np.round(y, 1)
        ours = bb.wilcoxon(x, y)
        ref = stats.wilcoxon(x, y, zero_method="wilcox", correction=True, method="auto")
        exact += ours.method == "exact"
        normal += ours.method == "normal"
        assert ours.statistic == pytest.approx(float(ref.statistic), rel=1e-12), trial
        assert ours.p_value == pytest.approx(float(ref.pvalue), rel=1e-9, abs=1e-15), trial
    assert exact > 0 and normal > 0


def test_friedman_matches_scipy(peer):
    stats = peer("scipy.stats")
    rng = np.random.default_rng(5)
    for trial in range(20):
        blocks, k = int(rng.integers(3, 30)), int(rng.integers(3, 7))
        v = rng.normal(size=(blocks, k)) + np.arange(k) * 0.3
        if trial % 2:
            v = np.round(v, 0)  # ties within blocks
        ours = bb.friedman(v)
        ref = stats.friedmanchisquare(*v.T)
        assert ours.statistic == pytest.approx(float(ref.statistic), rel=1e-10), trial
        assert ours.p_value == pytest.approx(float(ref.pvalue), rel=1e-8, abs=1e-300), trial


def test_mann_whitney_matches_scipy(peer):
    stats = peer("scipy.stats")
    rng = np.random.default_rng(9)
    for trial in range(20):
        x = np.round(rng.normal(size=int(rng.integers(4, 40))), 1)
        y = np.round(rng.normal(0.3, 1, size=int(rng.integers(4, 40))), 1)
        ours = bb.mann_whitney(x, y)
        ref = stats.mannwhitneyu(x, y, alternative="two-sided", use_continuity=True, method="asymptotic")
        assert ours.u == pytest.approx(float(ref.statistic), rel=1e-12), trial
        assert ours.p_value == pytest.approx(float(ref.pvalue), rel=1e-9), trial
