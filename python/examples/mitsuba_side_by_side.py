"""A basis, a target and its fitted combination rendered side by side by Mitsuba 3.

    python python/examples/mitsuba_side_by_side.py --out side_by_side.png

Selects a basis of k materials of the embedded collection (greedy, by fitting error),
fits a target by it, and renders one scene: the basis materials in the back row, the
target (left) and its fitted combination (right) in front, on a grey floor under a
constant sky and a sun, with Mitsuba's path tracer and the brdf_basis BSDF plugin.

The variant is ``scalar_rgb`` unless ``--variant llvm_ad_rgb`` (much faster; needs
``DRJIT_LIBLLVM_PATH`` set to LLVM 15 or newer that compiles on this CPU, e.g. Debian's
``libllvm19``: ``/usr/lib/x86_64-linux-gnu/libLLVM-19.so``).
"""

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--target", default="unglazed-terracotta")
    ap.add_argument("-k", type=int, default=5)
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--width", type=int, default=480)
    ap.add_argument("--out", default="side_by_side.png")
    a = ap.parse_args()

    import mitsuba as mi

    mi.set_variant(a.variant)
    import brdf_basis as bb
    import brdf_basis.mitsuba as bbm

    bbm.register()
    coll = bb.Collection.default()
    others = [n for n in coll.names if n != a.target]
    sel = bb.select(coll, "greedy", k=a.k, candidates=others, stride=3)
    fit = bb.fit(coll, sel.basis, [a.target], stride=3)
    t = fit.targets[0]
    print(f"basis {sel.basis}; {a.target}: MAE {t.mae:.4g}, Lambertian {np.round(t.lambertian, 4)}")
    fit_json = Path(tempfile.mkdtemp()) / "fit.json"
    fit.save(fit_json)

    target = bb.Brdf.material(coll, a.target)
    fitted = bb.Brdf.fitted(coll, fit_json, a.target)
    sphere_err = bb.image_error(bb.render(target, size=128), bb.render(fitted, size=128))
    print(f"normalised image error of the fit on the SPEC 7 sphere: {sphere_err:.4g}")

    T = mi.ScalarTransform4f
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 4},
        "sensor": {
            "type": "perspective",
            "fov": 32,
            "to_world": T.look_at(origin=[0, 4.6, 9.0], target=[0, 0.4, -0.4], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": a.width, "height": a.width * 9 // 16, "rfilter": {"type": "gaussian"}},
            "sampler": {"type": "independent", "sample_count": a.spp},
        },
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 0.35}},
        "sun": {"type": "directional", "direction": [-0.5, -1.0, -0.6], "irradiance": {"type": "rgb", "value": 3.0}},
        "floor": {
            "type": "rectangle",
            "to_world": T.translate([0, -0.001, 0]) @ T.rotate([1, 0, 0], -90) @ T.scale(12),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.35}},
        },
        "target": {"type": "sphere", "center": [-1.05, 0.9, 1.0], "radius": 0.9, "bsdf": bbm.bsdf(target)},
        "fitted": {"type": "sphere", "center": [1.05, 0.9, 1.0], "radius": 0.9, "bsdf": bbm.bsdf(fitted)},
    }
    n = len(sel.basis)
    for i, name in enumerate(sel.basis):
        x = (i - (n - 1) / 2) * 1.05
        scene[f"basis{i}"] = {"type": "sphere", "center": [x, 0.45, -1.9], "radius": 0.45, "bsdf": bbm.bsdf(bb.Brdf.material(coll, name))}
    img = mi.render(mi.load_dict(scene))
    mi.util.write_bitmap(a.out, img)
    print(f"back row: {', '.join(sel.basis)}; front: {a.target} (left), its fit (right)")
    print(f"wrote {a.out}")
    (Path(a.out).with_suffix(".json")).write_text(json.dumps({"basis": sel.basis, "target": a.target, "mae": t.mae, "sphere_image_error": sphere_err}, indent=2) + "\n")


if __name__ == "__main__":
    main()
