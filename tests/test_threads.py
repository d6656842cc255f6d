"""numpy's BLAS on one thread inside lpvid's entry points (lpvid._threads)."""

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
