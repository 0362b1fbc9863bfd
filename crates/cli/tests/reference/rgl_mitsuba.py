#!/usr/bin/env python3
"""Reference values of the four RGL-EPFL measured BSDFs from Mitsuba 3's `measured` BSDF.

Usage (from the repository root, with `pip install mitsuba numpy`):

    python3 tests/reference/rgl_mitsuba.py [BSDF_DIR] [OUT_CSV]

BSDF_DIR defaults to ../shared/data/real/rgl_bsdf, OUT_CSV to
tests/reference/rgl_mitsuba_values.csv. For each file, a fixed set of direction pairs
(seeded: uniform over the hemisphere, near-grazing, near-specular, normal incidence,
negative azimuths, and a few below the horizon) is rounded to float32 (Mitsuba's
`scalar_rgb` works in float32), evaluated with `BSDF.eval`, which returns
f(wi, wo) cos(theta_o), and divided by cos(theta_o) = wo.z. The CSV holds the float32
directions exactly (as decimal float64 text) and f in RGB: values computed from the
files, none of their bytes. tests/rgl.rs compares the crate's evaluation against it.
"""

import csv
import math
import os
import sys

import mitsuba as mi
import numpy as np

FILES = [
    "cc_ibiza_sunset_rgb",
    "cg_sunflower_rgb",
    "colodur_napoli_4f_rgb",
    "paper_white_rgb",
]
SEED = 20181201


def sph(theta, phi):
    s = math.sin(theta)
    return np.array([s * math.cos(phi), s * math.sin(phi), math.cos(theta)])


def rotate(v, axis, angle):
    """Rodrigues rotation of v about the unit axis."""
    axis = axis / np.linalg.norm(axis)
    c, s = math.cos(angle), math.sin(angle)
    return v * c + np.cross(axis, v) * s + axis * np.dot(axis, v) * (1 - c)


def direction_pairs(rng):
    """(kind, wi, wo) in float64; rounded to float32 later."""
    pairs = []
    # Uniform over the hemisphere up to 85 degrees (cosine of theta uniform).
    for _ in range(140):
        ti = math.acos(rng.uniform(math.cos(math.radians(85)), 1.0))
        to = math.acos(rng.uniform(math.cos(math.radians(85)), 1.0))
        pairs.append(("uniform", sph(ti, rng.uniform(-math.pi, math.pi)),
                      sph(to, rng.uniform(-math.pi, math.pi))))
    # Near-grazing: one or both directions between 80 and 89 degrees.
    for k in range(50):
        ti = math.radians(rng.uniform(80, 89)) if k % 3 != 1 else math.radians(rng.uniform(0, 80))
        to = math.radians(rng.uniform(80, 89)) if k % 3 != 0 else math.radians(rng.uniform(0, 80))
        pairs.append(("grazing", sph(ti, rng.uniform(-math.pi, math.pi)),
                      sph(to, rng.uniform(-math.pi, math.pi))))
    # Near-specular: the mirror direction tilted by 0.2 to 4 degrees about a random axis.
    for _ in range(60):
        ti = math.radians(rng.uniform(0, 80))
        wi = sph(ti, rng.uniform(-math.pi, math.pi))
        mirror = np.array([-wi[0], -wi[1], wi[2]])
        axis = np.cross(mirror, rng.normal(size=3))
        wo = rotate(mirror, axis, math.radians(rng.uniform(0.2, 4.0)))
        if wo[2] <= 0.01:
            wo = mirror
        pairs.append(("specular", wi, wo))
    # In the plane of incidence, both sides, every 5 degrees of theta_o at theta_i = 45.
    for to in range(-85, 90, 5):
        wi = sph(math.radians(45), 0.0)
        wo = sph(math.radians(abs(to)), math.pi if to > 0 else 0.0)
        pairs.append(("plane", wi, wo))
    # Normal incidence, and incident directions at the tabulated-slice edge (theta_i
    # beyond the last measured slice's neighbours).
    for _ in range(15):
        pairs.append(("normal", np.array([0.0, 0.0, 1.0]),
                      sph(math.radians(rng.uniform(0, 85)), rng.uniform(-math.pi, math.pi))))
    for _ in range(15):
        pairs.append(("steep", sph(math.radians(rng.uniform(86, 89.5)), rng.uniform(-math.pi, math.pi)),
                      sph(math.radians(rng.uniform(0, 85)), rng.uniform(-math.pi, math.pi))))
    # Mirror images in y (negative azimuths): an isotropic material gives both the same.
    for kind, wi, wo in list(pairs[:20]):
        pairs.append(("mirror_y", wi * [1, -1, 1], wo * [1, -1, 1]))
    # Exact zeros: normal incidence with each sign of zero in x and y, outgoing
    # directions in the coordinate planes, and exact mirror pairs (m = z exactly in
    # float32). Azimuths of zero vectors follow Mitsuba's conventions here.
    zeros = [(0.0, 0.0), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0)]
    s, c = math.sin(math.radians(35)), math.cos(math.radians(35))
    outs = [(s, 0.0), (s, -0.0), (-s, 0.0), (-s, -0.0), (0.0, s), (-0.0, -s), (s * 0.6, s * 0.8)]
    for zx, zy in zeros:
        for ox, oy in outs:
            pairs.append(("zeros", np.array([zx, zy, 1.0]), np.array([ox, oy, c])))
    for t in (10, 30, 50, 70):
        st, ct = math.sin(math.radians(t)), math.cos(math.radians(t))
        for ix, iy in [(st, 0.0), (-st, 0.0), (st, -0.0), (0.0, st), (0.0, -st), (-0.0, st)]:
            pairs.append(("exact_mirror", np.array([ix, iy, ct]), np.array([-ix, -iy, ct])))
    # Below the horizon: zero.
    for _ in range(5):
        pairs.append(("below", sph(math.radians(rng.uniform(0, 80)), rng.uniform(-math.pi, math.pi)),
                      sph(math.radians(rng.uniform(95, 170)), rng.uniform(-math.pi, math.pi))))
    return pairs


def main():
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    bsdf_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(root, "..", "shared", "data", "real", "rgl_bsdf")
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(root, "tests", "reference", "rgl_mitsuba_values.csv")
    mi.set_variant("scalar_rgb")
    rng = np.random.default_rng(SEED)
    pairs = direction_pairs(rng)
    ctx = mi.BSDFContext()
    rows = []
    for name in FILES:
        bsdf = mi.load_dict({"type": "measured", "filename": os.path.join(bsdf_dir, name + ".bsdf")})
        for kind, wi, wo in pairs:
            wi = np.float32(wi / np.linalg.norm(wi))
            wo = np.float32(wo / np.linalg.norm(wo))
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(*[float(x) for x in wi])
            v = bsdf.eval(ctx, si, mi.Vector3f(*[float(x) for x in wo]))
            fcos = [float(v[0]), float(v[1]), float(v[2])]
            cos_o = float(wo[2])
            f = [x / cos_o if cos_o > 0 else 0.0 for x in fcos]
            rows.append([name, kind] + [repr(float(x)) for x in wi] + [repr(float(x)) for x in wo]
                        + [repr(x) for x in f])
    with open(out, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["file", "kind", "wi_x", "wi_y", "wi_z", "wo_x", "wo_y", "wo_z", "r", "g", "b"])
        w.writerows(rows)
    print(f"wrote {out}: {len(rows)} rows (mitsuba {mi.__version__}, scalar_rgb)")


if __name__ == "__main__":
    main()
