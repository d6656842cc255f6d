"""The report's figures: which ones, and drawing them here or in worker processes.

Each figure is a :class:`FigureJob`: the name of a builder in
:mod:`lpvid.plots`, its arguments, and the file it is saved to. Jobs pickle,
so a process pool can draw them on other cores at the same time; threads do
not help, because matplotlib holds the GIL while it lays out and renders.
:class:`FigurePool` is such a pool, whose workers start and import
matplotlib in the background while the caller still computes;
:func:`start_drawing` draws a list of jobs in it, or here one after the
other when there is no pool.
"""

from __future__ import annotations

import multiprocessing
import signal
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures import wait as wait_for
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from lpvid._spread import waited
from lpvid.pipeline.result import IdentifyResult

T = TypeVar("T")

__all__ = ["Drawing", "FigureJob", "report_jobs", "draw", "start_drawing", "FigurePool"]


@dataclass(frozen=True)
class FigureJob:
    """One figure of a report: ``lpvid.plots.<builder>(*args, **kwargs)`` saved as ``name``."""

    builder: str
    name: str
    caption: str
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)


def report_jobs(result: IdentifyResult, labels: dict[str, Any]) -> list[FigureJob]:
    """The figures of :func:`lpvid.report.markdown.write_report` for ``result``, in report order."""
    model, data, cov = result.model, result.data, result.covariance
    jobs = [
        FigureJob(
            "frf_fit",
            "frf_identification.png",
            "Measured FRF, model FRF, error |G - Gm| and sigma at the identification points",
            (model, data),
            {"title": "identification points", **labels},
        )
    ]
    if result.validation is not None:
        jobs.append(
            FigureJob(
                "frf_fit",
                "frf_validation.png",
                "The same at the validation points",
                (model, result.validation),
                {"title": "validation points", **labels},
            )
        )
    # Even on the basis's scale (log10(p) for a basis on the log scale).
    spread = np.geomspace if model.basis.scales[0] == "log" else np.linspace
    p_grid = spread(*data.p_range, 60) if data.n_params == 1 else None
    if p_grid is not None:
        jobs.append(
            FigureJob(
                "magnitude_surface",
                "surface.png",
                "Magnitude of the chosen model over frequency and scheduling",
                (model, data.freqs_hz, p_grid),
                {"p_marks": data.p, **labels},
            )
        )
    if cov is not None:
        band = {k: v for k, v in labels.items() if k != "p_label"}
        band["p_label"] = labels.get("p_label", "p")
        jobs.append(
            FigureJob(
                "frf_band",
                "band_identification.png",
                "Model FRF with its 95 % band (first-order covariance) and the measured FRF "
                "at the identification points",
                (cov, data),
                {"title": "identification points", **band},
            )
        )
        if result.validation is not None:
            jobs.append(
                FigureJob(
                    "frf_band",
                    "band_validation.png",
                    "The same at the validation points, where the model was not fitted",
                    (cov, result.validation),
                    {"title": "validation points", **band},
                )
            )
        if p_grid is not None:
            jobs.append(
                FigureJob(
                    "frf_std_map",
                    "band_map.png",
                    "Width of the 95 % band relative to |G_m| over frequency and scheduling "
                    "(first output and input; dashed: identification points)",
                    (cov, data.freqs_hz, p_grid),
                    {"p_marks": data.p, "p_label": band["p_label"]},
                )
            )
    jobs.append(
        FigureJob(
            "group_norms",
            "group_norms.png",
            "Relative group magnitudes of the SMILE model and the chosen model",
            ({"SMILE": result.initial, "chosen": model},),
        )
    )
    # The entries carry the unregularised model and, when given, validation V_NLS
    # with its noise floor.
    jobs.append(
        FigureJob(
            "accuracy_path",
            "path.png",
            "Accuracy against simplicity along the l2,1 path",
            (result.entries,),
            {"chosen": result.chosen},
        )
    )
    return jobs


def draw(job: FigureJob, folder: Path) -> Path:
    """Build the figure of ``job`` and save it in ``folder``; returns the file written."""
    from lpvid import plots

    return plots.save(getattr(plots, job.builder)(*job.args, **job.kwargs), folder / job.name)


class Drawing:
    """Figures being drawn (:func:`start_drawing`): call it to wait for them."""

    def __init__(
        self, jobs: Sequence[FigureJob], folder: Path, pool: Executor | None = None
    ) -> None:
        self.jobs, self.folder, self.pool = list(jobs), folder, pool
        folder.mkdir(parents=True, exist_ok=True)
        self.futures: list[Future[Path]] = (
            [pool.submit(draw, job, folder) for job in self.jobs] if pool else []
        )

    def __call__(self) -> list[tuple[str, str]]:
        """Wait: (caption, path relative to the folder's parent) of every figure.

        Raises the first failure (cancelling the jobs not yet started); an
        interruption is raised as it is.
        """
        if self.pool is None:
            for job in self.jobs:
                draw(job, self.folder)
        try:
            for fut in self.futures:
                waited(fut)
        except BaseException:
            self.abandon()
            raise
        return [(job.caption, f"{self.folder.name}/{job.name}") for job in self.jobs]

    def abandon(self) -> None:
        """Cancel the jobs not started and wait for those running (their outcome dropped).

        After it no worker writes into the folder any more: the caller may
        remove it.
        """
        for fut in self.futures:
            fut.cancel()
        running = [f for f in self.futures if not f.cancelled()]
        wait_for(running)


