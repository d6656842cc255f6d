"""The whole identification pipeline: local models, initial models, NLS, l2,1 path, a choice.

:func:`identify` chains :func:`~lpvid.identify_lti`, the initial models of
:mod:`lpvid.initial` (SMILE in every coherent form, continuation, global
starts), :func:`~lpvid.fit_nls` and the l2,1 path of :func:`~lpvid.l21_path`,
then chooses a model on the path and says why.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import replace
from typing import Any

import numpy as np

from lpvid._progress import Progress, check_progress, say
from lpvid._spread import SMALL_RUN_BYTES, check_executor, cores, own_threads
from lpvid._threads import single_blas
from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData
from lpvid.errors import ConvergenceWarning
from lpvid.fit.fits import fit_nls, raise_if_interrupted, warn_if_unconverged
from lpvid.fit.memory import check_memory, local_memory, pipeline_memory
from lpvid.fit.results import PathResult
from lpvid.fit.settings import DEFAULT_GAMMAS, ROUTES, L21Settings, check_gammas
from lpvid.initial.blocks import BlockPieces, hand_out_blocks
from lpvid.initial.candidates import candidates_of
from lpvid.initial.choice import choose
from lpvid.initial.grown import GROWN
from lpvid.initial.local import local_models
from lpvid.initial.localmodels import LocalModels
from lpvid.model.layout import strictly_proper
from lpvid.pipeline.bulge import bulge
from lpvid.pipeline.fewpoints import choose_route, open_between
from lpvid.pipeline.misfit import advice, far_fit, misfit
from lpvid.pipeline.opening import FollowAhead, open_routes
from lpvid.pipeline.path import Along
from lpvid.pipeline.problem import IdentifyArguments, Problem, check_validation
from lpvid.pipeline.result import IdentifyResult, PathEntry, path_entry
from lpvid.pipeline.routes import follow
from lpvid.trust.steps import finish

__all__ = [
    "DEFAULT_GAMMAS",
    "PathEntry",
    "IdentifyResult",
    "Problem",
    "check_gammas",
    "check_validation",
    "identify",
]


def _unsaid(message: str) -> None:
    """Where a piece's progress goes until it is taken (:class:`FollowAhead` keeps its own)."""


