"""Choose the order and the basis: :func:`identify` over a grid, on any executor.

Every (order, basis) pair is one :func:`lpvid.identify` run (and, without
validation data, one run per held-out scheduling point): independent work
handed to a :class:`concurrent.futures.Executor`, threads on the local cores
by default or a Dask cluster through its ``distributed.Client``.
What a task returns is assembled in the grid's order, so the result does not
depend on where or in which order the tasks ran.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable, Iterable, Mapping
from concurrent.futures import FIRST_COMPLETED, Executor, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lpvid._capture import collected
from lpvid._checks import positive_int
from lpvid._progress import Progress, check_progress, say
from lpvid._spread import POLL_S, check_executor
from lpvid._threads import single_blas
from lpvid.data.basis import Basis, Polynomial
from lpvid.data.frf import FrfData
from lpvid.fit.cost import vnls
from lpvid.fit.memory import pipeline_memory, runs_at_once
from lpvid.fit.settings import DEFAULT_GAMMAS, IdentifySettings, PathSettings
from lpvid.initial.orders import order_hints
from lpvid.model.layout import fixed_mask
from lpvid.pipeline.capacity import zero_model
from lpvid.pipeline.problem import IdentifyArguments, Problem, check_validation
from lpvid.pipeline.result import IdentifyResult
from lpvid.pipeline.run import identify
from lpvid.selection.result import GridRow, SelectResult, basis_label, choose_pair, free_in_use
from lpvid.selection.scales import log_grid

__all__ = ["held_out_points", "select"]


#: The error text of a pair that Ctrl-C cancelled.
CANCELLED = "cancelled"


@dataclass
class _Outcome:
    """What one task sends back: a result or a held-out V_NLS, or the error."""

    result: IdentifyResult | None = None
    vnls: float | None = None
    floor: int | None = None
    seconds: float = 0.0
    error: str | None = None
    warnings: list[tuple[type[Warning], str]] = field(default_factory=list)


def _run(job: Callable[[], _Outcome]) -> _Outcome:
    t0 = time.perf_counter()
    with collected() as caught:
        try:
            out = job()
        except Exception as exc:  # recorded in the grid, never lost
            out = _Outcome(error=f"{type(exc).__name__}: {exc}")
    out.seconds = time.perf_counter() - t0
    out.warnings = list(caught)
    return out


@dataclass(frozen=True)
class _Shared:
    """What every identify run of the grid shares: the data and the settings."""

    data: FrfData
    validation: FrfData | None
    time_data: Any
    settings: IdentifySettings

    def problem(self, order: int, basis: Basis, fixed: Any, point: int | None = None) -> Problem:
        """The problem of one pair (checked in its task), without ``point`` when given."""
        data, validation = self.data, self.validation
        if point is not None:
            data, validation = data.subset([q for q in range(data.n_points) if q != point]), None
        return Problem(
            data, order, basis, validation, fixed, self.time_data, settings=self.settings
        )


def _identify_task(shared: _Shared, order: int, basis: Basis, fixed: Any) -> _Outcome:
    """One pair on all the data (runs where the executor puts it)."""
    return _run(lambda: _Outcome(result=identify(shared.problem(order, basis, fixed))))


def _held_out_task(shared: _Shared, point: int, order: int, basis: Basis, fixed: Any) -> _Outcome:
    """One pair without scheduling point ``point``, judged at that point."""

    def job() -> _Outcome:
        res = identify(shared.problem(order, basis, fixed, point))
        out = shared.data.subset([point])
        return _Outcome(vnls=vnls(res.model, out), floor=out.n_residuals)

    return _run(job)


def held_out_points(data: FrfData, bases: Iterable[Basis]) -> list[int]:
    """The scheduling points the rotation holds out, in the data's order.

    The interior points (those not at the lowest or highest value of any
    scheduling parameter: the model is judged where it interpolates), when
    every basis leaves points to spare, ``N > Nb + 2``; else none.
    """
    if any(data.n_points <= len(b) + 2 for b in bases):
        return []
    p = data.p_rows
    edge = np.any((p == p.min(axis=0)) | (p == p.max(axis=0)), axis=1)
    return [int(q) for q in np.flatnonzero(~edge)]


def _orders(orders: Any) -> list[int]:
    try:
        values = list(orders)
    except TypeError as exc:
        raise TypeError(
            f"orders: expected a sequence of positive integers, got {type(orders).__name__}"
        ) from exc
    out = sorted(positive_int(n, "orders") for n in values)
    if not out:
        raise ValueError("orders: needs at least one order")
    if len(set(out)) < len(out):
        raise ValueError(f"orders: {sorted({n for n in out if out.count(n) > 1})} given twice")
    return out


def _bases(bases: Any, data: FrfData) -> list[Basis]:
    try:
        values = list(bases)
    except TypeError as exc:
        raise TypeError(
            f"bases: expected a sequence of lpvid bases or degrees, got {type(bases).__name__}"
        ) from exc
    out: list[Basis] = []
    for b in values:
        if not isinstance(b, Basis):
            degree = positive_int(b, "bases", minimum=0)
            b = Polynomial(degree, domain=data.p_range)
        if b.n_params != data.n_params:
            raise ValueError(
                f"bases: {basis_label(b)} takes {b.n_params} scheduling parameter(s), the data "
                f"have {data.n_params}"
            )
        if b in out:
            raise ValueError(f"bases: {basis_label(b)} given twice")
        out.append(b)
    if not out:
        raise ValueError("bases: needs at least one basis")
    return out


def _fixed_for(fixed: Any, order: int, basis: Basis, data: FrfData) -> Any:
    """The fixed parameters of one pair, checked against its layout."""
    spec = fixed(order, basis) if callable(fixed) else fixed
    if not callable(fixed) and spec is not None and not isinstance(spec, Mapping):
        raise TypeError(
            "fixed: a boolean mask over theta fits one order and basis only; give a dict such "
            "as {'D': True} or {'A': [0]}, or a callable (order, basis) -> fixed"
        )
    try:
        fixed_mask(zero_model(order, basis, data), spec)
    except (ValueError, TypeError) as exc:
        raise type(exc)(f"fixed: for order {order}, {basis_label(basis)}: {exc}") from exc
    return spec


@dataclass
class _Task:
    row: int
    point: int | None  # the held-out point, None for the run on all the data
    args: tuple[Any, ...]


def _message(row: GridRow, task: _Task, out: _Outcome, done: int, total: int) -> str:
    what = row.label if task.point is None else f"{row.label}, point {task.point} held out"
    count = f"({done}/{total})"
    if out.error is not None:
        return f"{what}: failed after {out.seconds:.1f} s: {out.error} {count}"
    if out.result is None:
        return f"{what}: V_NLS/floor {float(out.vnls) / float(out.floor):.3f} {count}"  # type: ignore[arg-type]
    e = out.result.final
    val = (
        ""
        if e.validation_vnls is None or not e.validation_floor
        else f", validation {e.validation_vnls / e.validation_floor:.3f}"
    )
    return (
        f"{what}: V_NLS/floor {e.vnls / e.noise_floor:.3f}{val}, {e.n_groups} groups, "
        f"{out.seconds:.1f} s {count}"
    )


def _submit(executor: Executor, task: _Task) -> Future[_Outcome]:
    fn = _identify_task if task.point is None else _held_out_task
    return executor.submit(fn, *task.args)


def _gather(
    executor: Executor,
    tasks: list[_Task],
    rows: list[GridRow],
    progress: Progress | None,
) -> tuple[dict[int, _Outcome], bool]:
    """Run the tasks, largest pairs first; returns the outcomes by task index and Ctrl-C."""
    size = {k: rows[t.row].order ** 2 * (len(rows[t.row].basis) + 1) for k, t in enumerate(tasks)}
    futures: dict[Future[_Outcome], int] = {}
    outcomes: dict[int, _Outcome] = {}

    def take(f: Future[_Outcome]) -> None:
        k = futures[f]
        try:
            out = f.result()
        except Exception as exc:  # the executor's own failure (pickling, a lost worker)
            out = _Outcome(error=f"{type(exc).__name__}: {exc}")
        outcomes[k] = out
        say(progress, _message(rows[tasks[k].row], tasks[k], out, len(outcomes), len(tasks)))

    try:
        for k in sorted(size, key=lambda k: -size[k]):
            futures[_submit(executor, tasks[k])] = k
        pending = set(futures)
        while pending:
            done, pending = wait(pending, timeout=POLL_S, return_when=FIRST_COMPLETED)
            for f in sorted(done, key=lambda f: futures[f]):
                take(f)
    except KeyboardInterrupt:
        for f in futures:
            f.cancel()
        for f in futures:  # what finished meanwhile is kept
            if futures[f] not in outcomes and f.done() and not f.cancelled():
                try:
                    take(f)
                except KeyboardInterrupt:
                    break
        return outcomes, True
    return outcomes, False


def _fill(
    rows: list[GridRow],
    tasks: list[_Task],
    outcomes: dict[int, _Outcome],
    fixed: list[Any],
    held_out: bool,
) -> None:
    """Write the outcomes into the rows, in the grid's order whatever the order they came in."""
    folds: dict[int, list[_Outcome | None]] = {}
    for k, task in enumerate(tasks):
        row, out = rows[task.row], outcomes.get(k)
        if task.point is not None:
            folds.setdefault(task.row, []).append(out)
        if out is None:
            continue
        row.seconds += out.seconds
        prefix = "" if task.point is None else f"held-out point {task.point}: "
        row.warnings += [(c, prefix + m) for c, m in out.warnings]
        if task.point is not None:
            if out.error is not None and row.error is None:
                row.error = f"{prefix}{out.error}"
            continue
        if out.error is not None or out.result is None:
            row.error = out.error
            continue
        res, e = out.result, out.result.final
        row.result = res
        row.vnls, row.noise_floor, row.n_groups = e.vnls, e.noise_floor, e.n_groups
        row.n_free = free_in_use(res.model, e.nonzero_groups, fixed[task.row])
        if not held_out:
            row.validation_vnls, row.validation_floor = e.validation_vnls, e.validation_floor
    for i, row in enumerate(rows):
        outs = folds.get(i, [])
        if row.error is None and not row.ok:
            row.error = CANCELLED
        elif held_out and row.error is None:
            if any(o is None for o in outs):
                row.error = "held-out rotation cancelled"
            else:
                row.validation_vnls = float(sum(float(o.vnls) for o in outs))  # type: ignore[union-attr,arg-type]
                row.validation_floor = int(sum(int(o.floor) for o in outs))  # type: ignore[union-attr,arg-type]