def start_drawing(jobs: Sequence[FigureJob], folder: Path, pool: Executor | None = None) -> Drawing:
    """Start drawing ``jobs`` into ``folder``; returns the :class:`Drawing` to wait for.

    With a ``pool``, the jobs are submitted now and run while the caller goes
    on; without, they are drawn here, one after the other, when the returned
    call is made. The call returns (caption, path relative to the folder's
    parent) pairs once every figure is written, or raises the first failure
    (cancelling the jobs not yet started); an interruption is raised as it is.
    ``abandon()`` stops the drawing (for a caller that gives up the folder).
    """
    return Drawing(jobs, folder, pool)


#: Modules the forkserver imports before it forks workers (none picks a backend).
_PRELOAD = (
    "lpvid.report.figures",
    "lpvid.plots",
    "matplotlib.figure",
    "matplotlib.backends.backend_agg",
)


def _start_forkserver() -> None:
    """Start the forkserver (when it is not running) with Ctrl-C blocked in it.

    A signal mask is inherited through fork and exec: the server and every
    worker forked from it never see SIGINT, also while the server imports
    its preload list (Python would print a traceback there). Here, a SIGINT
    that arrives meanwhile stays pending and is delivered when the mask is
    restored; none is lost.
    """
    from multiprocessing import forkserver, resource_tracker

    # The resource tracker's start unblocks SIGINT when it is done: start it first.
    resource_tracker.ensure_running()
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        forkserver.ensure_running()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _ignore_sigint() -> None:
    """Workers leave Ctrl-C to the caller (it cancels what is queued and shuts them down)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _warm() -> None:
    """A worker's first job: import matplotlib's pyplot (when it is installed)."""
    try:
        from lpvid.plots._style import _pyplot

        _pyplot()
    except ImportError:
        pass  # the figure jobs raise it, with the install hint


class FigurePool(ProcessPoolExecutor):
    """A process pool for :func:`start_drawing`, whose workers start in the background.

    The workers are started from a fresh interpreter (``forkserver`` where
    there is one, else ``spawn``), never forked from this process: lpvid's
    core runs threads, and a fork copies their locks but not the threads.
    With ``forkserver``, the server imports lpvid's plots and matplotlib's
    figure and Agg modules once, and each worker forked from it starts with
    them (this sets the process's forkserver preload list; it has no effect
    when the server runs already). A thread starts the workers and has each
    import matplotlib's pyplot, so that the constructor returns at once and
    the workers warm up while the caller computes. The workers ignore
    Ctrl-C (SIGINT): the caller's interruption cancels what is queued, and
    the shutdown waits for the figures being drawn. Shut it down when done
    (``pool.shutdown()`` or a ``with`` block).

    Parameters
    ----------
    workers : int
        Worker processes (at least one).

    Raises
    ------
    ValueError
        When ``workers`` is not a positive integer.
    OSError
        When this system has no process pools (no semaphores, say).
    """

    def __init__(self, workers: int = 2) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers: expected a positive integer, got {workers!r}")
        if "forkserver" in multiprocessing.get_all_start_methods():
            context = multiprocessing.get_context("forkserver")
            context.set_forkserver_preload(list(_PRELOAD))
            _start_forkserver()
        else:
            context = multiprocessing.get_context("spawn")
        super().__init__(workers, mp_context=context, initializer=_ignore_sigint)
        self.workers = workers
        self._start_error: BaseException | None = None
        self._starting = threading.Thread(
            target=self._start_workers, name="lpvid-figure-pool", daemon=True
        )
        self._starting.start()

    def _start_workers(self) -> None:
        """Start every worker (a launch waits for the forkserver's imports)."""
        try:
            for _ in range(self.workers):
                super().submit(_warm)
        except BaseException as exc:  # raised by the next submit
            self._start_error = exc

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        """Schedule ``fn(*args, **kwargs)`` once the workers are started."""
        self._starting.join()
        if self._start_error is not None:
            raise self._start_error  # as the start raised it (OSError, BrokenProcessPool)
        return super().submit(fn, *args, **kwargs)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Shut the pool down (after its workers have started)."""
        self._starting.join()
        super().shutdown(wait=wait, cancel_futures=cancel_futures)
