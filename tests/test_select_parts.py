"""lpvid.select's grid logic, fast: a stand-in for identify whose outcome per pair is set here.

Each test replaces :func:`lpvid.identify` (as lpvid.selection.grid calls it) by
``_Fake``: it records the problem of every run and returns a model of the
pair's order and basis whose numbers are set in the test (the V_NLS, the
groups kept), so what select writes into the grid, how it judges the pairs
and what it says can be compared with values worked out by hand. The
executors are stand-ins too where the order of the runs matters: one that
runs each task as it is handed out, one that leaves some never started.
"""

import logging
import os
import re
import signal
import threading
import time
import warnings
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import pytest

import lpvid
import lpvid.fit.memory
import lpvid.selection.grid
import lpvid.testing
from lpvid.fit.settings import DEFAULT_GAMMAS

F = np.linspace(5.0, 20.0, 6)  # 6 lines; SISO: every point has 6 complex residuals


def _data(p, seed=0):
    true = lpvid.testing.modal_lpv([[10.0, 3.0]], l=1, r=1)
    return lpvid.testing.noisy_data(true, p, F, np.random.default_rng(seed), 0.05)


FIVE = _data(np.linspace(0.0, 1.0, 5))  # interior points 1, 2, 3
THREE = _data([0.0, 0.5, 1.0])  # N = Nb + 2 for degree 1: nothing to hold out
VAL = _data([0.25, 0.75], seed=1)


TRUE = lpvid.testing.modal_lpv([[10.0, 3.0]], l=1, r=1)


def _model(order, basis, p):
    """The stand-in's model of a pair fitted on the points ``p``: differs with the points.

    Order 2 is the true system (its D moved a little with the points), any
    other order a first-order lag far from the data.
    """
    k = len(basis) + 1
    A, B = np.zeros((k, order, order)), np.zeros((k, order, 1))
    C, D = np.zeros((k, 1, order)), np.zeros((k, 1, 1))
    if order == 2:
        for X, Y in ((A, TRUE.A), (B, TRUE.B), (C, TRUE.C), (D, TRUE.D)):
            X[:2] = Y[: min(k, 2)]
        D[0] += 1e-3 * float(np.sum(p))
    else:
        A[0] = -np.diag(np.arange(1.0, order + 1)) * (5.0 + 40.0 * float(np.sum(p)))
        B[0], C[0], D[0] = 1.0, 1.0, 0.1
    return lpvid.LpvModel(A, B, C, D, basis=basis)


@dataclass
class _Final:
    vnls: float
    noise_floor: int
    n_groups: int
    nonzero_groups: dict
    validation_vnls: float | None
    validation_floor: int | None


@dataclass
class _Result:
    model: lpvid.LpvModel
    final: _Final


class _Fake:
    """identify for select's tests: ``numbers[(order, degree)] = (V/M, kept, val V/M)``.

    ``kept`` are the basis indices kept per matrix (``nonzero_groups``).
    ``fail`` names the runs that raise: ``(order, degree, point)`` with point
    None for the run on all the data; ``warn`` likewise the runs that warn;
    ``sleep`` seconds every run takes.
    """

    def __init__(self, numbers, fail=(), warn=(), sleep=0.0, gate=None):
        self.numbers, self.fail, self.warn, self.sleep = numbers, set(fail), set(warn), sleep
        self.gate = gate
        self.calls = []
        self.finished = []

    def __call__(self, problem):
        data, n, b = problem.data, problem.order, problem.basis
        p = data.p.ravel()
        held = [q for q, x in enumerate(FIVE.p.ravel()) if x not in p] if data.n_points == 4 else []
        point = held[0] if held else None
        self.calls.append((n, b.degree, point, problem))
        if self.gate is not None and (n, b.degree) in self.gate[1]:
            self.gate[0].wait(10)
        time.sleep(self.sleep)
        self.finished.append((n, b.degree, point))
        if (n, b.degree, point) in self.warn:
            where = "all" if point is None else f"without {point}"
            warnings.warn(f"spare pole ({where})", lpvid.ConvergenceWarning, stacklevel=1)
        if (n, b.degree, point) in self.fail:
            raise RuntimeError(f"no start\n  for order {n}")
        ratio, kept, val = self.numbers[(n, b.degree)]
        v = problem.validation
        final = _Final(
            vnls=ratio * data.n_residuals,
            noise_floor=data.n_residuals,
            n_groups=sum(len(x) for x in kept.values()),
            nonzero_groups=kept,
            validation_vnls=None if v is None else val * v.n_residuals,
            validation_floor=None if v is None else v.n_residuals,
        )
        return _Result(_model(n, b, p), final)


