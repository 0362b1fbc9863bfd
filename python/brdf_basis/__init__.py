"""brdf-basis from Python: BRDF bases, distances, selections and NNLS fits on NumPy arrays.

Every computation is the Rust library's (``brdf_basis._native``, PyO3); this module adds
small result classes over the JSON the command line writes, so that ``result.to_json()``
is byte for byte what ``brdf-basis select|fit|cv --json`` would write.

>>> import brdf_basis as bb
>>> coll = bb.Collection.default()
>>> d = bb.distance_matrix(coll, stride=8)        # (N, N) float64, BRDF_it
>>> d.shape == (len(coll), len(coll))
True
>>> sel = bb.select(coll, method="greedy", k=3, stride=8)
>>> fits = bb.fit(coll, sel.basis, stride=8)
>>> len(fits.targets) == len(coll) - 3
True

Long calls release the GIL, stop on Ctrl-C (``KeyboardInterrupt``) and report progress
with ``progress=True`` (a line on stderr) or ``progress=callable(done, total)``.
``backend`` is ``"auto"`` (a hardware GPU if any, else the CPU), ``"cpu"`` or ``"gpu"``.
Errors are ``ValueError`` (bad input), ``FileNotFoundError`` / ``OSError`` (files) or
``RuntimeError`` (GPU), with the library's message.
"""

from __future__ import annotations

import json as _json
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence, Union

import os as _os
import tempfile as _tempfile

import numpy as _np

# Mesa's Vulkan loader (probed by backend="auto" and "gpu") complains on every probe
# without a runtime directory; the command line makes a private one too.
if not _os.environ.get("XDG_RUNTIME_DIR"):
    import atexit as _atexit
    import shutil as _shutil

    _os.environ["XDG_RUNTIME_DIR"] = _runtime = _tempfile.mkdtemp(prefix="brdf-basis-runtime-")
    _atexit.register(_shutil.rmtree, _runtime, True)

from . import _native  # noqa: E402
from ._native import (  # noqa: E402
    Brdf,
    Collection,
    backend_name,
    distance_matrix,
    image_error,
    image_metrics,
    ciede2000,
    srgb_to_lab,
    srgb_to_ictcp,
    delta_e_itp,
    mask,
    nnls,
    render,
    silhouette,
)

__all__ = [
    "Brdf",
    "Collection",
    "CvResult",
    "FitResult",
    "FriedmanResult",
    "KMedoidsResult",
    "MannWhitneyResult",
    "Plan",
    "SampleFit",
    "Selection",
    "TargetFit",
    "WilcoxonResult",
    "backend_name",
    "cross_validate",
    "defaults",
    "distance_matrix",
    "fit",
    "friedman",
    "image_error",
    "image_metrics",
    "ciede2000",
    "srgb_to_lab",
    "srgb_to_ictcp",
    "delta_e_itp",
    "kmedoids",
    "mann_whitney",
    "mask",
    "nnls",
    "plan",
    "fit_samples",
    "acquisition_cv",
    "AcquisitionCv",
    "render",
    "select",
    "silhouette",
    "wilcoxon",
]

Progress = Union[bool, Callable[[int, int], Any], None]


@dataclass(frozen=True)
class Selection:
    """A basis selection: what ``brdf-basis select --json`` writes.

    ``basis`` is the chosen materials (empirical: the contributors; k-medoids and GCUK:
    the medoids of the best run; greedy, swap, GA: the basis found). ``data`` is the
    whole JSON object; ``score`` (greedy, swap, ga) and ``db_index`` (kmedoids, gcuk)
    are ``None`` where they do not apply.
    """

    method: str
    basis: list
    score: Optional[float]
    db_index: Optional[float]
    data: dict = field(repr=False)
    _json: str = field(repr=False)

    @classmethod
    def from_json(cls, text: str) -> "Selection":
        d = _json.loads(text)
        best = d.get("best")
        return cls(
            method=d["method"],
            basis=list(best["medoids"] if best else d["basis"]),
            score=d.get("score"),
            db_index=best["db_index"] if best else None,
            data=d,
            _json=text,
        )

    def to_json(self) -> str:
        """The JSON text, as the command line writes it."""
        return self._json


