"""The scheduling range a stability statement covers: checks, grids, and A(p) as a polynomial.

A range follows lpvid's convention (:mod:`lpvid.data.schedule`): ``(lo, hi)``
for one scheduling parameter, ``[(lo, hi), ...]`` for several. Where the
basis has a domain, the range must lie inside it: outside, the model is
an extrapolation nobody fitted. A parameter the basis takes on the log
scale is gridded evenly in its logarithm and mapped from [-1, 1]
geometrically (:func:`to_p`), so that ``A(p)`` stays a polynomial in the
mapped variable.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.data.basis import Legendre, Polynomial
from lpvid.data.schedule import range_pairs, scale_grid
from lpvid.model.frozen import frozen_A
from lpvid.model.lpv import LpvModel

__all__ = ["check_range", "as_convention", "box_grid", "polynomial_A", "to_p"]

#: Relative slack when comparing a range with the basis domain.
_SLACK = 1e-9


def check_range(model: LpvModel, p_range: Any) -> list[tuple[float, float]]:
    """The range as ``(lo, hi)`` pairs: given, else the model's; inside the basis domain.

    An LTI model (no basis function) needs no range: ``[(0, 0)]``.

    Raises
    ------
    ValueError
        When there is no range (neither given nor the model's), when it has
        the wrong number of pairs, or when it reaches outside the basis domain.
    """
    if not isinstance(model, LpvModel):
        raise TypeError(f"model: expected an LpvModel, got {type(model).__name__}")
    value = p_range if p_range is not None else model.p_range
    if value is None and model.n_basis == 0:
        # An LTI model: the same frozen model everywhere.
        return [(0.0, 0.0)] * model.basis.n_params
    if value is None:
        raise ValueError(
            "p_range: the model has no scheduling range (its basis has no domain); "
            "pass p_range=(lo, hi)"
        )
    pairs = range_pairs(value, model.basis.n_params, "p_range")
    domain = getattr(model.basis, "domain", None)
    if domain is not None:
        for k, ((lo, hi), (dlo, dhi)) in enumerate(zip(pairs, domain, strict=True)):
            slack = _SLACK * (dhi - dlo)
            if lo < dlo - slack or hi > dhi + slack:
                which = "" if len(pairs) == 1 else f" of parameter {k}"
                raise ValueError(
                    f"p_range: ({lo:g}, {hi:g}){which} reaches outside the basis domain "
                    f"({dlo:g}, {dhi:g}), where the model is an extrapolation"
                )
    model.basis.sup_norms(pairs)  # the basis must be finite on the range
    return pairs


def as_convention(pairs: list[tuple[float, float]]) -> Any:
    """``(lo, hi)`` for one parameter, the list of pairs otherwise."""
    return pairs[0] if len(pairs) == 1 else list(pairs)


def box_grid(
    pairs: list[tuple[float, float]], max_points: int, scales: tuple[str, ...] | None = None
) -> NDArray[np.float64]:
    """A grid over the box with at most about ``max_points`` points, shape (M, Np).

    Even on every parameter's scale (``scales``, default linear: see
    :func:`lpvid.data.schedule.axis_values`).
    """
    per_axis = max(2, int(np.floor(max_points ** (1.0 / len(pairs)))))
    return scale_grid(pairs, per_axis, scales)


def to_p(
    t: NDArray[np.float64], pair: tuple[float, float], scale: str = "linear"
) -> NDArray[np.float64]:
    """Map ``t`` in [-1, 1] onto ``(lo, hi)``: affinely, or on the log scale geometrically.

    On the log scale ``log10(p)`` is affine in ``t`` (``p = lo (hi/lo)^((t+1)/2)``),
    so that a basis on that scale is a polynomial in ``t``.
    """
    lo, hi = pair
    u = (np.asarray(t, dtype=float) + 1.0) * 0.5
    if scale == "log":
        return np.clip(lo * (hi / lo) ** u, lo, hi)
    return lo + u * (hi - lo)


def polynomial_A(model: LpvModel, pairs: list[tuple[float, float]]) -> NDArray[np.float64] | None:
    """``A(p)`` as a polynomial in ``t`` (the range mapped onto [-1, 1]), when it is one.

    Exactly polynomial for an LTI model and for :class:`lpvid.Polynomial`
    and :class:`lpvid.Legendre` bases of one scheduling parameter (both
    polynomials of ``p``, or of ``log10(p)`` on the log scale, after an
    affine map; ``t`` is mapped onto the range by :func:`to_p` on the same
    scale); None otherwise. The
    coefficients come from the model's own values at Chebyshev points and
    are checked at other points.

    Returns
    -------
    ndarray, shape (d + 1, n, n) or None
        ``A(p) = sum_k coef[k] t^k``; trailing zero coefficients dropped.
    """
    if model.n_basis == 0:
        return model.A[:1].copy()
    basis = model.basis
    if len(pairs) != 1 or not isinstance(basis, (Polynomial, Legendre)):
        return None
    d = int(basis.degree)
    scale = basis.scales[0]
    t = np.cos(np.pi * (np.arange(d + 1) + 0.5) / (d + 1))
    values = frozen_A(model, to_p(t, pairs[0], scale)[:, None])
    V = np.polynomial.polynomial.polyvander(t, d)
    n = model.n_states
    coef = np.linalg.solve(V, values.reshape(d + 1, -1)).reshape(d + 1, n, n)
    check = np.linspace(-1.0, 1.0, 7)
    direct = frozen_A(model, to_p(check, pairs[0], scale)[:, None])
    again = np.tensordot(np.polynomial.polynomial.polyvander(check, d), coef, axes=1)
    if np.max(np.abs(again - direct)) > 1e-8 * max(1.0, float(np.max(np.abs(direct)))):
        return None
    norms = np.array([np.max(np.abs(c)) for c in coef])
    top = float(norms.max()) if norms.size else 0.0
    keep = int(np.nonzero(norms > 1e-14 * max(top, 1e-300))[0].max(initial=0)) + 1
    return coef[:keep]
