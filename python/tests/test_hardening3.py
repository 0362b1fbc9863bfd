"""Audit 3 (issue 49), the Python door: D1 (an eps whose weights underflow gave all-zero
coefficients without an error) and U8 (``eps=True`` ran with eps 1; a non-square image,
an out-of-range sRGB colour and a NaN CIELAB colour were taken). Each test fails on
the code the audit ran."""

import numpy as np
import pytest

import brdf_basis as bb

BASIS = ["sandblasted-aluminium", "machined-iron", "white-nylon-66"]


def test_an_eps_outside_its_range_is_refused_naming_it():
    c = bb.Collection.default()
    for eps in [1e300, 1.4e154, 1e-300]:
        with pytest.raises(ValueError, match=r"eps must lie between 1e-100 and 1e100"):
            bb.fit(c, BASIS, ["polished-gold"], stride=8, eps=eps, backend="cpu")
    ang = np.array([[10.0, 0.0, 12.0, 180.0], [20.0, 0.0, 25.0, 180.0], [30.0, 0.0, 35.0, 90.0], [40.0, 0.0, 45.0, 180.0]])
    rgb = np.tile([0.1, 0.12, 0.15], (4, 1))
    with pytest.raises(ValueError, match=r"eps must lie between 1e-100 and 1e100"):
        bb.fit_samples(c, BASIS, ang, rgb, eps=1e160)


def test_eps_must_be_a_number_not_a_bool():
    c = bb.Collection.default()
    for bad in [True, False]:
        with pytest.raises(TypeError, match=r"eps: expected a number"):
            bb.fit(c, BASIS, ["polished-gold"], stride=8, eps=bad, backend="cpu")


def test_image_metrics_refuses_a_non_square_image():
    # U8: a 32 x 64 image was scored (the sphere mask and FLIP assume a square render).
    ref = np.full((32, 64, 3), 0.2, dtype=np.float32)
    with pytest.raises(ValueError, match=r"reference: a sphere render is square .* 32 x 64"):
        bb.image_metrics(ref, ref)
    sq = np.full((32, 32, 3), 0.2, dtype=np.float32)
    with pytest.raises(ValueError, match=r"test: a sphere render is square"):
        bb.image_metrics(sq, ref)
    assert bb.image_metrics(sq, sq)["image_error"] == 0.0


def test_srgb_to_lab_refuses_out_of_range_input():
    # U8: (2, 0, 0) was clamped to (1, 0, 0) silently.
    for bad in [(2.0, 0.0, 0.0), (-0.1, 0.5, 0.5), (float("nan"), 0.0, 0.0)]:
        with pytest.raises(ValueError, match=r"rgb: an sRGB-encoded colour lies in \[0, 1\]"):
            bb.srgb_to_lab(bad)
    assert bb.srgb_to_lab((1.0, 1.0, 1.0))[0] == pytest.approx(100.0)


def test_ciede2000_refuses_nan_input():
    # U8: NaN input returned NaN.
    with pytest.raises(ValueError, match=r"lab1: a CIELAB colour is finite"):
        bb.ciede2000((float("nan"), 0.0, 0.0), (50.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=r"lab2: a CIELAB colour is finite"):
        bb.ciede2000((50.0, 0.0, 0.0), (50.0, float("inf"), 0.0))
    assert bb.ciede2000((50.0, 0.0, 0.0), (50.0, 0.0, 0.0)) == 0.0
