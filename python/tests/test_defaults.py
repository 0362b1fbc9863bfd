"""One home per setting (issue 47): the bindings hold no default of their own. A keyword
argument left out is ``None``, which the library's request resolves; ``bb.defaults()``
reads the requests' defaults, and a call with the defaults records the same settings as
the command line with its defaults."""

import inspect
import json

import numpy as np
import pytest

import brdf_basis as bb
from brdf_basis import _native

from test_requests import cli_error  # noqa: F401 (a fixture)

NATIVE = {
    "distance_matrix": _native.distance_matrix,
    "select": _native.select_json,
    "fit": _native.fit_json,
    "plan": _native.plan_json,
    "fit_samples": _native.fit_samples,
    "cross_validate": _native.cross_validate_json,
    "acquisition_cv": _native.acquisition_cv_json,
    # The helpers that are not commands: their defaults are the library's parameter types'.
    "kmedoids": _native.kmedoids,
    "render": _native.render,
    "image_error": _native.image_error,
    "mask": _native.mask,
}
BASIS = ["polished-gold", "matte-white-paint"]


def test_no_binding_repeats_a_default():
    d = bb.defaults()
    assert set(d) == set(NATIVE)
    for name, native in NATIVE.items():
        params = inspect.signature(native).parameters
        for p in params.values():
            assert p.default in (inspect.Parameter.empty, None), (name, p.name, p.default)
        for key in d[name]:
            assert key in params, (name, key)
    for name in ("select", "fit", "plan", "fit_samples", "cross_validate", "acquisition_cv"):
        for p in inspect.signature(getattr(bb, name)).parameters.values():
            assert p.default in (inspect.Parameter.empty, None), (name, p.name, p.default)


def test_the_defaults_are_the_requests():
    d = bb.defaults()
    for name in ("select", "fit", "plan", "fit_samples", "cross_validate", "acquisition_cv"):
        assert (d[name]["objective"], d[name]["eps"]) == ("relative", 0.01), name
    for name in ("distance_matrix", "select", "fit", "cross_validate", "acquisition_cv"):
        assert (d[name]["mask"], d[name]["weighting"], d[name]["stride"]) == ("evaluation", "uniform", 1), name


def test_a_fit_with_the_defaults_records_them_as_the_cli_does(cli, tmp_path):
    out = tmp_path / "fit.json"
    cli("fit", "--basis", ",".join(BASIS), "--targets", "polished-copper", "--no-appearance", "--json", out)
    r = bb.fit(bb.Collection.default(), BASIS, ["polished-copper"], appearance=False, backend="cpu")
    assert r.to_json() == out.read_text()
    d = bb.defaults()["fit"]
    for key in ("objective", "eps", "mask", "weighting"):
        assert r.data[key] == d[key], key


def test_a_selection_with_the_defaults_records_them_as_the_cli_does(cli, tmp_path):
    out = tmp_path / "sel.json"
    cli("select", "--method", "greedy", "-k", 2, "--stride", 8, "--json", out)
    sel = bb.select(bb.Collection.default(), "greedy", k=2, stride=8, backend="cpu")
    assert sel.to_json() == out.read_text()
    d = bb.defaults()["select"]
    assert (sel.data["fit_objective"], sel.data["eps"]) == (d["objective"], d["eps"])
    assert (sel.data["mask"], sel.data["weighting"]) == (d["mask"], d["weighting"])


def test_a_distance_matrix_with_the_defaults_is_the_cli_one(cli, tmp_path):
    out = tmp_path / "d.npy"
    cli("distance", "--out", out)
    assert np.load(out).tobytes() == bb.distance_matrix(bb.Collection.default(), backend="cpu").tobytes()


def _samples_csv(tmp_path, angles, rgb):
    p = tmp_path / "s.csv"
    rows = ["theta_i,phi_i,theta_o,phi_o,r,g,b"]
    rows += [",".join(map(repr, [*map(float, a), *map(float, y)])) for a, y in zip(angles, rgb)]
    p.write_text("\n".join(rows) + "\n")
    return p


def test_fit_samples_is_the_request_of_fit_samples(cli, tmp_path):
    # Two samples for three columns: the request warns and suggests where to measure.
    angles = [[10, 0, 20, 180], [30, 0, 40, 90]]
    rgb = [[0.2, 0.3, 0.4], [0.1, 0.2, 0.25]]
    out = tmp_path / "fit.json"
    csv = _samples_csv(tmp_path, angles, rgb)
    stdout = cli("fit", "--basis", ",".join(BASIS), "--samples", csv, "--json", out)
    assert "wrote" in stdout
    d = json.loads(out.read_text())
    r = bb.fit_samples(bb.Collection.default(), BASIS, np.array(angles, float), np.array(rgb, float))
    (t,) = d["targets"]
    assert r.coefficients[0].tolist() == t["lambertian"]
    assert [r.coefficients[1 + i].tolist() for i in range(2)] == [t["coefficients"][b] for b in BASIS]
    assert (d["objective"], d["eps"]) == (bb.defaults()["fit_samples"]["objective"], bb.defaults()["fit_samples"]["eps"])
    assert r.warnings and all(isinstance(w, str) for w in r.warnings)


