"""A parameter-dependent Lyapunov function for a bounded rate of variation.

**A bounded rate** (:func:`rate_stability`, continuous time): ``V(x, p) =
x^T P(p) x`` with ``P`` a polynomial of total degree ``degree`` in the mapped
parameters ``t_k = 2 (p_k - lo_k) / (hi_k - lo_k) - 1`` and ``|dp_k/dt| <=
nu_k``: by the chain rule ``dt_k/dt = 2 v_k / (hi_k - lo_k)``, and

    A(p)^T P(p) + P(p) A(p) + sum_k dP/dt_k 2 v_k / (hi_k - lo_k) < 0

for every ``p`` in the box and every ``v`` at the ``2^Np`` vertices of the
rate box (the expression is affine in ``v``, so the vertices cover the
box), with ``P(p) > 0``: ``V`` decreases along every trajectory whose
scheduling stays in the box with those rates, and the model is
exponentially stable for them. Certified as above (``mu`` and ``mu_P`` from
the recomputed identities). A failure is None, never False: ``P`` of a
higher degree, or a Lyapunov function of another form, may exist; False
only when a frozen model is unstable (a constant scheduling is a trajectory
for every rate). At ``nu -> 0`` the condition asks for every frozen model
to be stable with a ``P(p)`` of that degree; at large ``nu`` it forces
``dP/dp`` towards 0, the quadratic certificate.

**A basis on the log scale** maps ``log10(p_k)``, so ``dt_k/dp_k = 2 /
((log10 hi_k - log10 lo_k) p_k ln 10)`` varies over the box: the program
takes its largest value, at ``p_k = lo_k``, for the rate of ``t_k`` (a
certificate for a larger rate box in ``t``, so it holds; it may miss rates
that only the upper part of the range could bear).

**Discrete time is refused.** ``V(x_{k+1}) < V(x_k)`` involves ``P`` at
``p_{k+1}`` and at ``p_k``, a polynomial in ``2 Np`` variables with the
next value constrained both to the rate box and to the box: a larger
program of another shape, not built here (ValueError).

:func:`max_rate` finds the largest certified scale ``s`` of ``nu = s w`` by
bisection on a geometric scale to a relative tolerance ``rel_tol``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._threads import single_blas
from lpvid.data.schedule import range_fraction
from lpvid.model.frozen import frozen_poles, stability_margin
from lpvid.model.lpv import LpvModel
from lpvid.stable.boxsos import Exp, program_size, solve_box
from lpvid.stable.lyapunov import KAPPA
from lpvid.stable.multi import _at, _scaled, polynomial_terms
from lpvid.stable.ranges import as_convention, box_grid, check_range

__all__ = [
    "SMALL_RATE_BYTES",
    "RateBound",
    "RateCertificate",
    "max_rate",
    "rate_stability",
    "report_rate",
]

#: ``stability(..., rate="small")``: the largest memory estimate of one program computed.
SMALL_RATE_BYTES = 64 * 2**20


@dataclass(frozen=True)
class RateCertificate:
    """A parameter-dependent Lyapunov function for a bounded rate, and its check.

    ``V(x, p) = x^T P(p) x``, ``P(p) = sum_b P_b t^b`` with ``t`` the
    parameters mapped onto ``[-1, 1]`` (module notes of :mod:`lpvid.stable.rates`).

    Attributes
    ----------
    P : dict
        ``P_b`` per exponent tuple ``b`` (one entry per parameter).
    p_range : list of (lo, hi)
        The box.
    rate : ndarray, shape (Np,)
        The rate bounds ``nu_k`` certified (``|dp_k/dt| <= nu_k``, model time units).
    mu : float
        Certified ``-(A^T P + P A + sum_k dP/dp_k v_k) >= mu I`` on the box, every
        rate in the rate box (model units).
    mu_p : float
        Certified ``P(p) >= mu_p I`` on the box.
    eps : float
        The solver's ``eps`` (model units).
    residual : float
        Largest ``sum_a ||R_a||`` of the identities, recomputed (program units).
    degree : int
        Total degree of ``P`` in the mapped parameters.
    kappa : float
        Bound on ``P``'s coefficients searched.
    scales : tuple of str
        The basis's scale of every parameter (empty: linear): ``t_k`` maps
        ``log10(p_k)`` on the log scale, where the program takes the
        largest ``|dt_k/dp_k|`` over the box (at ``lo_k``) for the rate.
    """

    P: dict[Exp, NDArray[np.float64]]
    p_range: list[tuple[float, float]]
    rate: NDArray[np.float64]
    mu: float
    mu_p: float
    eps: float
    residual: float
    degree: int
    kappa: float
    scales: tuple[str, ...] = ()

    def _scales(self) -> tuple[str, ...]:
        return self.scales or ("linear",) * len(self.p_range)

    def _t(self, p: Any) -> NDArray[np.float64]:
        """``p`` mapped to [-1, 1] on every parameter's scale (the program's variables)."""
        row = np.atleast_1d(np.asarray(p, dtype=float))[None, :]
        return 2.0 * range_fraction(row, self.p_range, self._scales())[0] - 1.0

    def P_at(self, p: Any) -> NDArray[np.float64]:
        """``P(p)`` at one scheduling value (``Np`` numbers)."""
        return _at(self.P, self._t(p))

    def dP_at(self, p: Any) -> NDArray[np.float64]:
        """``dP/dp_k`` at one scheduling value, shape (Np, n, n) (chain rule included)."""
        t = self._t(p)
        dt = _dt_dp(self.p_range, self._scales(), np.atleast_1d(np.asarray(p, dtype=float)))
        n = next(iter(self.P.values())).shape[0]
        out = np.zeros((len(self.p_range), n, n))
        for k in range(len(self.p_range)):
            for b, Pb in self.P.items():
                if b[k] > 0:
                    e = np.array(b) - np.eye(len(b), dtype=int)[k]
                    out[k] += b[k] * float(np.prod(t**e)) * Pb * dt[k]
        return out

    def inequality(self, A: NDArray[np.float64], p: Any, v: Any) -> NDArray[np.float64]:
        """``-(A^T P + P A + sum_k dP/dp_k v_k)`` at ``p``, rate ``v``: ``>= mu I`` if certified."""
        P = self.P_at(p)
        dP = np.tensordot(np.atleast_1d(np.asarray(v, dtype=float)), self.dP_at(p), axes=1)
        return -(A.T @ P + P @ A + dP)


def _dt_dp(
    pairs: list[tuple[float, float]], scales: tuple[str, ...], p: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``dt_k/dp_k`` at ``p`` (one value per parameter): the chain rule of the map to [-1, 1].

    ``2 / (hi - lo)`` on the linear scale, ``2 / ((log10 hi - log10 lo) p ln 10)``
    on the log scale (largest at ``p = lo``, where :func:`_rate_program`
    takes it for the whole box); 0 for a range of one value.
    """
    out = np.zeros(len(pairs))
    for k, ((lo, hi), scale) in enumerate(zip(pairs, scales, strict=True)):
        if hi == lo:
            continue
        if scale == "log":
            out[k] = 2.0 / (np.log10(hi / lo) * np.log(10.0) * p[k])
        else:
            out[k] = 2.0 / (hi - lo)
    return out