@dataclass(frozen=True)
class TargetFit:
    """The fit of one target: ``lambertian`` (3,), ``coefficients`` (k, 3) in basis order."""

    material: str
    lambertian: _np.ndarray
    coefficients: _np.ndarray
    mae: float
    residual: _np.ndarray


@dataclass(frozen=True)
class FitResult:
    """Fits of targets by a basis: what ``brdf-basis fit --json`` writes.

    ``coefficients`` is (targets, 1 + k, 3): the Lambertian column, then the basis.
    """

    basis: list
    mask: str
    weighting: str
    targets: list
    data: dict = field(repr=False)
    _json: str = field(repr=False)

    @classmethod
    def from_json(cls, text: str) -> "FitResult":
        d = _json.loads(text)
        basis = list(d["basis"])
        targets = [
            TargetFit(
                material=t["material"],
                lambertian=_np.array(t["lambertian"], dtype=_np.float64),
                coefficients=_np.array([t["coefficients"][b] for b in basis], dtype=_np.float64).reshape(len(basis), 3),
                mae=t["mae"],
                residual=_np.array(t["residual"], dtype=_np.float64),
            )
            for t in d["targets"]
        ]
        return cls(basis, d["mask"], d["weighting"], targets, d, text)

    @property
    def coefficients(self) -> _np.ndarray:
        return _np.stack([_np.vstack([t.lambertian, t.coefficients]) for t in self.targets])

    @property
    def mae(self) -> _np.ndarray:
        return _np.array([t.mae for t in self.targets])

    @property
    def objective(self) -> str:
        """The fit objective (SPEC 11): ``l2``, ``relative`` or ``log``."""
        return self.data.get("objective", "l2")

    @property
    def appearance(self) -> list:
        """Per target, its appearance metrics (SPEC 11: ``log_rmse``, ``lights`` with the
        image error, CIEDE2000 and FLIP under each of the four lights, and their means), or
        ``None`` when the fit was made with ``appearance=False``."""
        return [t.get("appearance") for t in self.data["targets"]]

    def to_json(self) -> str:
        """The JSON text, as the command line writes it."""
        return self._json

    def save(self, path) -> None:
        """Writes the JSON (readable by ``brdf-basis render --fit`` and ``Brdf.fitted``),
        atomically (a temporary file renamed into place). As the command line, it refuses a
        symbolic link (writing through it would replace the file it points to) and anything
        but a regular file (``ValueError``)."""
        p = _os.fspath(path)
        if _os.path.islink(p):
            raise ValueError(f"{p}: is a symbolic link; give the file itself or a new name")
        if _os.path.exists(p) and not _os.path.isfile(p):
            raise ValueError(f"{p}: exists and is not a regular file; give a file name")
        fd, tmp = _tempfile.mkstemp(prefix=".brdf-basis-", dir=_os.path.dirname(p) or ".")
        try:
            with _os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(self._json)
            # mkstemp's 0600 would make the file private: keep a replaced file's mode.
            _os.chmod(tmp, _os.stat(p).st_mode & 0o777 if _os.path.exists(p) else 0o644)
            _os.replace(tmp, p)
        except BaseException:
            _os.unlink(tmp)
            raise


@dataclass(frozen=True)
class CvResult:
    """K-fold cross-validation: what ``brdf-basis cv --json`` writes."""

    folds: list
    results: list
    tests: list
    data: dict = field(repr=False)
    _json: str = field(repr=False)

    @classmethod
    def from_json(cls, text: str) -> "CvResult":
        d = _json.loads(text)
        return cls(d["folds"], d["results"], d["tests"], d, text)

    def to_json(self) -> str:
        return self._json


@dataclass(frozen=True)
class KMedoidsResult:
    """k-medoids on a matrix: medoids (indices), labels (index into medoids), loss."""

    medoids: list
    labels: list
    loss: float
    iterations: int
    db_index: float


