"""Figures drawn in worker processes: the same files, errors raised, Ctrl-C left alone."""

from __future__ import annotations

import dataclasses
import os
import signal
import time
import warnings
from pathlib import Path

import pytest
from systems import first_order_frf

import lpvid
from lpvid.report.figures import FigureJob, FigurePool, draw, report_jobs, start_drawing


@pytest.fixture(scope="module")
def small_result():
    """A one-state LPV system identified on four points (validation at two of them)."""
    data, validation = first_order_frf()
    basis = lpvid.Polynomial(2, domain=(0.0, 1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        return lpvid.identify(
            data, 1, basis, validation=validation, fixed={"D": True}, gammas=[0.1]
        )


@pytest.fixture(scope="module")
def pool():
    with FigurePool(2) as p:
        yield p


def test_report_jobs_follow_the_data(small_result):
    names = [j.name for j in report_jobs(small_result, {})]
    assert names == [
        "frf_identification.png",
        "frf_validation.png",
        "surface.png",
        "band_identification.png",
        "band_validation.png",
        "band_map.png",
        "group_norms.png",
        "path.png",
    ]
    # No validation data: no validation figures.
    bare = dataclasses.replace(small_result, validation=None)
    assert "frf_validation.png" not in [j.name for j in report_jobs(bare, {})]


def test_figures_drawn_in_the_pool_are_the_figures_drawn_here(small_result, pool, tmp_path, plt):
    jobs = [
        j
        for j in report_jobs(small_result, {"outputs": ["y [m]"], "p_label": "p [-]"})
        if j.name in ("frf_identification.png", "band_map.png", "path.png")
    ]
    here = start_drawing(jobs, tmp_path / "here")()
    there = start_drawing(jobs, tmp_path / "there", pool)()
    assert [c for c, _ in here] == [c for c, _ in there] == [j.caption for j in jobs]
    assert [r for _, r in there] == [f"there/{j.name}" for j in jobs]
    for job in jobs:
        made = (tmp_path / "there" / job.name).read_bytes()
        assert made.startswith(b"\x89PNG"), job.name
        assert made == (tmp_path / "here" / job.name).read_bytes(), job.name


def test_a_failing_figure_is_raised_by_the_pool(small_result, pool, tmp_path, plt):
    bad = FigureJob("frf_fit", "bad.png", "", (small_result.model, "not data"))
    with pytest.raises(TypeError) as here:
        draw(bad, tmp_path)
    good = report_jobs(small_result, {})[-1]
    wait = start_drawing([good, bad], tmp_path / "figs", pool)
    with pytest.raises(TypeError) as there:
        wait()
    assert str(there.value) == str(here.value)
    assert not (tmp_path / "figs" / "bad.png").exists()
    # The pool still works after a failed figure.
    assert pool.submit(pow, 2, 5).result() == 32


def test_the_workers_leave_ctrl_c_to_the_caller(pool):
    pid = pool.submit(os.getpid).result()
    assert pid != os.getpid()
    os.kill(pid, signal.SIGINT)  # as Ctrl-C in a terminal reaches the whole group
    time.sleep(0.5)
    # A worker killed by KeyboardInterrupt would break the pool (BrokenProcessPool).
    assert [pool.submit(abs, -k).result() for k in range(4)] == [0, 1, 2, 3]
    status = Path(f"/proc/{pid}/status")
    if status.exists():
        state = next(ln for ln in status.read_text().splitlines() if ln.startswith("State:"))
        assert "zombie" not in state, state


@pytest.mark.parametrize("workers", [0, -1, True, 1.5, "2"])
def test_figure_pool_checks_workers(workers):
    with pytest.raises(ValueError, match=r"^workers: expected a positive integer, got "):
        FigurePool(workers)