def _rate_case(
    model: LpvModel, p_range: Any, rate: Any
) -> tuple[list[tuple[float, float]], dict[Exp, NDArray] | None, NDArray]:
    if not isinstance(model, LpvModel):
        raise TypeError(f"model: expected an LpvModel, got {type(model).__name__}")
    if model.Ts is not None:
        raise ValueError(
            "model: the rate certificate is for continuous-time models; in discrete time "
            "V(x_{k+1}) involves P at p_{k+1} and p_k (a program in 2 Np variables with the next "
            "value inside the box), which lpvid does not build: use the quadratic certificate"
        )
    pairs = check_range(model, p_range)
    nu = np.atleast_1d(np.asarray(rate, dtype=float))
    if nu.shape == (1,):
        nu = np.full(len(pairs), nu[0])
    if nu.shape != (len(pairs),) or not np.all(np.isfinite(nu)) or np.any(nu < 0):
        raise ValueError(
            f"rate: expected {len(pairs)} finite bound(s) >= 0 on |dp_k/dt|, got {rate!r}"
        )
    return pairs, polynomial_terms(model, pairs), nu


def _rate_program(
    A: dict[Exp, NDArray],
    pairs: list[tuple[float, float]],
    nu: NDArray,
    degree: int,
    kappa: float,
    extra: int,
    scales: tuple[str, ...],
) -> tuple[bool | None, RateCertificate | None, str]:
    As, scale = _scaled(A, False)
    # the rate of every mapped parameter, |dt_k/dt| <= nu_k max |dt_k/dp_k| over the box
    r = nu * _dt_dp(pairs, scales, np.array([lo for lo, _ in pairs]))
    cases = [
        (As, r * np.array(s) / scale) for s in itertools.product((-1.0, 1.0), repeat=len(pairs))
    ]
    sol = solve_box(cases, len(pairs), degree, False, kappa, extra, "the rate certificate")
    if isinstance(sol, str):
        return None, None, f"not decided: {sol}"
    cert = RateCertificate(
        P=sol.P,
        p_range=list(pairs),
        rate=nu.copy(),
        mu=sol.mu * scale,
        mu_p=sol.mu_p,
        eps=sol.eps * scale,
        residual=sol.residual,
        degree=degree,
        kappa=float(kappa),
        scales=tuple(scales),
    )
    if sol.mu > 0 and sol.mu_p > 0:
        return (
            True,
            cert,
            (
                f"certified for |dp/dt| <= {_fmt(nu)}: P(p) of degree {degree} with P(p) >= "
                f"{sol.mu_p:.3g} I and -(A^T P + P A + dP/dt) >= {cert.mu:.3g} I on the box"
            ),
        )
    return (
        None,
        cert,
        (
            f"not decided for |dp/dt| <= {_fmt(nu)}: no P(p) of degree {degree} found (certified "
            f"bound {cert.mu:.3g}; a relaxation: a higher degree or another V may succeed)"
        ),
    )


