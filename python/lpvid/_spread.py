"""The independent work of one identify run on an executor, taken back in a fixed order.

:func:`lpvid.identify` hands the pieces of its work that do not depend on
one another (the refinement of every subspace start of the local models,
the runners of one round of the race of the starts, the blocks route's
starts, the warm and the pinned fit at one gamma)
to a :class:`concurrent.futures.Executor` when it is given one; when not,
a small run hands them to threads of its own (:func:`own_threads`) and a
large one runs them here, one after the other. Results are taken in the order
the pieces were handed out, never as they finish, and the core's fits are
the same to the last bit on any number of threads: the run is the same
wherever the pieces ran. Work may be handed out before the caller knows
it will need it (:meth:`Spread.hand_out`) and dropped when it does not.

A piece on a thread of this process runs the core's parallel loops in
order on its own thread (:func:`_run`): beside other pieces and the
caller's thread, loops handed to the core's pool from each of them would
queue there behind each other's, more threads than cores.

Ctrl-C reaches the main thread only, and the core notices it there alone.
When the wait for a piece is interrupted (or a piece fails), every piece
still out is dropped: those not started are cancelled; those running on a
thread of this process have their stop flag set, which their fits notice
at the next step as they notice Ctrl-C (:func:`stop_flag`, read by the
fitting functions), and the wait goes on until they have stopped, so that
nothing runs on once the KeyboardInterrupt is raised. Pieces running in
other processes (a Dask cluster) cannot be stopped from here: they finish
there and their results are dropped.

A piece's warnings are collected where it runs (:func:`lpvid._capture.collected`)
and raised again here when its result is taken.
"""

from __future__ import annotations

import os
import threading
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, ThreadPoolExecutor, wait
from concurrent.futures import TimeoutError as WaitTimeout  # not the builtin before 3.11
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid import _core
from lpvid._capture import collected
from lpvid._threads import single_blas

__all__ = [
    "POLL_S",
    "SMALL_RUN_BYTES",
    "Piece",
    "Spread",
    "THREAD_FLOPS",
    "check_executor",
    "cores",
    "own_threads",
    "product",
    "side_by_side",
    "stop_flag",
    "waited",
]

_STOP: ContextVar[threading.Event | None] = ContextVar("lpvid_stop", default=None)

#: Seconds between the main thread's looks at Ctrl-C while it waits for a
#: piece. A process-directed SIGINT may be delivered to a worker thread;
#: the main thread, blocked on a lock without a timeout, would then see it
#: only when the piece it waits for ends (never, when that piece waits for
#: the run to stop).
POLL_S = 0.05


def stop_flag() -> threading.Event | None:
    """The stop flag of the piece running in this thread (None outside a piece)."""
    return _STOP.get()


def waited(future: Future[Any]) -> Any:
    """``future.result()``, waited for in short waits so that Ctrl-C is seen (:data:`POLL_S`)."""
    while True:  # the main thread runs its signal handlers between the waits
        try:
            return future.result(timeout=POLL_S)
        except WaitTimeout:
            if future.done():  # the piece's own TimeoutError
                raise


