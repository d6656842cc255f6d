"""identify on an executor: the same run as without one, to the last bit, wherever the pieces ran.

The positioning stage with its validation data runs a guarded path whose
first gamma needs the pinned fit, and a race that drops its global starts
after one round: every kind of piece identify hands out is there.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import warnings
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from typing import Any

import numpy as np
import pytest

import lpvid
import lpvid.testing
from lpvid._spread import Spread, check_executor, stop_flag


class LastFirst(Executor):
    """Runs the tasks handed out in this thread, the last handed out first, once a result is asked.

    The results come back in the reverse of the order the tasks were handed
    out: a run that took them as they finish would see them reversed.
    """

    def __init__(self, log: list[str] | None = None) -> None:
        self.log = log  # where to note every piece handed out, by its function's name
        self.queue: list[tuple[Future[Any], Any, tuple[Any, ...]]] = []
        self.ran: list[Any] = []
        self.handed: list[tuple[str, Future[Any]]] = []

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> Future[Any]:
        future = _Lazy(self)
        self.queue.append((future, fn, args))
        self.handed.append((args[1].__name__, future))
        if self.log is not None:
            self.log.append(f"handed {args[1].__name__}")
        return future

    def run_all(self) -> None:
        while self.queue:
            future, fn, args = self.queue.pop()
            if not future.set_running_or_notify_cancel():
                continue
            self.ran.append(args[1])  # the piece's function (lpvid._spread._run's argument)
            try:
                future.set_result(fn(*args))
            except BaseException as exc:
                future.set_exception(exc)


class _Lazy(Future):
    def __init__(self, owner: LastFirst) -> None:
        super().__init__()
        self.owner = owner

    def result(self, timeout: float | None = None) -> Any:
        self.owner.run_all()
        return super().result(timeout)


def _identify(ds: Any, executor: Executor | None = None) -> lpvid.IdentifyResult:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        return lpvid.identify(
            ds.identification,
            ds.order,
            ds.basis,
            validation=ds.validation,
            fixed=ds.fixed,
            executor=executor,
        )


@pytest.fixture(scope="module")
def stage():
    """The stage, and its run here: one piece after the other (no threads of identify's own)."""
    ds = lpvid.datasets.positioning_stage()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(lpvid._spread, "cores", lambda: 1)
        return ds, _identify(ds)


def assert_same_run(a: lpvid.IdentifyResult, b: lpvid.IdentifyResult) -> None:
    """The same local models, candidates (raced alike), path, choice and model, bit for bit."""
    for x, y in zip(a.local, b.local, strict=True):
        assert np.array_equal(x.theta, y.theta)
    assert [(c.name, c.refined, c.vnls, c.validation_vnls) for c in a.candidates] == [
        (c.name, c.refined, c.vnls, c.validation_vnls) for c in b.candidates
    ]
    assert [(e.gamma, e.pinned, e.vnls, e.validation_vnls) for e in a.entries] == [
        (e.gamma, e.pinned, e.vnls, e.validation_vnls) for e in b.entries
    ]
    assert (a.chosen, a.start, a.reason, a.refitted) == (b.chosen, b.start, b.reason, b.refitted)
    assert np.array_equal(a.model.theta, b.model.theta)


def test_the_stage_exercises_every_kind_of_piece(stage):
    _, here = stage
    assert any(e.pinned for e in here.entries)  # the pinned fit was needed (and kept)
    assert any(not c.refined for c in here.candidates)  # the race dropped runners
    assert len(here.local) > 1


def test_identify_on_threads_is_the_run_here(stage):
    ds, here = stage
    with ThreadPoolExecutor(2) as pool:
        on_threads = _identify(ds, pool)
    assert_same_run(here, on_threads)


class _Counted(ThreadPoolExecutor):
    """A thread pool that keeps itself and counts what it was handed."""

    made: list[_Counted] = []

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.handed = 0
        self.pieces: set[str] = set()  # the pieces' functions (lpvid._spread._run's argument)
        _Counted.made.append(self)

    def submit(self, *args: Any, **kwargs: Any) -> Any:
        self.handed += 1
        self.pieces.add(args[2].__name__)
        return super().submit(*args, **kwargs)


def test_without_an_executor_identify_runs_on_threads_of_its_own_and_the_same(stage, monkeypatch):
    """One thread per core for the run, every piece handed to them, closed after; the same run."""
    ds, here = stage
    _Counted.made = []
    monkeypatch.setattr(lpvid._spread, "ThreadPoolExecutor", _Counted)
    monkeypatch.setattr(lpvid._spread, "cores", lambda: 3)
    assert_same_run(here, _identify(ds))
    (pool,) = _Counted.made
    assert pool._max_workers == 3 and pool.handed > len(here.local) and pool._shutdown


def test_a_large_run_refines_its_local_models_on_threads_of_its_own(stage, monkeypatch):
    """One point's fits are small where the run is not: only they go to threads; the same run."""
    import lpvid.pipeline.run as run
    from lpvid._spread import SMALL_RUN_BYTES

    ds, here = stage
    real = run.pipeline_memory
    monkeypatch.setattr(run, "pipeline_memory", lambda *a: (SMALL_RUN_BYTES + 1, real(*a)[1]))
    _Counted.made = []
    monkeypatch.setattr(lpvid._spread, "ThreadPoolExecutor", _Counted)
    monkeypatch.setattr(lpvid._spread, "cores", lambda: 2)
    assert_same_run(here, _identify(ds))
    (pool,) = _Counted.made
    assert pool.pieces == {"_refined"} and pool.handed >= len(here.local) and pool._shutdown
    monkeypatch.setattr(run, "local_memory", lambda *a: SMALL_RUN_BYTES + 1)  # a large point
    _Counted.made = []
    assert_same_run(here, _identify(ds))
    assert _Counted.made == []


def test_own_threads_only_when_none_is_given_and_there_are_cores(monkeypatch):
    from lpvid._spread import SMALL_RUN_BYTES, own_threads

    given = ThreadPoolExecutor(1)
    with own_threads(given, 0) as got:
        assert got is given
    assert not given._shutdown  # the caller's pool is the caller's to close
    given.shutdown()
    monkeypatch.setattr(lpvid._spread, "cores", lambda: 1)
    with own_threads(None, 0) as got:
        assert got is None
    monkeypatch.setattr(lpvid._spread, "cores", lambda: 2)
    with own_threads(None, SMALL_RUN_BYTES) as got:
        assert isinstance(got, ThreadPoolExecutor) and got._max_workers == 2
    assert got._shutdown
    with own_threads(None, SMALL_RUN_BYTES + 1) as got:  # a large run: its fits take the cores
        assert got is None
    with own_threads(None, 2**30, budget=2**30) as got:  # within a budget of its own
        assert isinstance(got, ThreadPoolExecutor)
    with own_threads(None, 2**30 + 1, budget=2**30) as got:
        assert got is None

    def on_a_thread():
        with own_threads(None, 0) as got:
            return got

    with ThreadPoolExecutor(1) as other:  # a run on another pool's thread: spread already
        assert other.submit(on_a_thread).result() is None


def test_cores_are_those_this_process_may_run_on():
    from lpvid._spread import cores

    expected = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert cores() == expected >= 1
    if not hasattr(os, "sched_setaffinity") or expected < 2:
        return
    mask = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(mask)})  # this thread on one core (restored below)
    try:
        assert cores() == 1
    finally:
        os.sched_setaffinity(0, mask)
    assert os.sched_getaffinity(0) == mask


