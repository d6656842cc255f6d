"""Memory: what a fit needs, what the process may still allocate, and MemoryError first.

A fit's peak memory is estimated from the sizes of the problem by the core
(``rust/fit/estimate.rs``: every large array the fit allocates, read off
the code that allocates it, and checked against the peak a counting
allocator measures in ``tests/core_memory.rs``). What the process may still
allocate is the smallest of the address-space limit (``RLIMIT_AS``, e.g.
``prlimit --as`` or ``ulimit -v``) less the address space in use, the memory
limit of the process's cgroup (a container's limit) less its usage, and the
system's ``MemAvailable`` (Linux; elsewhere nothing is known and nothing is
refused). :func:`fit_nls`, :func:`fit_l21`, :func:`l21_path`,
:func:`identify`, :func:`select` and :func:`fit_time` compare the two before
any work and raise :class:`MemoryError` naming both when the fit cannot fit.
An allocation that still fails in the core (the estimate is of the fit
alone; other threads may take memory meanwhile) raises ``MemoryError`` with
the size of the array, never a crash.

The figure checked is :func:`resident` of the arrays' peak: half as much
again for what the memory allocators hold back (freed blocks kept for
reuse) and 64 MB for the first run in a process (:data:`RESIDENT`,
:data:`FIRST_RUN`, measured with ``benches/bench_scale.py``).

In bytes, with ``P = (Nb + 1)(n + l)(n + r)`` free parameters (fewer when
some are fixed), ``L = (n + l)(n + r)`` parameters of one LTI model,
``F_t = 4 floor(128 / (l r))`` lines per block and ``t`` threads (the main
terms of the estimate; :func:`fit_memory` gives the whole of it):

- one Gauss-Newton evaluation of FRF data, the largest of
  ``4 L^2 min(N B, N + t B)`` with ``B = ceil(F / F_t)`` blocks of lines
  per point (each point's running sum of its blocks' Gram pieces, and the
  pieces that wait for an earlier block of their point),
  ``8 L^2 N`` plus ``4 L^2 (Nb + 1)(Nb + 2)`` (the points' Gram matrices
  and their sums per pair of basis functions) plus ``8 P^2`` (``J^T J``),
  and ``16 N F l r`` for the residuals;
- Levenberg-Marquardt: that evaluation plus ``8 P^2`` (the matrix of the
  current point) and, during a step, ``8 P^2`` (its Cholesky factor);
- the l2,1 fit: ``8 P^2`` plus one cone program, about ``144 K^2 / 2``
  bytes for ``K = Nb/(Nb + 1) P`` grouped parameters (Clarabel's copy of
  the dense block, its KKT matrix and factor, and the program as built),
  kept between steps, plus the evaluation;
- time records (``T`` samples, ``S`` = free parameters of A and B plus
  ``n``): ``8 S^2 (t + 1)`` (the threads' sums and the Gram matrix of a
  record), ``16 (2048 / l) l S`` (a block of Jacobian rows) and, for a
  continuous-time model, ``8 (2048 / l) n^2 (n + r)`` (the hold's
  derivatives of a block).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid import _core
from lpvid.fit._limits import available_memory, human

__all__ = [
    "available_memory",
    "check_covariance",
    "check_fit",
    "check_memory",
    "covariance_memory",
    "fit_memory",
    "human",
    "local_memory",
    "pipeline_memory",
    "resident",
    "runs_at_once",
    "sizes_memory",
]

#: Resident memory per byte of a run's arrays at their peak: blocks freed
#: and kept by the allocators for reuse (the extension's keeps up to 1 GB
#: of its large blocks, ``rust/memory/blocks.rs``; glibc's heaps up to
#: 16 MB at their tops) make the process grow by more than the arrays alive
#: at once. Measured with ``benches/bench_scale.py`` (identify's own growth
#: of the peak resident memory over the core's estimate of its arrays):
#: 1.27-1.30 at n = 16 2x2 (394-402 MB against 310 MB) and 1.20-1.23 at
#: n = 24 3x3 (1128-1157 against 937 MB). Before the extension allocated
#: its large blocks itself, glibc kept them in its heaps and n = 16 grew by
#: 371 to 744 MB from run to run.
RESIDENT = 1.5

#: What the first run in a process adds besides its arrays: modules loaded
#: on first use, BLAS buffers, thread stacks. Measured: identify's growth
#: was 34-76 MB on the gantry-size rungs, whose arrays are 9-16 MB.
FIRST_RUN = 64 << 20


def sizes_memory(
    n: int,
    l: int,
    r: int,
    nb: int,
    *,
    method: str = "lm",
    frf: tuple[int, int] | None = None,
    records: Sequence[int] | None = None,
    continuous: bool = False,
    estimate_x0: bool = True,
    free: NDArray[np.bool_] | None = None,
    pinned: bool = False,
) -> dict[str, int]:
    """The core's estimate of a fit's peak memory from the sizes, by part (bytes).

    Parameters
    ----------
    n, l, r, nb : int
        States, outputs, inputs, basis functions.
    method : {"lm", "l21"}
        Levenberg-Marquardt, or the l2,1 cone steps.
    frf : (N, F), optional
        Scheduling points and frequency lines of FRF data.
    records : sequence of int, optional
        Samples of every time record.
    continuous : bool
        The time records belong to a continuous-time model (zero-order hold).
    estimate_x0 : bool
        The records' initial states are estimated.
    free : bool array over theta, optional
        Free parameters (default all).
    pinned : bool
        The l2,1 fit keeps its steps off flat directions (one more dense matrix).

    Returns
    -------
    dict
        ``evaluation`` (one Gauss-Newton evaluation), ``held`` (what the
        optimiser keeps), ``step`` (one step beyond that), ``total`` (the
        peak) and the ``threads`` of the core's pool it was made for.
    """
    return dict(
        _core.fit_memory(
            (n, r, l, nb),
            method,
            None if free is None else np.ascontiguousarray(free, dtype=bool),
            frf,
            None if records is None else [int(t) for t in records],
            continuous,
            estimate_x0,
            pinned,
        )
    )


def resident(nbytes: int) -> int:
    """What a run whose arrays peak at ``nbytes`` needs of the machine.

    ``RESIDENT * nbytes + FIRST_RUN`` (:data:`RESIDENT`, :data:`FIRST_RUN`).
    """
    return int(RESIDENT * nbytes) + FIRST_RUN


def _shape(model: Any) -> tuple[int, int, int, int]:
    """``model.shape`` from the arrays (``(n, r, l, Nb)``; without naming the basis functions)."""
    nb1, l, n = model.C.shape
    return n, model.B.shape[2], l, nb1 - 1


def _sizes(data: Any, time_data: Any, continuous: bool) -> dict[str, Any]:
    """The keyword arguments of :func:`sizes_memory` for FRF data and time records."""
    from lpvid.fit.timecost import as_time_cost

    records, x0 = None, True
    if time_data is not None:
        cost = as_time_cost(time_data)
        records = cost.data.n_samples
        x0 = isinstance(cost.x0, str) and cost.x0 == "estimate"
    return dict(
        frf=None if data is None else (data.n_points, data.n_lines),
        records=records,
        continuous=continuous,
        estimate_x0=x0,
    )


def fit_memory(
    model: Any,
    data: Any = None,
    *,
    method: str = "lm",
    fixed: Any = None,
    time_data: Any = None,
    pinned: bool = False,
) -> int:
    """Bytes a fit of ``model`` needs of the machine at its peak: the figure the fits check.

    The core's estimate of the fit's arrays at their peak
    (:func:`sizes_memory`), times :data:`RESIDENT` (what the memory
    allocator holds back), plus :data:`FIRST_RUN`.

    Parameters
    ----------
    model : LpvModel
        The model to fit (its shape and basis).
    data : FrfData, optional
        FRF data.
    method : {"lm", "l21"}
        :func:`lpvid.fit_nls` / :func:`lpvid.fit_time` (``"lm"``) or
        :func:`lpvid.fit_l21` / :func:`lpvid.l21_path` (``"l21"``).
    fixed : optional
        Fixed parameters, as in :func:`lpvid.fixed_mask`.
    time_data : TimeData or TimeCost, optional
        Time records (alone, or beside ``data``).
    pinned : bool
        As in :func:`lpvid.fit_l21`.

    Returns
    -------
    int

    Examples
    --------
    >>> import lpvid
    >>> ds = lpvid.datasets.gantry()
    >>> start = lpvid.identify(ds.identification, ds.order, ds.basis).model
    >>> need = lpvid.fit_memory(start, ds.identification)
    >>> 1e6 < need < 1e8
    True

    """
    from lpvid.model.layout import free_mask

    n, r, l, nb = _shape(model)
    arrays = sizes_memory(
        n,
        l,
        r,
        nb,
        method=method,
        free=free_mask(model, fixed),
        pinned=pinned,
        **_sizes(data, time_data, model.Ts is None),
    )["total"]
    return resident(arrays)


def covariance_memory(n_free: int, n_params: int) -> int:
    """Bytes :func:`lpvid.covariance` needs at its peak (numpy, not the core).

    ``J^T J``, the basis of the complement of the similarity directions,
    the projected matrix and its scaled copy, LAPACK's copy and workspace
    of the eigendecomposition (``syevd``: about twice the matrix) and the
    eigenvectors: eight ``n_free x n_free`` matrices, then the
    ``n_params x n_params`` result.
    """
    return 8 * (8 * n_free * n_free + n_params * n_params)


def check_memory(need: int, what: str, sizes: str | Callable[[], str] = "") -> None:
    """Raise :class:`MemoryError` when ``need`` bytes are more than the process may allocate.

    Parameters
    ----------
    need : int
        Bytes the run needs at its peak (an estimate).
    what : str
        The run, for the message (e.g. ``"fit_nls"``).
    sizes : str or callable
        The sizes the estimate comes from, for the message (or the call that
        says them, made only for the message).
    """
    room, source = available_memory()
    if room is None or need <= room:
        return
    said = sizes() if callable(sizes) else sizes
    of = f" ({said})" if said else ""
    raise MemoryError(
        f"{what} needs about {human(need)} ({need} bytes) of memory at its peak{of}, "
        f"estimated from its sizes before any work, and this process can allocate "
        f"{human(room)} more: {source}. Fewer states, basis functions, lines or points (or "
        "fixed parameters) make it smaller; lpvid.fit_memory gives the estimate."
    )


def _describe(n: int, l: int, r: int, nb: int, n_free: int, sizes: dict[str, Any]) -> str:
    """The sizes behind an estimate, for messages."""
    parts = [f"n = {n}, {l} output(s) x {r} input(s), Nb = {nb}, {n_free} free parameters"]
    frf, records = sizes.get("frf"), sizes.get("records")
    if frf is not None:
        parts.append(f"N = {frf[0]} points, F = {frf[1]} lines")
    if records is not None:
        parts.append(f"{len(records)} time record(s) of up to {max(records)} samples")
    return "; ".join(parts)


def check_fit(
    what: str,
    model: Any,
    data: Any,
    free: NDArray[np.bool_],
    method: str,
    time_data: Any = None,
    pinned: bool = False,
) -> None:
    """:func:`check_memory` for one fit of ``model`` (the fitting functions call it first)."""
    n, r, l, nb = _shape(model)
    sizes = _sizes(data, time_data, model.Ts is None)
    arrays = sizes_memory(n, l, r, nb, method=method, free=free, pinned=pinned, **sizes)["total"]
    check_memory(resident(arrays), what, lambda: _describe(n, l, r, nb, int(np.sum(free)), sizes))


def check_covariance(model: Any, data: Any, free: NDArray[np.bool_]) -> None:
    """:func:`check_memory` for :func:`lpvid.covariance`: one evaluation, then numpy's share."""
    n, r, l, nb = _shape(model)
    sizes = _sizes(data, None, model.Ts is None)
    n_free = int(np.sum(free))
    evaluation = sizes_memory(n, l, r, nb, free=free, **sizes)["evaluation"]
    need = resident(evaluation + covariance_memory(n_free, free.size))
    check_memory(need, "covariance", lambda: _describe(n, l, r, nb, n_free, sizes))