@pytest.fixture
def fake(monkeypatch):
    """Install a stand-in for identify: ``fake(numbers, ...)`` returns it."""

    def install(numbers, **kw):
        f = _Fake(numbers, **kw)
        monkeypatch.setattr(lpvid.selection.grid, "identify", f)
        return f

    return install


class _Now(Executor):
    """Runs each task as it is handed out; ``first`` of them, the others never start."""

    def __init__(self, first=None, broken=None):
        self.first, self.broken, self.futures = first, broken, []

    def submit(self, fn, *args, **kwargs):
        f = Future()
        self.futures.append(f)
        if self.broken is not None:
            f.set_exception(self.broken)
        elif self.first is None or len(self.futures) <= self.first:
            f.set_result(fn(*args, **kwargs))
        return f


def _select(*args, **kwargs):
    """select, its convergence warnings hidden; a KeyboardInterrupt out of it fails the test.

    (Not left to stop pytest: select's own Ctrl-C handling is what is tested.)
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        try:
            return lpvid.select(*args, **kwargs)
        except KeyboardInterrupt as exc:
            raise AssertionError(f"select raised KeyboardInterrupt: {exc}") from exc


def _free(order, kept, fixed=()):
    """Free parameters in use of a SISO model: A n^2, B n, C n, D 1 per coefficient kept."""
    size = {"A": order * order, "B": order, "C": order, "D": 1}
    return sum(size[x] * (1 + len(kept.get(x, []))) for x in "ABCD" if x not in fixed)


# (order, degree) -> (V_NLS / M on all the data, groups kept, validation V_NLS / M)
NUMBERS = {
    (1, 1): (40.0, {"A": [1]}, 30.0),
    (1, 2): (35.0, {"A": [1, 2], "B": [2]}, 29.0),
    (2, 1): (1.0, {"A": [1], "C": [1]}, 1.08),
    (2, 2): (0.9, {"A": [1, 2], "B": [1], "D": [2]}, 1.0),
}


def test_the_validation_rule_fills_the_grid_and_keeps_the_simplest_within(fake):
    """Rejects rows out of the grid's order, numbers taken from the wrong run, a wrong choice."""
    f = fake(NUMBERS)
    sel = _select(FIVE, [2, 1], [1, 2], validation=VAL, executor=_Now())
    assert [(r.order, r.basis.degree) for r in sel.grid] == [(1, 1), (1, 2), (2, 1), (2, 2)]
    m, mv = 5 * 6, 2 * 6  # N F l r of the data and of the validation data
    for r in sel.grid:
        ratio, kept, val = NUMBERS[(r.order, r.basis.degree)]
        assert r.ok and r.error is None and r.warnings == []
        assert r.result.final.nonzero_groups is kept and r.result.model.n_states == r.order
        assert (r.vnls, r.noise_floor) == (pytest.approx(ratio * m, rel=1e-12), m)
        assert (r.validation_vnls, r.validation_floor) == (pytest.approx(val * mv, rel=1e-12), mv)
        assert r.n_groups == sum(len(x) for x in kept.values())
        assert r.n_free == _free(r.order, kept)
        assert r.basis == lpvid.Polynomial(r.basis.degree, domain=(0.0, 1.0))
    # best validation V/M 1.0 (2, poly:2, 20 + 6 = 26 free); 1.08 within 10 %, 18 free: chosen
    assert (sel.order, sel.basis.degree, sel.rule, sel.tolerance) == (2, 1, "validation", 0.1)
    assert sel.reason.endswith("2 of 4 pairs are within")
    assert not sel.interrupted and sel.timings["total_s"] > 0
    # one run per pair, on all the data with the validation data and select's settings
    assert sorted((n, d, q) for n, d, q, _ in f.calls) == [(n, d, None) for n, d in NUMBERS]
    for *_, problem in f.calls:
        assert problem.data is FIVE and problem.validation is VAL and problem.fixed is None
        assert problem.settings.path.gammas == DEFAULT_GAMMAS
        assert problem.settings.path.tolerance == 0.1
    tight = _select(FIVE, [1, 2], [1, 2], validation=VAL, tolerance=0.05, executor=_Now())
    assert (tight.order, tight.basis.degree, tight.tolerance) == (2, 2, 0.05)
    assert {c[3].settings.path.tolerance for c in f.calls[4:]} == {0.05}