def test_results_are_taken_in_order_not_as_they_finish(stage):
    ds, here = stage
    pool = LastFirst()
    assert_same_run(here, _identify(ds, pool))
    names = {fn.__name__ for fn in pool.ran}
    # the local models, the race's runners, and the pinned fit beside the warm one
    assert {"_refined", "_advanced", "_judged"} <= names


def test_the_local_models_subspace_starts_are_made_in_the_calling_thread(monkeypatch):
    """numpy's LAPACK work stays in the caller's thread; only the core's refinements go out.

    OpenBLAS, limited to one thread at run time, gave n = 24 3x3 subspace
    starts 1e-9 apart on a pool's thread after a run on the main one, and
    five of nine local models changed.
    """
    import threading
    from concurrent.futures import ThreadPoolExecutor

    import lpvid.initial.local as local

    where = []
    made = local._point_starts

    def recorded(*args):
        where.append(threading.current_thread())
        return made(*args)

    monkeypatch.setattr(local, "_point_starts", recorded)
    true = lpvid.testing.one_group_lpv(0)
    data = lpvid.testing.noisy_data(
        true, [0.0, 0.5, 1.0], np.linspace(2, 100, 40), np.random.default_rng(1), 0.01
    )
    here = local.local_models(data, 10, strictly_proper=True)
    with ThreadPoolExecutor(2) as pool:
        there = local.local_models(data, 10, strictly_proper=True, executor=pool)
    assert len(where) == 6 and all(t is threading.current_thread() for t in where)
    for a, b in zip(here, there, strict=True):
        np.testing.assert_array_equal(a.theta, b.theta)


