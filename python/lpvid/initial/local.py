"""One LTI model per scheduling point: the local estimates SMILE interpolates."""

from __future__ import annotations

from concurrent.futures import Executor
from typing import Any

import numpy as np

from lpvid._checks import positive_float, positive_int
from lpvid._spread import Spread
from lpvid._threads import single_blas
from lpvid.data.basis import Polynomial
from lpvid.data.frf import FrfData
from lpvid.fit.cost import vnls_value as vnls
from lpvid.fit.fits import fit_nls, raise_if_interrupted
from lpvid.fit.settings import LOCAL_FTOL
from lpvid.initial.coherent import balance
from lpvid.initial.continuation import continue_local
from lpvid.initial.diagnosis import consistency
from lpvid.initial.localmodels import LocalModels, is_stable
from lpvid.initial.subspace import fd_subspace, max_order
from lpvid.model.lpv import LpvModel

__all__ = ["SAME_FIT", "check_local_order", "identify_lti", "local_models"]

#: Refined starts of one point whose V_NLS are within this fraction of the
#: lowest are one fit reached by several routes (ended at
#: :data:`lpvid.fit.settings.LOCAL_FTOL` they agree to 4e-14 to 2e-7 of it
#: on the small system of ``bench_small.py``, seeds 0-2), and the first in
#: the starts' order is kept: the lowest would let the last bits of the data
#: choose among them, and with them the state coordinates that every route
#: built on the local models follows (synthetic system at five points, draw
#: 6 of bench_few.py: three starts at 109.419277162, another kept on each of
#: two 1e-12 changes of the data, their coordinates 100 % apart). A stated
#: margin above the spread of such ties (a thousand times it when the fits
#: ran to 1e-10), far below the noise.
SAME_FIT = 1e-6


@single_blas
def identify_lti(
    data: FrfData,
    order: int,
    *,
    strictly_proper: bool = False,
    stable: bool = True,
    refine: bool = True,
    n_rows: int | None = None,
    max_iter: int = 100,
    ftol: float = LOCAL_FTOL,
    continuation: bool | str = False,
    executor: Executor | None = None,
) -> LocalModels:
    """Identify one LTI state-space model per scheduling point from its FRF.

    Each point gets frequency-domain subspace estimates weighted by sigma
    (:func:`lpvid.fd_subspace` with 3n, 2n and n + 1 block rows;
    unstable poles mirrored into the stable region when ``stable``), each
    as found and balanced; every one is refined by Levenberg-Marquardt on
    that point's V_NLS (:func:`lpvid.fit_nls`) and the best refined model is
    kept: the lowest V_NLS among the stable ones when ``stable`` (among all
    when none is stable), else the lowest V_NLS.

    Parameters
    ----------
    data : FrfData
        FRFs at N scheduling points.
    order : int
        State dimension n of every model.
    strictly_proper : bool
        Fix D to zero (``fixed={"D": True}`` in the refinement).
    stable : bool
        Mirror unstable poles of the subspace estimate before refinement
        (default True). The refinement may still move a pole out when the
        data demand it; ``result.unstable`` says which models are unstable.
    refine : bool
        Run the Levenberg-Marquardt refinement (default True).
    n_rows : int, optional
        Block rows of the subspace step (see :func:`lpvid.fd_subspace`);
        default: try 3n, 2n and n + 1.
    max_iter : int
        Most Levenberg-Marquardt steps per point.
    ftol : float
        A refinement ends when a step lowers the point's V_NLS by less than
        ``ftol`` times it, >= 0 (default :data:`lpvid.fit.settings.LOCAL_FTOL`,
        a millionth; :func:`lpvid.fit_nls` runs to 1e-10 by default).
    continuation : bool or "auto"
        After the plain identification, walk from the best-determined point
        outwards and refine each point's model from its neighbour's
        (:func:`lpvid.initial.continue_local`), so that the models stay on
        one branch: always (True), never (False, the default), or when
        :func:`lpvid.consistency` flags a point (``"auto"``).
    executor : concurrent.futures.Executor, optional
        Where the points' models are refined, each start's refinement one
        task (the subspace starts are computed here; see
        :func:`lpvid.identify`), and the continuation's walks
        (:func:`lpvid.initial.continue_local`); default here, one after the
        other. The models are the same either way.

    Returns
    -------
    LocalModels
        The models with per-point V_NLS, noise floor (``F l r``), unstable
        flags, the subspace estimates the kept models started from
        (``.initial``) and ``p``. Each model's ``info`` says which start it
        came from (``n_rows``, ``balanced_start``) and how many steps it took;
        ``.starts`` says per point whether the plain or the continuation
        start was kept, and ``.consistency`` holds the diagnosis of the plain
        models when continuation was considered.

    Raises
    ------
    ValueError, TypeError
        When ``order`` is not a positive integer or exceeds what the data
        support (the subspace step needs ``2 F r >= (n + 1) r + n``).

    """
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    n = positive_int(order, "order")
    check_local_order(n, data)
    max_iter = positive_int(max_iter, "max_iter")
    ftol = positive_float(ftol, "ftol", allow_zero=True)
    if not (isinstance(continuation, bool) or continuation == "auto"):
        raise ValueError(f"continuation: expected True, False or 'auto', got {continuation!r}")
    if continuation is not False and not refine:
        raise ValueError("continuation: a continuation refines the models; it needs refine=True")
    return local_models(
        data,
        n,
        strictly_proper=strictly_proper,
        stable=stable,
        refine=refine,
        n_rows=n_rows,
        max_iter=max_iter,
        ftol=ftol,
        continuation=continuation,
        executor=executor,
    )


