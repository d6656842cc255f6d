"""Ctrl-C (SIGINT) while the core computes: fits stop cleanly, pipelines stop, the CLI exits 130.

Python ignores SIGINT for good when the process starts with it ignored (a
background job, nohup, some CI runners). These tests install Python's own
handler for their duration and restore the one they found.
"""

import os
import signal
import subprocess
import sys
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import lpvid

FINISHED = threading.Event()  # set by a test once its run has returned


def sigint_when(event: threading.Event, delay: float) -> threading.Thread:
    """Send SIGINT to this process ``delay`` seconds after ``event`` is set.

    Not once the run under test has returned (``FINISHED``): a late signal
    would land in another test.
    """
    FINISHED.clear()

    def run() -> None:
        if event.wait(timeout=60):
            threading.Event().wait(delay)
            if not FINISHED.is_set():
                os.kill(os.getpid(), signal.SIGINT)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


# Fits that only a signal ends: no tolerance is ever met.
ENDLESS = dict(
    max_outer=1000, max_inner=1000, ftol=0.0, dphi_min=0.0, dvnls_min=0.0, dtheta_min=0.0
)


@pytest.fixture(scope="module")
def gantry():
    ds = lpvid.datasets.gantry(n_lines=120)
    local = lpvid.identify_lti(ds.identification, ds.order)
    start = lpvid.smile(local, basis=ds.basis, form="modal")
    return ds, start


def started(event: threading.Event):
    """A callback that only says the fit is running (the signal arrives while Rust computes)."""

    def callback(row):
        event.set()

    return callback


def test_ctrl_c_in_fit_nls_returns_the_best_model_so_far(python_sigint, gantry):
    ds, good = gantry
    data = ds.identification
    # A start far off: about 200 steps, 0.3 s, to the end. The signal is sent
    # as soon as the first step is done; whether it lands in the core or in
    # the callback, the fit stops the same way.
    rng = np.random.default_rng(0)
    start = good.with_theta(good.theta * (1 + 0.2 * rng.standard_normal(good.theta.size)))
    go = threading.Event()
    sigint_when(go, 0.0)
    fit = lpvid.fit_nls(start, data, max_iter=100000, xtol=0, ftol=0, callback=started(go))
    FINISHED.set()
    assert fit.interrupted and fit.stop == "keyboard_interrupt"
    assert "Ctrl-C" in fit.message
    assert fit.vnls <= lpvid.vnls(start, data)
    assert fit.vnls == pytest.approx(lpvid.vnls(fit.model, data), rel=1e-12)
    with pytest.raises(KeyboardInterrupt):
        lpvid.fit.fits.raise_if_interrupted(fit)


def test_ctrl_c_in_fit_l21_without_a_callback(python_sigint, gantry):
    ds, start = gantry
    data = ds.identification
    go = threading.Event()
    sigint_when(go, 0.3)
    go.set()  # no callback: the core alone notices the signal
    reg = lpvid.fit_l21(start, data, 1e-3, **ENDLESS)
    FINISHED.set()
    assert reg.stop == "keyboard_interrupt" and reg.interrupted
    assert reg.n_iter < 1000
    assert reg.vnls == pytest.approx(lpvid.vnls(reg.model, data), rel=1e-12)


def test_ctrl_c_in_l21_path_stops_the_sweep(python_sigint, gantry):
    ds, start = gantry
    go = threading.Event()
    sigint_when(go, 0.3)
    path = lpvid.l21_path(
        start,
        ds.identification,
        [1e-1, 1e-2, 1e-3],
        callback=started(go),
        **ENDLESS,
    )
    FINISHED.set()
    assert len(path) < 3
    assert path[-1].stop == "keyboard_interrupt"
    assert all(r.stop != "keyboard_interrupt" for r in path.results[:-1])


def test_ctrl_c_in_identify_stops_the_whole_run(python_sigint, gantry):
    ds, _ = gantry
    go = threading.Event()
    # Shortly after the path starts (its first fit takes about 0.1 s on the
    # gantry, the whole path about 0.25 s): the signal lands in a fit, not
    # after the run (a fixed delay from the start did once identify took
    # 0.6 s).
    sigint_when(go, 0.02)
    seen = []

    def progress(message: str) -> None:
        seen.append(message)
        if message.startswith("l2,1 path"):
            go.set()

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
            with pytest.raises(KeyboardInterrupt):
                lpvid.identify(
                    ds.identification,
                    ds.order,
                    ds.basis,
                    validation=ds.validation,
                    progress=progress,
                )
    finally:
        FINISHED.set()
    # Stopped within the path: not every gamma was fitted.
    assert any(m.startswith("l2,1 path") for m in seen)
    assert sum(m.lstrip().startswith("gamma =") for m in seen) < 5


def test_ctrl_c_in_the_demo_exits_130_and_writes_nothing(tmp_path):
    out = tmp_path / "demo"
    # The child gets the default SIGINT disposition whatever this process has,
    # so that Python installs its handler there.
    proc = subprocess.Popen(
        [sys.executable, "-m", "lpvid.cli.commands", "demo", "--out", str(out), "--no-figures"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert proc.stdout is not None
    for line in proc.stdout:  # wait until the fits are running
        if "initial models" in line:
            break
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == "lpvid demo: interrupted"
    assert not (out / "report.md").exists() and not (out / "model.json").exists()


def test_ctrl_c_in_a_terminal_stops_the_demo_and_its_figure_workers(tmp_path):
    """SIGINT to the whole process group (a terminal's Ctrl-C) while the figure pool warms up."""
    pytest.importorskip("matplotlib")
    out = tmp_path / "demo"
    proc = subprocess.Popen(
        [sys.executable, "-m", "lpvid.cli.commands", "demo", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own group, as a terminal's foreground job
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert proc.stdout is not None
    for line in proc.stdout:  # the fits run, the workers are starting
        if "initial models" in line:
            break
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == "lpvid demo: interrupted"
    assert "Traceback" not in err and "leaked" not in err, err
    assert not (out / "report.md").exists() and not (out / "model.json").exists()


class SignallingPool(ThreadPoolExecutor):
    """Threads whose first piece of the race gets SIGINT, then waits for its stop flag.

    Keeps every future it handed out, to check that none runs on.
    """

    def __init__(self) -> None:
        super().__init__(2)
        self.futures: list = []
        self.fired = False

    def submit(self, fn, /, *args, **kwargs):
        stop, piece, piece_args = args
        if not self.fired and piece.__name__ == "_advanced":
            self.fired = True

            def first(*a):
                # Ctrl-C delivered to this worker thread, as a terminal's SIGINT may be: the
                # main thread, waiting for this piece, must still see it.
                signal.pthread_kill(threading.get_ident(), signal.SIGINT)
                stop.wait(timeout=30)  # set once the main thread has the KeyboardInterrupt
                return piece(*a)

            args = (stop, first, piece_args)
        future = super().submit(fn, *args, **kwargs)
        self.futures.append(future)
        return future


def test_ctrl_c_stops_identify_and_the_fits_on_its_threads(python_sigint, gantry):
    ds, _ = gantry
    with SignallingPool() as pool:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
            with pytest.raises(KeyboardInterrupt):
                lpvid.identify(ds.identification, ds.order, ds.basis, executor=pool)
        assert pool.fired
        # nothing runs on: every piece has ended (or never started) once identify raised
        assert all(f.done() for f in pool.futures)
        stopped = [f for f in pool.futures if not f.cancelled() and f.exception() is not None]
        assert stopped and all(isinstance(f.exception(), KeyboardInterrupt) for f in stopped)