def test_the_few_points_starts_on_an_executor_are_those_made_here():
    """The blocks route's starts and the global start from every point, handed out last first."""
    from lpvid.initial.blocks import hand_out_blocks
    from lpvid.pipeline.misfit import global_everywhere

    true, fixed = lpvid.testing.one_group_lpv(0), {"D": True}
    data = lpvid.testing.noisy_data(
        true, [0.0, 0.4, 1.0], np.linspace(2, 100, 60), np.random.default_rng(1), 0.01
    )
    problem = lpvid.Problem(data, 10, true.basis, fixed=fixed)
    local = lpvid.identify_lti(data, 10, strictly_proper=True)
    makers = {
        "_block_candidates_at": lambda ex: hand_out_blocks(
            data, true.basis, fixed, local, executor=ex
        ).take(),
        "_global_all": lambda ex: global_everywhere(problem, local, ex),
    }
    for name, make in makers.items():
        pool = LastFirst()
        here, there = make(None), make(pool)
        assert len(here) >= 2 and [fn.__name__ for fn in pool.ran] == [name] * len(here)
        assert [c.name for c in there] == [c.name for c in here]
        for a, b in zip(here, there, strict=True):
            np.testing.assert_array_equal(a.model.theta, b.model.theta)
            assert a.vnls == b.vnls


def test_the_continuation_on_an_executor_is_the_walk_here():
    """Each side of the root its own piece (handed out last first here): the same models."""
    true = lpvid.testing.one_group_lpv(0)
    points = [0.0, 0.2, 0.45, 0.7, 1.0]
    data = lpvid.testing.noisy_data(
        true, points, np.linspace(2, 100, 60), np.random.default_rng(1), 0.01
    )
    plain = lpvid.identify_lti(data, 10, strictly_proper=True)
    here = lpvid.initial.continue_local(data, plain, root=2, strictly_proper=True)
    pool = LastFirst()
    there = lpvid.initial.continue_local(data, plain, root=2, strictly_proper=True, executor=pool)
    assert [fn.__name__ for fn in pool.ran] == ["_walk", "_walk"]
    assert here.starts == there.starts and any(s != "plain" for s in here.starts)
    np.testing.assert_array_equal(here.vnls, there.vnls)
    for a, b in zip([*here, *here.initial], [*there, *there.initial], strict=True):
        np.testing.assert_array_equal(a.theta, b.theta)


def _few(points: list[float], executor: Executor | None, said: list | None = None) -> Any:
    """one_group_lpv(0) at ``points``, 60 lines, without validation data."""
    true = lpvid.testing.one_group_lpv(0)
    lines = np.linspace(2, 100, 60)
    data = lpvid.testing.noisy_data(true, points, lines, np.random.default_rng(1), 0.01)
    say = None if said is None else said.append
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        return lpvid.identify(
            data, 10, true.basis, fixed={"D": True}, executor=executor, progress=say
        )


def test_the_blocks_route_handed_out_before_the_main_path_is_the_run_here(monkeypatch):
    """Taken when the points leave the structure open (three points), dropped when they
    determine it (five): the same run as one piece after the other either way."""
    monkeypatch.setattr(lpvid._spread, "cores", lambda: 1)  # the runs here: no threads of its own
    # (five points evenly spaced leave it open with the local models ended at
    # LOCAL_FTOL: these five determine it, with the local models run to 1e-10 too)
    for points, taken in (([0.0, 0.4, 1.0], True), ([0.0, 0.2, 0.45, 0.7, 1.0], False)):
        said: list[str] = []
        here, pool = _few(points, None), LastFirst(said)
        there = _few(points, pool, said)
        assert_same_run(here, there)
        assert any(c.name.startswith("blocks:") for c in here.candidates) is taken
        ahead = [f for name, f in pool.handed if name == "_block_candidates_at"]
        assert ahead and all(f.cancelled() is not taken for f in ahead)
        first_fit = next(k for k, m in enumerate(said) if "gamma =" in m)
        assert said.index("handed _block_candidates_at") < first_fit


