"""The Python surface: shapes, types, errors, progress and interruption."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import brdf_basis as bb


def test_collection_basics():
    c = bb.Collection.default()
    assert len(c) == len(c.names) == len(c.kinds) > 10
    assert set(c.kinds) == {"analytic"}
    assert "polished-gold" in c and "no-such" not in c
    assert c.names[c.index("polished-gold")] == "polished-gold"
    p = c.analytic("polished-gold")
    assert set(p) == {"d", "s", "F0", "n"}
    a = c.tabulate("polished-gold", backend="cpu")
    assert a.shape == (3, 90, 90, 180) and a.dtype == np.float32
    for name in ("valid", "evaluation"):
        m = bb.mask(name)
        assert m.shape == (90, 90, 180) and m.dtype == np.bool_
    assert (bb.mask("evaluation") <= bb.mask("valid")).all()
    assert (a[:, ~bb.mask("valid")] == -1).all()


def test_errors_are_python_exceptions_with_the_library_message(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.csv"):
        bb.Collection.load(tmp_path / "nope.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("material,d_r\nx,1\n")
    with pytest.raises(ValueError, match="bad.csv"):
        bb.Collection.load(bad)
    c = bb.Collection.default()
    with pytest.raises(ValueError, match="did you mean `polished-gold`"):
        c.tabulate("polished-golf")
    with pytest.raises(ValueError, match="stride"):
        bb.distance_matrix(c, stride=0)
    with pytest.raises(ValueError, match="mask"):
        bb.distance_matrix(c, mask="everything")
    with pytest.raises(ValueError, match="backend"):
        bb.distance_matrix(c, backend="tpu")
    with pytest.raises(ValueError):
        bb.select(c, "kmedoids", k=len(c) + 1)
    with pytest.raises(ValueError, match="k"):
        bb.select(c, "greedy")
    with pytest.raises(ValueError, match="dimension|length"):
        bb.nnls(np.eye(3), np.ones(2))
    x = np.array([0.0, 0.1, 5.0, 5.2])
    d = np.abs(x[:, None] - x[None, :])
    with pytest.raises(ValueError, match="order `bogus`"):
        bb.kmedoids(d, 2, order="bogus")
    with pytest.raises(ValueError, match="twice"):
        bb.kmedoids(d, 2, medoids=[1, 1])
    with pytest.raises(ValueError, match="expected 2 initial medoids"):
        bb.kmedoids(d, 2, medoids=[1])
    with pytest.raises(TypeError, match="not str"):
        bb.kmedoids(d, 2, medoids="01")
    with pytest.raises(ValueError, match="tolerance"):
        bb.kmedoids(d, 2, tolerance=1.0)


def test_progress_callable_and_flag(capsys):
    seen = []
    d = bb.distance_matrix(bb.Collection.default(), stride=6, backend="cpu", progress=lambda done, total: seen.append((done, total)))
    assert d.shape[0] == d.shape[1]
    assert seen and seen[-1][0] == seen[-1][1] > 0
    assert all(a <= b for (a, _), (b, _) in zip(seen, seen[1:]))
    bb.distance_matrix(bb.Collection.default(), stride=6, backend="cpu", progress=True)
    assert "distances:" in capsys.readouterr().err


def test_ctrl_c_interrupts_a_long_call():
    """SIGINT during a full-grid distance matrix stops it with KeyboardInterrupt before it
    finishes, and the library is usable afterwards. The signal is sent from the first
    progress report that is not the last, so it always lands inside the call (a timer
    could fire after a quick call returned and interrupt the test session instead)."""
    c = bb.Collection.default()
    seen = []

    def progress(done, total):
        seen.append((done, total))
        if len(seen) == 1 and done < total:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)  # the handler raises here, inside the call

    with pytest.raises(KeyboardInterrupt):
        bb.distance_matrix(c, stride=1, backend="cpu", progress=progress)
    assert len(seen) == 1 and seen[0][0] < seen[0][1], seen
    assert bb.distance_matrix(c, stride=9, backend="cpu").shape == (len(c), len(c))


def test_the_gil_is_released_during_long_calls():
    c = bb.Collection.default()
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.time())
            time.sleep(0.01)

    t = threading.Thread(target=tick)
    t.start()
    t0 = time.time()
    bb.distance_matrix(c, stride=2, backend="cpu")
    took = time.time() - t0
    stop.set()
    t.join()
    during = [x for x in ticks if t0 < x < t0 + took]
    assert took < 0.2 or len(during) >= 0.3 * took / 0.01, (took, len(during))


def test_brdf_and_render():
    c = bb.Collection.default()
    f = bb.Brdf.material(c, "matte-white-paint")
    d = c.analytic("matte-white-paint")["d"]
    wi = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    v = f.eval(wi, wi[::-1].copy())
    assert v.shape == (2, 3)
    assert f.eval1((0, 0, 1), (0.6, 0, 0.8)) == tuple(v[0])
    img = bb.render(f, size=32)
    assert img.shape == (32, 32, 3) and img.dtype == np.float32
    assert bb.image_error(img, img) == 0.0
    assert np.all(v >= np.array(d) / np.pi - 1e-12)


def test_fit_result_fields(tmp_path):
    c = bb.Collection.default()
    r = bb.fit(c, ["polished-gold", "matte-white-paint"], ["polished-copper", "polished-brass"], stride=8, backend="cpu")
    assert [t.material for t in r.targets] == ["polished-copper", "polished-brass"]
    assert r.coefficients.shape == (2, 3, 3) and r.mae.shape == (2,)
    r.save(tmp_path / "f.json")
    assert (tmp_path / "f.json").read_text() == r.to_json()
    fitted = bb.Brdf.fitted(c, tmp_path / "f.json", "polished-copper")
    assert bb.render(fitted, size=16).shape == (16, 16, 3)


def test_gpu_backend_gives_the_cpu_numbers(request):
    """On any Vulkan adapter (lavapipe in CI): the same BRDF_it matrix, bit for bit (one
    accumulation order on every back-end)."""
    try:
        name = bb.backend_name("gpu")
    except RuntimeError as e:
        if os.environ.get("BRDF_BASIS_REQUIRE_GPU") == "1":
            pytest.fail(f"BRDF_BASIS_REQUIRE_GPU=1 but no GPU adapter: {e}")
        pytest.skip(f"SKIP (no adapter) {request.node.name}: {e}")
    c = bb.Collection.default()
    gpu = bb.distance_matrix(c, stride=6, backend="gpu")
    cpu = bb.distance_matrix(c, stride=6, backend="cpu")
    assert name.startswith("gpu")
    assert gpu.tobytes() == cpu.tobytes()
