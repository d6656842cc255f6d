"""Stability of every frozen model over the whole scheduling range, and quadratic stability.

**Frozen stability on the continuum.** The margin of a frozen model
(:func:`lpvid.model.frozen.stability_margin`: ``1 - max |lambda|`` in discrete
time, the smallest ``-Re lambda / |lambda|`` in continuous time) is a
continuous function of ``p``; stability can only change where a pole
touches the boundary. For ``A(p)`` polynomial in one parameter (LTI models,
:class:`lpvid.Polynomial` and :class:`lpvid.Legendre` bases) these places
are found exactly: a pole lies on the boundary only where
``det(A(p) (x) A(p) - I) = 0`` (discrete time: ``lambda_i lambda_j = 1``)
or ``det(A(p) (x) I + I (x) A(p)) = 0`` (continuous time: ``lambda_i +
lambda_j = 0``), a polynomial eigenvalue problem in ``p`` whose real roots
in the range are computed (the guardian map of Saydy, Tits and Abed). The
margin is then evaluated at these roots, between every two of them and on
a grid, so that a window of instability, however narrow, is found (up to
the accuracy of the computed roots); on a basis's log scale the same holds
in ``log10(p)`` (:func:`lpvid.stable.ranges.to_p`). Otherwise (several parameters, other
bases, or a pencil too large) the margin is evaluated on a fine grid; the
smallest local minima are refined in both cases (Brent's method in one
dimension, Nelder-Mead in several) for ``.margin`` and ``.worst_p``.

**Quadratic stability** (a common Lyapunov matrix over the range, for any
variation of the scheduling): :mod:`lpvid.stable.lyapunov` for one
parameter, :mod:`lpvid.stable.rates` (a sum of squares on the box) for
several. **A bounded rate** (``rate=True``: the largest ``|dp_k/dt|``
certified with a parameter-dependent ``P(p)``, continuous time):
:mod:`lpvid.stable.rates`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._minimise import minimise_bounded
from lpvid._problemlike import ProblemLike
from lpvid._threads import single_blas
from lpvid.model.frozen import frozen_poles, stability_margin
from lpvid.model.lpv import LpvModel
from lpvid.stable.lyapunov import LyapunovCertificate
from lpvid.stable.multi import model_quadratic
from lpvid.stable.ranges import as_convention, box_grid, check_range, polynomial_A, to_p
from lpvid.stable.rates import RateCertificate, report_rate

__all__ = ["StabilityReport", "format_p", "margins", "stability"]

#: Largest companion pencil (rows) of the exact crossing test; larger models use the grid.
MAX_PENCIL = 1200
#: Grid points of the grid method (one parameter; about as many for several).
GRID_POINTS = 2001
#: Local minima of the sampled margin refined.
REFINED = 5


@dataclass
class StabilityReport:
    """Outcome of :func:`lpvid.stability`.

    Attributes
    ----------
    stable : bool
        Every frozen model on the range is stable (margin > 0).
    margin : float
        Smallest stability margin over the range: discrete time ``1 -``
        spectral radius, continuous time the smallest ``-Re lambda /
        |lambda|`` (negative where unstable).
    worst_p : float or ndarray
        Where it is reached (an array of Np values for several parameters).
    p_range : tuple or list of tuple
        The range checked.
    discrete : bool
        Discrete-time model.
    method : str
        ``"crossings"`` (exact: the places where a pole can touch the
        boundary were computed) or ``"grid"`` (a fine grid with refinement).
    crossings : ndarray
        Scheduling values where a pole may touch the stability boundary
        (``"crossings"`` only; may contain points where two poles merely
        satisfy the same equation).
    n_checked : int
        Frozen models evaluated.
    quadratic : bool or None
        A common quadratic Lyapunov function exists over the range (True,
        with ``certificate``), does not (False), or was not decided (None;
        ``note`` says why).
    certificate : LyapunovCertificate or None
        The Lyapunov matrix and its certified bound.
    note : str
        What the quadratic test found, in words.
    seconds : float
        Time taken.
    rate : ndarray or None
        The largest rate bounds ``nu_k`` (``|dp_k/dt| <= nu_k``, shape (Np,),
        model time units) for which a parameter-dependent Lyapunov function
        was certified (:func:`lpvid.max_rate`, to its ``rel_tol``); ``inf``
        when ``quadratic`` is True (any rate); None when not asked or not
        certified (``rate_note`` says why).
    rate_certificate : RateCertificate or None
        The certificate at ``rate`` (None when ``rate`` is ``inf``: then
        ``certificate`` holds for every rate).
    rate_note : str
        What the rate test found, in words (empty when not asked).
    """

    stable: bool
    margin: float
    worst_p: Any
    p_range: Any
    discrete: bool
    method: str
    crossings: NDArray[np.float64]
    n_checked: int
    quadratic: bool | None
    certificate: LyapunovCertificate | None
    note: str
    seconds: float = field(default=0.0)
    rate: NDArray[np.float64] | None = None
    rate_certificate: RateCertificate | None = None
    rate_note: str = ""

    def summary(self) -> str:
        """One sentence on frozen stability, one on quadratic stability."""
        kind = "1 - spectral radius" if self.discrete else "smallest -Re(pole)/|pole|"
        where = format_p(self.worst_p)
        how = (
            "exact crossing test" if self.method == "crossings" else "grid with refinement"
        ) + f", {self.n_checked} frozen models"
        state = "stable" if self.stable else "NOT stable"
        if self.n_checked == 1:
            first = (
                f"the model does not depend on p and is {state}: margin {self.margin:.3g} ({kind})"
            )
            return f"{first}\n{self.note}"
        first = (
            f"frozen models {state} over p in {_fmt_range(self.p_range)}: smallest margin "
            f"{self.margin:.3g} ({kind}) at p = {where} ({how})"
        )
        rate = f"\nbounded rate: {self.rate_note}" if self.rate_note else ""
        return f"{first}\n{self.note}{rate}"

    def __str__(self) -> str:
        return self.summary()


def format_p(p: Any) -> str:
    """A scheduling value for messages: ``0.5`` or ``(0.1, 2)``."""
    arr = np.atleast_1d(np.asarray(p, dtype=float))
    return f"{arr[0]:.6g}" if arr.size == 1 else "(" + ", ".join(f"{v:.4g}" for v in arr) + ")"


def _fmt_range(rng: Any) -> str:
    pairs = [rng] if isinstance(rng, tuple) else rng
    if all(lo == hi for lo, hi in pairs):
        return "(" + ", ".join(f"{lo:g}" for lo, _ in pairs) + ")"
    return " x ".join(f"[{lo:g}, {hi:g}]" for lo, hi in pairs)


def margins(model: LpvModel, p: Any) -> NDArray[np.float64]:
    """Stability margin of the frozen models at every scheduling value, shape (M,)."""
    return stability_margin(frozen_poles(model, p), model.Ts)


def _symmetric_part(n: int) -> NDArray[np.float64]:
    """Orthonormal rows spanning ``vec`` of the symmetric n x n matrices, shape (n(n+1)/2, n^2)."""
    i, j = np.triu_indices(n)
    Q = np.zeros((i.size, n * n))
    k = np.arange(i.size)
    w = np.where(i == j, 1.0, np.sqrt(0.5))
    Q[k, i + j * n] = w
    Q[k, j + i * n] = w
    return Q


def _guardian(coef: NDArray[np.float64], discrete: bool) -> list[NDArray[np.float64]]:
    """Coefficients of the guardian matrix polynomial of ``A(t)`` (module notes).

    ``A (x) A - I`` (discrete time) or ``A (x) I + I (x) A`` (continuous
    time), restricted to the symmetric matrices (an invariant subspace on
    which the eigenvalues are ``lambda_i lambda_j`` or ``lambda_i +
    lambda_j`` for ``i <= j``), which halves the size.
    """
    n = coef.shape[1]
    d = coef.shape[0] - 1
    Q = _symmetric_part(n)
    eye = np.eye(n)
    if discrete:
        L = [np.zeros((Q.shape[0], Q.shape[0])) for _ in range(2 * d + 1)]
        for i in range(d + 1):
            for j in range(d + 1):
                L[i + j] += Q @ np.kron(coef[i], coef[j]) @ Q.T
        L[0] -= np.eye(Q.shape[0])
    else:
        L = [Q @ (np.kron(c, eye) + np.kron(eye, c)) @ Q.T for c in coef]
    while len(L) > 1 and not np.any(L[-1]):
        L.pop()
    return L


def _crossings(coef: NDArray[np.float64], discrete: bool) -> NDArray[np.float64] | None:
    """Real roots in [-1, 1] of ``det`` of the guardian polynomial; None when too large.

    The polynomial eigenvalue problem is shifted to the point ``t0`` of
    {0, -0.5, 0.5} where the guardian matrix is best conditioned and
    reversed (``t = t0 + 1 / mu``), so that a standard eigenvalue problem
    of the companion matrix gives every root; with no well-conditioned
    shift, the generalised problem is solved.
    """
    from math import comb

    L = _guardian(coef, discrete)
    D, m = len(L) - 1, L[0].shape[0]
    if D == 0:
        return np.zeros(0)
    if m * D > MAX_PENCIL:
        return None
    scale = max(float(np.max(np.abs(x))) for x in L)
    stack = np.array(L) / scale
    best = None
    for t0 in (0.0, -0.5, 0.5):
        # Taylor coefficients at t0: M_j = sum_k comb(k, j) t0^(k - j) L_k.
        T = np.array(
            [
                [comb(k, j) * t0 ** (k - j) if k >= j else 0.0 for k in range(D + 1)]
                for j in range(D + 1)
            ]
        )
        M = np.tensordot(T, stack, axes=1)
        cond = np.linalg.cond(M[0])
        if best is None or cond < best[0]:
            best = (cond, t0, M)
    cond, t0, M = best
    with np.errstate(all="ignore"):
        if cond < 1e10:
            # mu^D P(t0 + 1/mu) = sum_j M_j mu^(D - j): monic after M_0^-1.
            C = np.linalg.solve(M[0], np.hstack(list(M[1:])))
            comp = np.zeros((m * D, m * D))
            comp[:m, :] = -C
            comp[m:, :-m] = np.eye(m * (D - 1))
            mu = np.linalg.eigvals(comp)
            mu = mu[np.abs(mu) > 1e-300]
            ev = t0 + 1.0 / mu
        else:
            from scipy.linalg import eigvals

            comp = np.zeros((m * D, m * D))
            comp[:-m, m:] = np.eye(m * (D - 1))
            comp[-m:, :] = -np.hstack(list(stack[:D]))
            rhs = np.eye(m * D)
            rhs[-m:, -m:] = stack[D]
            ev = eigvals(comp, rhs)
    ev = ev[np.isfinite(ev)]
    near = (np.abs(ev.imag) <= 1e-3 * (1.0 + np.abs(ev))) & (np.abs(ev.real) <= 1.0 + 1e-9)
    return np.unique(np.clip(ev.real[near], -1.0, 1.0))


def _refine_1d(model: LpvModel, ps: NDArray, ms: NDArray) -> tuple[float, float, int]:
    """Brent's method around the smallest local minima of the sampled margin."""
    order = np.argsort(ps)
    ps, ms = ps[order], ms[order]
    k = int(np.argmin(ms))
    best_p, best_m = float(ps[k]), float(ms[k])
    if ps.size < 3:
        return best_p, best_m, 0
    inner = (ms[1:-1] <= ms[:-2]) & (ms[1:-1] <= ms[2:])
    ends = [0] if ms[0] <= ms[1] else []
    ends += [ps.size - 1] if ms[-1] <= ms[-2] else []
    minima = np.concatenate([ends, np.nonzero(inner)[0] + 1])
    minima = minima.astype(int)
    minima = minima[np.argsort(ms[minima])][:REFINED]
    span = float(ps[-1] - ps[0])
    evals = 0

    def f(x: float) -> float:
        return float(margins(model, [x])[0])

    for i in minima:
        a, b = float(ps[max(i - 1, 0)]), float(ps[min(i + 1, ps.size - 1)])
        if b <= a:
            continue
        x, fx, used = minimise_bounded(f, a, b, xatol=1e-12 * span)
        evals += used
        if fx < best_m:
            best_p, best_m = x, fx
    return best_p, best_m, evals