@dataclass(frozen=True)
class WilcoxonResult:
    """Wilcoxon signed-rank test (two-sided): statistic = min(W+, W-)."""

    n: int
    zeros: int
    w_plus: float
    w_minus: float
    statistic: float
    z: Optional[float]
    p_value: float
    method: str


@dataclass(frozen=True)
class FriedmanResult:
    """Friedman test (tie-corrected chi-square) with the Iman-Davenport F variant."""

    statistic: float
    dof: int
    p_value: float
    mean_ranks: list
    blocks: int
    iman_davenport: dict


@dataclass(frozen=True)
class MannWhitneyResult:
    """Mann-Whitney U test (two-sided, normal approximation)."""

    u: float
    z: float
    p_value: float


def _fields(cls, d: dict) -> dict:
    return {k: d[k] for k in cls.__dataclass_fields__}


def select(collection: Collection, method: str, k: Optional[int] = None, **options) -> Selection:
    """Selects a basis as ``brdf-basis select --method METHOD``.

    ``method``: ``empirical``, ``kmedoids``, ``gcuk``, ``greedy``, ``swap``, ``ga``.
    Options (the command line's flags, underscores for dashes): ``k_min``, ``k_max``,
    ``runs``, ``algorithm``, ``population``, ``generations``, ``more_than``,
    ``candidates``, ``targets``, ``init`` (lists of names), ``ga_population``,
    ``ga_generations``, ``ga_crossover``, ``ga_mutation``, ``metric``, ``mask``,
    ``weighting``, ``stride``, ``seed``, ``backend``, ``progress``. An option the method
    does not use is refused, naming it (``seed``: kmedoids, gcuk and ga only).

    >>> sel = select(Collection.default(), "kmedoids", k=3, runs=2, stride=8)
    >>> len(sel.basis)
    3
    """
    return Selection.from_json(_native.select_json(collection, method, k=k, **_name_options(options)))


def fit(collection: Collection, basis: Sequence[str], targets: Optional[Sequence[str]] = None, **options) -> FitResult:
    """Fits ``targets`` (default: every material outside ``basis``) as non-negative
    combinations of a Lambertian term and ``basis``, as ``brdf-basis fit``.

    Options: ``mask``, ``weighting``, ``stride``, ``solver`` (``exact``, ``pgd``),
    ``gram`` (``auto``, ``grid``), ``backend``, ``progress``.

    >>> r = fit(Collection.default(), ["polished-gold", "matte-white-paint"], ["polished-copper"], stride=8)
    >>> r.coefficients.shape
    (1, 3, 3)
    """
    t = None if targets is None else _names(targets, "targets")
    return FitResult.from_json(_native.fit_json(collection, _names(basis, "basis"), t, **options))


@dataclass(frozen=True)
class Plan:
    """Where to measure (``brdf-basis plan --json``): ``samples`` is a list of dicts with
    ``theta_i, phi_i, theta_o, phi_o`` in degrees, in the order chosen (the first n' of
    an n-plan are the n'-plan; with ``restarts`` > 1 a separate call at a smaller n may
    choose another path: measure a prefix)."""

    basis: list
    criterion: str
    n: int
    candidates_per_step: int
    candidates: int
    samples: list
    history: list
    seed: int
    restarts: int = 1
    _json: str = field(repr=False, default="")

    @property
    def angles(self) -> _np.ndarray:
        """The samples' ``(theta_i, phi_i, theta_o, phi_o)`` in degrees, shape (n, 4)."""
        return _np.array([[s["theta_i"], s["phi_i"], s["theta_o"], s["phi_o"]] for s in self.samples], dtype=_np.float64)

    def to_json(self) -> str:
        """The JSON text, as ``brdf-basis plan --json`` writes it."""
        return self._json


