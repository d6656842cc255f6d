"""Scheduling values: as points, their range, and scaled to the unit box.

One convention throughout lpvid: a scheduling range is one ``(lo, hi)``
pair per parameter, given as ``(lo, hi)`` when there is one parameter and
as ``[(lo1, hi1), (lo2, hi2), ...]`` otherwise (what
:meth:`lpvid.Basis.sup_norms`, ``LpvModel(p_range=...)`` and the basis
domains take).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_int, real_array
from lpvid._graphs import spanning_tree_walk

__all__ = [
    "SCALES",
    "as_rows",
    "axis_values",
    "check_positive",
    "range_fraction",
    "scale_grid",
    "decades",
    "scale_list",
    "between_points",
    "model_range",
    "propagation_order",
    "range_pairs",
    "subtrees",
    "scheduling_range",
    "unit_scaled",
]

#: The scales a scheduling parameter may be taken on.
SCALES = ("linear", "log")


def as_rows(p: ArrayLike, name: str = "p") -> NDArray[np.float64]:
    """Scheduling values as an ``(N, Np)`` array (a 1-D array is one parameter)."""
    arr = real_array(p, name, ndim=(1, 2))
    return arr.reshape(arr.shape[0], -1)


def range_pairs(value: Any, n_params: int | None = None, name: str = "p_range") -> list[Any]:
    """A scheduling range in lpvid's convention as a list of ``(lo, hi)`` pairs, checked.

    Parameters
    ----------
    value : (lo, hi) or sequence of (lo, hi)
        The range, one pair per parameter, every pair with ``lo < hi``.
    n_params : int, optional
        The number of scheduling parameters expected.
    name : str
        Argument name for error messages.

    Returns
    -------
    list of (float, float)

    Examples
    --------
    >>> from lpvid.data.schedule import range_pairs
    >>> range_pairs((0, 1))
    [(0.0, 1.0)]

    """
    arr = real_array(value, name)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name}: expected (lo, hi) or a list of such pairs, got {value!r}")
    if np.any(arr[:, 1] <= arr[:, 0]):
        raise ValueError(f"{name}: every pair needs lo < hi, got {value!r}")
    if n_params is not None and arr.shape[0] != n_params:
        raise ValueError(f"{name}: {arr.shape[0]} pairs given for {n_params} scheduling parameters")
    return [(float(lo), float(hi)) for lo, hi in arr]


def scheduling_range(p: ArrayLike, name: str = "p") -> Any:
    """The range spanned by scheduling values, in lpvid's convention.

    Parameters
    ----------
    p : array_like, shape (N,) or (N, Np)
    name : str
        Argument name for error messages.

    Returns
    -------
    tuple or list of tuple
        ``(lo, hi)`` for one parameter, ``[(lo, hi), ...]`` per parameter
        otherwise (floats).

    Examples
    --------
    >>> from lpvid.data.schedule import scheduling_range
    >>> scheduling_range([3.0, 1.0, 2.0])
    (1.0, 3.0)
    >>> scheduling_range([[0.0, 5.0], [1.0, 4.0]])
    [(0.0, 1.0), (4.0, 5.0)]

    """
    rows = as_rows(p, name)
    pairs = [(float(lo), float(hi)) for lo, hi in zip(rows.min(0), rows.max(0), strict=True)]
    return pairs[0] if len(pairs) == 1 else pairs


def unit_scaled(p: ArrayLike, name: str = "p") -> NDArray[np.float64]:
    """Scheduling values ``(N, Np)`` with every parameter mapped to [0, 1].

    A parameter that does not vary maps to 0.
    """
    rows = as_rows(p, name)
    span = np.ptp(rows, axis=0)
    return (rows - rows.min(axis=0)) / np.where(span > 0, span, 1.0)


def model_range(p: ArrayLike, name: str = "p") -> Any:
    """:func:`scheduling_range` of ``p``, or None when a parameter does not vary.

    The default ``p_range`` of a model built from data at these values
    (a range with ``lo == hi`` cannot scale group magnitudes).
    """
    rng = scheduling_range(p, name)
    pairs = [rng] if isinstance(rng, tuple) else rng
    return rng if all(hi > lo for lo, hi in pairs) else None


def propagation_order(
    p: NDArray[np.float64], root: int | None = None
) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """Visit order and parents of the points along a minimum spanning tree.

    The points are joined by the minimum spanning tree of their distances in
    the scheduling space (each parameter scaled to [0, 1]); the tree is
    walked breadth first from ``root``, by default the point nearest the
    centre. In one dimension this is the chain of sorted points walked
    outwards from the root.

    Parameters
    ----------
    p : ndarray, shape (N, Np)
    root : int, optional
        The point to start from (default: the one whose farthest point is
        nearest).

    Returns
    -------
    order : ndarray of int
        Points in visiting order (the root first).
    parent : ndarray of int
        ``parent[k]`` is the already visited neighbour of point k (-1 for the root).

    """
    N = p.shape[0]
    s = unit_scaled(p)
    dist = np.linalg.norm(s[:, None, :] - s[None, :, :], axis=2)
    if root is None:
        root = int(np.argmin(np.max(dist, axis=1)))
    elif not 0 <= root < N:
        raise ValueError(f"root: expected a point index in 0..{N - 1}, got {root}")
    if N == 1:
        return np.array([0]), np.array([-1])
    return spanning_tree_walk(dist, root)


def subtrees(order: NDArray[np.int_], parent: NDArray[np.int_]) -> list[list[int]]:
    """A walk of :func:`propagation_order` after its root, cut into the subtrees below the root.

    One list per neighbour of the root, each in walking order (a point
    after its parent): the parts of the walk that depend on the root
    alone, and not on one another.
    """
    root = int(order[0])
    top: dict[int, int] = {}
    out: dict[int, list[int]] = {}
    for q in (int(k) for k in order[1:]):
        m = int(parent[q])
        top[q] = q if m == root else top[m]
        out.setdefault(top[q], []).append(q)
    return list(out.values())


def between_points(p: ArrayLike, steps: int = 8) -> NDArray[np.float64]:
    """Scheduling values on the segments joining neighbouring points.

    The segments are the edges of the minimum spanning tree of the points
    (in one dimension: consecutive sorted points), each cut into ``steps``
    equal parts; the points themselves are included.

    Parameters
    ----------
    p : array_like, shape (N,) or (N, Np)
    steps : int

    Returns
    -------
    ndarray, shape (M, Np)

    """
    arr = as_rows(p)
    steps = positive_int(steps, "steps")
    order, parent = propagation_order(arr)
    t = np.linspace(0.0, 1.0, steps + 1)[1:-1, None]
    out = [arr]
    for q in order[1:]:
        a, b = arr[parent[q]], arr[q]
        out.append(a + t * (b - a))
    return np.concatenate(out)


def scale_list(value: Any, n_params: int, name: str = "scale") -> tuple[str, ...]:
    """The scale of every scheduling parameter, checked.

    Parameters
    ----------
    value : str or sequence of str
        One of :data:`SCALES` for every parameter, or one per parameter.
    n_params : int
        The number of scheduling parameters.
    name : str
        Argument name for error messages.

    Returns
    -------
    tuple of str
        One scale per parameter.

    Examples
    --------
    >>> from lpvid.data.schedule import scale_list
    >>> scale_list("log", 2)
    ('log', 'log')

    """
    values = [value] * n_params if isinstance(value, str) else value
    try:
        values = list(values)
    except TypeError as exc:
        raise TypeError(
            f"{name}: expected 'linear' or 'log', or one of them per scheduling parameter, "
            f"got {type(value).__name__}"
        ) from exc
    if len(values) != n_params:
        raise ValueError(
            f"{name}: {len(values)} scales given for {n_params} scheduling parameter(s)"
        )
    for v in values:
        if not isinstance(v, str) or v not in SCALES:
            raise ValueError(f"{name}: expected 'linear' or 'log' for every parameter, got {v!r}")
    return tuple(values)


def check_positive(p: NDArray[np.float64], scales: tuple[str, ...], name: str = "p") -> None:
    """Refuse scheduling values at or below zero on a parameter taken on the log scale.

    Parameters
    ----------
    p : ndarray, shape (N, Np)
    scales : tuple of str
        The scale of every parameter.
    name : str
        Argument name for the error message.

    Raises
    ------
    ValueError
        Naming ``name``, the parameter and its smallest value.
    """
    for k, scale in enumerate(scales):
        if scale == "log" and p.shape[0] and not np.all(p[:, k] > 0):
            which = "" if len(scales) == 1 else f" (parameter {k + 1})"
            raise ValueError(
                f"{name}: a basis on the log scale takes scheduling values above zero; "
                f"got {float(np.min(p[:, k])):g}{which}"
            )


def axis_values(lo: float, hi: float, count: int, scale: str = "linear") -> NDArray[np.float64]:
    """``count`` values from ``lo`` to ``hi``, evenly spread on the parameter's scale.

    Evenly in the value (``"linear"``) or in its logarithm (``"log"``,
    ``lo > 0``); the ends are ``lo`` and ``hi`` exactly.

    Examples
    --------
    >>> from lpvid.data.schedule import axis_values
    >>> axis_values(1.0, 100.0, 3, "log")
    array([  1.,  10., 100.])

    """
    if scale != "log":
        return np.linspace(lo, hi, count)
    out = np.geomspace(lo, hi, count)
    out[0], out[-1] = lo, hi
    return out


def decades(lo: float, hi: float) -> float:
    """How many decades ``[lo, hi]`` spans: ``log10(hi / lo)``, NaN unless ``0 < lo``."""
    return float(np.log10(hi / lo)) if lo > 0 and hi > 0 else float("nan")


def scale_grid(
    pairs: Sequence[tuple[float, float]], per_axis: int, scales: Sequence[str] | None = None
) -> NDArray[np.float64]:
    """Every combination of ``per_axis`` values per parameter, shape (per_axis^Np, Np).

    Each axis from ``lo`` to ``hi``, evenly on its parameter's scale
    (:func:`axis_values`; ``scales`` default linear on every parameter);
    the first parameter varies slowest.

    Examples
    --------
    >>> from lpvid.data.schedule import scale_grid
    >>> scale_grid([(0.0, 1.0), (1.0, 100.0)], 2, ("linear", "log")).tolist()
    [[0.0, 1.0], [0.0, 100.0], [1.0, 1.0], [1.0, 100.0]]

    """
    scales = tuple(scales) if scales is not None else ("linear",) * len(pairs)
    axes = [axis_values(lo, hi, per_axis, sc) for (lo, hi), sc in zip(pairs, scales, strict=True)]
    return np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)


def range_fraction(
    p: NDArray[np.float64],
    pairs: Sequence[tuple[float, float]],
    scales: Sequence[str] | None = None,
) -> NDArray[np.float64]:
    """``p`` (M, Np) as the fraction of the range on every parameter's scale.

    ``(p - lo) / (hi - lo)``; on the log scale the fraction of ``log10(p)``
    between ``log10(lo)`` and ``log10(hi)`` (``p`` and ``lo`` above zero).
    ``scales`` default linear on every parameter.

    Examples
    --------
    >>> import numpy as np
    >>> from lpvid.data.schedule import range_fraction
    >>> range_fraction(np.array([[0.5, 10.0]]), [(0.0, 1.0), (1.0, 100.0)], ("linear", "log"))
    array([[0.5, 0.5]])

    """
    lo = np.array([a for a, _ in pairs])
    hi = np.array([b for _, b in pairs])
    out = (p - lo) / (hi - lo)
    for k, scale in enumerate(scales or ()):
        if scale == "log":
            out[:, k] = np.log10(p[:, k] / lo[k]) / np.log10(hi[k] / lo[k])
    return out