def _refine_nd(
    model: LpvModel, pts: NDArray, ms: NDArray, pairs: list[tuple[float, float]]
) -> tuple[NDArray, float, int]:
    """Nelder-Mead (within the box) from the grid points with the smallest margins."""
    from scipy.optimize import minimize

    k = int(np.argmin(ms))
    best_p, best_m = pts[k].copy(), float(ms[k])
    evals = 0
    for i in np.argsort(ms)[:REFINED]:
        res = minimize(
            lambda x: float(margins(model, x[None, :])[0]),
            pts[i],
            method="Nelder-Mead",
            bounds=pairs,
            options={"xatol": 1e-10, "fatol": 1e-14, "maxfev": 400},
        )
        evals += int(res.nfev)
        if res.fun < best_m:
            best_p, best_m = np.asarray(res.x, dtype=float), float(res.fun)
    return best_p, best_m, evals


@single_blas
def stability(
    model: LpvModel,
    p_range: Any = None,
    *,
    quadratic: bool = True,
    rate: bool | str = False,
    rate_degree: int = 2,
) -> StabilityReport:
    """Stability of every frozen model over the whole scheduling range, and quadratic stability.

    See the notes of :mod:`lpvid.stable.scan` for how the continuum is
    covered and of :mod:`lpvid.stable.lyapunov` for what the quadratic
    certificate states.

    Parameters
    ----------
    model : LpvModel
    p_range : (lo, hi) or sequence of (lo, hi), or Problem, optional
        The range; default the model's (its basis domain). It must lie
        inside the basis domain. A :class:`lpvid.Problem`: its range.
    quadratic : bool
        Also look for a common quadratic Lyapunov function (a semidefinite
        program; needs the clarabel package, ``pip install "lpvid[lmi]"``).
    rate : bool or "small"
        Also find the largest rate of variation certified with a
        parameter-dependent ``P(p)`` (:func:`lpvid.max_rate`; continuous
        time; about ten programs). Skipped (``rate = inf``) when the model is
        quadratically stable. ``"small"``: only when one program's memory
        estimate is at most :data:`lpvid.stable.rates.SMALL_RATE_BYTES` (seconds, not minutes;
        the report's choice), else ``rate_note`` says how to ask.
    rate_degree : int
        Total degree of ``P(p)`` in the mapped parameters for ``rate``.

    Returns
    -------
    StabilityReport

    Raises
    ------
    ValueError
        When there is no range, or it reaches outside the basis domain.

    Examples
    --------
    >>> import lpvid
    >>> basis = lpvid.Polynomial(1, domain=(0.0, 1.0))   # psi_1 = s = 2 p - 1
    >>> m = lpvid.LpvModel([[[0.5]], [[0.45]]], [[[1.0]], [[0.0]]], [[[1.0]], [[0.0]]],
    ...                    basis=basis, Ts=1.0)
    >>> rep = lpvid.stability(m, quadratic=False)
    >>> rep.stable, round(rep.margin, 6), round(rep.worst_p, 6)
    (True, 0.05, 1.0)

    """
    t0 = time.perf_counter()
    if rate not in (True, False, "small"):
        raise ValueError(f'rate: expected True, False or "small", got {rate!r}')
    if isinstance(p_range, ProblemLike):
        p_range = p_range.p_range
    pairs = check_range(model, p_range)
    discrete = model.Ts is not None
    coef = polynomial_A(model, pairs)
    crossings = np.zeros(0)
    method = "grid"
    scales = model.basis.scales
    if len(pairs) == 1:
        roots = None if coef is None else _crossings(coef, discrete)
        if roots is not None:
            method = "crossings"
            knots = np.unique(np.concatenate([[-1.0, 1.0], roots]))
            mids = 0.5 * (knots[:-1] + knots[1:])
            ts = np.unique(np.concatenate([np.linspace(-1.0, 1.0, 201), roots, mids]))
            crossings = to_p(roots, pairs[0], scales[0])
        else:
            ts = np.linspace(-1.0, 1.0, GRID_POINTS)
        if pairs[0][0] == pairs[0][1]:  # an LTI model: one frozen model
            ts = np.zeros(1)
        ps = to_p(ts, pairs[0], scales[0])
        ms = margins(model, ps[:, None])
        worst, margin, extra = _refine_1d(model, ps, ms)
        worst_p: Any = worst
        checked = ps.size + extra
    else:
        pts = box_grid(pairs, GRID_POINTS, scales)
        ms = margins(model, pts)
        worst_p, margin, extra = _refine_nd(model, pts, ms, pairs)
        checked = pts.shape[0] + extra
    stable = bool(margin > 0) and bool(np.all(ms > 0))
    if not quadratic:
        q, cert, note = None, None, "quadratic stability: not asked (quadratic=False)"
    elif not stable:
        q, cert, note = (
            False,
            None,
            (f"not quadratically stable: the frozen model at p = {format_p(worst_p)} is unstable"),
        )
    else:
        q, cert, note = model_quadratic(model, pairs, coef, discrete)
    nu, rate_cert, rate_note = report_rate(model, pairs, stable, q, rate, rate_degree, worst_p)
    return StabilityReport(
        stable=stable,
        margin=float(margin),
        worst_p=worst_p,
        p_range=as_convention(pairs),
        discrete=discrete,
        method=method,
        crossings=crossings,
        n_checked=int(checked),
        quadratic=q,
        certificate=cert,
        note=note,
        seconds=time.perf_counter() - t0,
        rate=nu,
        rate_certificate=rate_cert,
        rate_note=rate_note,
    )