def pipeline_memory(
    data: Any, order: int, basis: Any, time_data: Any = None, refit: bool = True
) -> tuple[int, str]:
    """Bytes one :func:`lpvid.identify` run needs at its peak, and the sizes, for messages.

    The arrays of the largest of its fits with every parameter free (the
    Levenberg-Marquardt fits of the starts, the l2,1 fits of the path with
    the pinned directions, and with ``refit`` the covariance of the chosen
    model, :func:`covariance_memory`), as :func:`resident` memory. The local
    models (the subspace step: 63 MB of numpy arrays at n = 24 3x3 with
    1000 lines), SMILE and the results kept along the way are smaller.
    Against ``benches/bench_scale.py`` (identify's own growth of the peak
    resident memory, 2026-11-27, one cone program at a time): gantry 8 MB
    against this 96 MB, n = 10 2x2 39 against 103 MB, n = 16 2x2 185
    against 394 MB, n = 24 3x3 661 against 1155 MB, n = 32 4x4 1547
    against 5333 MB.
    """
    l, r, nb = data.n_outputs, data.n_inputs, len(basis)
    sizes = _sizes(data, time_data, data.Ts is None)
    lm = sizes_memory(order, l, r, nb, method="lm", **sizes)
    path = sizes_memory(order, l, r, nb, method="l21", pinned=True, **sizes)
    n_params = (nb + 1) * (order + l) * (order + r)
    arrays = max(lm["total"], path["total"])
    if refit:
        arrays = max(arrays, lm["evaluation"] + covariance_memory(n_params, n_params))
    return resident(arrays), _describe(order, l, r, nb, n_params, sizes)