def plan(collection: Collection, basis: Sequence[str], n: int, **options) -> Plan:
    """Plans ``n`` measurement directions for a new material (SPEC 10) on the
    evaluation-mask cell centres, as ``brdf-basis plan``.

    Options: ``criterion`` (``error``, ``condition``, ``random``), ``targets`` (training
    materials; default every material outside ``basis``), ``candidates_per_step``,
    ``shortlist``, ``seed``, ``restarts`` (``error``: seeded greedy paths sharing each
    step's candidates, the lowest final training score kept), ``objective`` and ``eps``
    (SPEC 11: the rows weighted by the objective's shared weights; default relative),
    ``backend``, ``progress``.

    >>> p = plan(Collection.default(), ["polished-gold", "matte-white-paint"], 3, criterion="condition")
    >>> p.angles.shape
    (3, 4)
    """
    text = _native.plan_json(collection, _names(basis, "basis"), n, **_name_options(options))
    d = _json.loads(text)
    return Plan(**{k: d[k] for k in Plan.__dataclass_fields__ if k != "_json"}, _json=text)


@dataclass(frozen=True)
class AcquisitionCv:
    """Acquisition cross-validation (SPEC 10): what ``brdf-basis cv --acquisition --json``
    writes. ``results`` is a list of dicts, one per method, plan, n and noise (``plan``,
    ``n``, ``noise``, ``mean_rho``, ``median_rho``, ``mean_dense_rho``, ``ratio``,
    ``mean_mae``, ``median_mae``, ``mean_image_error``, ``median_image_error``,
    ``held_out``, ``fold_plans``, ...)."""

    folds: list
    seed: int
    select: dict
    k: int
    candidates_per_step: int
    results: list
    collection_fingerprint: str
    _json: str = field(repr=False, default="")

    def result(self, plan: str, n: int, noise: float = 0.0, method: Optional[str] = None) -> dict:
        """The result of one plan, n and noise (first method unless ``method``)."""
        for r in self.results:
            if r["plan"] == plan and r["n"] == n and r["noise"] == noise and (method is None or r["method"] == method):
                return r
        raise KeyError((plan, n, noise, method))

    def to_json(self) -> str:
        """The JSON text, as ``brdf-basis cv --acquisition --json`` writes it."""
        return self._json


def acquisition_cv(collection: Collection, **options) -> AcquisitionCv:
    """Acquisition cross-validation, as ``brdf-basis cv --acquisition``: per fold a basis
    chosen on the training materials, plans on them, held-out materials measured at the
    plans (with relative noise) and reconstructed.

    Options: ``methods`` (list), ``k``, ``plans`` (list of ``error``, ``condition``,
    ``random``, ``nielsen``), ``ns`` (list), ``noises`` (list), ``folds``,
    ``candidates_per_step``, ``shortlist``, ``render_size``, ``mask``, ``weighting``,
    ``stride``, ``seed``, ``objective`` and ``eps`` (SPEC 11; default relative),
    ``appearance`` (log-RMSE, image error, CIEDE2000, ΔE_ITP and FLIP under four lights of
    every reconstruction; default True), ``ridge`` (the ridge and energy bound of the fits
    from samples; default True), ``test`` (a fixed split: the held-out materials' names,
    scored as one fold; not with ``folds``), ``backend``, ``progress``.
    """
    text = _native.acquisition_cv_json(collection, **_name_options(options))
    d = _json.loads(text)
    return AcquisitionCv(**{k: d[k] for k in AcquisitionCv.__dataclass_fields__ if k != "_json"}, _json=text)


@dataclass(frozen=True)
class SampleFit:
    """A material fitted from samples: ``coefficients`` (1 + k, 3) (Lambertian first),
    residual per channel, MAE and relative residual on the samples, and the rank and
    condition number of the sampled design (a rank below its columns or a large condition
    means the samples do not determine the fit), and the warnings ``brdf-basis fit
    --samples`` prints (samples too few or a design ill-conditioned, with where to
    measure next)."""

    coefficients: _np.ndarray
    residual: tuple
    mae: float
    relative_residual: float
    rank: int
    condition: float
    warnings: tuple = ()