@single_blas
def identify(
    data: FrfData | Problem,
    order: int | None = None,
    basis: Basis | None = None,
    gammas: Sequence[float] | None = None,
    validation: FrfData | None = None,
    fixed: Any = None,
    *,
    forms: Sequence[str] | None = None,
    routes: Sequence[str] = ROUTES,
    tolerance: float = 0.1,
    settings: L21Settings | None = None,
    progress: Progress | None = None,
    time_data: Any = None,
    stable: bool = False,
    refit: bool = True,
    executor: Any = None,
) -> IdentifyResult:
    """Identify an LPV model from FRF data: the whole pipeline.

    1. One LTI model per scheduling point (:func:`~lpvid.identify_lti`).
    2. Initial LPV models by several routes (:func:`lpvid.initial_candidates`):
       SMILE over ``basis`` in every coherent form from the plain local
       models, the same from local models found by continuation along the
       scheduling axis, and global starts from one well-determined local
       model; each is refined by :func:`~lpvid.fit_nls`. The start is chosen
       by :func:`lpvid.initial.choose`: among models stable between the
       points, the lowest validation V_NLS (identification V_NLS without
       validation data), the simpler on a near tie.
    3. The reweighted l2,1 path over ``gammas`` from the refined start
       (as :func:`~lpvid.l21_path`: warm-started, largest gamma first).
       With ``validation`` data and one scheduling point per coefficient
       matrix (directions flat at the data), a fit that validates more than
       ``tolerance`` above the best so far is also tried with its steps
       kept off the flat directions (``fit_l21(..., pinned=True)``) and the
       better one kept (see :mod:`lpvid.pipeline.path`).
    4. A choice among the unregularised model and the path: with
       ``validation`` data, the simplest model whose validation V_NLS is
       within ``tolerance`` of the best; without, the knee of the
       accuracy-versus-number-of-groups curve, each number of groups
       represented by its most regularised fit within the noise of the
       best with that number.
    5. With ``refit`` and validation data, the chosen model refitted on
       its support (dropped groups fixed at zero), kept only when it
       validates better (:func:`lpvid.trust.support.judged_refit`: without
       validation data nothing can judge it, and on systems with a known
       truth it interpolated worse); then the parameter covariance of the
       model returned (linearised on its support) and the stability of its
       frozen models over the scheduling range. ``reason`` says whether the
       model was refitted.

    With ``time_data`` (records along a varying scheduling trajectory),
    steps 1-2 use the FRF data alone; the chosen start is then refined on
    the sum of both costs (:func:`~lpvid.fit_nls` with ``time_data``), and
    the path and the choice run on that sum, each part weighted by its own
    noise.

    Every argument but ``progress`` and ``executor`` goes into one
    :class:`lpvid.Problem`, checked once before any work (``settings``
    those of the path's l2,1 fits, default ``L21Settings(max_outer=10)``,
    its ``ftol`` also that of the starts' fits; ``gammas``, ``tolerance``,
    ``routes``, ``forms``, ``stable`` and ``refit`` as in
    :class:`lpvid.IdentifySettings`); ``identify(problem)`` takes one made
    beforehand, the other arguments then left out.

    Parameters
    ----------
    data : FrfData or Problem
        Identification data, or the whole problem.
    order : int
        Number of states.
    basis : Basis
        Basis functions of the scheduling dependency (normalise the
        scheduling range: e.g. ``Polynomial(4, domain=(p_min, p_max))``).
    gammas : sequence of float, optional
        Regularisation weights (lpvid's normalised gamma, see
        :func:`~lpvid.fit_l21`); default :data:`DEFAULT_GAMMAS`.
    validation : FrfData, optional
        Data at other scheduling values, used to judge every model.
    fixed : optional
        Parameters kept fixed (see :func:`~lpvid.fixed_mask`). With
        ``{"D": True}`` the local models are strictly proper and D stays zero.
    forms : sequence of str, optional
        Coherent forms to try (default all, see :data:`lpvid.initial.interpolation.FORMS`).
    routes : sequence of str
        Routes to initial models: ``"plain"``, ``"continuation"``,
        ``"global"`` (default all).
    tolerance : float
        Relative slack on the best validation V_NLS for the choice.
    settings : L21Settings, optional
        Settings of the l2,1 fits on the path; default
        ``L21Settings(max_outer=10)``. The starts' fits end by their own
        rule (:data:`lpvid.fit.settings.START_FTOL`; pass a
        :class:`lpvid.Problem` with :class:`lpvid.fit.settings.StartSettings`
        to change it).
    progress : callable, optional
        Called with a short message at every stage and every fit on the
        path (the same messages go to the ``lpvid`` logger at INFO).
    time_data : TimeData or TimeCost, optional
        Time records of the same system (see :func:`lpvid.fit_time`).
    stable : bool
        Keep every frozen model on the scheduling range (the basis domain,
        else the data's range) stable: each model of the path (and the
        unregularised one) that is not is replaced by its refit on its
        support with stability kept, from the model made stable
        (:func:`lpvid.stable.enforce.stabilised`); the choice is then among
        stable models. (The l2,1 fits themselves run unconstrained: at an
        active stability constraint, rejected cone steps would stop their
        simplification.)
    refit : bool
        With validation data, refit the chosen model by Levenberg-Marquardt
        with its dropped groups fixed at zero (removes the shrinkage of the
        l2,1 penalty) and return the refit when it validates better
        (:attr:`IdentifyResult.refitted`). False: never refit.
    executor : concurrent.futures.Executor or distributed.Client, optional
        Where the independent fits run, each one task: the refinement of
        every subspace start of the local models, the runners of every
        round of the race of the starts, the blocks route's and (after a
        misfit) the global starts when the points leave the structure open
        (for a small run without validation data or time records, the
        blocks route's starts are handed out before the main path, beside
        it, and dropped when its structure turns out determined), and (on
        an executor of other processes, such as a Dask cluster) a guarded
        path's pinned fit beside the warm one at every gamma, dropped when
        not needed (on threads here it would take the warm fit's cores).
        A piece on a thread of this process runs the core's loops on its
        own thread (:mod:`lpvid._spread`). The results are taken in a
        fixed order, never as they finish, so the run is the same to the
        last bit: the same local models, the same starts kept and dropped,
        the same path and model. Default: for a small run (its peak
        memory estimate at most 256 MiB, :data:`lpvid._spread.SMALL_RUN_BYTES`)
        called from the main thread, threads of this process, one per core
        it may run on (none on one core); else here, one after the other. A small
        model's fits hardly spread over the cores inside the core, and two
        side by side take about half the time: the synthetic n = 10 SISO
        system at six points (``benches/bench_small.py``) 1.44 -> 1.24 s,
        its local models 0.63 -> 0.40 s, on two cores; the gantry 0.98 of
        the time, n = 10 0.94. A large model's fits take every core
        themselves (n = 16 0.92), and two at once would hold two fits'
        memory; but one point's fits are small where the run is not: a
        large run refines its local models on threads of its own, one per
        core, when together they need no more memory than the run itself
        (:func:`lpvid.fit.memory.local_memory`; n = 16 2x2 the local
        models 2.1 -> 1.6 s). The run is the same either way. A Dask cluster: its
        ``distributed.Client(address)`` itself (taken as its
        ``get_executor()``) or that executor (its workers need
        lpvid; the data, models and fits are pickled to them). Tasks on
        threads here run at once, each fit with its own memory: the check
        before any work (MemoryError below) counts one fit, and every fit
        checks again as it starts.

    Returns
    -------
    IdentifyResult

    Warns
    -----
    ConvergenceWarning
        When the unregularised fit or a fit on the path stops at its
        iteration limit with its objective still falling (the entry's
        ``converged`` is then False), and when the chosen model has unstable
        frozen models on the scheduling range.

    Raises
    ------
    KeyboardInterrupt
        When Ctrl-C stops one of the fits. With an executor, the tasks not
        started are cancelled and the fits running on threads of this
        process stopped (at their next step) before it is raised; tasks in
        other processes finish there and are dropped.
    ValueError
        On bad arguments, and when the start chosen on the FRFs diverges
        along a time record (the message names the record and the sample).
    MemoryError
        Before any work, when the run needs more memory than the process
        may allocate (:func:`lpvid.available_memory`). Its peak is that of
        its largest fit, every parameter free: with ``P = (Nb + 1)(n + l)
        (n + r)`` parameters, ``L = (n + l)(n + r)`` per LTI model and
        ``F_t = 4 floor(128 / (l r))`` lines per block, about ``8 P^2`` bytes
        for ``J^T J`` and as much again during a Levenberg-Marquardt step or
        ``72 K^2`` (``K = Nb P / (Nb + 1)``: one cone program) during an
        l2,1 step, plus one evaluation: ``4 L^2 N ceil(F / F_t)`` for the
        Gram pieces of the blocks of lines or ``8 L^2 (N + (Nb + 1)(Nb + 2)
        / 2) + 8 P^2`` for the points' Gram matrices, their sums and
        ``J^T J``; with ``refit``, ``64 P^2`` for the covariance; then half
        as much again and 64 MB for what the allocator holds back and the
        first run's modules (:func:`lpvid.fit.memory.resident`). At n = 16 2x2
        (N = 9, F = 500) that is 394 MB, n = 24 3x3 (N = 9, F = 1000)
        1155 MB; ``benches/bench_scale.py`` measured 185 and 661 MB of
        growth (:func:`lpvid.fit.memory.pipeline_memory`).
    """
    t0 = time.perf_counter()
    arguments = IdentifyArguments.of(locals())  # before any other local name
    progress = check_progress(progress)
    if isinstance(data, Problem):
        arguments.refuse()
        problem = data
    else:
        problem = arguments.problem(data)
    p = problem
    need, sizes = pipeline_memory(p.data, p.order, p.basis, p.time_data, p.settings.refit)
    check_memory(need, "identify", sizes)  # before any work
    with own_threads(check_executor(executor), need) as spread_on:
        return _run(problem, progress=progress, executor=spread_on, t0=t0, need=need)