def test_the_held_out_rotation_judges_each_pair_at_the_interior_points(fake):
    """Rejects a rotation that leaves out the wrong point, judges elsewhere or sums wrongly."""
    f = fake({(1, 1): (50.0, {}, None), (2, 1): (1.0, {"A": [1]}, None)})
    sel = _select(FIVE, [1, 2], [1], executor=_Now())
    assert sel.rule == "held-out"
    runs = sorted((n, q) for n, _, q, _ in f.calls if q is not None)
    assert runs == [(1, 1), (1, 2), (1, 3), (2, 1), (2, 2), (2, 3)]
    for _, _, q, problem in f.calls:
        if q is not None:
            kept = [k for k in range(5) if k != q]
            np.testing.assert_array_equal(problem.data.G, FIVE.G[kept])
            assert problem.validation is None
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    for r in sel.grid:
        total = 0.0
        for q in (1, 2, 3):
            p = np.delete(FIVE.p.ravel(), q)
            total += lpvid.vnls(_model(r.order, basis, p), FIVE.subset([q]))
        assert r.validation_vnls == pytest.approx(total, rel=1e-10)
        assert r.validation_floor == 3 * 6
        assert r.vnls == pytest.approx(f.numbers[(r.order, 1)][0] * 30, rel=1e-12)
        assert r.noise_floor == 30 and r.error is None
    one, two = (r.validation_vnls for r in sel.grid)
    assert one > 1.1 * two and sel.order == 2  # the true system is the best at the held-out points
    assert "held-out V_NLS" in sel.reason


def test_the_noise_floor_rule_when_no_point_is_to_spare(fake):
    """Rejects held-out runs where no basis leaves points to spare, or another rule."""
    # M = 18: the floor is reached at V_NLS <= 18 + 2 sqrt(18) = 26.5, V/M <= 1.47
    f = fake({(1, 1): (1.6, {}, None), (2, 1): (1.4, {"A": [1]}, None), (3, 1): (1.0, {}, None)})
    sel = _select(THREE, [1, 2, 3], [1], executor=_Now())
    assert sel.rule == "noise floor" and sel.order == 2
    assert all(q is None for _, _, q, _ in f.calls) and len(f.calls) == 3
    assert all(r.validation_vnls is None and r.validation_floor is None for r in sel.grid)
    # five points but a basis of 3 functions: N = Nb + 2, no rotation for any pair
    f = fake({(2, 1): (1.4, {}, None), (2, 3): (1.2, {}, None)})
    assert _select(FIVE, [2], [1, 3], executor=_Now()).rule == "noise floor"
    assert len(f.calls) == 2


