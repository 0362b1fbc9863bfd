"""One door per command, three ways (issue 47): the same small settings given to the
command line and to Python give the same result (the same JSON text, matrix bytes or
image bits) and the same refusal of one invalid setting, in the same words.
``crates/cli/tests/doors.rs`` holds the command line against the library's requests with
these settings and these refusal texts, so the three doors agree. Each runs in seconds
on the embedded default collection, on the CPU."""

import json

import numpy as np
import pytest

import brdf_basis as bb

from test_requests import cli_error  # noqa: F401 (a fixture)

BASIS = ["polished-gold", "matte-white-paint"]

# The samples of the fit --samples door (crates/cli/tests/doors.rs: SAMPLES).
SAMPLES = """theta_i,phi_i,theta_o,phi_o,r,g,b
10,0,20,180,0.21,0.18,0.12
30,0,40,90,0.35,0.3,0.2
50,0,10,0,0.12,0.1,0.07
0,0,60,45,0.18,0.16,0.1
20,90,20,270,2.5,2.1,1.4
45,0,45,180,1.1,0.9,0.6
"""


def refusal(call) -> str:
    with pytest.raises(ValueError) as e:
        call()
    return str(e.value)


def coll():
    return bb.Collection.default()


def test_distance_door(cli, cli_error, tmp_path):
    out = tmp_path / "d.npy"
    cli("distance", "--stride", 9, "--out", out)
    ours = bb.distance_matrix(coll(), stride=9, backend="cpu")
    assert np.load(out).tobytes() == ours.tobytes()
    one = tmp_path / "one.csv"
    one.write_text("material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nalone,0.1,0.1,0.1,0.2,0.2,0.2,0.05,100\n")
    msg = cli_error("distance", one, "--out", tmp_path / "o.npy")
    py = refusal(lambda: bb.distance_matrix(bb.Collection.load(str(one)), backend="cpu"))
    assert py == msg == "a distance matrix needs at least 2 materials, the collection has 1"


def test_select_door(cli, cli_error, tmp_path):
    out = tmp_path / "s.json"
    cli("--seed", 4, "select", "--method", "kmedoids", "-k", 3, "--runs", 2, "--stride", 8, "--json", out)
    sel = bb.select(coll(), "kmedoids", k=3, runs=2, stride=8, seed=4, backend="cpu")
    assert sel.to_json() == out.read_text()
    msg = cli_error("--seed", 4, "select", "--method", "greedy", "-k", 3, "--json", tmp_path / "g.json")
    py = refusal(lambda: bb.select(coll(), "greedy", k=3, seed=4, backend="cpu"))
    assert py == msg == "--seed applies to kmedoids, gcuk and ga, not to --method greedy"


def test_fit_door(cli, cli_error, tmp_path):
    out = tmp_path / "f.json"
    targets = ["polished-copper", "gloss-black-enamel"]
    cli("fit", "--basis", ",".join(BASIS), "--targets", ",".join(targets), "--stride", 6, "--no-appearance", "--json", out)
    r = bb.fit(coll(), BASIS, targets, stride=6, appearance=False, backend="cpu")
    assert r.to_json() == out.read_text()
    msg = cli_error("fit", "--basis", ",".join(BASIS), "--all-others", "--objective", "l2", "--eps", 5, "--json", tmp_path / "f2.json")
    py = refusal(lambda: bb.fit(coll(), BASIS, objective="l2", eps=5, backend="cpu"))
    assert py == msg == (
        "--eps 5 applies to --objective relative, not to --objective l2: only the relative objective has an offset; leave --eps out"
    )


def test_fit_samples_door(cli, cli_error, tmp_path):
    s = tmp_path / "s.csv"
    s.write_text(SAMPLES)
    out = tmp_path / "f.json"
    cli("fit", "--basis", ",".join(BASIS), "--samples", s, "--json", out)
    rows = np.array([[float(x) for x in line.split(",")] for line in SAMPLES.splitlines()[1:]])
    r = bb.fit_samples(coll(), BASIS, rows[:, :4], rows[:, 4:])
    t = json.loads(out.read_text())["targets"][0]
    # The same numbers, to the bit (JSON keeps every f64 exactly).
    assert t["lambertian"] == list(r.coefficients[0])
    assert [t["coefficients"][b] for b in BASIS] == [list(c) for c in r.coefficients[1:]]
    assert (t["residual"], t["mae"]) == (list(r.residual), r.mae)
    msg = cli_error("fit", "--basis", ",".join(BASIS), "--samples", s, "--objective", "log", "--eps", 0.5, "--json", tmp_path / "f2.json")
    py = refusal(lambda: bb.fit_samples(coll(), BASIS, rows[:, :4], rows[:, 4:], objective="log", eps=0.5))
    assert py == msg == (
        "--eps 0.5 applies to --objective relative, not to --objective log: only the relative objective has an offset; leave --eps out"
    )


