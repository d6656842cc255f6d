"""Input checks shared by the public constructors.

Every check names the argument it looks at, so that a user reading the error
knows which of their inputs is wrong and what was expected.
"""

from __future__ import annotations

import numbers
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: The axes of FRF arrays (G, sigma) and of scheduling points, as the errors name them.
FRF_AXES = ("point", "line", "output", "input")
POINT_AXES = ("point", "parameter")


def real_array(
    value: Any,
    name: str,
    ndim: int | tuple[int, ...] | None = None,
    axes: tuple[str, ...] = (),
) -> NDArray[np.float64]:
    """Return ``value`` as a finite float64 array, or raise naming ``name``.

    ``axes`` names the array's axes (``("point", "line", ...)``) for the
    error that says where the first NaN or Inf is (:func:`finite`).

    Always a new C-ordered array: numpy sums along a strided axis in
    another order than along a contiguous one (pairwise summation only
    within contiguous runs), so a result computed from a transposed or
    sliced input would change in the last bits when the same values arrive
    laid out otherwise (a copy sent to another process, a Dask worker).
    Measured: the local models of ``benches/bench_scale.py``'s n16 rung,
    whose sigma was a transposed array, and with them every fit after,
    differed between ``identify`` here and on a process pool.
    """
    try:
        arr = np.asarray(value)
    except Exception as exc:  # pragma: no cover - numpy raises many types
        raise TypeError(f"{name}: cannot be read as an array ({exc})") from exc
    if np.iscomplexobj(arr):
        raise TypeError(f"{name}: must be real, got a complex array")
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.bool_)
    ):
        raise TypeError(f"{name}: must be numeric, got dtype {arr.dtype}")
    arr = np.array(arr, dtype=np.float64, order="C")
    _check_ndim(arr, name, ndim)
    finite(arr, name, axes)
    return arr


def complex_array(
    value: Any,
    name: str,
    ndim: int | tuple[int, ...] | None = None,
    axes: tuple[str, ...] = (),
) -> NDArray[np.complex128]:
    """Return ``value`` as a finite complex128 array, or raise naming ``name``.

    A new C-ordered array, as :func:`real_array`, ``axes`` as there.
    """
    try:
        arr = np.asarray(value)
    except Exception as exc:  # pragma: no cover
        raise TypeError(f"{name}: cannot be read as an array ({exc})") from exc
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.number):
        raise TypeError(f"{name}: must be numeric, got dtype {arr.dtype}")
    arr = np.array(arr, dtype=np.complex128, order="C")
    _check_ndim(arr, name, ndim)
    finite(arr, name, axes)
    return arr


def finite(arr: np.ndarray, name: str, axes: tuple[str, ...] = ()) -> None:
    """Raise naming ``name`` when ``arr`` holds a NaN or Inf: how many, and where the first is.

    The first is given by the names of ``axes`` where they are known
    (``point 2, line 17``) and by its index otherwise.
    """
    bad = ~np.isfinite(arr)
    if not bad.any():
        return
    first = tuple(int(i) for i in np.argwhere(bad)[0])
    if len(axes) >= len(first) > 0:
        where = ", ".join(f"{axis} {i}" for axis, i in zip(axes, first, strict=False))
    else:
        where = f"index {first}" if first else "its value"
    count = int(bad.sum())
    many = f"{count} entries, the first" if count > 1 else "1 entry"
    raise ValueError(f"{name}: contains NaN or Inf ({many} at {where})")


def _check_ndim(arr: np.ndarray, name: str, ndim: int | tuple[int, ...] | None) -> None:
    if ndim is None:
        return
    allowed = (ndim,) if isinstance(ndim, int) else ndim
    if arr.ndim not in allowed:
        want = " or ".join(str(d) for d in allowed)
        raise ValueError(f"{name}: expected a {want}-dimensional array, got shape {arr.shape}")


def positive_int(value: Any, name: str, minimum: int = 1) -> int:
    """Return ``value`` as an int >= ``minimum``, or raise naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected an integer, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value}")
    return int(value)


def positive_float(value: Any, name: str, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite float > 0 (or >= 0), or raise naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name}: expected a real number, got {type(value).__name__}")
    v = float(value)
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name}: expected a finite number {bound}, got {value}")
    return v


def flag(value: Any, name: str) -> bool:
    """Return ``value`` as a bool (a Python or numpy bool only), or raise naming ``name``."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected True or False, got {type(value).__name__}")
    return bool(value)


def sample_time(Ts: Any) -> float | None:
    """Validate a sample time: None (continuous time) or a positive number."""
    if Ts is None:
        return None
    return positive_float(Ts, "Ts")


def same_sample_time(a: float | None, b: float | None) -> bool:
    """Whether two sample times describe the same time domain.

    Both None (continuous time), or both numbers equal to 1e-12 relative
    (sample times read back from files may differ in the last bits).
    """
    if a is None or b is None:
        return a is None and b is None
    # numpy.isclose's rule (atol 0) on two floats, without its array set-up
    # (11 us a call, 164 calls in a gantry identify).
    return bool(a == b or abs(a - b) <= 1e-12 * abs(b))


def generator(seed: Any, name: str = "seed") -> np.random.Generator:
    """``np.random.default_rng(seed)``, or a TypeError naming ``name`` that says what it takes."""
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError) as exc:
        raise TypeError(
            f"{name}: expected None, an int (or sequence of ints) or a numpy Generator, "
            f"got {seed!r} ({exc})"
        ) from exc