@single_blas
def select(
    data: FrfData | Problem,
    orders: Iterable[int],
    bases: Iterable[Basis | int],
    validation: FrfData | None = None,
    gammas: Any = None,
    fixed: Any = None,
    *,
    executor: Any = None,
    tolerance: float = 0.1,
    progress: Progress | None = None,
    log_scale: Any = "auto",
) -> SelectResult:
    """Choose the model order and the basis: :func:`lpvid.identify` for every pair, then a choice.

    Every (order, basis) pair of the grid is identified by
    :func:`lpvid.identify` (its own choice of gamma included), the runs
    spread over ``executor``. The choice:

    - with ``validation`` data: among the pairs whose validation V_NLS is
      within ``tolerance`` of the best, the simplest (fewest free parameters
      in use: those of the constant parts and of the groups kept, fixed ones
      not counted), then the fewest basis functions, then the lowest
      validation V_NLS;
    - without, when every basis leaves scheduling points to spare
      (``N > Nb + 2``): the same rule on the V_NLS at held-out points, each
      interior scheduling point held out in turn (the pair identified on the
      other points and judged at that one; :func:`held_out_points`), which
      costs one more identify run per pair and point;
    - else the smallest order, then the fewest basis functions, whose V_NLS
      reaches the noise floor (``V_NLS <= M + 2 sqrt(M)``).

    A scheduling parameter whose values are above zero and span more than
    a decade is tried on the log scale too (``log_scale``): every
    polynomial basis gets a twin on that scale, judged with the others;
    ``result.scales`` (the table's last line) says what was tried, why, and
    which scale the chosen pair is on.

    A pair that fails (an order beyond what the data determine, a singular
    model, no start) is recorded in the grid with its error and the others
    go on. Ctrl-C cancels the runs not started and returns what is done
    (``result.interrupted``); runs already going on threads finish in the
    background. The warnings of each run are collected in its row
    (``row.warnings``); those of the chosen pair's run on all the data are
    raised again, prefixed with the pair.

    Memory: each identify run needs what :func:`lpvid.identify` says
    (about ``8 P^2`` bytes for ``J^T J`` of its ``P = (Nb + 1)(n + l)(n + r)``
    parameters, twice that during a step, ``144 K^2`` for the cone programs,
    ``K = Nb P / (Nb + 1)``, ``64 P^2`` for the covariance, then half as
    much again and 64 MB: :func:`lpvid.fit.memory.pipeline_memory`), and with
    the default threads the runs that go on
    at once add up: fewer threads run at once when the largest runs would
    not fit together in what the process may allocate
    (:func:`lpvid.available_memory`), and a pair that does not fit alone is
    recorded in the grid with its ``MemoryError`` before any work.

    Parameters
    ----------
    data : FrfData or Problem
        Identification data; or a :class:`lpvid.Problem`, whose data,
        validation data, time records, fixed parameters and settings every
        run of the grid takes (its order, basis and scheduling range are
        not used: each pair has its own), ``validation``, ``gammas``,
        ``fixed`` and ``tolerance`` then left out.
    orders : iterable of int
        Model orders to try.
    bases : iterable of Basis or int
        Bases to try; an int ``d`` is ``Polynomial(d, domain=data.p_range)``.
    validation : FrfData, optional
        Data at other scheduling values; judges the pairs (and each
        identify run's choice of gamma).
    gammas : sequence of float, optional
        Regularisation weights of every run (see :func:`lpvid.identify`).
    fixed : None, dict or callable, optional
        Fixed parameters of every pair: a dict as in :func:`lpvid.fixed_mask`
        that fits every order and basis (``{"D": True}``; ``{"A": [0]}``
        and other coefficient indices that every basis has; boolean arrays
        of the shape of D), or a callable ``fixed(order, basis)`` returning
        the fixed parameters of that pair in any form
        :func:`lpvid.fixed_mask` takes. A boolean mask over theta is
        refused: it fits one order and basis only.
    executor : concurrent.futures.Executor or distributed.Client, optional
        Where the runs go. Default: a thread pool with one thread per core
        (the fits release the GIL). A Dask cluster: its
        ``distributed.Client(address)`` (or its ``get_executor()``); its workers need
        lpvid, and everything sent pickles (data, bases, results). The
        pairs already run side by side: each identify run gets no
        executor of its own (its fits run one after the other in its task;
        see :func:`lpvid.identify`'s ``executor``).
    tolerance : float
        Relative slack on the best validation (or held-out) V_NLS; also
        passed to every identify run.
    progress : callable, optional
        Called with a short message as each run ends (in the calling
        thread; the same messages go to the ``lpvid`` logger at INFO).
    log_scale : {"auto", True, False}
        ``"auto"``: the rule above (:mod:`lpvid.selection.scales`);
        ``True``: the log scale tried for every parameter above zero;
        ``False``: the bases as given.

    Returns
    -------
    SelectResult

    Raises
    ------
    ValueError, TypeError
        On bad arguments (naming the argument), and when no pair of the grid
        could be identified (the message lists why).
    MemoryError
        Before any work, with the default threads, when not one pair of the
        grid fits in what the process may allocate.
    KeyboardInterrupt
        When Ctrl-C stops the run before any pair is done.

    Examples
    --------
    >>> import numpy as np, lpvid, lpvid.testing
    >>> rng = np.random.default_rng(0)
    >>> true = lpvid.testing.modal_lpv([[10.0, 3.0]])  # order 2, linear in p
    >>> f = np.linspace(2, 30, 40)
    >>> data = lpvid.testing.noisy_data(true, [0.0, 0.5, 1.0], f, rng, 0.01)
    >>> val = lpvid.testing.noisy_data(true, [0.25, 0.75], f, rng, 0.01)
    >>> sel = lpvid.select(data, [1, 2, 3], [1, 2], validation=val)
    >>> sel.order, sel.basis.degree, sel.rule
    (2, 1, 'validation')

    """
    t0 = time.perf_counter()
    if isinstance(data, Problem):
        shared_args = IdentifyArguments(
            validation=validation, gammas=gammas, fixed=fixed, tolerance=tolerance
        )
        shared_args.refuse()
        problem = data
        data, validation, fixed = problem.data, problem.validation, problem.fixed
        ns, bs = _orders(orders), _bases(bases, data)
        shared = _Shared(data, validation, problem.time_data, problem.settings)
    else:
        if not isinstance(data, FrfData):
            raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
        validation = check_validation(data, validation)
        ns, bs = _orders(orders), _bases(bases, data)
        gs = DEFAULT_GAMMAS if gammas is None else gammas
        path = PathSettings(gammas=gs, tolerance=tolerance)
        shared = _Shared(data, validation, None, IdentifySettings(path=path))
    tol = shared.settings.path.tolerance
    bs, why = log_grid(bs, data, validation, log_scale)
    executor = check_executor(executor)
    progress = check_progress(progress)
    pairs = [(n, b) for n in ns for b in bs]
    fixes = [_fixed_for(fixed, n, b, data) for n, b in pairs]
    hints = order_hints(data)
    say(progress, str(hints))
    points = [] if validation is not None else held_out_points(data, bs)
    rule = "validation" if validation is not None else "held-out" if points else "noise floor"
    rows = [GridRow(order=n, basis=b) for n, b in pairs]
    tasks = [_Task(i, None, (shared, n, b, fixes[i])) for i, (n, b) in enumerate(pairs)]
    tasks += [
        _Task(i, q, (shared, q, n, b, fixes[i])) for i, (n, b) in enumerate(pairs) for q in points
    ]
    say(progress, f"{len(pairs)} pairs, {len(tasks)} identify runs; the pairs judged by {rule}")
    own = None
    if executor is None:
        needs = [pipeline_memory(data, n, b)[0] for n, b in pairs]
        at_once = runs_at_once(needs, min(len(tasks), os.cpu_count() or 1), "select")
        own = ThreadPoolExecutor(max_workers=at_once)
    try:
        outcomes, interrupted = _gather(executor or own, tasks, rows, progress)  # type: ignore[arg-type]
    finally:
        if own is not None:
            own.shutdown(wait=False, cancel_futures=True)
    _fill(rows, tasks, outcomes, fixes, rule == "held-out")
    try:
        chosen, reason = choose_pair(rows, rule, tol)
    except ValueError:
        if interrupted:
            raise KeyboardInterrupt("select: interrupted before any pair was done") from None
        why = "; ".join(f"{r.label}: {' '.join(str(r.error).split())}" for r in rows)
        raise ValueError(f"select: no pair of the grid could be identified: {why}") from None
    result = SelectResult(
        grid=rows,
        chosen=chosen,
        reason=reason,
        rule=rule,
        tolerance=tol,
        hints=hints,
        interrupted=interrupted,
        timings={"total_s": time.perf_counter() - t0},
        scales=why,
    )
    row = result.row
    for category, message in row.warnings:
        if not message.startswith("held-out point"):
            warnings.warn(f"{row.label}: {message}", category, stacklevel=3)
    return result
