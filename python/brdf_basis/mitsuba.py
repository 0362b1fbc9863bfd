"""A Mitsuba 3 BSDF for brdf-basis materials.

>>> import mitsuba as mi
>>> mi.set_variant("scalar_rgb")
>>> import brdf_basis as bb, brdf_basis.mitsuba as bbm
>>> bbm.register()                                   # adds the BSDF plugin "brdf_basis"
>>> bsdf = mi.load_dict({"type": "brdf_basis", "material": "polished-gold"})
>>> coll = bb.Collection.default()
>>> fitted = bbm.bsdf(bb.Brdf.fitted(coll, "fits.json", "polished-gold"))   # doctest: +SKIP

Scene-file parameters of the plugin ``brdf_basis``:

* ``material`` (string): a material of the collection (a MERL table, an analytic row);
* ``collection`` (string, optional): COLLECTION paths separated by ``|`` (an analytic
  ``.csv``, a ``.binary``, a directory of them); default: the embedded collection;
* ``fit`` (string, optional): a ``brdf-basis fit`` JSON; the BSDF is then the fitted
  combination of ``material``;
* ``key`` (string): instead of the above, a :class:`brdf_basis.Brdf` handed over by
  :func:`bsdf` (any BRDF the library can evaluate).

``eval`` is the library's BRDF (analytic evaluation, the MERL lookup of SPEC 2, or the
combination ``a0 / pi + sum a_k f_k``) times ``cos theta_o``; ``sample`` draws from
an equal mixture of the cosine-weighted hemisphere and Blinn half-vector lobes of
exponents :data:`EXPONENTS` around the mirror direction, and ``pdf`` is the mixture's
density: unbiased for every material (the cosine component covers the hemisphere), and
close enough to any highlight up to ``n ~ 4000`` to keep fireflies down. Works in the scalar variants (``scalar_rgb``);
in the JIT variants (``llvm_ad_rgb``) the plugin evaluates through NumPy, which needs
wavefront mode: :func:`register` then turns Dr.Jit's symbolic loops and calls off.
"""

from __future__ import annotations

import itertools
import math
from typing import Optional, Sequence, Tuple, Union

import numpy as np

from . import Brdf, Collection

_REGISTRY: dict = {}
_COUNTER = itertools.count()
_COLLECTIONS: dict = {}


def bsdf(brdf: Brdf) -> dict:
    """A scene-dictionary entry for ``brdf`` (a :class:`brdf_basis.Brdf`):
    ``{"type": "brdf_basis", "key": ...}``, for ``mi.load_dict``."""
    if not isinstance(brdf, Brdf):
        raise TypeError(f"expected a brdf_basis.Brdf, got {type(brdf).__name__}")
    key = f"brdf{next(_COUNTER)}"
    _REGISTRY[key] = brdf
    return {"type": "brdf_basis", "key": key}


def _collection(spec: str) -> Collection:
    if spec not in _COLLECTIONS:
        paths = [p for p in spec.split("|") if p]
        _COLLECTIONS[spec] = Collection.load(*paths) if paths else Collection.default()
    return _COLLECTIONS[spec]


def _prop(props, name: str) -> Optional[str]:
    return props[name] if name in props else None


def _brdf_of(props) -> Brdf:
    key = _prop(props, "key")
    if key is not None:
        if key not in _REGISTRY:
            raise ValueError(f"brdf_basis BSDF: unknown key `{key}` (make the entry with brdf_basis.mitsuba.bsdf(brdf))")
        return _REGISTRY[key]
    material = _prop(props, "material")
    if material is None:
        raise ValueError("brdf_basis BSDF: give `material` (a material of the collection) or `key` (from brdf_basis.mitsuba.bsdf)")
    coll = _collection(_prop(props, "collection") or "")
    fit = _prop(props, "fit")
    return Brdf.fitted(coll, fit, material) if fit else Brdf.material(coll, material)


