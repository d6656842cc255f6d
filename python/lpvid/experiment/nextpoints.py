"""Where to measure next: the scheduling values whose FRF would shrink the model's bands most.

**Criterion.** The quantity to shrink is the model's predicted relative
FRF variance averaged over the scheduling range,

    U = mean over p in the range of E||dG(p)||^2 / ||G_m(p)||^2,

``||.||`` the Frobenius norm over every frequency line, output and input
(the square of what :func:`lpvid.testing.worst_relative_error` measures
against a truth), ``E||dG(p)||^2`` from the parameter covariance ``C`` of
the returned model (:attr:`lpvid.IdentifyResult.covariance`, first order,
as :meth:`lpvid.Covariance.frf_std`). ``U`` is ``tr(C W)`` with ``W`` the
mean over the range of the sensitivity of the relative FRF to theta.

One more FRF at ``p_c`` on the data's lines, with standard deviation
``sigma_c``, adds ``H_c = J_c^T J_c`` (its sigma-weighted Jacobian, real
and imaginary parts) to the information ``J^T J``; the covariance becomes
``C' = C - C J_c^T (I/2 + J_c C J_c^T)^-1 J_c C`` (``C = (J^T J)^+ / 2``:
Woodbury's identity), and the candidate that lowers ``U`` most is
suggested. ``J_c`` factors through the frozen model at ``p_c``
(``J_c = J_lti(p_c) (w(p_c)^T (x) I)``, ``w = [1, psi(p_c)]``), so each
candidate costs a solve of the size of one frozen model's parameters.
``k > 1`` points are chosen greedily: each chosen point updates ``C``
before the next is chosen (a point is never suggested twice).

**Ties.** Candidates whose predicted ``U`` lies within
:data:`lpvid.experiment.design.TIE` (0.1 %) of the lowest promise the same;
the one farthest from every measured (and already chosen) point is taken.

**Candidates.** By default a grid over the range (the model's basis
domain, else the data's range): 101 values for one parameter, 21 per
parameter for two, 9 for three, 5 beyond, evenly on the basis's scale of
every parameter (in ``log10(p)`` on the log scale); ``U`` is averaged on
the same grid. Candidates outside the range are refused (the basis extrapolates
there); measured values are left out (one FRF per scheduling value), and
repeated candidates count once.

**The new measurement's noise.** ``sigma_c`` is by default the data's
sigma at the measured point nearest ``p_c`` (each scheduling parameter
scaled to its range, on the basis's scale), or what the caller gives.

**What it cannot see, and the committee that can.** ``C`` is the
covariance of the model on its support (dropped groups held at zero) on
the directions the data determine: directions the measured points leave
open (:mod:`lpvid.trust.silent`) count as known here. When the points
leave the model's structure open, :func:`lpvid.identify` keeps the other
fits within the noise (:attr:`lpvid.IdentifyResult.between`), and where
they disagree is where the data are silent. Then the criterion is the
*committee's*: ``s(p) = ||spread(p)|| / ||G_m(p)||``, the relative spread
of :meth:`lpvid.pipeline.between.Between.spread` over the grid (the
committee's: the models :func:`lpvid.resampled` adds say how far off the
model is, not where to measure, and are left out here), and a
measurement at ``c`` is taken to settle it around ``c``: ``s(p)`` becomes
``s(p) min(1, |p - c| / h)``, ``h`` the spacing the points will have (the
range over ``N + k``, every parameter scaled to its range on its scale). The candidate
that lowers the grid mean of ``s^2`` most is suggested (a narrow spike of
one member counts for little, a wide disagreement for much), ``k > 1``
greedily, each settling its neighbourhood before the next; ties as
below. ``band`` is ``s`` over the grid, ``band_after`` what the settling
leaves, ``variance`` the mean of ``s^2`` before and after each point.

Why not the resampled models: this run's fits within the noise are
hypotheses the measured data allow, and a measurement where they disagree
tells them apart; the resampled models are what runs on data simulated
from the returned model give, centred on it. Measured with the loop of
``benches/bench_plan.py`` (``--resample 5`` against without, the same
draws; ``docs/fewpoints.md``): points added to reach a worst error of 0.01,
0.95 against 1.15 on the synthetic system (20 draws) but 2.30 (36 of 40
met) against 1.95 (39 of 40) on ``one_group_lpv``: over the 60 draws the
committee's placement needed fewer points in 14, the resampled spread's in
10, and the committee's costs no runs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_int, real_array
from lpvid._rows import unique_rows
from lpvid._threads import single_blas
from lpvid.data.frf import FrfData
from lpvid.data.schedule import range_fraction, range_pairs, scale_grid
from lpvid.experiment.design import TIE, factor, greedy_update
from lpvid.fit.judge import identify_range
from lpvid.pipeline.result import IdentifyResult
from lpvid.trust.relative import GridParts, relative_band, target
from lpvid.trust.uncertainty import (
    Covariance,
    _lti_index,
    band_radius,
    coefficient_weights,
    frozen_grams,
)

__all__ = ["Suggestion", "next_points", "suggest_points"]

#: Slack, relative to the range, for candidates on its edge and for
#: candidates at a measured point.
_SLACK = 1e-9
#: The scale of every scheduling parameter (``Basis.scales``), None for linear on every one.
Scales = tuple[str, ...] | None


@dataclass(frozen=True, eq=False)
class Suggestion:
    """Where :func:`suggest_points` suggests measuring next, and what it predicts.

    Attributes
    ----------
    points : ndarray, shape (k,) or (k, Np)
        The suggested scheduling values, in the order chosen.
    measured : ndarray, shape (N,) or (N, Np)
        The scheduling values of the identification data.
    grid : ndarray, shape (Q,) or (Q, Np)
        Scheduling values over the range at which the band is averaged.
    band : ndarray, shape (Q,)
        The relative 95 % band at ``grid`` now:
        ``band_radius(0.95) * sqrt(E||dG||^2) / ||G_m||`` (Frobenius norms
        over every line, output and input).
    band_after : ndarray, shape (Q,)
        The same, predicted once every suggested point is measured.
    variance : ndarray, shape (k + 1,)
        The criterion (the mean over ``grid`` of ``E||dG||^2 / ||G_m||^2``)
        now and after each suggested point.
    p_range : tuple or list of tuple
        The scheduling range (the model's, else the data's).
    criterion : str
        ``"covariance"`` (the bands' reduction) or ``"committee"`` (where
        the fits within the noise disagree most; module notes).
    """

    points: NDArray[np.float64]
    measured: NDArray[np.float64]
    grid: NDArray[np.float64]
    band: NDArray[np.float64]
    band_after: NDArray[np.float64]
    variance: NDArray[np.float64]
    p_range: Any
    criterion: str = "covariance"

    def summary(self) -> str:
        """One line per suggested point with the predicted RMS band over the range."""
        committee = self.criterion == "committee"
        radius = 1.0 if committee else band_radius(0.95)
        rms = radius * np.sqrt(np.maximum(self.variance, 0.0))
        what = (
            ", where the fits within the noise disagree most (RMS relative spread"
            if committee
            else " (RMS relative 95 % band"
        )
        lines = [
            f"where to measure next{what} over the range now {rms[0]:.3g}; "
            f"the largest {np.max(self.band):.3g})"
        ]
        pts = self.points.reshape(len(self.points), -1)
        name = "spread" if committee else "band"
        for k, p in enumerate(pts):
            where = ", ".join(f"{x:.6g}" for x in p)
            lines.append(f"  {k + 1}. p = {where}: RMS {name} -> {rms[k + 1]:.3g}")
        return "\n".join(lines)


def _range_grid(pairs: list[tuple[float, float]], scales: Scales = None) -> NDArray[np.float64]:
    """The default grid over the range, shape (Q, Np).

    101 values for one parameter, 21 per parameter for two, 9 for three, 5
    beyond; evenly on every parameter's scale (``scales``, default linear).
    """
    return scale_grid(pairs, {1: 101, 2: 21, 3: 9}.get(len(pairs), 5), scales)


def _unmeasured(
    cands: NDArray[np.float64],
    measured: NDArray[np.float64],
    pairs: list[tuple[float, float]],
    scales: Scales = None,
) -> NDArray[np.float64]:
    """The candidates (M, Np) that are not measured scheduling values (within the slack)."""
    at, seen = range_fraction(cands, pairs, scales), range_fraction(measured, pairs, scales)
    near = np.abs(at[:, None, :] - seen[None, :, :])
    return cands[~np.any(np.all(near <= _SLACK, axis=2), axis=1)]


def default_candidates(p_range: Any, measured: ArrayLike) -> NDArray[np.float64]:
    """The candidates :func:`suggest_points` takes by default: (M, Np).

    The grid over ``p_range`` (101 values for one parameter, 21 per
    parameter for two, 9 for three, 5 beyond) less the ``measured``
    scheduling values.
    """
    pairs = range_pairs(p_range)
    rows = real_array(measured, "measured", ndim=(1, 2)).reshape(-1, len(pairs))
    return _unmeasured(_range_grid(pairs), rows, pairs)


def _candidates(value: Any, pairs: list[tuple[float, float]]) -> NDArray[np.float64]:
    """Candidates as (M, Np), checked to lie in the range."""
    n_params = len(pairs)
    arr = real_array(value, "candidates", ndim=(0, 1, 2))
    if n_params == 1:
        if arr.ndim == 2 and arr.shape[1] != 1:
            raise ValueError(
                f"candidates: expected shape (M,) or (M, 1) for one scheduling parameter, "
                f"got {arr.shape}"
            )
        arr = arr.reshape(-1, 1)
    elif arr.ndim != 2 or arr.shape[1] != n_params:
        raise ValueError(
            f"candidates: expected shape (M, {n_params}) for {n_params} scheduling "
            f"parameters, got {arr.shape}"
        )
    if arr.shape[0] == 0:
        raise ValueError("candidates: expected at least one scheduling value, got none")
    s = range_fraction(arr, pairs)
    outside = np.any((s < -_SLACK) | (s > 1 + _SLACK), axis=1)
    if np.any(outside):
        bad = arr[outside]
        shown = "; ".join(", ".join(f"{x:g}" for x in row) for row in bad[:5])
        more = f" and {len(bad) - 5} more" if len(bad) > 5 else ""
        rng = ", ".join(f"({lo:g}, {hi:g})" for lo, hi in pairs)
        raise ValueError(
            f"candidates: {len(bad)} value(s) outside the scheduling range {rng}, where the "
            f"model is an extrapolation nobody fitted: {shown}{more}"
        )
    _, first, _ = unique_rows(arr)
    return arr[np.sort(first)]


def _noise(
    data: FrfData, candidates: NDArray, pairs: list, sigma: Any, scales: Scales = None
) -> NDArray[np.float64]:
    """The standard deviation of a measurement at every candidate: (M, F, l, r)."""
    shape = data.G.shape[1:]
    if sigma is not None:
        s = real_array(sigma, "sigma")
        try:
            s = np.broadcast_to(s, shape)
        except ValueError as exc:
            raise ValueError(
                f"sigma: expected a value or an array broadcastable to (F, l, r) = {shape}, "
                f"got shape {s.shape}"
            ) from exc
        if np.any(s <= 0):
            raise ValueError("sigma: standard deviations must be > 0 everywhere")
        return np.broadcast_to(s, (len(candidates), *shape))
    measured = range_fraction(data.p_rows, pairs, scales)
    at = range_fraction(candidates, pairs, scales)
    nearest = np.argmin(((at[:, None, :] - measured[None, :, :]) ** 2).sum(axis=2), axis=1)
    return data.sigma[nearest]


def _covariance_of(result: Any) -> Covariance:
    if not isinstance(result, IdentifyResult):
        raise TypeError(
            f"result: expected the IdentifyResult of lpvid.identify, got {type(result).__name__}"
        )
    cov = result.covariance
    if cov is None:
        raise ValueError(
            "result: has no parameter covariance (result.covariance is None), and the "
            "suggestion is computed from it; lpvid.identify sets it for the model it returns"
        )
    if not isinstance(cov, Covariance):
        raise TypeError(
            f"result.covariance: expected an lpvid.Covariance, got {type(cov).__name__}"
        )
    return cov


@single_blas
def suggest_points(
    result: IdentifyResult, candidates: ArrayLike | None = None, k: int = 1, *, sigma: Any = None
) -> Suggestion:
    """The scheduling values where one more FRF would shrink the model's bands most, and why.

    See the module notes (:mod:`lpvid.experiment.nextpoints`) for the criterion:
    the relative FRF variance averaged over the scheduling range, after a
    low-rank update of the parameter covariance with each candidate's
    information; ``k > 1`` points greedily.

    Parameters
    ----------
    result : IdentifyResult
        From :func:`lpvid.identify` (its :attr:`~lpvid.IdentifyResult.covariance`
        and data are used).
    candidates : array_like, shape (M,) or (M, Np), optional
        Scheduling values to choose from, inside the range (the model's,
        else the data's); a value outside is an error. Default: a grid over
        the range, 101 values for one parameter, 21 per parameter for two,
        9 for three, 5 beyond (the grid the band is averaged on). Measured
        values are left out (one FRF per scheduling value).
    k : int
        Points to suggest.
    sigma : float or array_like broadcastable to (F, l, r), optional
        Standard deviation of the new measurement on the data's lines.
        Default: the data's sigma at the measured point nearest each
        candidate (every parameter scaled to its range).

    Returns
    -------
    Suggestion

    Raises
    ------
    TypeError, ValueError
        For a result without covariance, candidates of the wrong shape or
        outside the range, ``k`` larger than the candidates not measured yet.
    """
    cov = _covariance_of(result)
    k = positive_int(k, "k")
    model, data = cov.model, result.data
    n_params = model.basis.n_params
    pairs = range_pairs(identify_range(model, data), n_params)
    scales = model.basis.scales
    grid = _range_grid(pairs, scales)
    cands = grid if candidates is None else _candidates(candidates, pairs)
    cands = _unmeasured(cands, data.p_rows, pairs, scales)
    if len(cands) < k:
        raise ValueError(
            f"k: {k} point(s) asked for, but only {len(cands)} candidate(s) are not measured yet"
        )
    between = getattr(result, "between", None)
    if between is not None and between.members:
        return _by_committee(result, _placing(between), cands, grid, pairs, scales, k)
    index = _lti_index(model)
    f = data.freqs_hz
    parts = GridParts(model, f, grid)
    W = target(parts, index)
    R = factor(frozen_grams(model, f, cands, 1.0 / _noise(data, cands, pairs, sigma, scales) ** 2))
    picks, variance, after = greedy_update(
        cov.theta,
        W,
        index,
        coefficient_weights(model, cands),
        R,
        k,
        range_fraction(cands, pairs, scales),
        range_fraction(data.p_rows, pairs, scales),
    )
    points = cands[picks]
    return Suggestion(
        points=points[:, 0] if n_params == 1 else points,
        measured=data.p.copy(),
        grid=grid[:, 0] if n_params == 1 else grid,
        band=relative_band(cov.theta, parts, index),
        band_after=relative_band(after, parts, index),
        variance=variance,
        p_range=pairs[0] if n_params == 1 else pairs,
    )


def _placing(between: Any) -> Any:
    """What the committee's criterion follows: ``between`` less resampled models (module notes)."""
    return replace(between, resampled=[])


def _by_committee(
    result: IdentifyResult,
    between: Any,
    cands: NDArray,
    grid: NDArray,
    pairs: list,
    scales: Scales,
    k: int,
) -> Suggestion:
    """The committee's criterion (module notes)."""
    data = result.data
    f = data.freqs_hz
    measured = range_fraction(data.p_rows, pairs, scales)
    h = 1.0 / (data.n_points + k)
    at, on_grid = range_fraction(cands, pairs, scales), range_fraction(grid, pairs, scales)
    band = between.relative_spread(f, grid)
    gap = np.min(np.linalg.norm(at[:, None, :] - measured[None, :, :], axis=2), axis=1)
    # a measurement at a candidate settles the spread around it, to zero at the candidate
    settle = np.minimum(1.0, np.linalg.norm(at[:, None, :] - on_grid[None, :, :], axis=2) / h)
    after = band.copy()
    picks: list[int] = []
    variance = [float(np.mean(band**2))]
    for _ in range(k):
        gain = np.sum((1.0 - settle**2) * after[None, :] ** 2, axis=1)
        gain[picks] = -np.inf
        best = float(gain.max())
        tied = np.flatnonzero(gain >= best - TIE * abs(best))
        c = int(tied[np.argmax(gap[tied])])
        picks.append(c)
        gap = np.minimum(gap, np.linalg.norm(at - at[c], axis=1))
        after = after * settle[c]
        variance.append(float(np.mean(after**2)))
    points = cands[picks]
    one = len(pairs) == 1
    return Suggestion(
        points=points[:, 0] if one else points,
        measured=data.p.copy(),
        grid=grid[:, 0] if one else grid,
        band=band,
        band_after=after,
        variance=np.array(variance),
        p_range=pairs[0] if one else pairs,
        criterion="committee",
    )


@single_blas
def next_points(
    result: IdentifyResult, candidates: ArrayLike | None = None, k: int = 1, *, sigma: Any = None
) -> NDArray[np.float64]:
    """The scheduling values where one more FRF measurement would shrink the model's bands most.

    ``suggest_points(result, candidates, k, sigma=sigma).points``: see
    :func:`suggest_points` for the arguments and :mod:`lpvid.experiment.nextpoints`
    for the criterion.

    Returns
    -------
    ndarray, shape (k,) or (k, Np)
        In the order chosen (the first is the best single point).

    Examples
    --------
    >>> import numpy as np, lpvid, lpvid.testing
    >>> true = lpvid.testing.one_group_lpv(0, n=2)
    >>> f = np.linspace(5, 60, 40)
    >>> data = lpvid.testing.noisy_data(true, [0.0, 0.3, 0.6, 1.0], f,
    ...                                 np.random.default_rng(0), 0.01)
    >>> result = lpvid.identify(data, 2, true.basis, fixed={"D": True})
    >>> lpvid.next_points(result, k=2).shape
    (2,)

    """
    return suggest_points(result, candidates, k, sigma=sigma).points
