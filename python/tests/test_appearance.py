"""Appearance (SPEC 11): fit objectives against scipy, CIEDE2000 and CIELAB against
colour-science, FLIP against NVIDIA's own Python package (flip-evaluator)."""

import numpy as np
import pytest

import brdf_basis as bb


def test_ciede2000_matches_colour_science_on_random_pairs():
    colour = pytest.importorskip("colour")
    rng = np.random.default_rng(7)
    lab1 = np.column_stack([rng.uniform(0, 100, 500), rng.uniform(-100, 100, 500), rng.uniform(-100, 100, 500)])
    lab2 = lab1 + rng.normal(0, 8, lab1.shape)
    lab2[:, 0] = np.clip(lab2[:, 0], 0, 100)
    want = colour.delta_E(lab1, lab2, method="CIE 2000")
    got = np.array([bb.ciede2000(list(a), list(b)) for a, b in zip(lab1, lab2)])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_srgb_to_lab_matches_colour_science():
    colour = pytest.importorskip("colour")
    rng = np.random.default_rng(3)
    rgb = rng.uniform(0, 1, (200, 3))
    d65 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    want = colour.XYZ_to_Lab(colour.sRGB_to_XYZ(rgb), d65)
    got = np.array([bb.srgb_to_lab(list(c)) for c in rgb])
    # The white: sRGB's (the sum of its matrix's rows) against colour's D65 chromaticity,
    # which differ in the fourth decimal.
    np.testing.assert_allclose(got, want, atol=0.05)


def test_ictcp_and_delta_e_itp_match_colour_science():
    """ICtCp (BT.2100 PQ) and ΔE_ITP (BT.2124) against colour-science: display sRGB decoded
    by the sRGB curve, BT.709 to BT.2020 by their primaries, white at 100 cd/m²."""
    colour = pytest.importorskip("colour")
    rng = np.random.default_rng(11)
    rgb = rng.uniform(0, 1, (300, 3))
    rgb[:20] = rng.uniform(0, 0.04, (20, 3))  # the sRGB curve's linear segment
    rgb[20] = [0.0, 0.0, 0.0]
    rgb[21] = [1.0, 1.0, 1.0]
    lin = colour.models.eotf_sRGB(rgb)
    bt2020 = colour.RGB_to_RGB(lin, colour.RGB_COLOURSPACES["sRGB"], colour.RGB_COLOURSPACES["ITU-R BT.2020"])
    want = colour.RGB_to_ICtCp(100.0 * bt2020, method="ITU-R BT.2100-2 PQ")
    got = np.array([bb.srgb_to_ictcp(list(c)) for c in rgb])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    other = np.clip(rgb + rng.normal(0, 0.03, rgb.shape), 0, 1)
    want_other = colour.RGB_to_ICtCp(
        100.0
        * colour.RGB_to_RGB(
            colour.models.eotf_sRGB(other), colour.RGB_COLOURSPACES["sRGB"], colour.RGB_COLOURSPACES["ITU-R BT.2020"]
        ),
        method="ITU-R BT.2100-2 PQ",
    )
    want_de = colour.difference.delta_E_ITP(want, want_other)
    got_de = np.array([bb.delta_e_itp(list(a), list(b)) for a, b in zip(got, want_other)])
    np.testing.assert_allclose(got_de, want_de, rtol=1e-9, atol=1e-9)
    with pytest.raises(ValueError, match="rgb"):
        bb.srgb_to_ictcp([1.5, 0.0, 0.0])
    with pytest.raises(ValueError, match="ictcp1"):
        bb.delta_e_itp([float("nan"), 0.0, 0.0], [0.0, 0.0, 0.0])


def _display_u8(img):
    return np.round(255.0 * np.clip(np.maximum(img, 0.0) ** (1.0 / 2.2), 0.0, 1.0)).astype(np.uint8)


def _sphere_mask(size):
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    return x * x + y * y < 1.0


