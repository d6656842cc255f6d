"""Are the local models on one branch? A diagnosis along the scheduling axes.

:func:`consistency` computes it; its result, :class:`Consistency`, is
defined in :mod:`lpvid.initial.localmodels` (a :class:`LocalModels` carries
one) and re-exported here.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_float, positive_int
from lpvid._rows import unique_rows
from lpvid._threads import single_blas
from lpvid.data.schedule import unit_scaled
from lpvid.initial.localmodels import Consistency, local_p, lti_models
from lpvid.initial.poles import describe_pole, is_real, match_poles, pole_coordinates

__all__ = ["Consistency", "consistency"]

Arr = NDArray[np.float64]


def _neighbours(s: Arr, k: int) -> list[tuple[int, int]]:
    """Unique pairs joining every point to its k nearest points."""
    dist = np.linalg.norm(s[:, None, :] - s[None, :, :], axis=2)
    np.fill_diagonal(dist, np.inf)
    pairs = set()
    for q in range(s.shape[0]):
        for m in np.argsort(dist[q], kind="stable")[:k]:
            pairs.add((min(q, int(m)), max(q, int(m))))
    return sorted(pairs)


@single_blas
def consistency(
    local_models: Any,
    p: ArrayLike | None = None,
    *,
    threshold: float = 3.0,
    min_distance: float = 0.2,
    neighbours: int | None = None,
) -> Consistency:
    """Diagnose how consistent local LTI models are along the scheduling axes.

    Parameters
    ----------
    local_models : LocalModels or sequence of LpvModel
        LTI models (Nb = 0) of one order, e.g. from :func:`lpvid.identify_lti`.
    p : array_like, shape (N,) or (N, Np), optional
        Scheduling values; default ``local_models.p``.
    threshold : float
        Score (rate relative to the median rate) above which a point is
        flagged.
    min_distance : float
        Smallest worst-pole distance worth flagging, in ``log(-s)`` units
        (0.2: a 20 % change of frequency or of about 0.2 rad in damping angle);
        keeps noise from flagging points of a nearly constant system.
    neighbours : int, optional
        Points compared with each point; default ``2 Np`` (two per
        parameter: along a line the neighbours on both sides, or the next
        point on the same side at an end).

    Returns
    -------
    Consistency

    Examples
    --------
    >>> import numpy as np, lpvid
    >>> ms = [lpvid.LpvModel([[-a]], [[1.0]], [[1.0]]) for a in (1.0, 1.1, 1.2, 50.0, 1.4)]
    >>> lpvid.consistency(ms, [0, 1, 2, 3, 4]).inconsistent
    [3]

    """
    models = lti_models(local_models, minimum=2)
    parr = local_p(local_models, p).reshape(len(models), -1)
    thr = positive_float(threshold, "threshold")
    dmin = positive_float(min_distance, "min_distance", allow_zero=True)
    N, n_par = parr.shape
    k = 2 * n_par if neighbours is None else positive_int(neighbours, "neighbours")
    k = min(k, N - 1)
    s = unit_scaled(parr)
    if unique_rows(s)[0].shape[0] != N:
        raise ValueError("p: scheduling values must be distinct")
    coords = [pole_coordinates(m) for m in models]
    pairs = []
    worst_pair: dict[tuple[int, int], tuple[int, int]] = {}
    for a, b in _neighbours(s, k):
        d, i, j = match_poles(coords[a], coords[b])
        rate = d / float(np.linalg.norm(s[a] - s[b]))
        pairs.append((a, b, d, rate))
        worst_pair[(a, b)] = (i, j)
    # Each point's smallest rate; their median is the reference. (The median
    # over all pairs would not do: a point in the middle is among the nearest
    # of most others, so that one odd model can spoil most pairs.)
    low = np.full(N, np.inf)
    dists = np.zeros(N)
    best: dict[int, tuple[int, int, float, float]] = {}
    for pr in pairs:
        for q in pr[:2]:
            if pr[3] < low[q]:
                low[q], dists[q], best[q] = pr[3], pr[2], pr
    ref = float(np.median(low))
    scores = low / ref if ref > 0 else np.where(low > 0, np.inf, 1.0)
    # Real poles per model: a pair that splits into two real poles at one
    # point only is a change of structure whatever the distances say.
    n_real = np.array([int(np.sum(is_real(c))) for c in coords])
    near: dict[int, set[int]] = {q: set() for q in range(N)}
    for a, b, _, _ in pairs:
        near[a].add(b)
        near[b].add(a)
    odd = [q for q in range(N) if all(n_real[m] != n_real[q] for m in near[q])]
    bad = [q for q in range(N) if (scores[q] > thr and dists[q] > dmin) or q in odd]
    details = {}
    for q in odd:
        others = sorted({int(n_real[m]) for m in near[q]})
        details[q] = (
            f"{n_real[q]} real pole(s), its nearest points have "
            f"{' or '.join(str(v) for v in others)}"
        )
    for q in set(bad) - set(odd):
        a, b, d, _ = best[q]
        i, j = worst_pair[(a, b)]
        mine, other = (i, j) if q == a else (j, i)
        m = b if q == a else a
        details[q] = (
            f"pole {describe_pole(coords[q][mine])} pairs with "
            f"{describe_pole(coords[m][other])} at point {m} (distance {d:.2f})"
        )
    return Consistency(parr, scores, dists, pairs, ref, thr, dmin, bad, details)
