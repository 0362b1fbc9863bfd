"""Shared helpers of the Python tests.

A test that needs something absent (a peer package such as scipy, the shared data in
``../shared``, the ``brdf-basis`` binary) skips, naming the test and what is missing;
with ``BRDF_BASIS_REQUIRE_SHARED=1`` (CI) it fails instead.
"""

import importlib
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SHARED = REPO.parent / "shared" / "data"


def required() -> bool:
    return os.environ.get("BRDF_BASIS_REQUIRE_SHARED") == "1"


def missing(request, what: str):
    msg = f"SKIP ({what}) {request.node.name}"
    if required():
        pytest.fail(f"BRDF_BASIS_REQUIRE_SHARED=1 but {what} ({request.node.name})")
    pytest.skip(msg)


@pytest.fixture
def peer(request):
    """``peer("scipy.stats")``: the module, or a skip (CI: a failure) naming it."""

    def get(name: str):
        try:
            return importlib.import_module(name)
        except ImportError:
            missing(request, f"no {name.split('.')[0]}")

    return get


@pytest.fixture
def shared(request):
    """``shared("ngan2005_ashikhmin_shirley.csv")``: the path in ../shared/data."""

    def get(name: str) -> Path:
        p = SHARED / name
        if not p.exists():
            missing(request, f"no shared data: {p} is missing")
        return p

    return get


@pytest.fixture
def cli(request):
    """Runs the ``brdf-basis`` binary (``$BRDF_BASIS_BIN``, else ``target/release``)."""
    exe = Path(os.environ.get("BRDF_BASIS_BIN") or REPO / "target" / "release" / "brdf-basis")
    if not exe.exists():
        missing(request, f"no brdf-basis binary at {exe} (cargo build --release)")

    def run(*args) -> str:
        r = subprocess.run([str(exe), "--quiet", "--backend", "cpu", *map(str, args)], capture_output=True, text=True)
        assert r.returncode == 0, f"brdf-basis {' '.join(map(str, args))}: {r.stderr}"
        return r.stdout

    return run