def fit_samples(
    collection: Collection, basis: Sequence[str], angles, rgb, sigma=None, *, objective=None, eps=None, seed=None
) -> SampleFit:
    """Fits a new material from its samples (SPEC 10): ``angles`` (n, 4) in degrees
    ``theta_i, phi_i, theta_o, phi_o``, ``rgb`` (n, 3) reflectance in MERL units,
    optional ``sigma`` (n, 3) standard deviations. Non-negative per channel, with the
    Lambertian term, as ``brdf-basis fit --samples``. ``objective`` (``"l2"``,
    ``"relative"`` with ``eps``, ``"log"``; ``None``: the default, relative) weights each
    sample by the objective's weight at its measured value (SPEC 11). ``seed``: of the
    directions the warnings suggest. The library's ``run::FitSamplesRequest`` makes the
    rules, with the command line's messages.

    >>> c = Collection.default(); b = ["polished-gold", "matte-white-paint"]
    >>> f = Brdf.material(c, "matte-white-paint")
    >>> a = _np.array([[10, 0, 20, 180], [30, 0, 40, 90], [50, 0, 10, 0], [0, 0, 60, 45]], float)
    >>> y = _np.array([f.eval1(_dir(t[0], t[1]), _dir(t[2], t[3])) for t in a])
    >>> r = fit_samples(c, b, a, y)
    >>> bool(abs(r.coefficients[2] - 1).max() < 1e-6)
    True
    """
    a = _rows(angles, 4, "angles", "theta_i, phi_i, theta_o, phi_o")
    y = _rows(rgb, 3, "rgb", "r, g, b")
    s = None if sigma is None else [tuple(r) for r in _rows(sigma, 3, "sigma", "sigma_r, sigma_g, sigma_b")]
    coef, res, mae, rel, rank, cond, warn = _native.fit_samples(
        collection, _names(basis, "basis"), [tuple(r) for r in a], [tuple(r) for r in y], s, objective, eps, seed
    )
    return SampleFit(_np.asarray(coef), tuple(res), mae, rel, rank, cond, tuple(warn))


def defaults() -> dict:
    """The settings each command function takes when a keyword argument is left out
    (``None``), by function name (``distance_matrix``, ``select``, ``fit``, ``plan``,
    ``fit_samples``, ``cross_validate``, ``acquisition_cv``, and the helpers ``kmedoids``,
    ``render``, ``image_error``, ``mask``): read from the library's requests and parameter
    types, the one home of the defaults (the command line's ``--help`` shows the same).
    Settings whose default depends on others (a method's ``k``, ``runs``, ...) are left
    to the request.

    >>> defaults()["fit"]["objective"]
    'relative'
    """
    return _json.loads(_native.defaults_json())


def _rows(x, cols: int, what: str, columns: str) -> _np.ndarray:
    """``x`` as a float64 array of shape (n, cols), or a ValueError naming its shape: an
    array is never reshaped, so a transposed one (channels first) is refused rather than
    read as other samples."""
    a = _np.asarray(x, dtype=_np.float64)
    if a.ndim == 2 and a.shape[1] == cols:
        return a
    hint = ""
    if a.ndim == 2 and a.shape[0] == cols:
        hint = f" (it looks transposed: pass {what}.T)"
    elif a.ndim == 1 and a.shape[0] == cols:
        hint = f" (one sample: pass [{what}])"
    raise ValueError(
        f"{what} has shape {a.shape}; expected (n, {cols}): one row of {columns} per sample{hint}"
    )


def _names(x, what: str) -> list:
    """``x`` as a list of material names; a single string is refused (it would be read
    as a list of its characters)."""
    if isinstance(x, (str, bytes)):
        raise TypeError(f"{what} must be a list of material names, not the string {x!r}: pass [{x!r}]")
    return list(x)


def _name_options(options: dict) -> dict:
    """Checks the options that take lists of names (or of methods, plans)."""
    for k in ("targets", "candidates", "init", "methods", "plans"):
        if isinstance(options.get(k), (str, bytes)):
            _names(options[k], k)
    return options


def _dir(theta_deg: float, phi_deg: float) -> tuple:
    """Unit direction of polar angle ``theta`` and azimuth ``phi`` in degrees."""
    t, p = _np.radians(theta_deg), _np.radians(phi_deg)
    return (float(_np.sin(t) * _np.cos(p)), float(_np.sin(t) * _np.sin(p)), float(_np.cos(t)))


