"""Audit 3 (issue 49), the Python door: D1 (an eps whose weights underflow gave all-zero
coefficients without an error) and U8 (``eps=True`` ran with eps 1). Each test fails on
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