def test_flip_matches_flip_evaluator_over_the_sphere():
    flip = pytest.importorskip("flip_evaluator")
    c = bb.Collection.default()
    ref = bb.render(bb.Brdf.material(c, "polished-gold"), size=128)
    test = bb.render(bb.Brdf.material(c, "gloss-red-enamel"), size=128)
    ours = bb.image_metrics(ref, test)
    a = _display_u8(ref).astype(np.float32) / 255.0
    b = _display_u8(test).astype(np.float32) / 255.0
    err, _, _ = flip.evaluate(a, b, "LDR", inputsRGB=True, applyMagma=False, parameters={"ppd": 67.0})
    err = np.asarray(err).reshape(128, 128)
    want = float(err[_sphere_mask(128)].mean())
    assert want > 0.01
    assert abs(ours["flip"] - want) <= 1e-3 * max(want, 1e-3), (ours, want)
    # And a render against itself scores 0 on every metric.
    same = bb.image_metrics(ref, ref)
    assert same == {"image_error": 0.0, "ciede2000": 0.0, "delta_e_itp": 0.0, "flip": 0.0}


def test_image_delta_e_itp_matches_colour_science_over_the_sphere():
    """The renders' mean ΔE_ITP: SPEC 7's display values read as sRGB, white at 100 cd/m²,
    colour-science's ICtCp and ΔE_ITP per sphere pixel, averaged."""
    colour = pytest.importorskip("colour")
    c = bb.Collection.default()
    ref = bb.render(bb.Brdf.material(c, "polished-gold"), size=64)
    test = bb.render(bb.Brdf.material(c, "gloss-red-enamel"), size=64)
    ours = bb.image_metrics(ref, test)

    def itp(img):
        d = np.clip(np.maximum(img.astype(np.float64), 0.0) ** (1.0 / 2.2), 0.0, 1.0)
        lin = colour.models.eotf_sRGB(d[_sphere_mask(64)])
        s, b = colour.RGB_COLOURSPACES["sRGB"], colour.RGB_COLOURSPACES["ITU-R BT.2020"]
        return colour.RGB_to_ICtCp(100.0 * colour.RGB_to_RGB(lin, s, b), method="ITU-R BT.2100-2 PQ")

    want = float(colour.difference.delta_E_ITP(itp(ref), itp(test)).mean())
    assert want > 1.0
    assert abs(ours["delta_e_itp"] - want) <= 1e-9 * want, (ours, want)


@pytest.mark.parametrize("objective", ["relative", "log"])
def test_weighted_fit_meets_the_optimum_of_scipy_nnls_on_the_sqrt_weighted_system(objective):
    scipy_opt = pytest.importorskip("scipy.optimize")
    c = bb.Collection.default()
    basis = ["polished-gold", "gloss-black-enamel", "matte-white-paint"]
    target = "polished-copper"
    fit = bb.fit(c, basis, [target], objective=objective, appearance=False, backend="cpu")
    assert fit.objective == objective
    coef = fit.coefficients[0]  # (1 + k, 3)
    mask = np.asarray(bb.mask("evaluation")).reshape(-1)
    cols = [c.tabulate(n, backend="cpu").reshape(3, -1)[:, mask].astype(np.float64) for n in basis]
    y = c.tabulate(target, backend="cpu").reshape(3, -1)[:, mask].astype(np.float64)
    # theta_i of each evaluation cell, from the MERL grid's cell centres (SPEC 2).
    i, j, k = np.meshgrid(np.arange(90), np.arange(90), np.arange(180), indexing="ij")
    th = (((i + 0.5) / 90.0) ** 2 * np.pi / 2).reshape(-1)[mask]
    td = ((j + 0.5) * np.pi / 180.0).reshape(-1)[mask]
    pd = ((k + 0.5) * np.pi / 180.0).reshape(-1)[mask]
    cos_i = np.cos(th) * np.cos(td) - np.sin(th) * np.sin(td) * np.cos(pd)
    w = 1.0 / mask.sum()
    lam = np.full(y.shape[1], np.float32(1.0 / np.pi), dtype=np.float64)
    for ch in range(3):
        yc = y[ch]
        if objective == "relative":
            W = w / (np.maximum(yc, 0.0) + 0.01) ** 2
        else:
            q = np.maximum(cos_i, 0.0) / (1.0 + np.maximum(yc, 0.0) * np.maximum(cos_i, 0.0))
            W = w * q * q
        A = np.column_stack([lam] + [col[ch] for col in cols])
        s = np.sqrt(W)
        x, _ = scipy_opt.nnls(A * s[:, None], yc * s, maxiter=1000)
        obj = lambda v: float(np.sum(W * (A @ v - yc) ** 2))
        scale = float(np.sum(W * yc * yc))
        ours = obj(coef[:, ch])
        assert ours - obj(x) <= 1e-6 * scale, (objective, ch, ours, obj(x), scale)