def test_progress_messages_and_the_log(fake, caplog):
    """Rejects progress messages with wrong numbers, counts, point or failure text."""
    fake(
        {(1, 1): (40.0, {"A": [1]}, 30.0), (2, 1): (1.25, {"A": [1], "B": [1]}, 1.5)},
        fail={(1, 1, None)},
    )
    said = []
    with caplog.at_level(logging.INFO, logger="lpvid"):
        _select(FIVE, [1, 2], [1], validation=VAL, executor=_Now(), progress=said.append)
    assert said[0] == str(lpvid.order_hints(FIVE))
    assert said[1] == "2 pairs, 2 identify runs; the pairs judged by validation"
    assert re.fullmatch(
        r"order 1, poly:1: failed after \d+\.\d s: RuntimeError: no start\n  for order 1 \(1/2\)",
        said[2],
    )
    assert re.fullmatch(
        r"order 2, poly:1: V_NLS/floor 1\.250, validation 1\.500, 2 groups, \d+\.\d s \(2/2\)",
        said[3],
    )
    assert len(said) == 4
    assert [r.getMessage() for r in caplog.records if r.name == "lpvid"] == said
    # without validation data: the held-out runs, each with its point and V/floor there
    f = fake({(1, 1): (40.0, {}, None), (2, 1): (1.0, {}, None)})
    said.clear()
    _select(FIVE, [1, 2], [1], executor=_Now(), progress=said.append)
    assert said[1] == "2 pairs, 8 identify runs; the pairs judged by held-out"
    assert re.fullmatch(
        r"order 1, poly:1: V_NLS/floor 40\.000, 0 groups, \d+\.\d s \(1/8\)", said[2]
    )
    basis = lpvid.Polynomial(1, domain=(0.0, 1.0))
    for k, (n, q) in enumerate([(1, 1), (1, 2), (1, 3), (2, 1), (2, 2), (2, 3)]):
        m = re.fullmatch(
            rf"order {n}, poly:1, point {q} held out: V_NLS/floor (\S+) \({k + 3}/8\)", said[k + 4]
        )
        assert m, said[k + 4]
        at = FIVE.subset([q])
        expected = lpvid.vnls(_model(n, basis, np.delete(FIVE.p.ravel(), q)), at) / at.n_residuals
        assert float(m.group(1)) == pytest.approx(expected, rel=2e-3, abs=1e-3)
    assert len(f.calls) == 8


def test_the_largest_pairs_are_handed_out_first(fake):
    """Rejects another order of the runs than by size ``n^2 (Nb + 1)``, largest first."""
    f = fake(NUMBERS)
    _select(FIVE, [1, 2], [1, 2], validation=VAL, executor=_Now())
    # sizes: (1, 1) 2, (1, 2) 3, (2, 1) 8, (2, 2) 12
    assert [(n, d) for n, d, _, _ in f.calls] == [(2, 2), (2, 1), (1, 2), (1, 1)]
    f = fake({(1, 1): (40.0, {}, None), (2, 1): (1.0, {}, None)})
    _select(FIVE, [1, 2], [1], executor=_Now())
    assert [(n, q) for n, _, q, _ in f.calls] == [
        (2, None),
        (2, 1),
        (2, 2),
        (2, 3),
        (1, None),
        (1, 1),
        (1, 2),
        (1, 3),
    ]


def test_a_failing_run_is_recorded_and_the_others_go_on(fake):
    """Rejects a failure that stops the grid, is lost, or is written over by a later one."""
    numbers = {(n, d): (40.0 / n / d, {"A": [1]}, 30.0 / n / d) for n in (1, 2) for d in (1, 2)}
    fail = {(1, 1, None), (1, 1, 2), (2, 1, 2), (2, 1, 3), (1, 2, 1)}
    fake(numbers, fail=fail)
    sel = _select(FIVE, [1, 2], [1, 2], executor=_Now())
    one, one2, two, two2 = sel.grid
    assert one.error == "RuntimeError: no start\n  for order 1" and not one.ok
    assert one.vnls is None and one.n_free is None and one.validation_vnls is None
    # the run on all the data went through: a model, but no held-out V_NLS (the first failure)
    assert two.ok and two.vnls == pytest.approx(20.0 * 30) and two.n_free == _free(2, {"A": [1]})
    assert two.error == "held-out point 2: RuntimeError: no start\n  for order 2"
    assert two.validation_vnls is None and two.validation_floor is None
    assert one2.error == "held-out point 1: RuntimeError: no start\n  for order 1"
    assert two2.error is None and two2.validation_floor == 18 and sel.row is two2
    fake(numbers, fail=fail - {(1, 2, 1)} | {(1, 2, None), (2, 2, 1)})
    with pytest.raises(ValueError) as info:
        _select(FIVE, [1, 2], [1, 2], executor=_Now())
    assert str(info.value) == (
        "select: no pair of the grid could be identified: "
        "order 1, poly:1: RuntimeError: no start for order 1; "
        "order 1, poly:2: RuntimeError: no start for order 1; "
        "order 2, poly:1: held-out point 2: RuntimeError: no start for order 2; "
        "order 2, poly:2: held-out point 1: RuntimeError: no start for order 2"
    )
    # with validation data the pairs are judged on it: only the run on all the data fails
    fake(numbers | {(2, 1): (1.0, {}, 1.0), (2, 2): (0.9, {}, 2.0)}, fail=fail)
    sel = _select(FIVE, [1, 2], [1, 2], validation=VAL, executor=_Now())
    assert [r.ok for r in sel.grid] == [False, True, True, True] and sel.row is sel.grid[2]
    assert "1 pair(s) failed" in sel.summary()


