"""The Mitsuba 3 plugin: BSDF consistency, and the sphere of SPEC 7 rendered by Mitsuba
(orthographic camera, directional light, the ``direct`` integrator) against
``brdf-basis render`` of the same material: analytic, measured and fitted."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import brdf_basis as bb

TOL = 1e-3  # normalised image error (SPEC 7: gamma 2.2, exposure 0)
SIZE = 64
LLVM19 = Path("/usr/lib/x86_64-linux-gnu/libLLVM-19.so")


@pytest.fixture
def mi(peer):
    mi = peer("mitsuba")
    mi.set_variant("scalar_rgb")
    import brdf_basis.mitsuba as bbm

    bbm.register()
    return mi


def read_exr(mi, path) -> np.ndarray:
    a = np.array(mi.Bitmap(str(path)), dtype=np.float32)
    assert a.shape == (SIZE, SIZE, 3), a.shape
    return a


def mitsuba_sphere(entry, light=(45.0, 45.0)) -> np.ndarray:
    import brdf_basis.mitsuba as bbm

    return bbm.render_sphere(entry, size=SIZE, light=light)


def check(mi, ours_exr, entry, light, label, errors):
    ref = read_exr(mi, ours_exr)
    img = mitsuba_sphere(entry, light)
    err = bb.image_error(img, ref)
    errors[label] = err
    print(f"{label}: normalised image error Mitsuba vs brdf-basis render = {err:.3e}")
    assert err < TOL, (label, err)
    # Not a black image against a black image.
    assert ref.max() > 0.05 and img.max() > 0.05
    return err


@pytest.mark.parametrize("light", [(45.0, 45.0), (30.0, 160.0)])
def test_analytic_sphere_matches_brdf_basis_render(mi, cli, tmp_path, light):
    out = tmp_path / "a.exr"
    name = "gloss-red-enamel"
    cli("render", "--material", name, "--size", SIZE, "--light", f"{light[0]},{light[1]}", "--out", out)
    check(mi, out, {"type": "brdf_basis", "material": name}, light, f"analytic {name} {light}", {})


def test_measured_sphere_matches_brdf_basis_render(mi, cli, tmp_path):
    binary = tmp_path / "red-measured.binary"
    cli("tabulate", "--material", "gloss-red-enamel", "--out", binary)
    coll = bb.Collection.load(binary)
    assert coll.kinds == ["measured"]
    name = coll.names[0]
    out = tmp_path / "m.exr"
    cli("render", binary, "--material", name, "--size", SIZE, "--out", out)
    entry = {"type": "brdf_basis", "collection": str(binary), "material": name}
    check(mi, out, entry, (45.0, 45.0), f"measured {name}", {})


def test_fitted_sphere_matches_brdf_basis_render(mi, cli, tmp_path):
    fit = tmp_path / "fit.json"
    target = "polished-copper"
    cli("fit", "--basis", "polished-gold,matte-white-paint,gloss-black-enamel", "--targets", target, "--json", fit)
    out = tmp_path / "f.exr"
    cli("render", "--material", target, "--fit", fit, "--size", SIZE, "--out", out)
    entry = {"type": "brdf_basis", "material": target, "fit": str(fit)}
    check(mi, out, entry, (45.0, 45.0), f"fitted {target}", {})
    # The fit is not the target: the cross-check sees which one it renders.
    target_img = read_exr(mi, out)
    cli("render", "--material", target, "--size", SIZE, "--out", tmp_path / "t.exr")
    assert bb.image_error(target_img, read_exr(mi, tmp_path / "t.exr")) > 1e-3


def test_measured_ngan_table_of_shared_data(mi, cli, shared, tmp_path):
    """A material of the Ngan collection, tabulated to a .binary, through the plugin."""
    csv = shared("ngan2005_ashikhmin_shirley.csv")
    name = bb.Collection.load(csv).names[0]
    binary = tmp_path / "n.binary"
    cli("tabulate", csv, "--material", name, "--out", binary)
    mname = bb.Collection.load(binary).names[0]
    out = tmp_path / "n.exr"
    cli("render", binary, "--material", mname, "--size", SIZE, "--out", out)
    check(mi, out, {"type": "brdf_basis", "collection": str(binary), "material": mname}, (45.0, 45.0), f"measured {mname}", {})


def test_bsdf_eval_pdf_sample_are_consistent(mi, tmp_path):
    csv = tmp_path / "lambert.csv"
    csv.write_text("material,d_r,d_g,d_b,s_r,s_g,s_b,F0,n\nlambert,0.5,0.4,0.3,0,0,0,0.04,10\nshiny,0.1,0.1,0.1,0.5,0.5,0.5,0.5,80\n")
    rng = np.random.default_rng(3)
    ctx = mi.BSDFContext()
    for name in ("lambert", "shiny"):
        b = mi.load_dict({"type": "brdf_basis", "collection": str(csv), "material": name})
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(0.3, -0.2, float(np.sqrt(1 - 0.13)))
        total = np.zeros(3)
        n = 20000
        for _ in range(n):
            u = rng.random(3)
            bs, value = b.sample(ctx, si, float(u[0]), mi.Point2f(float(u[1]), float(u[2])))
            if bs.pdf <= 0:
                continue
            f = b.eval(ctx, si, bs.wo)
            pdf = b.pdf(ctx, si, bs.wo)
            assert pdf == pytest.approx(bs.pdf, rel=1e-5)
            for c in range(3):
                assert value[c] * pdf == pytest.approx(f[c], rel=1e-4, abs=1e-7)
            total += [value[0], value[1], value[2]]
        albedo = total / n
        if name == "lambert":
            # A Lambertian BRDF d / pi reflects d (Monte Carlo, 20,000 samples).
            np.testing.assert_allclose(albedo, [0.5, 0.4, 0.3], rtol=0.02)
        assert (albedo > 0).all() and (albedo < 1.0 + 1e-3).all()
        # The density integrates to 1 over the sphere (uniform directions, 200,000).
        m = 200000
        d = rng.normal(size=(m, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        vals = [b.pdf(ctx, si, mi.Vector3f(*map(float, v))) for v in d[:m // 10]]
        assert np.mean(vals) * 4 * np.pi == pytest.approx(1.0, rel=0.05)
        # Below the horizon: nothing.
        below = mi.Vector3f(0.0, 0.6, -0.8)
        assert b.pdf(ctx, si, below) == 0 and b.eval(ctx, si, below)[0] == 0


def test_llvm_variant_renders_the_same_sphere(peer, cli, tmp_path, request):
    """In llvm_ad_rgb (wavefront mode, LLVM 19: Debian's LLVM 15 miscompiles Mitsuba's
    kernels on AVX-512), in a subprocess: Dr.Jit reads the LLVM path at start."""
    peer("mitsuba")
    if not LLVM19.exists():
        from conftest import missing

        missing(request, f"no {LLVM19} (apt-get install libllvm19)")
    out = tmp_path / "a.exr"
    cli("render", "--material", "polished-gold", "--size", SIZE, "--out", out)
    code = f"""
import mitsuba as mi, numpy as np
mi.set_variant('llvm_ad_rgb')
import brdf_basis as bb, brdf_basis.mitsuba as bbm
bbm.register()
ref = np.array(mi.Bitmap({str(out)!r}), dtype=np.float32)
img = bbm.render_sphere({{'type': 'brdf_basis', 'material': 'polished-gold'}}, size={SIZE})
print(bb.image_error(img, ref))
"""
    env = dict(os.environ, DRJIT_LIBLLVM_PATH=str(LLVM19))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    err = float(r.stdout.strip().splitlines()[-1])
    print(f"llvm_ad_rgb analytic polished-gold: normalised image error {err:.3e}")
    assert err < TOL
