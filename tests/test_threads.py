"""numpy's BLAS on one thread inside lpvid's entry points (lpvid._threads)."""

import json

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import lpvid._threads as threads


def _blas_threads() -> set[int]:
    return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}


@pytest.fixture
def counted(monkeypatch):
    """The calls that set a limit, counted."""
    calls = []

    def counting(*args, **kwargs):
        calls.append(kwargs)
        return threadpool_limits(*args, **kwargs)

    monkeypatch.setattr(threads, "threadpool_limits", counting)
    return calls


def test_one_limit_for_nested_entry_points_and_the_callers_setting_after(counted):
    seen = []

    @threads.single_blas
    def inner():
        seen.append(("inner", _blas_threads()))

    @threads.single_blas
    def outer():
        seen.append(("outer", _blas_threads()))
        inner()
        inner()
        seen.append(("after inner", _blas_threads()))

    if not _blas_threads():
        pytest.skip("no BLAS library that threadpoolctl controls")
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()  # 2, or what a library allows
        outer()
        assert _blas_threads() == before
    assert [where for where, _ in seen] == ["outer", "inner", "inner", "after inner"]
    assert all(n == {1} for _, n in seen)
    assert len(counted) == 1
    inner()  # outside again: limits once more
    assert len(counted) == 2


def test_a_failing_entry_point_leaves_the_next_call_limited(counted):
    @threads.single_blas
    def fails():
        raise RuntimeError("boom")

    @threads.single_blas
    def fine():
        return _blas_threads()

    with pytest.raises(RuntimeError, match="boom"):
        fails()
    assert len(counted) == 1
    assert fine() in ({1}, set())
    assert len(counted) == 2


def test_an_entry_point_on_another_thread_within_a_limited_run_sets_no_limit(counted):
    """The pieces of a run on its threads: one limit for all, the caller's setting after."""
    from concurrent.futures import ThreadPoolExecutor

    @threads.single_blas
    def piece():
        return _blas_threads()

    @threads.single_blas
    def run():
        with ThreadPoolExecutor(2) as pool:
            return [f.result() for f in [pool.submit(piece) for _ in range(6)]]

    if not _blas_threads():
        pytest.skip("no BLAS library that threadpoolctl controls")
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        seen = run()
        assert _blas_threads() == before
    assert all(n == {1} for n in seen)
    assert len(counted) == 1


def _on_a_thread(fn):
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:
        return pool.submit(fn).result()


def test_the_last_to_return_on_another_thread_restores_the_callers_setting(blas_threads):
    """Entered on this thread, left last on another (as select's interrupted run ends on a
    pool thread): threadpoolctl 3.8 ignores every thread but the one that set a limit first."""
    import threading

    threadpool_limits(limits=2, user_api="blas")  # as a caller would: this thread in control
    before = _blas_threads()
    inside, entered, main_left = [], threading.Event(), threading.Event()

    @threads.single_blas
    def piece():
        entered.set()
        main_left.wait(10)
        inside.append(_blas_threads())

    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:
        threads._enter()
        try:
            running = pool.submit(piece)
            entered.wait(10)
        finally:
            threads._leave()
        main_left.set()
        running.result()
    assert inside == [{1}]
    assert _blas_threads() == before


def test_an_entry_point_on_another_thread_limits_after_one_on_this_thread(blas_threads):
    """After a run on the main thread, a run on a pool thread is limited too, and restored."""

    @threads.single_blas
    def run():
        return _blas_threads()

    threadpool_limits(limits=2, user_api="blas")  # as a caller would: this thread in control
    before = _blas_threads()
    assert run() == {1}
    assert _on_a_thread(run) == {1}
    assert _blas_threads() == before
    # and the caller keeps the control of its own limits
    threadpool_limits(limits=1, user_api="blas")
    assert _blas_threads() == {1}


def test_scipy_loaded_by_the_first_run_is_limited_too(tmp_path):
    """A fresh process: scipy's own BLAS (loaded by the run, after lpvid's import) on one thread."""
    import subprocess
    import sys

    script = (
        "import sys, json\n"
        "import lpvid._threads as t\n"
        "from threadpoolctl import threadpool_info\n"
        "assert 'scipy.linalg' not in sys.modules\n"
        "def libs(): return {i['filepath']: i['num_threads'] for i in threadpool_info()"
        " if i['user_api'] == 'blas'}\n"
        "before = libs()\n"
        "@t.single_blas\n"
        "def run():\n"
        "    import scipy.linalg\n"
        "    return libs()\n"
        "print(json.dumps([before, run(), libs()]))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=120
    )
    before, inside, after = json.loads(out.stdout)
    if not before:
        pytest.skip("no BLAS library that threadpoolctl controls")
    assert len(inside) >= len(before) and set(inside.values()) == {1}, inside
    assert all(after[k] == v for k, v in before.items()), (before, after)