def check_local_order(n: int, data: FrfData) -> None:
    """Refuse an order beyond what the subspace step can estimate from each point's lines."""
    F, l, r = data.n_lines, data.n_outputs, data.n_inputs
    limit = max_order(F, l, r)
    if n > limit:
        raise ValueError(
            f"order: {n} exceeds what the data support ({F} lines per point, {l} outputs x "
            f"{r} inputs allow at most order {limit})"
        )


def local_models(
    data: FrfData,
    n: int,
    *,
    strictly_proper: bool = False,
    stable: bool = True,
    refine: bool = True,
    n_rows: int | None = None,
    max_iter: int = 100,
    ftol: float = LOCAL_FTOL,
    continuation: bool | str = False,
    executor: Executor | None = None,
) -> LocalModels:
    """:func:`identify_lti` on arguments already checked (by it, or by a :class:`lpvid.Problem`)."""
    F, r = data.n_lines, data.n_inputs
    l = data.n_outputs
    rows = _row_choices(n, F, r, n_rows)
    spread = Spread(executor)
    points = [data.subset([q]) for q in range(data.n_points)]
    # Every point's subspace starts here, then every start's refinement a
    # piece (a point's starts take from 2 to 100 steps: one piece per start
    # keeps the threads evenly busy). The starts are numpy's work on small
    # arrays, which holds the GIL: on two threads they took twice the time
    # each and the stage no less (docs/performance.md, 2026-12-02). They
    # would give the same bits there (BLAS on one thread wherever an entry
    # point runs, lpvid._threads). The refinements are the core's.
    starts = [_point_starts(pt, n, rows, stable, strictly_proper) for pt in points]
    fixed = {"D": True} if strictly_proper else None
    calls = [
        (s, pt, fixed, max_iter, ftol, stable, refine)
        for pt, ss in zip(points, starts, strict=True)
        for s in ss
    ]
    refined = iter(spread.map(_refined, calls))
    found = [_best([next(refined) for _ in ss], ss) for ss in starts]
    models = [m for m, _, _, _ in found]
    costs = [c for _, c, _, _ in found]
    conv = [ok for _, _, ok, _ in found]
    initial = [s for _, _, _, s in found]
    floor = np.full(data.n_points, F * l * r)
    plain = LocalModels(models, data.p, data.freqs_hz, costs, floor, conv, initial)
    if continuation is False or data.n_points < 2:
        return plain
    diagnosis = consistency(plain)
    if continuation == "auto" and diagnosis.ok:
        return LocalModels(
            models, data.p, data.freqs_hz, costs, floor, conv, initial, consistency=diagnosis
        )
    return continue_local(
        data,
        plain,
        strictly_proper=strictly_proper,
        max_iter=max_iter,
        diagnosis=diagnosis,
        executor=executor,
    )


