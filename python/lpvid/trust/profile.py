"""A covariance's band checked beyond first order: each leading direction profiled in V_NLS.

The first-order band of a covariance ``C`` says that a change of
``theta`` by ``t`` standard deviations along a direction raises V_NLS by
``t^2 / 2`` (``C = (J^T J)^+ / 2``, V_NLS a sum of squares of residuals
of variance 1/2). Where the points see a direction barely, the step of
one standard deviation is large, and V_NLS rises much faster than that:
on the synthetic system at five points (``benches/bench_band.py``) the
step that moves the FRF between the points most raised V_NLS by 1e11
instead of 0.5, and the band there was ten or more times the actual
error. So each leading direction of the band is checked:

- **Leading directions.** With ``C = S S^T`` on the free parameters and
  ``W`` the mean over the range of the relative FRF's sensitivity
  (:func:`lpvid.trust.relative.target`, on the grid of
  :func:`lpvid.trust.silent.range_grid`), the eigenvectors ``z`` of
  ``S^T W S`` in order of their variance over the range; ``d = S z`` is a
  step of one standard deviation, and ``a^T theta`` with ``a = S^+T z`` the
  quantity it moves. The directions are taken until they hold
  :data:`TOP` of the band's variance over the range, at most :data:`MOST`.
- **The profile.** At ``theta + t d``, V_NLS is minimised over every
  change that keeps ``a^T theta`` (Levenberg-Marquardt steps, at most
  :data:`STEPS`, until a step gains less than :data:`SETTLED`); its rise
  above the same minimisation at ``t = 0`` (the model need not sit at
  V_NLS's least: a path entry does not; a model where Gauss-Newton
  predicts less than :data:`SETTLED` to gain, a refitted one, is taken to
  sit there) is the profile.
- **The reach** along ``+d`` and ``-d``. First order holds when the even
  part of V_NLS's rise at ``t = 1.96``, nothing else moved (the mean of
  the two signs' rises: the part of the gradient, where the model is not
  at V_NLS's least, cancels), is at most :data:`HOLDS` times
  ``chi2_1(0.95) / 2`` (:data:`LEVEL`, the 95 % bound of one direction):
  a margin, since under first order it is exactly :data:`LEVEL`. Then the
  direction keeps its band; so it does when the profile at ``t = 1.96``
  of either sign rises by at most that. Otherwise ``t`` runs up from
  ``1.96 / 2^HALVINGS``, doubling, each profile started from the last
  one's end, and the reach is the geometric middle of the last ``t`` whose
  profile stays at or below :data:`LEVEL` and the first beyond
  (:data:`HOLDS` times it at 1.96); the first ``t`` when none stays below. The larger
  reach of the two signs, over 1.96, scales the band along ``d``: a factor
  in ``(0, 1]``, a power of two times ``sqrt(2)`` but for 1 and the
  smallest.

The check leaves the band's other directions as they are and never widens
it; it is what V_NLS says along the directions that set the band, not a
new covariance. Cost: two evaluations of V_NLS per direction where first
order holds; elsewhere a profile at ``t = 0`` and one per ``t`` of the
climb (up to :data:`STEPS` Gauss-Newton evaluations and solves of the free
parameters' size each, a few where the climb's warm start is close).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from lpvid._threads import single_blas
from lpvid.data.frf import FrfData
from lpvid.fit.cost import build_problem
from lpvid.trust.relative import GridParts, target
from lpvid.trust.silent import _sym, range_grid
from lpvid.trust.uncertainty import Covariance, _lti_index

__all__ = ["BandCheck", "checked_band"]

#: The rise of V_NLS at the 95 % bound of one direction: chi2_1(0.95) / 2.
LEVEL = 1.920729410347062
#: The 95 % bound of one direction in standard deviations.
Z95 = 1.959963984540054
#: First order holds along a direction while its profile at ``Z95`` is at
#: most this many times :data:`LEVEL`.
HOLDS = 2.0
#: Share of the band's variance over the range that the leading directions hold.
TOP = 0.95
#: Most leading directions checked.
MOST = 10
#: Most Levenberg-Marquardt steps of one profile.
STEPS = 30
#: Most halvings of ``t`` along one direction and sign.
HALVINGS = 14
#: A profile has settled when a step lowers V_NLS by less than this (a
#: thousandth of :data:`LEVEL`).
SETTLED = 1e-3 * LEVEL


@dataclass(frozen=True)
class BandCheck:
    """What :func:`checked_band` found along the band's leading directions.

    Attributes
    ----------
    scales : ndarray, shape (k,)
        The factor on the band's standard deviation along each leading
        direction, in ``(0, 1]`` (1: first order holds there).
    shares : ndarray, shape (k,)
        Each direction's share of the band's variance over the range.
    steps : ndarray, shape (k, P)
        The step of one first-order standard deviation along each direction
        (``d`` of the module notes, in the layout of ``model.theta``).
    evaluations : int
        Evaluations of V_NLS or its Gauss-Newton pieces made.
    """

    scales: NDArray[np.float64]
    shares: NDArray[np.float64]
    steps: NDArray[np.float64] = field(repr=False)
    evaluations: int = 0

    def describe(self) -> str:
        """One line for people."""
        narrowed = self.scales < 1.0
        if not np.any(narrowed):
            return f"first order holds along the band's {len(self.scales)} leading direction(s)"
        held = float(np.sum(self.shares[narrowed]))
        return (
            f"V_NLS rises faster than first order along {int(np.sum(narrowed))} of the band's "
            f"{len(self.scales)} leading direction(s) ({held:.0%} of its variance over the "
            f"range): the band there is narrowed to where V_NLS allows, by factors "
            f"{np.min(self.scales):.2g} to {np.max(self.scales[narrowed]):.2g}"
        )


class _Profile:
    """V_NLS near a model, minimised with one linear quantity held."""

    def __init__(self, covariance: Covariance, data: FrfData, free: NDArray[np.bool_]) -> None:
        self.problem = build_problem(covariance.model, data)
        self.theta = covariance.model.theta
        self.free = free
        self.evaluations = 0
        v0, g, h = self._gauss_newton(np.zeros(int(free.sum())))
        self.v0 = v0
        # V_NLS's least on the free parameters is within SETTLED of the model's when
        # Gauss-Newton's predicted decrease g^T h^+ g / 4 is (a refitted model)
        gain = 0.25 * _pinv_form(h, g)
        self.at_least = gain <= SETTLED

    def _at(self, step: NDArray) -> NDArray:
        """``theta`` with ``step`` added to its free parameters."""
        theta = self.theta.copy()
        theta[self.free] += step
        return theta

    def fixed(self, d: NDArray, t: float) -> float:
        """The rise of V_NLS at ``theta + t d``, nothing else moved."""
        self.evaluations += 1
        return float(self.problem.vnls(self._at(t * d))) - self.v0

    def rise(
        self, d: NDArray, a: NDArray, t: float, start: NDArray, low: float = -math.inf
    ) -> tuple[float, NDArray]:
        """The profile at ``theta + t d`` holding ``a^T theta``, from ``theta + t d + start``.

        Ends when the rise is at or below ``low``, when a step lowers V_NLS
        by less than :data:`SETTLED` or none lowers it, or after
        :data:`STEPS` steps. Returns the rise and the offset reached
        (orthogonal to ``a``).
        """
        offset = start.copy()
        v, g, h = self._gauss_newton(t * d + offset)
        an = a / np.linalg.norm(a)
        hold = np.eye(an.size) - np.outer(an, an)
        pin = np.outer(an, an) * float(np.max(np.diag(h)))
        lam = 1e-3
        for _ in range(STEPS):
            if v - self.v0 <= low or lam > 1e12:
                break
            A = hold @ h @ hold + pin
            A += lam * np.diag(np.maximum(np.diag(A), np.finfo(float).tiny))
            try:
                step = hold @ np.linalg.solve(A, -(hold @ g) / 2.0)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            vt, gt, ht = self._gauss_newton(t * d + offset + step)
            if vt < v:
                offset, lam = offset + step, lam * 0.3
                settled = v - vt <= SETTLED
                v, g, h = vt, gt, ht
                if settled:
                    break
            else:
                lam *= 10.0
        return v - self.v0, offset

    def _gauss_newton(self, step: NDArray) -> tuple[float, NDArray, NDArray]:
        self.evaluations += 1
        v, g, h = self.problem.gauss_newton(self._at(step), self.free)
        return float(v), g, h.reshape(g.size, g.size)


def _pinv_form(h: NDArray, g: NDArray, rcond: float = 1e-12) -> float:
    """``g^T h^+ g`` for a symmetric ``h``, singular values below ``rcond`` times the largest cut.

    By least squares; where LAPACK's least squares gives up (OpenBLAS's
    divide-and-conquer SVD did on a finite symmetric 320 x 320 ``h`` of
    ``one_group_lpv`` at three points), by the symmetric eigendecomposition,
    whose eigenvalues' magnitudes are the singular values.
    """
    try:
        return float(g @ np.linalg.lstsq(h, g, rcond=rcond)[0])
    except np.linalg.LinAlgError:
        lam, V = np.linalg.eigh(_sym(h))
        keep = np.abs(lam) > rcond * float(np.max(np.abs(lam), initial=0.0))
        z = V[:, keep].T @ g
        return float(np.sum(z * z / lam[keep]))


def _scale(profile: _Profile, d: NDArray, a: NDArray) -> float:
    """The factor on the band along ``d``: the larger reach of ``+d`` and ``-d`` over 1.96."""
    # the even part of the rise, nothing else moved (the gradient's part, where the
    # model is not at V_NLS's least, cancels): first order says LEVEL
    if 0.5 * (profile.fixed(d, Z95) + profile.fixed(-d, Z95)) <= HOLDS * LEVEL:
        return 1.0
    # the profile's least value, the reference of its rise (the model need
    # not be at V_NLS's least: a path entry is not)
    least, start = 0.0, np.zeros(d.size)
    if not profile.at_least:
        least, start = profile.rise(d, a, 0.0, start)
    bound = least + HOLDS * LEVEL
    for step in (d, -d):
        if profile.rise(step, a, Z95, start, low=bound)[0] <= bound:
            return 1.0  # the profile holds first order's bound, within the margin
    return max(_climb(profile, d, a, least, start), _climb(profile, -d, a, least, start)) / Z95


def _climb(profile: _Profile, d: NDArray, a: NDArray, least: float, start: NDArray) -> float:
    """The reach along ``d`` (module notes): ``t`` doubled up to 1.96, each profile warm-started."""
    offset, inside = start, 0.0
    for k in range(HALVINGS, -1, -1):
        t = Z95 * 2.0**-k
        bound = least + (HOLDS if k == 0 else 1.0) * LEVEL
        r, offset = profile.rise(d, a, t, offset, low=bound)
        if r > bound:
            return inside * math.sqrt(2.0) if inside else t
        inside = t
    return Z95


@single_blas
def checked_band(
    covariance: Covariance, data: FrfData, held: NDArray[np.bool_]
) -> tuple[Covariance, BandCheck]:
    """The covariance with its band checked along its leading directions (module notes).

    Parameters
    ----------
    covariance : Covariance
        A first-order covariance of ``covariance.model`` (for instance the
        band of :attr:`lpvid.pipeline.between.Between.band`), zero outside
        the free parameters.
    data : FrfData
        The data the model was fitted to.
    held : ndarray of bool, shape (P,)
        The parameters the fit held (fixed, and the dropped groups').

    Returns
    -------
    Covariance
        The same but for its matrix: the band along each leading direction
        scaled by :attr:`BandCheck.scales`.
    BandCheck
    """
    model = covariance.model
    free = ~np.asarray(held, dtype=bool)
    C = covariance.theta[np.ix_(free, free)]
    lam, U = np.linalg.eigh(_sym(C))
    keep = lam > (lam[-1] if lam.size else 0.0) * 1e-13
    nothing = BandCheck(np.zeros(0), np.zeros(0), np.zeros((0, free.size)), 0)
    if not np.any(keep):
        return covariance, nothing
    S, S_plus = U[:, keep] * np.sqrt(lam[keep]), U[:, keep] / np.sqrt(lam[keep])
    parts = GridParts(model, data.freqs_hz, range_grid(model, data))
    W = target(parts, _lti_index(model))[np.ix_(free, free)]
    var, Z = np.linalg.eigh(_sym(S.T @ W @ S))
    var, Z = np.maximum(var[::-1], 0.0), Z[:, ::-1]
    total = float(np.sum(var))
    if total <= 0.0:
        return covariance, nothing
    k = min(MOST, int(np.searchsorted(np.cumsum(var) / total, TOP)) + 1)
    profile = _Profile(covariance, data, free)
    D, A = S @ Z[:, :k], S_plus @ Z[:, :k]  # the steps d and the quantities a, by column
    scales = np.array([_scale(profile, D[:, j], A[:, j]) for j in range(k)])
    steps = np.zeros((k, free.size))
    steps[:, free] = D.T
    check = BandCheck(scales, var[:k] / total, steps, profile.evaluations)
    narrowed = scales < 1.0
    if not np.any(narrowed):
        return covariance, check
    # C = S Z Z^T S^T: take out (1 - scale^2) of each narrowed direction's part
    Dn = D[:, narrowed]
    full = covariance.theta.copy()
    full[np.ix_(free, free)] = _sym(C - (Dn * (1.0 - scales[narrowed] ** 2)) @ Dn.T)
    return replace(covariance, theta=full), check
