"""One door per command (issue 34): the rules of a command are made by its request in the
library (``brdf_basis::run``), so Python refuses what the command line refuses, with the
same message (``crates/cli/tests/requests.rs`` checks the command line against the library)."""

import os
import subprocess
from pathlib import Path

import pytest

import brdf_basis as bb
from conftest import REPO, missing


@pytest.fixture
def cli_error(request, tmp_path):
    """Runs the binary on arguments it refuses; returns the message after ``error: ``."""
    exe = Path(os.environ.get("BRDF_BASIS_BIN") or REPO / "target" / "release" / "brdf-basis")
    if not exe.exists():
        missing(request, f"no brdf-basis binary at {exe} (cargo build --release)")

    def run(*args) -> str:
        r = subprocess.run([str(exe), "--quiet", "--backend", "cpu", *map(str, args)], capture_output=True, text=True)
        assert r.returncode != 0, f"brdf-basis {' '.join(map(str, args))} succeeded"
        lines = [l for l in r.stderr.splitlines() if l.startswith("error: ")]
        assert lines, r.stderr
        return lines[0][len("error: "):]

    return run


def test_plan_nielsen_is_refused_as_the_cli_refuses_it(cli_error, tmp_path):
    basis = ["polished-gold", "matte-white-paint"]
    msg = cli_error("plan", "--basis", ",".join(basis), "-n", 5, "--criterion", "nielsen", "--out", tmp_path / "p.csv")
    assert msg.startswith("--criterion nielsen: the peer baseline")
    with pytest.raises(ValueError) as e:
        bb.plan(bb.Collection.default(), basis, 5, criterion="nielsen", backend="cpu")
    assert str(e.value) == msg
    assert not list(tmp_path.iterdir())


def test_select_rules_are_the_cli_rules(cli_error, tmp_path):
    coll = bb.Collection.default()
    msg = cli_error("select", "--method", "gcuk", "-k", 5, "--json", tmp_path / "g.json")
    with pytest.raises(ValueError) as e:
        bb.select(coll, "gcuk", k=5, backend="cpu")
    assert str(e.value) == msg
    msg = cli_error("select", "--method", "kmedoids", "-k", 2, "--candidates", "polished-gold", "--json", tmp_path / "k.json")
    with pytest.raises(ValueError) as e:
        bb.select(coll, "kmedoids", k=2, candidates=["polished-gold"], backend="cpu")
    assert str(e.value) == msg == "--candidates applies to greedy, swap and ga, not to --method kmedoids"


def test_fit_refuses_a_target_given_twice(cli_error, tmp_path):
    t = "matte-white-paint"
    msg = cli_error("fit", "--basis", "polished-gold", "--targets", f"{t},{t}", "--json", tmp_path / "f.json")
    with pytest.raises(ValueError) as e:
        bb.fit(bb.Collection.default(), ["polished-gold"], [t, t], backend="cpu")
    assert str(e.value) == msg
    assert "is given twice" in msg


def test_restarts_out_of_range_is_refused_by_python_too():
    with pytest.raises(ValueError, match="--restarts 65: give 1 to 64"):
        bb.plan(bb.Collection.default(), ["polished-gold"], 3, restarts=65, backend="cpu")


def test_a_setting_the_method_does_not_use_is_refused_as_the_cli_refuses_it(cli_error, tmp_path):
    """Issue 47: a setting given to a method (objective) that does not use it is refused by
    the request, in the command line's words, instead of being ignored."""
    coll = bb.Collection.default()
    msg = cli_error("select", "--method", "kmedoids", "-k", 3, "--objective", "log", "--json", tmp_path / "k.json")
    assert msg == "--objective applies to empirical, greedy, swap and ga, not to --method kmedoids"
    with pytest.raises(ValueError) as e:
        bb.select(coll, "kmedoids", k=3, objective="log", backend="cpu")
    assert str(e.value) == msg
    msg = cli_error("select", "--method", "greedy", "-k", 3, "--runs", 50, "--json", tmp_path / "g.json")
    with pytest.raises(ValueError) as e:
        bb.select(coll, "greedy", k=3, runs=50, backend="cpu")
    assert str(e.value) == msg == "--runs applies to kmedoids and gcuk, not to --method greedy"
    msg = cli_error("fit", "--basis", "polished-gold", "--all-others", "--objective", "l2", "--eps", 5, "--json", tmp_path / "f.json")
    with pytest.raises(ValueError) as e:
        bb.fit(coll, ["polished-gold"], objective="l2", eps=5, backend="cpu")
    assert str(e.value) == msg
    assert msg.startswith("--eps 5 applies to --objective relative, not to --objective l2")
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="--eps .*: the relative objective's eps must be a positive number"):
            bb.fit(coll, ["polished-gold"], eps=bad, backend="cpu")
    assert not list(tmp_path.iterdir())