def test_fit_samples_refuses_as_the_cli_refuses(cli_error, tmp_path):  # noqa: F811
    angles, rgb = [[10, 0, 20, 180]], [[0.2, 0.3, 0.4]]
    csv = _samples_csv(tmp_path, angles, rgb)
    msg = cli_error("fit", "--basis", ",".join(BASIS), "--samples", csv, "--objective", "l2", "--eps", 0.5, "--json", tmp_path / "f.json")
    assert msg.startswith("--eps 0.5 applies to --objective relative")
    with pytest.raises(ValueError) as e:
        bb.fit_samples(bb.Collection.default(), BASIS, angles, rgb, objective="l2", eps=0.5)
    assert str(e.value) == msg


@pytest.mark.parametrize("stride", [0, 91])
def test_every_command_refuses_a_bad_stride_in_one_wording(stride):
    # The rule is the library's GridSpec (checked when built), in the command line's
    # words, before any work.
    c = bb.Collection.default()
    calls = {
        "distance_matrix": lambda: bb.distance_matrix(c, stride=stride, backend="cpu"),
        "select": lambda: bb.select(c, "greedy", k=2, stride=stride, backend="cpu"),
        "fit": lambda: bb.fit(c, BASIS, ["polished-copper"], stride=stride, backend="cpu"),
        "cross_validate": lambda: bb.cross_validate(c, stride=stride, backend="cpu"),
        "acquisition_cv": lambda: bb.acquisition_cv(c, stride=stride, backend="cpu"),
    }
    for name, call in calls.items():
        with pytest.raises(ValueError) as e:
            call()
        assert str(e.value) == f"--stride {stride}: expected a whole number from 1 (the full grid) to 90", name


def test_solver_and_gram_are_read_by_the_librarys_own_names():
    # One text form: the library's FromStr, with its refusal (no hand-written parser here).
    c = bb.Collection.default()
    for bad, words in (({"solver": "bogus"}, "give exact or pgd"), ({"gram": "bogus"}, "give auto or grid")):
        with pytest.raises(ValueError, match=words):
            bb.fit(c, BASIS, ["gloss-red-enamel"], objective="l2", stride=9, appearance=False, **bad)


def test_no_public_function_holds_a_literal_default():
    # Every function of the package and of its Mitsuba glue: a setting left out is None,
    # which the library resolves (the plug-in's registered name is a name, not a setting).
    import brdf_basis.mitsuba as bbm

    funcs = [(n, getattr(bb, n)) for n in bb.__all__ if inspect.isroutine(getattr(bb, n))]
    funcs += [(n, f) for n, f in vars(bbm).items() if inspect.isfunction(f) and not n.startswith("_") and f.__module__ == bbm.__name__]
    assert len(funcs) > 20
    for name, f in funcs:
        for p in inspect.signature(f).parameters.values():
            if (name, p.name) == ("register", "name"):
                continue
            assert p.default in (inspect.Parameter.empty, None), (name, p.name, p.default)


def test_the_helpers_left_alone_are_the_library_defaults():
    d = bb.defaults()
    assert d["kmedoids"] == {
        "seed": 1,
        "init": "build",
        "algorithm": "fasterpam",
        "restarts": 1,
        "max_iter": 100,
        "order": "shuffled",
        "tolerance": 1e-6,
    }
    assert d["render"] == {"size": 256, "light": [45.0, 45.0]}
    assert d["image_error"] == {"exposure": 0.0, "gamma": 2.2}
    assert d["mask"] == {"name": d["distance_matrix"]["mask"]}
    # A call without the settings is the call with them.
    rng = np.random.default_rng(3)
    x = rng.random((12, 2))
    dm = np.sqrt(((x[:, None, :] - x[None, :, :]) ** 2).sum(-1))
    k = d["kmedoids"]
    assert bb.kmedoids(dm, 3) == bb.kmedoids(dm, 3, **k)
    c = bb.Collection.default()
    f = bb.Brdf.material(c, "polished-gold")
    r = d["render"]
    img = bb.render(f)
    assert img.shape == (r["size"], r["size"], 3)
    assert np.array_equal(img, bb.render(f, size=r["size"], light=tuple(r["light"])))
    g = bb.render(bb.Brdf.material(c, "matte-white-paint"), size=32)
    h = bb.render(f, size=32)
    assert bb.image_error(g, h) == bb.image_error(g, h, **d["image_error"])
    assert bb.image_error(g, h) != bb.image_error(g, h, gamma=1.0)
    assert np.array_equal(bb.mask(), bb.mask(d["mask"]["name"]))
    assert not np.array_equal(bb.mask(), bb.mask("valid"))