def test_an_order_the_data_cannot_determine_fails_in_its_task(fake):
    """Rejects a pair whose problem is refused being lost or stopping the others."""
    fake({(1, 1): (40.0, {}, 30.0), (2, 1): (1.0, {}, 1.0)})
    # 6 lines at 2 validation points: order 9 has far more parameters than the data
    sel = _select(FIVE, [2, 9], [1], validation=VAL, executor=_Now())
    assert sel.grid[1].error.startswith("ValueError: order: 9") and not sel.grid[1].ok
    assert sel.order == 2


def test_an_executors_own_failure_is_recorded(fake):
    """Rejects an executor's failure (a lost worker) escaping select or being dropped."""
    fake(NUMBERS)
    with pytest.raises(ValueError) as info:
        _select(FIVE, [1, 2], [1], validation=VAL, executor=_Now(broken=OSError("lost worker")))
    assert str(info.value) == (
        "select: no pair of the grid could be identified: "
        "order 1, poly:1: OSError: lost worker; order 2, poly:1: OSError: lost worker"
    )


def test_the_warnings_of_the_chosen_run_on_all_the_data_are_raised_again(fake):
    """Rejects warnings lost, raised for other pairs or for the held-out runs, or unprefixed."""
    warn = {(2, 1, None), (2, 1, 2), (1, 1, None)}
    fake({(1, 1): (40.0, {}, None), (2, 1): (1.0, {}, None)}, warn=warn)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        sel = lpvid.select(FIVE, [1, 2], [1], executor=_Now())
    assert sel.order == 2
    assert [(w.category, str(w.message)) for w in seen] == [
        (lpvid.ConvergenceWarning, "order 2, poly:1: spare pole (all)")
    ]
    assert sel.row.warnings == [
        (lpvid.ConvergenceWarning, "spare pole (all)"),
        (lpvid.ConvergenceWarning, "held-out point 2: spare pole (without 2)"),
    ]
    assert sel.grid[0].warnings == [(lpvid.ConvergenceWarning, "spare pole (all)")]


def test_a_pairs_seconds_add_up_its_runs(fake):
    """Rejects a row's time that is not the sum of its runs (held-out runs included)."""
    fake({(1, 1): (40.0, {}, None)}, sleep=0.02)
    t0 = time.perf_counter()
    sel = _select(FIVE, [1], [1], executor=_Now())
    elapsed = time.perf_counter() - t0
    assert 4 * 0.02 <= sel.row.seconds <= sel.timings["total_s"] <= elapsed


def _stop_at_first(message):
    if "(1/" in message:
        raise KeyboardInterrupt


def test_ctrl_c_keeps_what_is_done_and_cancels_the_rest(fake):
    """Rejects results lost to Ctrl-C, runs not cancelled, or a choice among pairs not done."""
    fake(NUMBERS)
    now = _Now(first=2)  # the two largest pairs are done, the two others never start
    sel = _select(FIVE, [1, 2], [1, 2], validation=VAL, executor=now, progress=_stop_at_first)
    assert sel.interrupted
    assert [r.error for r in sel.grid] == ["cancelled", "cancelled", None, None]
    assert [r.ok for r in sel.grid] == [False, False, True, True]
    assert all(f.cancelled() for f in now.futures[2:])
    assert (sel.order, sel.basis.degree) == (2, 1)
    assert sel.summary().startswith("interrupted (Ctrl-C): 2 of 4 pairs done")
    # a second Ctrl-C while what is done is collected: select still returns what it has
    now = _Now(first=3)

    def always(message):
        if "pairs judged" not in message and "order hints" not in message:
            raise KeyboardInterrupt

    sel = _select(FIVE, [1, 2], [1, 2], validation=VAL, executor=now, progress=always)
    # the first run taken (Ctrl-C), then one more (Ctrl-C again): the collecting stops there
    assert sel.interrupted and sum(r.ok for r in sel.grid) == 2


