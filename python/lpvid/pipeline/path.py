"""The l2,1 path of :func:`lpvid.identify`, kept from trading away interpolation.

With one scheduling point per coefficient matrix (``N = Nb + 1``) a state
transformation at one point alone is flat at the data
(:func:`lpvid.model.similarity.pointwise_similarity_directions`): the warm-started
path can buy smaller groups with such moves, which only the model between
the points sees. These moves are how the path finds a sparse truth (the
one-group systems of ``benches/bench_between.py``: from 0.03-0.17 relative
FRF error between the points with every fit pinned to 0.004-0.03 warm; the
gantry without validation data: 10.8 -> 1.47 times the validation floor
from the start chosen now), and how it slides away from one once the
groups are found (the positioning stage: 1.36 at the first gamma, 1.82
three gammas later, the same 4 groups). So the path runs warm:

- with validation data, a warm fit whose validation V_NLS is more than
  ``tolerance`` above the best so far on the path (the unregularised model
  included) is refitted pinned from the same start
  (``fit_l21(..., pinned=True)``), and the one with the lower validation
  V_NLS is kept (and continues the path);
- without validation data the path is plain warm, and the choice
  (:func:`lpvid.pipeline.run.identify`'s knee) takes, for each number of
  groups, the most regularised fit within the noise of the best: the first
  fit that found those groups, before the slide;
- with other numbers of points, or with time records (which see the model
  between the points), no direction is flat and the path is plain warm.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, replace
from typing import Any

from lpvid._spread import Spread
from lpvid.data.frf import FrfData
from lpvid.fit.fits import fit_l21, raise_if_interrupted, warn_if_unconverged
from lpvid.fit.results import FitResult, L21Result
from lpvid.fit.settings import L21Settings
from lpvid.fit.timecost import TimeCost
from lpvid.model.lpv import LpvModel
from lpvid.model.similarity import flat_at_points
from lpvid.pipeline.result import PathEntry, path_entry
from lpvid.trust.steps import stable_fit

__all__ = ["Along", "path_mode", "run_path"]


def path_mode(
    model: LpvModel, data: FrfData, validation: FrfData | None, time_cost: TimeCost | None
) -> str:
    """How the path from ``model`` runs (see the module notes).

    ``"warm"`` (nothing flat at the data, or no validation data to guard
    with) or ``"guarded"`` (warm, pinned where the warm fit loses
    interpolation at the validation points).
    """
    if time_cost is not None or validation is None or not flat_at_points(model, data.p):
        return "warm"
    return "guarded"


@dataclass(frozen=True)
class _Fit:
    """How every fit of the path runs, warm or ``pinned``, and what judges it."""

    data: FrfData
    settings: L21Settings
    fixed: Any
    validation: FrfData | None
    p_range: Any
    stable: bool
    time_cost: TimeCost | None
    pinned: bool = False


def _judged(start: LpvModel, g: float, how: _Fit) -> tuple[L21Result, PathEntry]:
    """The fit at ``g`` from ``start`` (warm or ``pinned``) and its path entry."""
    data, settings, fixed, time_cost = how.data, how.settings, how.fixed, how.time_cost
    fit = fit_l21(
        start, data, g, settings, fixed, warn=False, time_data=time_cost, pinned=how.pinned
    )
    r = raise_if_interrupted(fit)
    threshold = settings.threshold
    kept = stable_fit(r, data, fixed, threshold, how.p_range, time_cost) if how.stable else r
    entry = path_entry(r.gamma, kept, data, how.validation, threshold, time_cost, pinned=how.pinned)
    return r, entry


@dataclass(frozen=True)
class Along:
    """What every path of one identify run shares, from whichever start it goes.

    ``tolerance`` the choice's slack on the best validation V_NLS,
    ``settings`` the l2,1 fits', ``say`` where progress goes, ``executor``
    where a guarded path's pinned fits may run.
    """

    validation: FrfData | None
    tolerance: float
    settings: L21Settings
    p_range: Any
    stable: bool
    time_cost: TimeCost | None
    say: Callable[[str], Any]
    executor: Executor | None = None


def run_path(
    nls: FitResult, gammas: Sequence[float], data: FrfData, fixed: Any, along: Along
) -> tuple[list[L21Result], list[PathEntry]]:
    """The path from ``nls`` over ``gammas`` (largest first): its fits and its entries.

    The entries start with the unregularised model's; each gamma adds the
    fit kept there (see the module notes). With ``stable`` an entry holds
    the fit's stable replacement (:func:`lpvid.trust.steps.stable_fit`)
    while the path goes on from the fit itself.

    With an ``executor`` of other processes (a Dask cluster), a guarded
    path runs the pinned fit of every gamma beside the warm one (its start
    is known) and drops it when the warm fit validates well enough; the
    workers would otherwise sit idle. On threads of this process the pinned
    fit runs only when needed: beside the warm one it would take the cores
    the warm fit's cone steps use (measured on two cores: the gantry's path
    1.0 -> 2.1 s, where no gamma needed it). The path is the same either way.
    """
    validation, tolerance, settings, say = (
        along.validation,
        along.tolerance,
        along.settings,
        along.say,
    )
    p_range, stable, time_cost = along.p_range, along.stable, along.time_cost
    mode = path_mode(nls.model, data, validation, time_cost)
    spread = Spread(along.executor)
    if mode != "guarded" or not spread.elsewhere:
        spread = Spread(None)  # each fit here, when taken
    warm_fit = _Fit(data, settings, fixed, validation, p_range, stable=stable, time_cost=time_cost)
    pinned_fit = replace(warm_fit, pinned=True)
    entries = [path_entry(0.0, nls, data, validation, settings.threshold, time_cost)]
    results: list[L21Result] = []
    current: FitResult = nls
    for g in gammas:
        try:
            warm = spread.submit(_judged, current.model, g, warm_fit)
            pinned = None
            if mode == "guarded":
                pinned = spread.submit(_judged, current.model, g, pinned_fit)
            r, e = spread.take(warm)
            if pinned is not None:
                assert e.validation_vnls is not None
                best = min(x.validation_vnls or float("inf") for x in entries)
                if e.validation_vnls > (1 + tolerance) * best:
                    r2, e2 = spread.take(pinned)
                    assert e2.validation_vnls is not None
                    say(
                        f"  gamma = {r.gamma:g}: the warm fit validates at "
                        f"{e.validation_vnls / best:.3f} x the best so far; pinned: "
                        f"{e2.validation_vnls / best:.3f} x, {e2.n_groups} groups"
                    )
                    if e2.validation_vnls < e.validation_vnls:
                        r, e = r2, e2
        finally:
            spread.drop()  # what is still out: not needed, or the run stops
        results.append(r)
        entries.append(e)
        current = r
        warn_if_unconverged(r, f"the l2,1 fit at gamma = {r.gamma:g}", stacklevel=3)
        say(
            f"  gamma = {r.gamma:g}: {r.n_groups} groups, V_NLS/floor "
            f"{r.vnls / r.noise_floor:.3f}, {r.n_iter} cone steps"
            + (", pinned" if e.pinned else "")
            + ("" if r.converged else f" ({r.message})")
        )
    return results, entries
