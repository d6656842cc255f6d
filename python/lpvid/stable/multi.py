"""Quadratic stability on a box of several scheduling parameters.

**Several parameters, any rate** (:func:`box_quadratic`): a common ``P``
with ``I <= P <= kappa I`` and ``F(t) > 0`` on the mapped box ``[-1, 1]^Np``
as a matrix sum of squares (:mod:`lpvid.stable.boxsos`), the same inequality
and standard as :mod:`lpvid.stable.lyapunov` (one parameter). True is
certified from the recomputed identity. False is a proof: the best ``eps``
of the common ``P`` at the points of a grid of the box (a program with fewer
conditions than the box's, so its optimum is at least the box's) is
negative beyond the solver's accuracy: no ``P`` with ``I <= P <= kappa I``
exists. Otherwise (the sum of squares is a relaxation for ``Np > 1``) None.

The program and its check, its size and what a sum of squares may miss:
:mod:`lpvid.stable.boxsos`.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.data.basis import Legendre, Polynomial
from lpvid.model.frozen import frozen_A
from lpvid.model.lpv import LpvModel
from lpvid.stable.boxsos import Exp, monomials, solve_box
from lpvid.stable.lyapunov import (
    _EPS_TOL,
    KAPPA,
    NO_CLARABEL,
    LyapunovCertificate,
    quadratic_stability,
)
from lpvid.stable.ranges import box_grid, polynomial_A, to_p

#: Points of the grid whose program can prove that no common P exists (several parameters).
GRID_FALSE = 64

__all__ = ["GRID_FALSE", "box_quadratic", "model_quadratic", "polynomial_terms"]


def polynomial_terms(
    model: LpvModel, pairs: list[tuple[float, float]]
) -> dict[Exp, NDArray[np.float64]] | None:
    """``A(p)`` as ``{exponent: A_g}`` in the mapped ``t`` (several parameters), or None.

    Exact for LTI models and :class:`lpvid.Polynomial`, :class:`lpvid.Legendre`
    bases; fitted from the model's values on a tensor grid of Chebyshev points
    and checked at other points.
    """
    n_params = len(pairs)
    if n_params == 1:
        coef = polynomial_A(model, pairs)
        return None if coef is None else {(k,): c for k, c in enumerate(coef)}
    if model.n_basis == 0:
        return {(0,) * n_params: model.A[0].copy()}
    if not isinstance(model.basis, (Polynomial, Legendre)):
        return None
    d = int(model.basis.degree)
    scales = model.basis.scales  # A is polynomial in t on every parameter's scale (to_p)
    exps = monomials(d, n_params)
    nodes = np.cos(np.pi * (np.arange(d + 1) + 0.5) / (d + 1))
    t = np.array(list(itertools.product(nodes, repeat=n_params)))
    rng = np.random.default_rng(0)
    check = rng.uniform(-1.0, 1.0, (7, n_params))

    def values(tt: NDArray) -> NDArray:
        p = np.stack([to_p(tt[:, k], pairs[k], scales[k]) for k in range(n_params)])
        return frozen_A(model, p.T)

    def vander(tt: NDArray) -> NDArray:
        return np.stack([np.prod(tt ** np.array(e), axis=1) for e in exps], axis=1)

    n = model.n_states
    coef = np.linalg.lstsq(vander(t), values(t).reshape(len(t), -1), rcond=None)[0]
    direct = values(check)
    again = (vander(check) @ coef).reshape(direct.shape)
    if np.max(np.abs(again - direct)) > 1e-8 * max(1.0, float(np.max(np.abs(direct)))):
        return None
    coef = coef.reshape(len(exps), n, n)
    top = max(float(np.max(np.abs(c))) for c in coef)
    return {e: c for e, c in zip(exps, coef, strict=True) if np.max(np.abs(c)) > 1e-14 * top} or {
        exps[0]: coef[0]
    }


def _at(A: dict[Exp, NDArray[np.float64]], t: NDArray[np.float64]) -> NDArray[np.float64]:
    """``A(t)`` at one point of the mapped box."""
    return sum(a * float(np.prod(np.asarray(t) ** np.array(e))) for e, a in A.items())


def _scaled(A: dict[Exp, NDArray], discrete: bool) -> tuple[dict[Exp, NDArray], float]:
    if discrete:
        return A, 1.0
    scale = max(max(float(np.linalg.norm(a, 2)) for a in A.values()), 1e-300)
    return {e: a / scale for e, a in A.items()}, scale


def box_quadratic(
    A: dict[Exp, NDArray[np.float64]],
    discrete: bool,
    kappa: float = KAPPA,
    extra: int = 0,
) -> tuple[bool | None, LyapunovCertificate | None, str]:
    """Quadratic stability of ``A(t)`` on ``[-1, 1]^Np`` (module notes).

    Parameters
    ----------
    A : dict
        ``A_g`` per exponent tuple (``Np`` entries).
    discrete : bool
    kappa : float
        Bound on the condition number of ``P``.
    extra : int
        Degrees added to the sums of squares (a tighter relaxation, a larger program).

    Returns
    -------
    quadratic : bool or None
    certificate : LyapunovCertificate or None
    note : str

    Raises
    ------
    MemoryError
        When the program cannot fit (:mod:`lpvid.stable.boxsos`).
    """
    n_params = len(next(iter(A)))
    if n_params == 1:
        d = max(e[0] for e in A)
        coef = np.array([A.get((k,), np.zeros_like(next(iter(A.values())))) for k in range(d + 1)])
        return quadratic_stability(coef, discrete, kappa)
    try:
        import clarabel  # noqa: F401
    except ImportError:
        return None, None, NO_CLARABEL
    As, scale = _scaled(A, discrete)
    zero = np.zeros(n_params)
    sol = solve_box([(As, zero)], n_params, 0, discrete, kappa, extra, "quadratic stability")
    if isinstance(sol, str):
        return None, None, f"not decided: {sol}"
    P = next(iter(sol.P.values()))
    d = max(sum(e) for e in A)
    cert = LyapunovCertificate(
        P=P,
        mu=sol.mu * scale,
        eps=sol.eps * scale,
        residual=sol.residual * scale,
        degree=d,
        discrete=discrete,
        kappa=float(kappa),
    )
    if sol.mu > 0 and sol.mu_p > 0:
        return (
            True,
            cert,
            (
                f"quadratically stable: a Lyapunov matrix P with I <= P <= {kappa:g} I and "
                f"F(p) >= {cert.mu:.3g} I on the whole box of {n_params} parameters "
                f"(certified from the recomputed sum-of-squares identity, A(p) of degree {d})"
            ),
        )
    # A proof of False: no common P even at the points of a grid of the box.
    grid = box_grid([(-1.0, 1.0)] * n_params, GRID_FALSE)
    zero_e = (0,) * n_params
    cases = [({zero_e: _at(As, t)}, zero) for t in grid]
    at = solve_box(cases, n_params, 0, discrete, kappa, 0, "quadratic stability (grid)")
    size = float(np.linalg.norm(P, 2)) * (
        1.0 + sum(float(np.linalg.norm(a, 2)) for a in As.values())
    )
    if not isinstance(at, str) and at.status == "Solved" and at.eps < -_EPS_TOL * size:
        return (
            False,
            cert,
            (
                f"not quadratically stable: no Lyapunov matrix with I <= P <= {kappa:g} I makes "
                f"F(p) positive even at the {len(grid)} points of a grid of the box (best eps "
                f"there {at.eps * scale:.3g})"
            ),
        )
    return (
        None,
        None,
        (
            f"quadratic stability not decided: the sum of squares on the box of {n_params} "
            f"parameters (a relaxation) gives the bound {sol.mu * scale:.3g}, and a common P "
            "exists at the grid's points"
        ),
    )


def model_quadratic(
    model: LpvModel, pairs: list[tuple[float, float]], coef: Any, discrete: bool
) -> tuple[bool | None, LyapunovCertificate | None, str]:
    """The quadratic certificate: exact for one parameter, a sum of squares for several."""
    if len(pairs) == 1 and coef is not None:
        return quadratic_stability(coef, discrete)
    terms = None if len(pairs) == 1 else polynomial_terms(model, pairs)
    if terms is None:
        return (
            None,
            None,
            (
                "quadratic stability not decided: the LMI certificate covers polynomial "
                "dependence (Polynomial, Legendre bases)"
            ),
        )
    try:
        return box_quadratic(terms, discrete)
    except MemoryError as exc:
        return None, None, f"quadratic stability not decided: {exc}"