def test_ctrl_c_in_the_rotation_leaves_pairs_unjudged(fake):
    """Rejects a held-out sum over a rotation that Ctrl-C cut short."""
    fake({(1, 1): (40.0, {}, None), (2, 1): (1.0, {}, None)})
    now = _Now(first=5)  # order 2 and its 3 points; order 1 on all the data only
    sel = _select(FIVE, [1, 2], [1], executor=now, progress=_stop_at_first)
    one, two = sel.grid
    assert one.ok and one.error == "held-out rotation cancelled" and one.validation_vnls is None
    assert two.error is None and two.validation_floor == 18 and sel.order == 2


def test_ctrl_c_before_any_pair_is_judged(fake):
    """Rejects a ValueError (or a result) where Ctrl-C came before any pair was done."""
    fake(NUMBERS, fail={(2, 2, None)})
    now = _Now(first=1)  # the one run done failed
    with pytest.raises(KeyboardInterrupt, match="^select: interrupted before any pair was done"):
        lpvid.select(FIVE, [1, 2], [1, 2], validation=VAL, executor=now, progress=_stop_at_first)


def test_ctrl_c_on_another_thread_is_seen_while_every_run_waits(fake, python_sigint):
    """Rejects a wait for the runs that does not wake up to see Ctrl-C (no polling)."""
    fake(NUMBERS)
    gate = threading.Event()
    with ThreadPoolExecutor(1) as pool:
        pool.submit(gate.wait, 10)  # the only worker is busy: the pairs wait in the queue
        # SIGINT delivered to the timer's thread: the main thread must still see it
        timer = threading.Timer(
            0.2, lambda: signal.pthread_kill(threading.get_ident(), signal.SIGINT)
        )
        t0 = time.perf_counter()
        timer.start()
        try:
            with pytest.raises(KeyboardInterrupt, match="before any pair was done"):
                lpvid.select(FIVE, [1, 2], [1], validation=VAL, executor=pool)
            assert time.perf_counter() - t0 < 5.0  # long before the gate opens
        finally:
            timer.cancel()
            gate.set()


def test_ctrl_c_does_not_wait_for_the_runs_going_on(fake, monkeypatch):
    """Rejects select waiting, after Ctrl-C, for the runs already going on its own threads."""
    gate = threading.Event()
    f = fake(NUMBERS, gate=(gate, {(2, 2)}))
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (None, "a test"))
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    timer = threading.Timer(5.0, gate.set)
    timer.start()
    try:
        sel = _select(FIVE, [2], [1, 2], validation=VAL, progress=_stop_at_first)
        assert (2, 2, None) not in f.finished  # still waiting at the gate
    finally:
        gate.set()
        timer.cancel()
    assert sel.interrupted and [r.error for r in sel.grid] == [None, "cancelled"]


class _Pool(ThreadPoolExecutor):
    made = []

    def __init__(self, max_workers):
        _Pool.made.append(max_workers)
        super().__init__(max_workers)