def cross_validate(collection: Collection, **options) -> CvResult:
    """K-fold cross-validation of selection methods, as ``brdf-basis cv``.

    Options: ``methods`` (list), ``ks`` (list), ``folds``, ``metric``, ``mask``,
    ``weighting``, ``stride``, ``runs``, ``ga_population``, ``ga_generations``,
    ``render_size``, ``seed``, ``backend``, ``progress``.
    """
    return CvResult.from_json(_native.cross_validate_json(collection, **_name_options(options)))


def kmedoids(
    d: _np.ndarray,
    k: int,
    *,
    seed: Optional[int] = None,
    init: Optional[str] = None,
    algorithm: Optional[str] = None,
    restarts: Optional[int] = None,
    max_iter: Optional[int] = None,
    order: Optional[str] = None,
    tolerance: Optional[float] = None,
    medoids: Optional[Sequence[int]] = None,
) -> KMedoidsResult:
    """k-medoids (FasterPAM or PAM) on a precomputed (N, N) distance matrix.

    ``restarts`` runs use seeds ``seed``, ``seed + 1``, ...: run 0 starts from BUILD
    (``init="build"``) or random medoids, the others from random medoids, and the lowest
    loss wins. FasterPAM visits the candidates in a permutation drawn from each run's seed
    (``order="shuffled"``, like the ``kmedoids`` package with a ``random_state``) or in
    item order (``"sequential"``, the package without one). ``medoids`` gives the initial
    medoids of one run instead; ``tolerance`` is the relative tie margin of the loss
    comparisons (0 compares strictly, as the package). A setting left out (``None``) is
    the library's, listed by ``defaults()["kmedoids"]`` (seed 1, BUILD, FasterPAM, one
    run, 100 iterations, shuffled, tolerance 1e-6).

    >>> import numpy as np
    >>> x = _np.array([0.0, 0.1, 5.0, 5.2]); d = _np.abs(x[:, None] - x[None, :])
    >>> round(kmedoids(d, 2).loss, 12)
    0.3
    """
    if isinstance(medoids, (str, bytes)):
        raise TypeError(f"medoids must be a sequence of item indices, not {type(medoids).__name__} {medoids!r}")
    start = None if medoids is None else [int(m) for m in medoids]
    m, l, loss, it, db = _native.kmedoids(
        _np.ascontiguousarray(d, dtype=_np.float64),
        k,
        seed=seed,
        init=init,
        algorithm=algorithm,
        restarts=restarts,
        max_iter=max_iter,
        order=order,
        tolerance=tolerance,
        medoids=start,
    )
    return KMedoidsResult(m, l, loss, it, db)


def wilcoxon(x: Sequence[float], y: Sequence[float]) -> WilcoxonResult:
    """Wilcoxon signed-rank test of paired samples (as ``scipy.stats.wilcoxon``)."""
    return WilcoxonResult(**_fields(WilcoxonResult, _json.loads(_native.wilcoxon_json(list(map(float, x)), list(map(float, y))))))


def friedman(blocks: _np.ndarray) -> FriedmanResult:
    """Friedman test; ``blocks[r, j]`` is treatment ``j`` in block ``r``."""
    b = _np.ascontiguousarray(blocks, dtype=_np.float64)
    return FriedmanResult(**_fields(FriedmanResult, _json.loads(_native.friedman_json(b))))


def mann_whitney(x: Sequence[float], y: Sequence[float]) -> MannWhitneyResult:
    """Mann-Whitney U test of two independent samples."""
    return MannWhitneyResult(**_fields(MannWhitneyResult, _json.loads(_native.mann_whitney_json(list(map(float, x)), list(map(float, y))))))


# The names the module imports for its own use are not part of the package's namespace
# (audit 2, U15): `numpy` is `_np`, and the annotations' helpers (strings under
# `from __future__ import annotations`, never evaluated) go once the classes are made.
del annotations, dataclass, field, Any, Callable, Optional, Sequence, Union