def _fmt(nu: NDArray) -> str:
    return f"{nu[0]:.4g}" if nu.size == 1 else "(" + ", ".join(f"{v:.4g}" for v in nu) + ")"


@single_blas
def rate_stability(
    model: LpvModel,
    rate: Any,
    p_range: Any = None,
    *,
    degree: int = 2,
    extra: int = 0,
    kappa: float = KAPPA,
) -> tuple[bool | None, RateCertificate | None, str]:
    """Stability for every scheduling in the box moving at ``|dp_k/dt| <= rate[k]`` (module notes).

    Parameters
    ----------
    model : LpvModel
        A continuous-time model whose ``A(p)`` is polynomial (LTI,
        :class:`lpvid.Polynomial`, :class:`lpvid.Legendre`).
    rate : float or sequence of float
        ``nu_k >= 0`` per parameter (one number: the same for every
        parameter), in the parameter's units per model time unit.
    p_range : (lo, hi) or sequence of (lo, hi), optional
        The box; default the model's.
    degree : int
        Total degree of ``P(p)`` in the mapped parameters.
    extra : int
        Degrees added to the sums of squares.
    kappa : float
        Bound on ``P``'s coefficients.

    Returns
    -------
    certified : bool or None
        True (certified), False (a frozen model is unstable) or None (not decided).
    certificate : RateCertificate or None
    note : str

    Raises
    ------
    ValueError
        For a discrete-time model (module notes), a range outside the basis
        domain, or rates that are not finite numbers ``>= 0``, one per parameter.
    MemoryError
        When the program cannot fit (:mod:`lpvid.stable.boxsos`).
    """
    pairs, A, nu = _rate_case(model, p_range, rate)
    _degree_arg(degree, extra)
    if A is None:
        return None, None, "not decided: the rate certificate needs A(p) polynomial in p"
    unstable = _frozen_unstable(model, pairs)
    if unstable:
        return False, None, unstable
    return _rate_program(A, pairs, nu, degree, kappa, extra, model.basis.scales)


def _frozen_unstable(model: LpvModel, pairs: list[tuple[float, float]]) -> str | None:
    """A frozen model of a grid of the box that is unstable (a proof for every rate), or None."""
    grid = box_grid(pairs, 401)
    ms = stability_margin(frozen_poles(model, grid), model.Ts)
    if np.min(ms) > 0:
        return None
    where = _fmt(grid[int(np.argmin(ms))])
    return f"not stable for any rate: the frozen model at p = {where} is unstable"


def _degree_arg(degree: int, extra: int) -> None:
    if not isinstance(degree, (int, np.integer)) or isinstance(degree, bool) or degree < 0:
        raise ValueError(f"degree: expected an integer >= 0, got {degree!r}")
    if not isinstance(extra, (int, np.integer)) or isinstance(extra, bool) or extra < 0:
        raise ValueError(f"extra: expected an integer >= 0, got {extra!r}")


@dataclass(frozen=True)
class RateBound:
    """Outcome of :func:`max_rate`.

    Attributes
    ----------
    rate : ndarray or None
        The largest rate bounds certified, ``nu_k = s w_k`` (shape (Np,)); None
        when not even the slowest rate tried was certified.
    certificate : RateCertificate or None
        The certificate at ``rate``.
    rel_tol : float
        ``s (1 + rel_tol)`` was not certified (or ``rate`` is the largest tried).
    solves : int
        Programs solved.
    note : str
        What was found, in words.
    """

    rate: NDArray[np.float64] | None
    certificate: RateCertificate | None
    rel_tol: float
    solves: int
    note: str