def cores() -> int:
    """The cores this process may run on (its affinity where the system tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


#: The largest peak memory of one run (:func:`lpvid.fit.memory.pipeline_memory`)
#: for which :func:`own_threads` runs its pieces side by side.
SMALL_RUN_BYTES = 256 * 2**20


@contextmanager
def own_threads(
    executor: Executor | None,
    need: int,
    budget: int = SMALL_RUN_BYTES,
    *,
    threads: int | None = None,
) -> Iterator[Executor | None]:
    """``executor``; when None, threads of this process, one per core, for the ``with`` block.

    Only for work whose peak memory ``need`` is at most ``budget`` (by
    default a small run: at most :data:`SMALL_RUN_BYTES`), on more than one
    core, called from the main thread (a run on a thread of another pool, :func:`lpvid.select`'s or
    the caller's, is already spread with its siblings). A small model's fits
    hardly spread over the cores inside the core (a local model of ten
    states on one output and input takes the same time on one thread of
    the core's pool as on two), so two side by side on two threads take
    about half the time. A large model's fits take every core themselves:
    threads beside them gained 8 % at n = 16 and would hold two fits'
    memory at once (:func:`lpvid.identify`'s notes). ``need`` is what the
    work handed out needs, ``budget`` the most it may need: a whole run
    against :data:`SMALL_RUN_BYTES`, or a large run's local models side by
    side (one per core, :func:`lpvid.fit.memory.local_memory` each)
    against the run's own peak estimate. ``threads``: so many threads
    instead of one per core (:func:`side_by_side`, whose calls at once
    must fit the budget).
    """
    main = threading.current_thread() is threading.main_thread()
    if executor is not None or not main or cores() < 2 or need > budget:
        yield executor
        return
    with ThreadPoolExecutor(threads or cores(), thread_name_prefix="lpvid") as pool:
        yield pool


#: Work (floating-point operations) of each call from which :func:`side_by_side`
#: puts the calls on threads: some 50 ms of numpy on one core, against the
#: start of a thread pool and the calls' wait for each other's Python code.
THREAD_FLOPS = 1e8


def side_by_side(
    fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]], *, flops: float, each: int
) -> list[Any]:
    """``[fn(*args) for args in calls]``: numpy work that does not spread by itself, side by side.

    On threads of this process where :func:`own_threads` allows it (the
    main thread, more than one core), each call doing :data:`THREAD_FLOPS`
    or more (``flops``): one per core, or fewer, so that the calls at once
    (``each`` bytes each) need at most :data:`SMALL_RUN_BYTES`; else one
    after the other. Either way numpy's BLAS runs on one thread
    (:func:`lpvid._threads.single_blas`), as in a run, so that each call is
    the same to the last bit wherever it ran; the results come in the
    order of ``calls``, a failure as :meth:`Spread.map` raises it.
    """
    threads = min(cores(), len(calls), SMALL_RUN_BYTES // max(each, 1))

    @single_blas
    def run() -> list[Any]:
        if threads < 2 or flops < THREAD_FLOPS:
            return [fn(*args) for args in calls]
        with own_threads(None, threads * each, threads=threads) as pool:
            return Spread(pool).map(fn, calls)

    return run()


#: Columns of each block of :func:`product`.
PRODUCT_BLOCK = 512


def product(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a @ b`` of numpy arrays, in blocks of :data:`PRODUCT_BLOCK` columns side by side.

    A product of :data:`THREAD_FLOPS` or more per block goes block by block
    (:func:`side_by_side`: on threads, numpy's BLAS on one each); the blocks'
    cuts depend on the shape alone, so the result does not depend on the
    number of cores (a product cut into column blocks gave the bits of the
    whole on one thread, 2026-11-30). A smaller one is ``a @ b``.
    """
    rows, inner = a.shape
    cols = b.shape[1]
    flops = 2.0 * rows * inner * min(cols, PRODUCT_BLOCK)
    if cols <= PRODUCT_BLOCK or flops < THREAD_FLOPS:
        return a @ b
    out = np.empty((rows, cols), dtype=np.result_type(a, b))

    def block(first: int) -> None:
        out[:, first : first + PRODUCT_BLOCK] = a @ b[:, first : first + PRODUCT_BLOCK]

    starts = [(first,) for first in range(0, cols, PRODUCT_BLOCK)]
    side_by_side(block, starts, flops=flops, each=8 * rows * PRODUCT_BLOCK)
    return out


def check_executor(executor: Any) -> Executor | None:
    """``executor`` checked: None, a :class:`concurrent.futures.Executor`, or a Dask client.

    A ``distributed.Client`` (what Dask users hold) is taken as its
    ``get_executor()``: the same cluster, behind the Executor interface.
    A :class:`~concurrent.futures.ProcessPoolExecutor` that forks its
    workers (the default on Linux before Python 3.14) is refused: it forks
    them while lpvid may run on other threads of this process (its pieces
    on threads, the core's pool), and a lock one of them holds at that
    moment (the core's allocator's) would be held for good in the worker.
    (A process forked while lpvid is idle runs it on a thread pool of its
    own.)
    """
    if isinstance(executor, ProcessPoolExecutor) and _forks(executor):
        raise ValueError(
            "executor: this ProcessPoolExecutor forks its workers while lpvid may run on other "
            "threads of this process, and a lock held there at the fork would be held for good "
            "in the worker (its fits could hang). Create it with "
            "mp_context=multiprocessing.get_context('forkserver') (or 'spawn')"
        )
    if executor is None or isinstance(executor, Executor):
        return executor
    if _is_dask_client(executor):
        made = executor.get_executor()
        if isinstance(made, Executor):
            return made
    raise TypeError(
        f"executor: expected a concurrent.futures.Executor or a distributed.Client, "
        f"got {type(executor).__name__}"
    )


def _forks(pool: ProcessPoolExecutor) -> bool:
    """Whether ``pool`` starts its workers by fork (its context, where CPython keeps it)."""
    context = getattr(pool, "_mp_context", None)
    return context is not None and context.get_start_method() == "fork"


def _is_dask_client(obj: Any) -> bool:
    """Whether ``obj`` is a ``distributed.Client`` (known without importing distributed)."""
    return any(
        cls.__name__ == "Client" and cls.__module__.split(".")[0] == "distributed"
        for cls in type(obj).__mro__
    ) and callable(getattr(obj, "get_executor", None))


def _run(
    stop: threading.Event | None, fn: Callable[..., Any], args: tuple[Any, ...]
) -> tuple[Any, list[tuple[type[Warning], str]]]:
    """Run one piece where the executor put it, with its stop flag and its warnings collected.

    A piece on a thread of this process (``stop`` given) runs the core's
    loops in order on its thread (:func:`lpvid._core._loops_here`): the
    pieces beside it and the caller's thread have the cores, and loops
    handed to the core's pool from every one of them would wait for each
    other's there. The same results either way.
    """
    token = _STOP.set(stop)
    before = None if stop is None else _core._loops_here(True)
    try:
        with collected() as caught:
            out = fn(*args)
        return out, list(caught)
    finally:
        if before is not None:
            _core._loops_here(before)
        _STOP.reset(token)


@dataclass
class Piece:
    """One piece of work handed out (or, without an executor, still to be run here)."""

    fn: Callable[..., Any]
    args: tuple[Any, ...]
    future: Future[Any] | None = None
    stop: threading.Event | None = None


class Spread:
    """Pieces of work on ``executor`` (None: each runs here, when taken).

    The pieces handed out and not yet taken are kept, so that :meth:`drop`
    finds every one of them, however far a loop of submissions got when
    Ctrl-C came.
    """

    def __init__(self, executor: Executor | None) -> None:
        self.executor = check_executor(executor)
        # Only threads of this process share the stop flags.
        self._threads = isinstance(executor, ThreadPoolExecutor)
        self._out: list[Piece] = []

    @property
    def elsewhere(self) -> bool:
        """Whether pieces run outside this process (an executor other than threads)."""
        return self.executor is not None and not self._threads

    def submit(self, fn: Callable[..., Any], *args: Any) -> Piece:
        """Hand out ``fn(*args)``; without an executor it runs when taken."""
        piece = Piece(fn, args)
        if self.executor is not None:
            piece.stop = threading.Event() if self._threads else None
            self._out.append(piece)
            piece.future = self.executor.submit(_run, piece.stop, fn, args)
        return piece

    def take(self, piece: Piece) -> Any:
        """The piece's result (waiting for it); its warnings are raised again here."""
        if piece.future is None:
            return piece.fn(*piece.args)
        out, caught = waited(piece.future)
        self._out.remove(piece)
        for category, message in caught:
            warnings.warn(message, category, stacklevel=2)
        return out

    def drop(self) -> None:
        """Drop the pieces not taken: cancel those not started, stop those running on threads.

        Waits until the stopped ones have ended (their fits stop at their
        next step); those in other processes run on there.
        """
        running = []
        for p in self._out:
            if p.future is None or p.future.cancel():
                continue
            if p.stop is not None:
                p.stop.set()
                running.append(p.future)
        self._out.clear()
        if running:
            wait(running)

    def hand_out(self, fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]]) -> list[Piece]:
        """Hand out ``fn(*args)`` for every call now; :meth:`take_all` takes them later.

        Without an executor nothing runs until taken. Work handed out ahead of
        the need for it (before the caller knows whether it will take it)
        is dropped with :meth:`drop` when not needed.
        """
        try:
            return [self.submit(fn, *args) for args in calls]
        except BaseException:
            self.drop()
            raise

    def take_all(self, pieces: Sequence[Piece]) -> list[Any]:
        """The pieces' results, in their order.

        On a failure (or Ctrl-C) every piece still out is dropped
        (:meth:`drop`) and the first failure in that order raised.
        """
        try:
            return [self.take(p) for p in pieces]
        except BaseException:
            self.drop()
            raise

    def map(self, fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]]) -> list[Any]:
        """``[fn(*args) for args in calls]``, the calls spread over the executor.

        The results come in the order of ``calls``. When a call fails (or
        Ctrl-C interrupts), the first failure in that order is raised once
        every call still out is dropped (:meth:`drop`).
        """
        if self.executor is None or len(calls) < 2:
            return [fn(*args) for args in calls]
        return self.take_all(self.hand_out(fn, calls))