#: Exponents of the Blinn half-vector lobes that ``sample`` mixes, with equal weights,
#: with the cosine-weighted hemisphere (a defensive mixture: every material, whatever
#: the width of its highlight, has some component close to it).
EXPONENTS = (8.0, 64.0, 512.0, 4096.0)


def _mixture_pdf(dr, mi, wi, wo):
    """Density of ``sample``'s mixture at ``wo`` (solid angle), 0 below the horizon."""
    w = 1.0 / (1 + len(EXPONENTS))
    cos_o = mi.Frame3f.cos_theta(wo)
    pdf = w * dr.maximum(cos_o, 0.0) / math.pi
    h = dr.normalize(wi + wo)
    cos_h = dr.maximum(mi.Frame3f.cos_theta(h), 0.0)
    jac = 1.0 / (4.0 * dr.maximum(dr.dot(wo, h), 1e-8))
    for n in EXPONENTS:
        pdf += w * (n + 1.0) / (2.0 * math.pi) * dr.power(cos_h, n) * jac
    up = (mi.Frame3f.cos_theta(wi) > 0) & (cos_o > 0)
    return dr.select(up, pdf, 0.0)


def register(name: str = "brdf_basis") -> None:
    """Registers the BSDF plugin ``name`` in the current Mitsuba variant (call
    ``mi.set_variant`` first). Scalar variants evaluate one direction pair per call;
    JIT variants (llvm, cuda) evaluate whole wavefronts through NumPy."""
    import drjit as dr
    import mitsuba as mi

    if mi.variant() is None:
        raise RuntimeError("set a Mitsuba variant first, e.g. mi.set_variant('scalar_rgb')")
    scalar = mi.variant().startswith("scalar")
    if not scalar:
        # The BSDF reads its inputs as NumPy arrays: the wavefront must be evaluated,
        # which symbolic loops and calls do not allow.
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)

    flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide

    class BrdfBasisBSDF(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.brdf = _brdf_of(props)
            self.m_flags = flags
            self.m_components = [flags]

        # brdf-basis convention: f(wi = towards the light, wo = towards the viewer), both
        # local (normal +z); reciprocal, so Mitsuba's (si.wi, wo) map to (wo, si.wi).
        if scalar:

            def _f(self, wi, wo):
                if wi[2] <= 0.0 or wo[2] <= 0.0:
                    return mi.Color3f(0.0)
                r, g, b = self.brdf.eval1((wo[0], wo[1], wo[2]), (wi[0], wi[1], wi[2]))
                return mi.Color3f(r, g, b) * wo[2]

        else:

            def _f(self, wi, wo):
                a = np.stack([np.asarray(wo.x), np.asarray(wo.y), np.asarray(wo.z)], axis=-1).astype(np.float64)
                b = np.stack([np.asarray(wi.x), np.asarray(wi.y), np.asarray(wi.z)], axis=-1).astype(np.float64)
                v = self.brdf.eval(a, b)
                up = (a[:, 2] > 0) & (b[:, 2] > 0)
                v = (v * (a[:, 2:3] * up[:, None])).astype(np.float32)
                return mi.Color3f(mi.Float(v[:, 0]), mi.Float(v[:, 1]), mi.Float(v[:, 2]))

        def eval(self, ctx, si, wo, active=True):
            return self._f(si.wi, wo)

        def pdf(self, ctx, si, wo, active=True):
            return _mixture_pdf(dr, mi, si.wi, wo)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi = si.wi
            # Component: 0 = cosine-weighted, i >= 1 = the Blinn lobe of EXPONENTS[i - 1].
            idx = dr.floor(sample1 * (1 + len(EXPONENTS)))
            n = mi.Float(EXPONENTS[-1])
            for i in range(len(EXPONENTS) - 1, -1, -1):
                n = dr.select(idx <= i + 1, EXPONENTS[i], n)
            cos_h = dr.power(sample2.x, 1.0 / (n + 1.0))
            sin_h = dr.safe_sqrt(1.0 - cos_h * cos_h)
            phi = 2.0 * math.pi * sample2.y
            h = mi.Vector3f(sin_h * dr.cos(phi), sin_h * dr.sin(phi), cos_h)
            lobe = 2.0 * dr.dot(wi, h) * h - wi
            wo = dr.select(idx < 1, mi.warp.square_to_cosine_hemisphere(sample2), lobe)
            bs = mi.BSDFSample3f()
            bs.wo = wo
            bs.pdf = _mixture_pdf(dr, mi, wi, wo)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            f = self._f(wi, wo)
            value = dr.select(bs.pdf > 0, f / dr.maximum(bs.pdf, 1e-20), 0.0)
            return bs, value

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"BrdfBasisBSDF[{self.brdf!r}]"

    mi.register_bsdf(name, lambda props: BrdfBasisBSDF(props))


def _render_settings(size: Optional[int], light: Optional[Tuple[float, float]]) -> tuple:
    """``size`` and ``light`` with those left out (``None``) the library's, as
    :func:`brdf_basis.render` takes them (``defaults()["render"]``)."""
    from . import defaults

    d = defaults()["render"]
    return (d["size"] if size is None else size, tuple(d["light"]) if light is None else light)


def sphere_scene(bsdf_entry: dict, *, size: Optional[int] = None, light: Optional[Tuple[float, float]] = None):
    """The sphere of SPEC 7 as a Mitsuba scene: a unit sphere seen by an orthographic
    camera from +z over [-1, 1]^2 (x right, y up), lit by a directional light of
    irradiance 1 from ``light = (theta, phi)`` degrees, the ``direct`` integrator.
    ``size`` and ``light`` left out are :func:`brdf_basis.render`'s."""
    import mitsuba as mi

    size, light = _render_settings(size, light)
    t, p = (math.radians(v) for v in light)
    wi = [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]
    T = mi.ScalarTransform4f
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
            "sensor": {
                "type": "orthographic",
                # look_at from +z with +y up: image columns run along world +x.
                "to_world": T.look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
                "sampler": {"type": "independent", "sample_count": 1},
            },
            "sphere": {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "bsdf": bsdf_entry},
            "light": {"type": "directional", "direction": [-v for v in wi], "irradiance": {"type": "rgb", "value": 1.0}},
        }
    )


