"""Refine many starts for the price of a few: staged Levenberg-Marquardt runs raced by halving.

Every initial candidate is a :class:`Runner`: a model and the stages of
:func:`lpvid.fit_nls` it goes through (one for a SMILE start, several for a
global start that frees the groups degree by degree). :func:`race` drops the
hopeless starts (V_NLS far above the best start's, or not finite) without a
step, gives the others a few steps, drops the worse half (unstable between
the points first, then by validation V_NLS, or identification V_NLS without
validation data), gives the rest twice as many steps, and so on (successive
halving), until the best few are refined to convergence.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._spread import Spread
from lpvid.data.frf import FrfData
from lpvid.data.schedule import between_points
from lpvid.fit.cost import vnls_value as vnls
from lpvid.fit.fits import fit_nls, raise_if_interrupted
from lpvid.fit.judge import VALIDATION_TIE, by_simplicity, dependence, tied
from lpvid.fit.results import FitResult
from lpvid.fit.settings import START_FTOL
from lpvid.model.frozen import frozen_stable
from lpvid.model.lpv import LpvModel

__all__ = ["HOPELESS", "ROUNDS", "Runner", "Stage", "race", "run_out"]

#: Levenberg-Marquardt steps each runner still in the race gets per round,
#: before the worse half is dropped; the last few are then refined to
#: convergence.
ROUNDS = (10, 20, 40)

#: A start whose V_NLS is more than this many times the best start's is
#: hopeless: it leaves the race without a step. Starts that went on to
#: win sat within 200 times the best start (the heavily damped test case);
#: those dropped by this rule on the scale ladder sat 10^5 to 10^9 times
#: above, and the first round of the race dropped them all the same. (They
#: took one step before they left: 10.3 s of n = 32's starts, 2.4 s of
#: n = 24's, for a V_NLS nothing reads but the list of candidates.)
HOPELESS = 1e4


@dataclass
class Stage:
    """One fit of a runner: which parameters stay fixed, and a label."""

    label: str
    fixed: NDArray[np.bool_]


def merge(a: FitResult | None, b: FitResult) -> FitResult:
    """Two consecutive Levenberg-Marquardt runs as one (``b`` continues ``a``)."""
    if a is None:
        return b
    rows = a.history + b.history
    lm = [r["seconds"] for r in rows if r["kind"] == "lm"]
    return FitResult(
        model=b.model,
        vnls=b.vnls,
        noise_floor=b.noise_floor,
        objective=b.objective,
        history=rows,
        timings={
            "lm_iter_s": float(np.mean(lm)) if lm else float("nan"),
            "socp_iter_s": float("nan"),
            "total_s": a.timings["total_s"] + b.timings["total_s"],
        },
        converged=b.converged,
        stop=b.stop,
        message=b.message,
        interrupted=b.interrupted,
        n_rejected=a.n_rejected + b.n_rejected,
    )


@dataclass
class Runner:
    """A start on its way to a refined candidate.

    Attributes
    ----------
    name, note : str
        The candidate's name and what was done, in words.
    model : LpvModel
        The current model.
    stages : list of Stage
        The fits to run in order.
    max_iter : int
        Most steps per stage.
    ftol : float
        A stage ends when a step lowers V_NLS by less than ``ftol`` times
        it (:data:`lpvid.fit.settings.START_FTOL`; see :func:`lpvid.fit_nls`).
    start : LpvModel or None
        The model the last stage started from (known once it starts).
    fit : FitResult or None
        The last stage's fit so far (all of its steps).
    history : list of dict
        One entry per finished stage: ``free_groups`` (its label), ``vnls``, ``n_iter``.
    done : bool
        Every stage converged or used its steps.
    dropped : int or None
        Steps taken when the race dropped it; None while it runs or once done.
    seconds : float
        Time spent fitting it.
    """

    name: str
    model: LpvModel
    stages: list[Stage]
    max_iter: int = 100
    ftol: float = START_FTOL
    note: str = ""
    start: LpvModel | None = None
    fit: FitResult | None = None
    history: list[dict[str, Any]] = field(default_factory=list)
    done: bool = False
    dropped: int | None = None
    seconds: float = 0.0
    _stage: int = 0
    _used: int = 0
    _lambda: float = 1e-2

    def __post_init__(self) -> None:
        if len(self.stages) == 1:
            self.start = self.model

    def current_vnls(self, data: FrfData) -> float:
        """V_NLS of the current model on the identification data."""
        return float(self.fit.vnls) if self.fit is not None else vnls(self.model, data)

    @property
    def steps(self) -> int:
        """Levenberg-Marquardt steps taken in all stages."""
        # A finished stage is in the history; once done, the last one is too.
        going = self.fit.n_iter if self.fit is not None and not self.done else 0
        return sum(h["n_iter"] for h in self.history) + going

    def advance(self, data: FrfData, budget: int) -> None:
        """Take up to ``budget`` more steps, moving through the stages."""
        while budget > 0 and not self.done:
            stage = self.stages[self._stage]
            steps = min(budget, self.max_iter - self._used)
            t0 = time.perf_counter()
            fit = fit_nls(
                self.model,
                data,
                stage.fixed,
                max_iter=steps,
                ftol=self.ftol,
                lambda0=self._lambda,
                warn=False,
            )
            raise_if_interrupted(fit)
            self.seconds += time.perf_counter() - t0
            self.fit = merge(self.fit, fit)
            self.model = fit.model
            self._used += fit.n_iter
            budget -= max(fit.n_iter, 1)
            if fit.history:
                self._lambda = max(float(fit.history[-1]["lambda"]), 1e-6)
            if fit.stop == "max_iterations" and self._used < self.max_iter:
                continue
            self.history.append(
                {"free_groups": stage.label, "vnls": float(fit.vnls), "n_iter": self._used}
            )
            if self._stage + 1 == len(self.stages):
                self.done = True
                break
            self._stage += 1
            self._used, self.fit, self._lambda = 0, None, 1e-2
            if self._stage + 1 == len(self.stages):
                self.start = self.model


def _rank(
    runners: Sequence[Runner], data: FrfData, validation: FrfData | None
) -> list[tuple[bool, bool, float, float, int]]:
    """Sort keys: unstable between the points last, then the (validation) V_NLS.

    Runners whose V_NLS ties with the best stable one's come first, from
    the simplest on (:func:`lpvid.fit.judge.by_simplicity`: the least
    scheduling dependence, then the cost, near-ties by the runners' order):
    as :func:`lpvid.initial.choose` ranks them, within the noise of
    the identification V_NLS, or within :data:`lpvid.fit.judge.VALIDATION_TIE`
    of the best validation V_NLS (:func:`lpvid.fit.judge.tied`).
    """
    between = between_points(data.p)
    judge = validation if validation is not None else data
    costs, unstable = [], []
    for r in runners:
        cost = vnls(r.model, validation) if validation is not None else r.current_vnls(data)
        costs.append(cost if np.isfinite(cost) else math.inf)
        unstable.append(not frozen_stable(r.model, between))
    stable_costs = [c if not u else math.inf for c, u in zip(costs, unstable, strict=True)]
    tolerance = None if validation is None else VALIDATION_TIE
    ties = tied(stable_costs if not all(unstable) else costs, judge.n_residuals, tolerance)
    tie = [k for k in range(len(runners)) if ties[k]]
    place = {}
    if tie:
        deps = [dependence(runners[k].model, data) for k in tie]
        order = by_simplicity(deps, [costs[k] for k in tie])
        place = {tie[i]: float(n) for n, i in enumerate(order)}
    return [
        (unstable[k], not ties[k], place.get(k, costs[k]), costs[k], k) for k in range(len(runners))
    ]


def _advanced(runner: Runner, data: FrfData, budget: int | None) -> Runner:
    """``runner`` after up to ``budget`` more steps (None: to the end of its stages)."""
    if budget is None:
        while not runner.done:
            runner.advance(data, runner.max_iter)
    else:
        runner.advance(data, budget)
    return runner


def _advance(
    spread: Spread,
    runners: list[Runner],
    data: FrfData,
    budget: int | None,
    step: Callable[[Runner], None] | None,
) -> None:
    """Advance the runners (each independent of the others) on ``spread``, in place."""
    moved = spread.map(_advanced, [(r, data, budget) for r in runners])
    for r, m in zip(runners, moved, strict=True):
        if m is not r:  # a copy from another process
            vars(r).update(vars(m))
        if step is not None:
            step(r)


def run_out(runners: Sequence[Runner], data: FrfData, executor: Executor | None = None) -> None:
    """Refine every runner to the end of its stages, no race (each one task on ``executor``)."""
    _advance(Spread(executor), [r for r in runners if not r.done], data, None, None)


def _unfitted(model: LpvModel, cost: float, data: FrfData, why: str) -> FitResult:
    """A fit of no step: ``model`` as it started, its V_NLS ``cost``, and why it was not fitted."""
    return FitResult(
        model=model,
        vnls=cost,
        noise_floor=data.n_residuals,
        objective=cost,
        history=[],
        timings={"lm_iter_s": math.nan, "socp_iter_s": math.nan, "total_s": 0.0},
        converged=False,
        stop="dropped",
        message=why,
        interrupted=False,
        n_rejected=0,
    )


def _drop_hopeless(
    runners: list[Runner], data: FrfData, step: Callable[[Runner], None] | None
) -> list[Runner]:
    """The runners that are not hopeless (see :data:`HOPELESS`); the others drop without a step."""
    costs = [r.current_vnls(data) for r in runners]
    best = min((c for c in costs if math.isfinite(c)), default=math.inf)
    if not math.isfinite(best):
        return runners  # no start to compare with
    ok = [cost <= HOPELESS * best for cost in costs]  # False for NaN
    kept = [r for r, k in zip(runners, ok, strict=True) if k]
    for r, cost, k in zip(runners, costs, ok, strict=True):
        if k:
            continue
        why = (
            f"not refined: V_NLS {cost:.5g} is more than {HOPELESS:g} times the best start's"
            if math.isfinite(cost)
            else f"not refined: V_NLS is not finite ({cost})"
        )
        r.fit, r.dropped = _unfitted(r.model, cost, data, why), r.steps
        if step is not None:
            step(r)
    return kept


def race(
    runners: Sequence[Runner],
    data: FrfData,
    validation: FrfData | None = None,
    *,
    rounds: Sequence[int] = ROUNDS,
    keep: int = 2,
    step: Callable[[Runner], None] | None = None,
    executor: Executor | None = None,
) -> list[Runner]:
    """Successive halving over the runners; returns them all (dropped ones marked).

    Starts whose V_NLS is not finite or above :data:`HOPELESS` times the
    best start's are dropped without a step (their fit is one of no step,
    ``stop`` "dropped"); they count among the runners of the first round
    when its worse half is dropped, so that the same runners go on as if
    they had run it. A runner dropped between two of its stages (its steps
    spent at the end of one) leaves with a fit of no step at the model that
    stage ended on, as a hopeless one does.

    Parameters
    ----------
    runners : sequence of Runner
    data : FrfData
        Identification data.
    validation : FrfData, optional
        Ranks the runners by validation V_NLS when given.
    rounds : sequence of int
        Steps per runner in each round; after each, the worse half is dropped
        (at least ``keep`` stay). The runners left after the last round run
        to convergence.
    keep : int
        Fewest runners refined to convergence.
    step : callable, optional
        Called with each runner after each of its rounds (progress).
    executor : concurrent.futures.Executor, optional
        Where the runners of a round run, each one task (see
        :func:`lpvid.identify`); default here, one after the other. The
        runners are taken back in their order and ranked here: the race
        keeps and drops the same runners either way.
    """
    spread = Spread(executor)
    entered = [r for r in runners if not r.done]
    alive = _drop_hopeless(entered, data, step)
    for round_, budget in enumerate(rounds):
        _advance(spread, alive, data, budget, step)
        keys = sorted(_rank(alive, data, validation))
        finite = [k for k in keys if math.isfinite(k[3])] or keys
        counted = entered if round_ == 0 else alive  # the hopeless count in the first round
        n_keep = max(keep, math.ceil(len(counted) / 2))
        stay = {k[-1] for k in finite[:n_keep]}
        for k, r in enumerate(alive):
            if k not in stay and not r.done:
                r.dropped = r.steps
                if r.fit is None:  # between two stages: it leaves with the last one's model
                    why = f"dropped by the race before a step of stage {r._stage + 1}"
                    r.fit = _unfitted(r.model, r.current_vnls(data), data, why)
        alive = [r for k, r in enumerate(alive) if k in stay and not r.done]
        if not alive:
            break
    _advance(spread, alive, data, None, step)
    return list(runners)