@single_blas
def max_rate(
    model: LpvModel,
    p_range: Any = None,
    *,
    direction: Any = None,
    degree: int = 2,
    rel_tol: float = 0.05,
    extra: int = 0,
    kappa: float = KAPPA,
) -> RateBound:
    """The largest rate bound certified by :func:`rate_stability`, by bisection.

    Parameters
    ----------
    model : LpvModel
    p_range : (lo, hi) or sequence of (lo, hi), optional
    direction : sequence of float, optional
        ``w_k > 0``: the bounds are ``nu_k = s w_k``; default ``hi_k - lo_k``
        (``s`` ranges per time unit).
    degree, extra, kappa
        As :func:`rate_stability`.
    rel_tol : float
        The bisection stops when the certified ``s`` and the refused one are
        within a factor ``1 + rel_tol``.

    Returns
    -------
    RateBound

    Raises
    ------
    ValueError
        As :func:`rate_stability`, and for a ``direction`` or ``rel_tol`` that are not positive.
    """
    n_params = len(check_range(model, p_range))
    pairs, A, _ = _rate_case(model, p_range, [0.0] * n_params)
    _degree_arg(degree, extra)
    if not (isinstance(rel_tol, (int, float)) and 1e-6 <= float(rel_tol) <= 10):
        raise ValueError(f"rel_tol: expected a number in [1e-6, 10], got {rel_tol!r}")
    w = (
        np.array([hi - lo for lo, hi in pairs])
        if direction is None
        else np.atleast_1d(np.asarray(direction, dtype=float))
    )
    if w.shape != (len(pairs),) or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ValueError(
            f"direction: expected {len(pairs)} finite number(s) > 0, got {direction!r}"
        )
    if A is None:
        return RateBound(None, None, rel_tol, 0, "not decided: A(p) is not polynomial in p")
    unstable = _frozen_unstable(model, pairs)
    if unstable:
        return RateBound(None, None, rel_tol, 0, unstable)
    scale = max(float(np.linalg.norm(a, 2)) for a in A.values()) / max(float(np.max(w)), 1e-300)
    solves = 0
    best: tuple[float, RateCertificate] | None = None
    refused: float | None = None

    def attempt(s: float) -> bool:
        nonlocal solves, best, refused
        solves += 1
        ok, cert, _ = _rate_program(A, pairs, s * w, degree, kappa, extra, model.basis.scales)
        if ok:
            if best is None or s > best[0]:
                best = (s, cert)
            return True
        refused = s if refused is None else min(refused, s)
        return False

    s = 0.5 * scale
    low, high = 1e-6 * scale, 1e4 * scale
    if attempt(s):
        while s < high and attempt(s * 4.0):
            s *= 4.0
    else:
        while s > low and not attempt(s / 4.0):
            s /= 4.0
    if best is None:
        return RateBound(
            None,
            None,
            rel_tol,
            solves,
            (f"no rate certified down to |dp/dt| <= {_fmt(low * w)} with P(p) of degree {degree}"),
        )
    while refused is not None and refused > best[0] * (1.0 + rel_tol):
        attempt(float(np.sqrt(best[0] * refused)))
    s_best, cert = best
    if refused is None:
        note = f"certified up to |dp/dt| <= {_fmt(s_best * w)}, the largest rate tried"
    else:
        note = (
            f"certified for |dp/dt| <= {_fmt(s_best * w)} (P(p) of degree {degree}); "
            f"{_fmt(refused * w)} was not (bisection to a factor {1 + rel_tol:g})"
        )
    return RateBound(s_best * w, cert, float(rel_tol), solves, note)


def report_rate(
    model: LpvModel,
    pairs: list[tuple[float, float]],
    stable: bool,
    q: bool | None,
    asked: bool | str,
    degree: int,
    worst_p: Any,
) -> tuple[NDArray[np.float64] | None, RateCertificate | None, str]:
    """The bounded-rate part of :func:`lpvid.stability` (``rate=True`` or ``"small"``)."""
    worst = np.atleast_1d(np.asarray(worst_p, dtype=float))
    if not asked:
        return None, None, ""
    if model.Ts is not None:
        return (
            None,
            None,
            (
                "not certified: the rate certificate is for continuous-time models "
                "(lpvid.stable.rates: discrete time is not built)"
            ),
        )
    if not stable:
        return (
            None,
            None,
            (f"not stable for any rate: the frozen model at p = {_fmt(worst)} is unstable"),
        )
    if q is True:
        return np.full(len(pairs), np.inf), None, "any rate (quadratically stable)"
    if asked == "small":
        terms = polynomial_terms(model, pairs)
        deg_a = 0 if terms is None else max(sum(e) for e in terms)
        size = program_size(model.n_states, len(pairs), deg_a, degree, False)
        if size["bytes"] > SMALL_RATE_BYTES:
            return (
                None,
                None,
                (
                    f"not computed here (one program of about {size['bytes'] / 2**20:.0f} MiB, "
                    f"blocks up to {max(size['blocks'])}: minutes); lpvid.max_rate(model) "
                    "computes it"
                ),
            )
    try:
        found = max_rate(model, as_convention(pairs), degree=degree)
    except MemoryError as exc:
        return None, None, f"not decided: {exc}"
    return found.rate, found.certificate, found.note