def render_sphere(bsdf_entry: Union[dict, Brdf], *, size: Optional[int] = None, light: Optional[Tuple[float, float]] = None) -> np.ndarray:
    """Renders :func:`sphere_scene` with Mitsuba, one camera ray through each pixel
    centre (SPEC 7's sampling; ``mi.render`` would jitter the rays inside the pixels):
    linear radiance, (size, size, 3) float32, row 0 at the top. ``size`` and ``light``
    left out are :func:`brdf_basis.render`'s (the same image size by default)."""
    import mitsuba as mi

    size, light = _render_settings(size, light)
    entry = bsdf(bsdf_entry) if isinstance(bsdf_entry, Brdf) else bsdf_entry
    scene = sphere_scene(entry, size=size, light=light)
    sensor = scene.sensors()[0]
    integrator = scene.integrator()
    sampler = sensor.sampler().clone()
    out = np.zeros((size, size, 3), dtype=np.float32)
    if mi.variant().startswith("scalar"):
        sampler.seed(0)
        for row in range(size):
            for col in range(size):
                pos = mi.Point2f((col + 0.5) / size, (row + 0.5) / size)
                ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
                spec, _, _ = integrator.sample(scene, sampler, ray)
                out[row, col] = [spec[0], spec[1], spec[2]]
        return out
    rows, cols = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    pos = mi.Point2f(mi.Float(((cols.ravel() + 0.5) / size).astype(np.float32)), mi.Float(((rows.ravel() + 0.5) / size).astype(np.float32)))
    sampler.seed(0, size * size)
    ray, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5, 0.5))
    spec, _, _ = integrator.sample(scene, sampler, ray)
    for c in range(3):
        out[..., c] = np.asarray(spec[c]).reshape(size, size)
    return out