def test_plan_door(cli, cli_error, tmp_path):
    out = tmp_path / "p.json"
    cli("plan", "--basis", ",".join(BASIS), "-n", 4, "--criterion", "condition", "--out", tmp_path / "p.csv", "--json", out)
    p = bb.plan(coll(), BASIS, 4, criterion="condition", backend="cpu")
    assert p.to_json() == out.read_text()
    msg = cli_error("plan", "--basis", ",".join(BASIS), "--criterion", "random", "--shortlist", 3, "--out", tmp_path / "q.csv")
    py = refusal(lambda: bb.plan(coll(), BASIS, 4, criterion="random", shortlist=3, backend="cpu"))
    assert py == msg == "--shortlist applies to error plans, not to --criterion random"
    # Issue 47: a condition plan over every candidate draws nothing at random.
    msg = cli_error(
        "--seed", 7, "plan", "--basis", ",".join(BASIS), "--criterion", "condition",
        "--candidates-per-step", 0, "--out", tmp_path / "s.csv",
    )
    py = refusal(
        lambda: bb.plan(coll(), BASIS, 2, criterion="condition", candidates_per_step=0, seed=7, backend="cpu")
    )
    assert py == msg
    assert msg.startswith("--seed 7 does not apply to plan --criterion condition --candidates-per-step 0: ")


def test_cv_door(cli, cli_error, tmp_path):
    out = tmp_path / "c.json"
    cli("cv", "--methods", "greedy,random", "-k", 2, "--folds", 3, "--stride", 9, "--render-size", 16, "--no-appearance", "--json", out)
    r = bb.cross_validate(
        coll(), methods=["greedy", "random"], ks=[2], folds=3, stride=9, render_size=16, appearance=False, backend="cpu"
    )
    assert r.to_json() == out.read_text()
    msg = cli_error("cv", "--methods", "greedy", "--runs", 30, "--json", tmp_path / "c2.json")
    py = refusal(lambda: bb.cross_validate(coll(), methods=["greedy"], runs=30, backend="cpu"))
    assert py == msg == "--runs applies to kmedoids and gcuk, not to --methods greedy"


def test_acquisition_door(cli, cli_error, tmp_path):
    out = tmp_path / "a.json"
    cli(
        "cv", "--acquisition", "-k", 3, "--plans", "condition", "-n", 3, "--noise", 0, "--folds", 2, "--stride", 6,
        "--candidates-per-step", 200, "--render-size", 16, "--no-appearance", "--json", out,
    )
    r = bb.acquisition_cv(
        coll(), k=3, plans=["condition"], ns=[3], noises=[0.0], folds=2, stride=6, candidates_per_step=200,
        render_size=16, appearance=False, backend="cpu",
    )
    assert r.to_json() == out.read_text()
    msg = cli_error("cv", "--acquisition", "--plans", "random", "--shortlist", 3, "--json", tmp_path / "a2.json")
    py = refusal(lambda: bb.acquisition_cv(coll(), plans=["random"], shortlist=3, backend="cpu"))
    assert py == msg == "--shortlist applies to error plans, not to --plans random"


def test_render_door(cli, cli_error, peer, tmp_path):
    out = tmp_path / "r.exr"
    cli("render", "--material", "polished-gold", "--size", 32, "--out", out)
    gold = bb.Brdf.material(coll(), "polished-gold")
    msg = cli_error("render", "--material", "polished-gold", "--size", 0, "--out", tmp_path / "r0.exr")
    py = refusal(lambda: bb.render(gold, size=0))
    assert py == msg == "invalid image size `0` (expected 1..=16384 pixels)"
    ours = np.asarray(bb.render(gold, size=32), dtype=np.float32)
    mi = peer("mitsuba")  # reads the OpenEXR (without it: a skip, after the refusal)
    mi.set_variant("scalar_rgb")
    exr = np.array(mi.Bitmap(str(out)), dtype=np.float32)
    assert exr.shape == ours.shape == (32, 32, 3)
    assert exr.tobytes() == ours.tobytes()