def local_memory(data: Any, order: int) -> int:
    """Bytes one local model's fit needs at its peak: one point of ``data``, an LTI model.

    The Levenberg-Marquardt fit of :func:`sizes_memory` at one point with a
    constant basis, as :func:`resident` memory: what each of the local
    models' refinements side by side on a thread of its own adds
    (:func:`lpvid.identify`).
    """
    lm = sizes_memory(
        order,
        data.n_outputs,
        data.n_inputs,
        0,
        method="lm",
        frf=(1, data.n_lines),
        continuous=data.Ts is None,
    )
    return resident(lm["total"])


def runs_at_once(needs: Sequence[int], most: int, what: str) -> int:
    """How many runs with these peak needs may go on at once in this process.

    At most ``most``, and no more than the largest of the runs that fit
    alone together fit in what the process may allocate. Raises
    :class:`MemoryError` when not one run fits alone.
    """
    room, source = available_memory()
    if room is None or not needs:
        return most
    fitting = sorted((x for x in needs if x <= room), reverse=True)
    if not fitting:
        raise MemoryError(
            f"{what}: every run needs more memory than this process can allocate: the "
            f"smallest about {human(min(needs))}, against {human(room)} ({source})"
        )
    at_once = max(most, 1)
    while at_once > 1 and sum(fitting[:at_once]) > room:
        at_once -= 1
    return at_once
