"""Acquisition from Python (SPEC 10): planning and fitting from sample arrays, checked
against a hand-made exact case and against the command line's plan."""

import json
import os
import subprocess

import numpy as np
import pytest

import brdf_basis as bb

# Broad lobes (n <= 87), so that 12 random samples determine the coefficients well.
BASIS = ["sandblasted-aluminium", "machined-iron", "white-nylon-66"]


def _dir(t, p):
    t, p = np.radians(t), np.radians(p)
    return (np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t))


def test_samples_of_an_exact_combination_give_back_its_coefficients():
    c = bb.Collection.default()
    fs = [bb.Brdf.material(c, n) for n in BASIS]
    rng = np.random.default_rng(7)
    angles = np.column_stack([
        rng.uniform(0, 80, 12), rng.uniform(-180, 180, 12),
        rng.uniform(0, 80, 12), rng.uniform(-180, 180, 12),
    ])
    truth = np.array([[0.05, 0.02, 0.01], [0.7, 0.2, 0.0], [0.0, 0.5, 0.3], [0.25, 0.0, 0.6]])
    y = np.array([
        truth[0] / np.pi + sum(truth[1 + b] * np.array(fs[b].eval1(_dir(*a[:2]), _dir(*a[2:]))) for b in range(3))
        for a in angles
    ])
    r = bb.fit_samples(c, BASIS, angles, y)
    assert r.coefficients.shape == (4, 3)
    np.testing.assert_allclose(r.coefficients, truth, atol=1e-7)
    assert r.rank == 4 and np.isfinite(r.condition)
    assert r.relative_residual < 1e-12


def test_sample_errors_are_value_errors_naming_the_row():
    c = bb.Collection.default()
    with pytest.raises(ValueError, match="line 2"):
        bb.fit_samples(c, BASIS, [[10, 0, 20, 0], [95, 0, 20, 0]], [[0.1] * 3, [0.1] * 3])
    with pytest.raises(ValueError):
        bb.fit_samples(c, ["no-such-material"], [[10, 0, 20, 0]], [[0.1] * 3])


def test_plan_is_the_command_lines_plan(tmp_path):
    exe = os.environ.get("BRDF_BASIS_BIN", "target/release/brdf-basis")
    if not os.path.exists(exe):
        if os.environ.get("BRDF_BASIS_REQUIRE_SHARED") == "1":
            pytest.fail(f"the binary {exe} is missing")
        pytest.skip(f"test_plan_is_the_command_lines_plan: no binary {exe}")
    c = bb.Collection.default()
    p = bb.plan(c, BASIS, 4, criterion="condition", backend="cpu")
    assert p.angles.shape == (4, 4) and p.n == 4 and p.criterion == "condition"
    q = bb.plan(c, BASIS, 2, criterion="condition", backend="cpu")
    np.testing.assert_array_equal(q.angles, p.angles[:2])
    out = tmp_path / "p.json"
    subprocess.run(
        [exe, "--quiet", "--backend", "cpu", "plan", "--basis", ",".join(BASIS), "-n", "4",
         "--criterion", "condition", "--json", str(out), "--out", str(tmp_path / "p.csv")],
        check=True,
    )
    cli = json.loads(out.read_text())
    assert cli["samples"] == json.loads(p.to_json())["samples"]


def test_the_docstring_examples_run():
    import doctest

    r = doctest.testmod(bb, optionflags=doctest.ELLIPSIS)
    assert r.attempted > 10 and r.failed == 0, r


def test_acquisition_cv_returns_the_json_content_and_runs_the_nielsen_baseline(tmp_path):
    c = bb.Collection.default()
    opts = dict(k=3, plans=["condition", "nielsen"], ns=[3, 6], noises=[0.0], folds=2,
                stride=6, candidates_per_step=200, render_size=32, backend="cpu")
    r = bb.acquisition_cv(c, **opts)
    assert isinstance(r, bb.AcquisitionCv)
    assert r.k == 3 and r.select["k"] == 3 and len(r.folds) == 2
    assert sorted({x["plan"] for x in r.results}) == ["condition", "nielsen"]
    assert len(r.results) == 2 * 2
    for x in r.results:
        rho = [h["rho"] for h in x["held_out"]]
        assert len(rho) == sum(len(f) for f in r.folds)
        assert x["mean_rho"] == pytest.approx(np.mean(rho))
        assert x["median_image_error"] == pytest.approx(np.median([h["image_error"] for h in x["held_out"]]))
        assert all(np.isfinite(rho)) and min(rho) >= 0
        assert [len(p) for p in x["fold_plans"]] == [x["n"]] * 2
    # Nested plans: the 3-sample plan of a fold is the first 3 of its 6-sample plan.
    n3, n6 = r.result("nielsen", 3), r.result("nielsen", 6)
    assert n3["fold_plans"][0] == n6["fold_plans"][0][:3]
    assert json.loads(r.to_json())["results"] == r.results
    # Deterministic for a seed.
    assert bb.acquisition_cv(c, **opts).results == r.results
    with pytest.raises(ValueError):
        bb.acquisition_cv(c, plans=["no-such-plan"])