def test_the_default_threads_are_as_many_as_runs_cores_and_memory_allow(fake, monkeypatch):
    """Rejects a default pool sized otherwise than min(runs, cores), fewer when memory is short."""
    fake(NUMBERS)
    monkeypatch.setattr(lpvid.selection.grid, "ThreadPoolExecutor", _Pool)
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (None, "a test"))
    _Pool.made.clear()
    monkeypatch.setattr(os, "cpu_count", lambda: 16)
    assert _select(FIVE, [1, 2], [1], validation=VAL).order == 2  # 2 runs
    assert _select(FIVE, [1, 2], [1]).order == 2  # 8 runs
    monkeypatch.setattr(os, "cpu_count", lambda: 3)
    _select(FIVE, [1, 2], [1], validation=VAL)
    _select(FIVE, [1, 2], [1])
    monkeypatch.setattr(os, "cpu_count", lambda: None)
    _select(FIVE, [1, 2], [1])
    assert _Pool.made == [2, 8, 2, 3, 1]
    # room for the largest run and not for the two largest together: one at a time
    needs = sorted(
        lpvid.fit.memory.pipeline_memory(FIVE, n, lpvid.Polynomial(1))[0] for n in (1, 2)
    )
    monkeypatch.setattr(
        lpvid.fit.memory, "available_memory", lambda: (needs[1] + needs[0] - 1, "t")
    )
    monkeypatch.setattr(os, "cpu_count", lambda: 16)
    _select(FIVE, [1, 2], [1], validation=VAL)
    assert _Pool.made[-1] == 1


def test_a_problem_gives_every_run_its_data_and_settings(fake):
    """Rejects a Problem's validation data, fixed parameters or settings not reaching the runs."""
    f = fake(NUMBERS)
    settings = lpvid.fit.settings.IdentifySettings(
        path=lpvid.fit.settings.PathSettings(gammas=[0.5, 0.05], tolerance=0.5)
    )
    records = lpvid.TimeData(np.ones(50), np.full(50, 0.5), np.zeros(50), dt=1e-3)
    problem = lpvid.Problem(
        FIVE, 1, lpvid.Polynomial(1), VAL, {"D": True}, records, settings=settings
    )
    sel = _select(problem, [1, 2], [1, 2], executor=_Now())
    assert sel.rule == "validation" and sel.tolerance == 0.5
    for _, d, q, run in f.calls:
        assert run.validation is VAL and run.fixed == {"D": True} and run.settings is settings
        assert run.time_data is problem.time_data
        assert run.data is FIVE and q is None
        assert run.basis == lpvid.Polynomial(d, domain=(0.0, 1.0))
    for r in sel.grid:
        assert r.n_free == _free(r.order, NUMBERS[(r.order, r.basis.degree)][1], fixed="D")
    # within 50 % of the best (1.0): 1.08 (18 - 2 = 16 free) against 26 - 3 = 23
    assert (sel.order, sel.basis.degree) == (2, 1)
    for given in (dict(validation=VAL), dict(tolerance=0.2), dict(fixed={"D": True})):
        with pytest.raises(TypeError, match="the problem holds these"):
            lpvid.select(problem, [1], [1], **given)