def test_the_blocks_routes_handed_out_ahead_are_followed_in_their_piece(monkeypatch):
    """The blocks route's paths followed in the piece that fitted their starts: the same
    routes, counts and progress, in the same order, as followed after the main path."""
    import lpvid.pipeline.run as run

    monkeypatch.setattr(lpvid._spread, "cores", lambda: 1)  # the runs here: no threads of its own
    here_said: list[str] = []
    there_said: list[str] = []
    followed_after: list[str] = []
    real = run.follow

    def follow(name: str, *args: Any) -> Any:
        followed_after.append(name)
        return real(name, *args)

    monkeypatch.setattr(run, "follow", follow)
    here = _few([0.0, 0.4, 1.0], None, here_said)
    blocks_here = [name for name in followed_after if name.startswith("blocks:")]
    followed_after.clear()
    there = _few([0.0, 0.4, 1.0], LastFirst(there_said), there_said)
    assert_same_run(here, there)
    assert blocks_here  # the blocks route was followed, after the main path
    assert len(followed_after) == 1  # the main path's route only: the blocks routes were ahead
    assert [m for m in there_said if not m.startswith("handed ")] == here_said


def test_the_blocks_route_handed_out_ahead_is_dropped_on_ctrl_c(monkeypatch):
    """Ctrl-C in the main path: the piece handed out before it is cancelled, nothing runs on."""
    import lpvid.pipeline.run as run

    def interrupted(*args: Any, **kwargs: Any) -> Any:
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "follow", interrupted)
    pool = LastFirst()
    with pytest.raises(KeyboardInterrupt):
        _few([0.0, 0.4, 1.0], pool)
    ahead = [f for name, f in pool.handed if name == "_block_candidates_at"]
    assert len(ahead) == 1 and ahead[0].cancelled()


def test_a_piece_on_a_thread_runs_the_core_loops_on_that_thread():
    """Set while the piece runs, as it was after; not for a piece run here."""
    from lpvid import _core

    def setting() -> bool:
        before = _core._loops_here(True)
        _core._loops_here(before)
        return before

    with ThreadPoolExecutor(1) as pool:
        spread = Spread(pool)
        assert spread.take(spread.submit(setting)) is True
        assert pool.submit(setting).result() is False  # the thread's own setting back
    here = Spread(None)
    assert here.take(here.submit(setting)) is False