def _best(
    refined: list[tuple[LpvModel, bool, tuple[bool, float]]], starts: list[LpvModel]
) -> tuple[LpvModel, float, bool, LpvModel]:
    """The local model of one point from its refined starts: its V_NLS, convergence, start.

    The best is kept: stable ones first when the models were to be stable,
    then the lowest V_NLS, where V_NLS within :data:`SAME_FIT` of the
    lowest ties and the first in the starts' order wins (a V_NLS that is
    not finite is the highest).
    """
    # A V_NLS that is not finite ranks last (NaN would compare with nothing).
    ranks = [(kind, cost if np.isfinite(cost) else np.inf) for _, _, (kind, cost) in refined]
    best = min(ranks)
    tied = [
        i
        for i, (kind, cost) in enumerate(ranks)
        if kind == best[0] and cost <= best[1] * (1 + SAME_FIT)
    ]
    k = tied[0]
    model, ok, (_, cost) = refined[k]
    return model, cost, ok, starts[k]


def _row_choices(n: int, n_lines: int, n_inputs: int, n_rows: int | None) -> list[int | None]:
    """Block-row counts to try: the one given, else 3n, 2n and n + 1 where the data allow."""
    if n_rows is not None:
        return [n_rows]
    q_max = (2 * n_lines * n_inputs - n) // n_inputs
    return sorted({min(k, q_max) for k in (3 * n, 2 * n, n + 1) if n + 1 <= min(k, q_max)})


@single_blas
def _point_starts(
    point: FrfData, n: int, rows: list[int | None], stable: bool, strictly_proper: bool
) -> list[LpvModel]:
    """Subspace estimates of one point, each as found and (when stable) balanced.

    The refinement is cheap and its outcome depends on the start (a pole
    outside the band can run off to infinity from one start and settle from
    another), so a few starts are refined and the best result kept. (A piece
    of :func:`identify_lti`'s work: BLAS stays on one thread wherever it runs.)
    """
    basis = Polynomial(0, n_params=point.n_params)
    out = []
    for q in rows:
        A, B, C, D = fd_subspace(
            point.freqs_hz,
            point.G[0],
            n,
            point.sigma[0],
            point.Ts,
            n_rows=q,
            stable=stable,
            strictly_proper=strictly_proper,
        )
        info = {"method": "fd_subspace", "n_rows": q, "balanced": False}
        out.append(LpvModel(A, B, C, D, basis=basis, Ts=point.Ts, info=info))
        bal, done = balance([(A, B, C, D)], point.Ts)
        if done:
            info = {**info, "balanced": True}
            out.append(LpvModel(*bal[0], basis=basis, Ts=point.Ts, info=info))
    return out


@single_blas
def _refined(
    start: LpvModel,
    point: FrfData,
    fixed: Any,
    max_iter: int,
    ftol: float,
    stable: bool,
    refine: bool,
) -> tuple[LpvModel, bool, tuple[bool, float]]:
    """One start refined (when ``refine``), whether it converged, and its rank among the point's.

    The rank: unstable after stable when ``stable``, then V_NLS (the fit's
    own, which is the refined model's to the last bit: the core's cost and
    its Gauss-Newton pieces give the same V_NLS).
    """
    if refine:
        model, ok, cost = _refine(start, point, fixed, max_iter, ftol)
    else:
        model, ok, cost = start, True, vnls(start, point)
    return model, ok, (stable and not is_stable(model), cost)


def _refine(
    start: LpvModel, data: FrfData, fixed: Any, max_iter: int, ftol: float
) -> tuple[LpvModel, bool, float]:
    result = raise_if_interrupted(
        fit_nls(start, data, fixed, max_iter=max_iter, ftol=ftol, warn=False)
    )
    info = {
        "method": "fd_subspace + fit_nls",
        "n_rows": start.info["n_rows"],
        "balanced_start": start.info["balanced"],
        "n_iter": int(result.n_iter),
    }
    model = LpvModel(*result.model.matrices().values(), basis=start.basis, Ts=start.Ts, info=info)
    return model, bool(result.converged), float(result.vnls)