def test_gammas_tolerance_and_fixed_reach_every_run(fake):
    """Rejects select's own gammas, tolerance or fixed parameters not given to every run."""
    f = fake({(1, 1): (40.0, {}, None), (2, 1): (1.0, {"A": [1]}, None)})
    sel = _select(FIVE, [1, 2], [1], None, [0.3, 0.03], {"D": True}, executor=_Now(), tolerance=2.0)
    assert len(f.calls) == 8
    for *_, run in f.calls:
        assert list(run.settings.path.gammas) == [0.3, 0.03]
        assert run.settings.path.tolerance == 2.0 and run.fixed == {"D": True}
    assert sel.grid[1].n_free == _free(2, {"A": [1]}, fixed="D") and sel.tolerance == 2.0
    seen = []

    def fixed(order, basis):
        seen.append((order, basis.degree))
        return {"A": [0]} if order == 2 else None

    f = fake({(1, 1): (40.0, {}, None), (2, 1): (1.0, {"A": [1]}, None)})
    sel = _select(FIVE, [1, 2], [1], fixed=fixed, executor=_Now())
    assert sorted(seen) == [(1, 1), (2, 1)]
    assert {(n, str(run.fixed)) for n, _, _, run in f.calls} == {(1, "None"), (2, "{'A': [0]}")}
    assert sel.grid[1].n_free == _free(2, {"A": [1]}) - 4  # A's constant part fixed
    # a callable may give a mask over theta: it is for one pair, that one's layout
    from lpvid.pipeline.capacity import zero_model

    def mask(order, basis):
        return lpvid.fixed_mask(zero_model(order, basis, FIVE), {"B": True})

    f = fake({(1, 1): (40.0, {}, None), (2, 1): (1.0, {"A": [1]}, None)})
    sel = _select(FIVE, [1, 2], [1], fixed=mask, executor=_Now())
    assert sel.grid[1].n_free == _free(2, {"A": [1]}) - 2  # B's 2 entries, constant part
    assert all(np.array_equal(run.fixed, mask(n, run.basis)) for n, _, _, run in f.calls)


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        (dict(orders=[]), ValueError, "orders: needs at least one order"),
        (dict(orders=[2, 3, 2, 3, 1]), ValueError, "orders: [2, 3] given twice"),
        (dict(orders=3), TypeError, "orders: expected a sequence of positive integers, got int"),
        (dict(bases=[]), ValueError, "bases: needs at least one basis"),
        (dict(bases=2), TypeError, "bases: expected a sequence of lpvid bases or degrees, got int"),
        (dict(bases=[1, 2, 1]), ValueError, "bases: poly:1 given twice"),
        (
            dict(bases=[lpvid.Polynomial(1, n_params=2)]),
            ValueError,
            "bases: poly:1 takes 2 scheduling parameter(s), the data have 1",
        ),
        (dict(data=FIVE.G), TypeError, "data: expected an FrfData, got ndarray"),
        (
            dict(progress="log"),
            TypeError,
            "progress: expected a callable taking one str (e.g. print) or None, got str",
        ),
        (
            dict(fixed=np.zeros(8, dtype=bool)),
            TypeError,
            "fixed: a boolean mask over theta fits one order and basis only; give a dict such "
            "as {'D': True} or {'A': [0]}, or a callable (order, basis) -> fixed",
        ),
    ],
)
def test_bad_arguments_are_refused_by_name(fake, kwargs, error, message):
    """Rejects a bad argument accepted, or refused with a message that does not name it."""
    f = fake(NUMBERS)
    args = dict(data=FIVE, orders=[1], bases=[1]) | kwargs
    with pytest.raises(error) as info:
        lpvid.select(**args)
    assert str(info.value) == message
    assert f.calls == []


def test_a_bad_order_or_degree_is_refused_by_name(fake):
    """Rejects a bad order or degree refused without naming the argument."""
    fake(NUMBERS)
    with pytest.raises(ValueError, match="^orders: "):
        lpvid.select(FIVE, [1, 0], [1])
    with pytest.raises(ValueError, match="^bases: "):
        lpvid.select(FIVE, [1], [1, -1])
    with pytest.raises(TypeError, match="^bases: "):
        lpvid.select(FIVE, [1], [1, "poly"])


def test_the_fixed_parameters_are_checked_for_every_pair(fake):
    """Rejects fixed parameters that fit one pair only being let through to the runs."""
    f = fake(NUMBERS)
    with pytest.raises(ValueError, match=r"^fixed: for order 2, poly:1: fixed\['A'\]"):
        lpvid.select(FIVE, [2], [2, 1], fixed={"A": [2]})  # poly:1 has coefficients 0 and 1
    with pytest.raises(TypeError, match=r"^fixed: for order 1, poly:1: fixed\['A'\]: expected"):
        lpvid.select(FIVE, [1, 2], [1], fixed=lambda n, b: {"A": "x"})
    assert f.calls == []


def test_degrees_and_bases_given_as_such(fake):
    """Rejects a degree not made a polynomial over the data's range, or degree 0 refused."""
    data = _data(np.linspace(2.0, 4.0, 5))
    f = fake({(1, 0): (40.0, {}, 30.0), (1, 1): (2.0, {}, 1.0), (1, 2): (1.9, {}, 1.02)})
    leg = lpvid.Legendre(2, domain=(2.0, 4.0))
    sel = _select(data, [1], [0, 1, leg], validation=_data([2.5, 3.5]), executor=_Now())
    assert [r.basis for r in sel.grid] == [
        lpvid.Polynomial(0, domain=(2.0, 4.0)),
        lpvid.Polynomial(1, domain=(2.0, 4.0)),
        leg,
    ]
    assert len(f.calls) == 3 and sel.basis == lpvid.Polynomial(1, domain=(2.0, 4.0))