def test_identify_on_a_dask_cluster_is_the_run_here(stage):
    distributed = pytest.importorskip("distributed")
    ds, here = stage
    with (
        distributed.LocalCluster(
            n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0"
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        on_dask = _identify(ds, client)  # the client itself, as Dask users hold it
    assert_same_run(here, on_dask)


def test_the_first_failure_in_order_is_raised():
    def piece(k: int) -> int:
        if k >= 1:
            raise ValueError(f"piece {k}")
        return k

    pool = LastFirst()
    with pytest.raises(ValueError, match="piece 1"):
        Spread(pool).map(piece, [(k,) for k in range(4)])
    assert len(pool.ran) == 4  # pieces 3 and 2 failed first


def test_drop_stops_the_running_piece_and_cancels_every_one_not_started():
    """Rejects a drop that ends at the first piece it cancels, or returns before a stopped one ends.

    A piece left queued would run on after the KeyboardInterrupt that
    dropped it (and the run's own pool would wait for it on the way out).
    """
    started = threading.Event()

    def running() -> str:
        started.set()
        flag = stop_flag()
        assert flag is not None and flag.wait(10)  # until the drop sets it
        return "stopped"

    with ThreadPoolExecutor(1) as pool:
        spread = Spread(pool)
        first = spread.submit(running)
        queued = [spread.submit(int, k) for k in range(3)]
        assert started.wait(10)
        spread.drop()
        assert first.future.done() and first.future.result()[0] == "stopped"
        assert [p.future.cancelled() for p in queued] == [True, True, True]


def test_warnings_of_pieces_reach_the_caller():
    def piece(k: int) -> int:
        warnings.warn(f"piece {k} warns", lpvid.ConvergenceWarning, stacklevel=1)
        return k

    with ThreadPoolExecutor(2) as pool, pytest.warns(lpvid.ConvergenceWarning) as caught:
        assert Spread(pool).map(piece, [(0,), (1,)]) == [0, 1]
    assert [str(w.message) for w in caught] == ["piece 0 warns", "piece 1 warns"]
    # taken one by one, a piece's warning points at the caller of take, not at take
    with ThreadPoolExecutor(1) as pool, pytest.warns(lpvid.ConvergenceWarning) as caught:
        spread = Spread(pool)
        assert spread.take(spread.submit(piece, 2)) == 2
    assert len(caught) == 1 and os.path.basename(caught[0].filename) != "_spread.py"


def test_executor_must_be_an_executor(stage):
    ds, _ = stage
    with pytest.raises(TypeError, match="executor: expected a concurrent.futures.Executor"):
        lpvid.identify(ds.identification, ds.order, ds.basis, executor=2)


def test_a_process_pool_that_forks_is_refused_before_any_work(stage):
    """It forks while lpvid may run on other threads, whose locks it would copy held."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    ds, _ = stage
    for method in ("fork", "forkserver", "spawn"):
        if method not in multiprocessing.get_all_start_methods():
            continue
        pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context(method))
        try:  # no worker starts before the first task
            if method == "fork":
                refused = pytest.raises(ValueError, match="forks its workers.*'forkserver'")
                with refused:
                    lpvid.identify(ds.identification, ds.order, ds.basis, executor=pool)
                with refused:
                    lpvid.select(ds.identification, [4], [1], executor=pool)
            else:
                assert check_executor(pool) is pool
        finally:
            pool.shutdown()
    # A pool whose context is not where CPython keeps it today is taken as one
    # that does not fork, not refused with an AttributeError.
    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"))
    context = pool.__dict__.pop("_mp_context")
    try:
        assert check_executor(pool) is pool
    finally:
        pool._mp_context = context
        pool.shutdown()


def test_a_dask_client_is_taken_as_its_executor():
    """A distributed.Client is read as its get_executor(); a look-alike elsewhere is not."""
    pool = ThreadPoolExecutor(1)

    def client_class(module: str) -> type:
        return type("Client", (), {"__module__": module, "get_executor": lambda self: pool})

    try:
        assert check_executor(client_class("distributed.client")()) is pool
        for module in ("mypackage", "notdistributed.client"):
            with pytest.raises(TypeError, match="or a distributed.Client, got Client"):
                check_executor(client_class(module)())
        broken = type("Client", (), {"__module__": "distributed", "get_executor": lambda s: 3})
        with pytest.raises(TypeError, match="got Client"):
            check_executor(broken())
        # a distributed class named Client without get_executor: the same error
        with pytest.raises(TypeError, match="or a distributed.Client, got Client"):
            check_executor(type("Client", (), {"__module__": "distributed.client"})())
    finally:
        pool.shutdown()


# The positioning stage without its `fixed` keeps a pinned fit, whose
# kept-off directions are made orthonormal by an SVD: on faer's thread pool
# that SVD (and a matrix-vector product of the cone step) summed in another
# order on one thread than on two, and the returned model differed.
_ON_THREADS = """
import hashlib, warnings
import lpvid
ds = lpvid.datasets.positioning_stage(seed=0)
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    r = lpvid.identify(ds.identification, ds.order, ds.basis, validation=ds.validation)
print(hashlib.sha1(r.model.theta.tobytes()).hexdigest(), any(e.pinned for e in r.entries))
"""


def test_identify_is_the_same_on_any_number_of_threads():
    """Pools of one thread and of three give the same run (a Dask worker has its own cores)."""
    out = {}
    for threads in (1, 3):  # each in a process of its own: the pool is made once per process
        env = {**os.environ, "RAYON_NUM_THREADS": str(threads)}
        done = subprocess.run(
            [sys.executable, "-c", _ON_THREADS],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert done.returncode == 0, done.stderr
        out[threads] = done.stdout.split()
    assert out[1][1] == "True"  # the pinned fit was kept
    assert out[1][0] == out[3][0]


def test_identify_lti_is_the_same_whatever_the_layout_of_the_data():
    """A transposed sigma gives the bits of its C-ordered copy (what a pickled copy is).

    numpy sums along a strided axis in another order than along a
    contiguous one; the data's arrays are stored C-ordered whatever the
    caller passed (before, the subspace step's weights differed in the last
    bits, and every local model with them).
    """
    rng = np.random.default_rng(3)
    true = lpvid.testing.random_lpv(rng, n=6, r=2, l=2, nb=0, Ts=None)
    f = np.linspace(0.05, 3.0, 300)
    clean = true.frf(f, [0.0])
    sigma = 0.01 * (1.0 + rng.random(clean.shape))
    noise = rng.standard_normal(clean.shape) + 1j * rng.standard_normal(clean.shape)
    G = clean + sigma * noise / np.sqrt(2.0)
    transposed = np.asfortranarray(sigma)
    assert not transposed.flags["C_CONTIGUOUS"]
    data = lpvid.FrfData([0.0], f, G, sigma=transposed)
    assert data.sigma.flags["C_CONTIGUOUS"] and data.G.flags["C_CONTIGUOUS"]
    (a,) = lpvid.identify_lti(lpvid.FrfData([0.0], f, G, sigma=sigma), 6)
    (b,) = lpvid.identify_lti(data, 6)
    assert np.array_equal(a.theta, b.theta)
    assert (
        lpvid.vnls(a, data) < 1.5 * data.n_residuals
    )  # a fit at the noise, not two equal failures
