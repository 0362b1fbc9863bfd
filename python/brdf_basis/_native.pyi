"""Type stubs of the compiled module ``brdf_basis._native`` (PyO3)."""

from os import PathLike
from typing import Any, Callable, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_Progress = Union[bool, Callable[[int, int], Any], None]
_Backend = str  # "auto" | "cpu" | "gpu"

class Collection:
    """An ordered collection of uniquely named materials: analytic Ashikhmin-Shirley rows
    of a CSV, or measured MERL tables.

    >>> coll = Collection.default()
    >>> "polished-gold" in coll, coll.kinds[0]
    (True, 'analytic')
    >>> coll.tabulate("polished-gold").shape
    (3, 90, 90, 180)
    """

    @staticmethod
    def load(*paths: _Path) -> Collection:
        """Loads COLLECTION arguments in order (an analytic ``.csv``, a MERL ``.binary``,
        an RGL-EPFL ``.bsdf``, directories of them); none: the embedded default. ``FileNotFoundError`` for a missing
        path, ``ValueError`` naming the file and line for bad content."""
    @staticmethod
    def default() -> Collection:
        """The embedded default collection."""
    @property
    def names(self) -> list[str]: ...
    @property
    def kinds(self) -> list[str]:
        """``"analytic"``, ``"measured"`` (MERL table), ``"neural"`` (NBRDF) or ``"rgl"`` (RGL-EPFL ``.bsdf``) per material."""
    @property
    def fingerprint(self) -> str:
        """The fingerprint result files record for their collection."""
    def __len__(self) -> int: ...
    def __contains__(self, name: str) -> bool: ...
    def index(self, name: str) -> int:
        """Index of ``name`` (``ValueError`` with close names when unknown)."""
    def analytic(self, name: str) -> Optional[dict]:
        """``{"d": [r, g, b], "s": [r, g, b], "F0": f, "n": n}``, or ``None`` if measured."""
    def tabulate(self, name: str, *, backend: Optional[_Backend] = None, progress: _Progress = None) -> npt.NDArray[np.float32]:
        """The material on the full MERL grid: (3, 90, 90, 180) float32 indexed
        ``[channel, theta_h, theta_d, phi_d]``, invalid cells -1 (``brdf-basis
        tabulate``'s table)."""

class Brdf:
    """A BRDF ``f(wi, wo) -> RGB`` (local directions, normal +z; ``wi`` towards the
    light, ``wo`` towards the viewer).

    >>> f = Brdf.material(Collection.default(), "matte-white-paint")
    >>> f.eval1((0, 0, 1), (0, 0, 1))   # doctest: +ELLIPSIS
    (...)
    """

    @staticmethod
    def material(collection: Collection, name: str) -> Brdf:
        """Material ``name``: analytic evaluation, or the MERL lookup (invalid cells 0)."""
    @staticmethod
    def fitted(collection: Collection, fit: _Path, target: str) -> Brdf:
        """The fitted combination of ``target`` in a ``brdf-basis fit`` JSON (checked
        against ``collection``'s fingerprint)."""
    def eval1(self, wi: Sequence[float], wo: Sequence[float]) -> Tuple[float, float, float]: ...
    def eval(self, wi: npt.NDArray[np.float64], wo: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """``wi``, ``wo`` of shape (..., 3): returns (..., 3)."""

def mask(name: Optional[str] = None) -> npt.NDArray[np.bool_]:
    """The grid mask (90, 90, 180): ``"evaluation"`` or ``"valid"``."""

def distance_matrix(
    collection: Collection,
    *,
    metric: Optional[str] = None,
    mask: Optional[str] = None,
    weighting: Optional[str] = None,
    stride: Optional[int] = None,
    backend: Optional[_Backend] = None,
    progress: _Progress = None,
) -> npt.NDArray[np.float64]:
    """The (N, N) distance matrix, the values ``brdf-basis distance`` writes to its .npy.

    >>> d = distance_matrix(Collection.default(), stride=8)
    >>> bool((d == d.T).all())
    True
    """

def select_json(collection: Collection, method: str, **options: Any) -> str: ...
def fit_json(collection: Collection, basis: list[str], targets: Optional[list[str]] = None, **options: Any) -> str: ...
def cross_validate_json(collection: Collection, **options: Any) -> str: ...
def plan_json(collection: Collection, basis: list[str], n: int, **options: Any) -> str: ...
def acquisition_cv_json(collection: Collection, **options: Any) -> str: ...
def fit_samples(
    collection: Collection,
    basis: list[str],
    angles: list[Tuple[float, float, float, float]],
    rgb: list[Tuple[float, float, float]],
    sigma: Optional[list[Tuple[float, float, float]]] = None,
    objective: Optional[str] = None,
    eps: Optional[float] = None,
    seed: Optional[int] = None,
) -> Tuple[npt.NDArray[np.float64], Tuple[float, float, float], float, float, int, float, list[str]]: ...
def defaults_json() -> str:
    """The defaults of every command's keyword arguments (``brdf_basis.defaults()``)."""
def nnls(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """``argmin |A x - b|`` subject to ``x >= 0`` (Lawson-Hanson).

    >>> import numpy as np
    >>> nnls(np.eye(2), np.array([1.0, -1.0]))
    array([1., 0.])
    """
def silhouette(d: npt.NDArray[np.float64], labels: Sequence[int]) -> float:
    """Mean silhouette on a precomputed distance matrix."""
def kmedoids(d: npt.NDArray[np.float64], k: int, *, seed: Optional[int] = None, init: Optional[str] = None, algorithm: Optional[str] = None, restarts: Optional[int] = None, max_iter: Optional[int] = None, order: Optional[str] = None, tolerance: Optional[float] = None, medoids: Optional[Sequence[int]] = None) -> Tuple[list[int], list[int], float, int, float]: ...
def wilcoxon_json(x: Sequence[float], y: Sequence[float]) -> str: ...
def friedman_json(blocks: npt.NDArray[np.float64]) -> str: ...
def mann_whitney_json(x: Sequence[float], y: Sequence[float]) -> str: ...
def render(brdf: Brdf, *, size: Optional[int] = None, light: Optional[Tuple[float, float]] = None) -> npt.NDArray[np.float32]:
    """The sphere of SPEC 7: (size, size, 3) float32 linear radiance (``brdf-basis render``)."""
def image_metrics(reference: npt.NDArray[np.float32], test: npt.NDArray[np.float32]) -> dict[str, float]: ...
def ciede2000(lab1: Sequence[float], lab2: Sequence[float]) -> float: ...
def srgb_to_lab(rgb: Sequence[float]) -> list[float]: ...
def image_error(a: npt.NDArray[np.float32], b: npt.NDArray[np.float32], *, exposure: Optional[float] = None, gamma: Optional[float] = None) -> float:
    """Normalised image error of SPEC 7 between two sphere renders."""
def backend_name(backend: Optional[_Backend] = None) -> str: ...