def _run(
    problem: Problem,
    *,
    progress: Progress | None,
    executor: Executor | None,
    t0: float,
    need: int,
) -> IdentifyResult:
    """The pipeline of :func:`identify` on a checked problem (nothing it holds is checked again).

    ``need``: the run's peak memory estimate. A small run's fits hardly
    spread over the cores inside the core
    (:data:`lpvid._spread.SMALL_RUN_BYTES`): the blocks route's fits are
    handed out to ``executor`` while the main path runs
    (:func:`_blocks_ahead`). A large run's local models go on threads of
    their own when, one per core, they need no more than the run will.
    """
    small = need <= SMALL_RUN_BYTES
    data, n, basis, fixed = problem.data, problem.order, problem.basis, problem.fixed
    validation, time_cost, p_range = problem.validation, problem.time_data, problem.p_range
    settings, starts = problem.settings, problem.settings.starts
    l21, tol, stable = settings.path.l21, settings.path.tolerance, settings.stable
    gs = np.asarray(settings.path.gammas, dtype=float)
    timings: dict[str, float] = {}

    say(progress, f"local models: order {n} at {data.n_points} scheduling points")
    t = time.perf_counter()
    # One point's fits are small even where the run is not: side by side on
    # threads of its own (see the executor's notes).
    side_by_side = cores() * local_memory(data, n)
    with own_threads(executor, side_by_side, max(need, SMALL_RUN_BYTES)) as points_on:
        local = local_models(data, n, strictly_proper=strictly_proper(fixed), executor=points_on)
    timings["local_s"] = time.perf_counter() - t

    say(progress, f"initial models ({', '.join(starts.routes)}), each refined by fit_nls")
    t = time.perf_counter()
    candidates = candidates_of(
        data,
        n,
        basis,
        fixed,
        validation=validation,
        routes=starts.routes,
        forms=starts.forms,
        local=local,
        diagnosis=None,
        max_iter=starts.max_iter,
        ftol=starts.ftol,
        halving=starts.halving,
        executor=executor,
    )
    if not candidates:
        raise ValueError("no initial model could be built for these local models")
    start, initial_reason = choose(candidates)
    timings["smile_s"] = time.perf_counter() - t
    assert start.fit is not None and start.start is not None
    nls = start.fit
    warn_if_unconverged(nls, "the unregularised fit (fit_nls)", stacklevel=2)
    for c in sorted(candidates, key=lambda c: (c.validation_vnls or 0.0, c.vnls)):
        val = "" if c.validation_vnls is None else f", validation {c.validation_vnls:.5g}"
        dropped = "" if c.refined else f", dropped after {c.fit.n_iter if c.fit else 0} steps"
        state = ("" if c.stable else ", unstable") + dropped
        say(progress, f"  {c.name}: V_NLS {c.vnls:.5g}{val}{state}")
    timings["nls_s"] = nls.timings["total_s"]
    if time_cost is not None:
        say(progress, f"refining the {start.name} start on the FRFs and the time records")
        nls = raise_if_interrupted(fit_nls(nls.model, data, fixed, warn=False, time_data=time_cost))
        warn_if_unconverged(nls, "the fit on FRFs and time records (fit_nls)", stacklevel=2)
        timings["nls_s"] += nls.timings["total_s"]

    say(progress, f"l2,1 path over {gs.size} values of gamma from the {start.name} start")
    t = time.perf_counter()
    along = Along(
        validation, tol, l21, p_range, stable, time_cost, lambda m: say(progress, m), executor
    )
    ahead = _blocks_ahead(problem, local, executor, along, gs) if small else None
    try:
        main = follow(start.name, nls, gs, data, fixed, along)
    except BaseException:
        if ahead is not None:
            ahead.drop()
        raise
    timings["path_s"] = time.perf_counter() - t
    t = time.perf_counter()
    routes, more, _ = open_routes(
        problem,
        main,
        local,
        lambda c: follow(c.name, c.fit, gs, data, c.structure, along),
        lambda message: say(progress, message),
        executor,
        ahead,
    )
    route_index, chosen, reason, members = choose_route(
        routes, data, validation, tol, local, l21.threshold
    )
    route = routes[route_index]
    route.say_warnings()
    grown = any(c.name.startswith(GROWN) for c in more)
    if grown:
        reason = f"{reason}; starts grown over the points were tried (lpvid.initial.grown)"
    timings["few_points_s"] = time.perf_counter() - t
    if route_index:
        chosen_start = next(c for c in more if c.name == route.name)
        start_model, start_name = chosen_start.start, chosen_start.name
        initial_reason = f"{initial_reason}; the {route.name} route's fit was then chosen"
    else:
        start_model, start_name = start.start, start.name
    e = route.entries[chosen]
    t = time.perf_counter()
    done = finish(
        e.model,
        e.gamma,
        data,
        route.fixed,
        l21.threshold,
        validation=validation,
        validation_vnls=e.validation_vnls,
        do_refit=settings.refit,
        stable=stable,
        p_range=p_range,
        time_data=time_cost,
    )
    reason = f"{reason}; {done.note}"
    refit_entry = (
        None
        if done.refit is None
        else path_entry(e.gamma, done.refit, data, validation, l21.threshold, time_cost)
    )
    final = refit_entry if done.refitted and refit_entry is not None else e
    wrong = misfit(
        final.vnls, final.noise_floor, local, final.validation_vnls, final.validation_floor
    )
    if wrong:
        reason = f"{reason}; a misfit: {wrong}"
        warnings.warn(
            f"identify: the model returned does not fit within the noise: {wrong}; every "
            f"route was tried ({len(routes)} followed through the path). Try: {advice(local)}",
            ConvergenceWarning,
            stacklevel=3,
        )
    elif grown and (far := far_fit(final.vnls, final.noise_floor, local)):
        reason = f"{reason}; still far: {far}"
        warnings.warn(
            f"identify: {far}, after starts grown over the points too. Try: {advice(local)}",
            ConvergenceWarning,
            stacklevel=3,
        )
    rises = bulge(done.model, data) if validation is None and time_cost is None else None
    if rises is not None and rises.bulges:
        reason = f"{reason}; it bulges: {rises.describe()}"
        warnings.warn(
            f"identify: the model returned is not to be trusted between the points: "
            f"{rises.describe()}, and no other fit within the noise avoids it. Measure an FRF "
            f"there (lpvid.next_points) or give validation data",
            ConvergenceWarning,
            stacklevel=3,
        )
    between = open_between(done, members, data, l21.threshold, time_cost)
    timings["finish_s"] = time.perf_counter() - t
    timings["total_s"] = time.perf_counter() - t0
    return IdentifyResult(
        model=done.model,
        chosen=chosen,
        reason=reason,
        entries=route.entries,
        initial=start_model,
        start=start_name,
        candidates=candidates + more,
        initial_reason=initial_reason,
        local=local,
        nls=route.nls,
        path=PathResult(route.results),
        data=data,
        validation=validation,
        timings=timings,
        time_data=time_cost,
        refit=done.refit,
        refit_entry=refit_entry,
        refitted=done.refitted,
        covariance=done.covariance,
        stability=done.stability,
        between=between,
        problem=problem,
    )


def _blocks_ahead(
    problem: Any, local: LocalModels, executor: Executor | None, along: Along, gammas: Any
) -> BlockPieces | None:
    """The blocks route's fits handed out before the main path, when it may need them.

    Without validation data or time records,
    :func:`lpvid.pipeline.opening.open_routes` takes them when the points
    leave the main path's structure open; the executor's threads fit them
    while the main path runs (a small run's fits take one core each), and
    then follow the paths of those it may follow
    (:class:`lpvid.pipeline.opening.FollowAhead`; ``along`` and
    ``gammas`` the main path's). The same fits and paths either way: only
    when they run changes. None without an executor, or when only a misfit
    could open the routes.
    """
    if executor is None or problem.validation is not None or problem.time_data is not None:
        return None
    starts = problem.settings.starts
    return hand_out_blocks(
        problem.data,
        problem.basis,
        problem.fixed,
        local,
        max_iter=starts.max_iter,
        ftol=starts.ftol,
        executor=executor,
        pieces=max(1, cores() - 1),
        after=FollowAhead(
            problem.data,
            tuple(float(g) for g in gammas),
            replace(along, say=_unsaid, executor=None),
            problem.settings.path.l21.threshold,
        ),
    )
