"""numpy work side by side on threads (lpvid._spread): the same results as one after the other.

Each test names the wrong code it rejects. The property that matters is
that a result does not depend on whether the work ran on threads or one
piece after the other (on a machine of one core, or called from a thread
other than the main one), so every test compares the two, bit for bit.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest
from threadpoolctl import threadpool_info

import lpvid
import lpvid.testing
from lpvid import _spread
from lpvid.initial.coherent import pairwise_form


def _where(k: int) -> tuple[int, str, int]:
    blas = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
    return k, threading.current_thread().name, max(blas)


def test_the_calls_go_to_threads_in_order_with_blas_on_one_thread():
    """Rejects the results taken as they finish, or numpy's BLAS left on every core in a call."""
    if _spread.cores() < 2:
        pytest.skip("one core: nothing runs side by side")
    out = _spread.side_by_side(_where, [(k,) for k in range(6)], flops=1e12, each=0)
    assert [k for k, _, _ in out] == list(range(6))
    assert all(name.startswith("lpvid") for _, name, _ in out)  # the own threads
    assert all(blas == 1 for _, _, blas in out)


def test_small_work_runs_here():
    """Rejects a thread pool started for calls below THREAD_FLOPS (or over the memory budget)."""
    main = threading.current_thread().name
    small = _spread.side_by_side(_where, [(0,), (1,)], flops=1e6, each=0)
    large = _spread.side_by_side(_where, [(0,), (1,)], flops=1e12, each=2**40)
    assert {name for _, name, _ in small + large} == {main}


def test_as_many_threads_as_the_memory_budget_holds(monkeypatch):
    """Rejects one thread per core where the calls at once would need more than the budget."""
    monkeypatch.setattr(_spread, "cores", lambda: 8)
    third = _spread.SMALL_RUN_BYTES // 3

    def name(k: int) -> str:
        threading.Event().wait(0.05)  # long enough for every thread of the pool to take one
        return threading.current_thread().name

    names = _spread.side_by_side(name, [(k,) for k in range(12)], flops=1e12, each=third)
    assert len(set(names)) == 3
    alone = _spread.side_by_side(name, [(k,) for k in range(4)], flops=1e12, each=2 * third)
    assert set(alone) == {threading.current_thread().name}


def test_the_cores_are_the_affinity_else_the_count(monkeypatch):
    """Rejects a count other than the process's affinity, or a wrong one where it is unknown."""
    monkeypatch.setattr(_spread.os, "sched_getaffinity", lambda pid: {0, 3, 5}, raising=False)
    assert _spread.cores() == 3
    monkeypatch.setattr(_spread.os, "sched_getaffinity", lambda pid: set(), raising=False)
    assert _spread.cores() == 1
    monkeypatch.delattr(_spread.os, "sched_getaffinity", raising=False)
    for count, expected in ((3, 3), (1, 1), (None, 1), (0, 1)):
        monkeypatch.setattr(_spread.os, "cpu_count", lambda count=count: count)
        assert _spread.cores() == expected


def test_a_product_goes_by_blocks_from_thread_flops_a_block_over_one_block(rng, monkeypatch):
    """Rejects another count of flops, a product of one block cut, or another memory per call.

    By :func:`lpvid._spread.product`'s notes: blocks when the columns are
    more than one block and a block's product (``2 rows inner block``
    flops) is :data:`~lpvid._spread.THREAD_FLOPS` or more, each call
    holding one block of the result.
    """
    calls = []

    def recorded(fn, starts, *, flops, each):
        calls.append((len(starts), flops, each))
        for args in starts:
            fn(*args)

    monkeypatch.setattr(_spread, "side_by_side", recorded)
    block = _spread.PRODUCT_BLOCK
    rows, inner = 3, 4
    a = rng.standard_normal((rows, inner))
    flops = 2.0 * rows * inner * block
    for cols, limit, by_blocks in (
        (block + 1, flops, True),  # a block's flops at the limit
        (block + 1, flops * 1.01, False),  # just below it
        (block, 0.0, False),  # one block, whatever its work
    ):
        calls.clear()
        monkeypatch.setattr(_spread, "THREAD_FLOPS", limit)
        b = rng.standard_normal((inner, cols))
        np.testing.assert_allclose(_spread.product(a, b), a @ b, rtol=1e-13)
        expected = [(2, flops, 8 * rows * block)] if by_blocks else []
        assert calls == expected, (cols, limit)


def test_the_first_failure_in_order_is_raised():
    """Rejects the failure that came first in time (or none) raised instead."""

    def fail_from_two(k: int) -> int:
        if k >= 2:
            raise ValueError(f"call {k}")
        return k

    with pytest.raises(ValueError, match="^call 2$"):
        _spread.side_by_side(fail_from_two, [(k,) for k in range(5)], flops=1e12, each=0)


@pytest.mark.parametrize("shape", [(300, 200, 1100), (90, 700, 1030)])
def test_a_product_in_blocks_is_the_same_on_any_number_of_cores(rng, shape, monkeypatch):
    """Rejects blocks cut by the number of cores, or a block left out or written twice."""
    rows, inner, cols = shape
    a = rng.standard_normal((rows, inner))
    b = rng.standard_normal((inner, cols))
    monkeypatch.setattr(_spread, "THREAD_FLOPS", 1.0)  # every product goes by blocks
    threaded = _spread.product(a, b)
    monkeypatch.setattr(_spread, "cores", lambda: 1)
    alone = _spread.product(a, b)
    np.testing.assert_array_equal(threaded, alone)
    np.testing.assert_allclose(threaded, a @ b, rtol=1e-12, atol=1e-12 * np.abs(a @ b).max())
    # A transposed view on the left (as the covariance's Z^T H), a product of one block.
    np.testing.assert_allclose(_spread.product(b.T, b[:, :7]), b.T @ b[:, :7], rtol=1e-12)


def _pairwise_in_order(models, p):
    """The pairwise form walked in order, its least squares built map by map (no Kronecker).

    Column ``i + j n`` of the system is the residual's change for
    ``T = E_ij``: ``(E A_k - A_m E) / |A_m|``, ``E B_k / |B_m|``,
    ``C_m E / |C_m|``, against ``(0, B_m / |B_m|, C_k / |C_m|)``.
    """
    from lpvid.data.schedule import propagation_order

    order, parent = propagation_order(p)
    out = [None] * len(models)
    out[order[0]] = models[order[0]]
    for k in order[1:]:
        (Am, Bm, Cm, _), (Ak, Bk, Ck, Dk) = out[parent[k]], models[k]
        n = Ak.shape[0]
        wa, wb, wc = (1.0 / np.linalg.norm(x) for x in (Am, Bm, Cm))
        columns = []
        for j in range(n):
            for i in range(n):
                E = np.zeros((n, n))
                E[i, j] = 1.0
                parts = (wa * (E @ Ak - Am @ E), wb * (E @ Bk), wc * (Cm @ E))
                columns.append(np.concatenate([x.ravel(order="F") for x in parts]))
        target = (np.zeros((n, n)), wb * Bm, wc * Ck)
        rhs = np.concatenate([x.ravel(order="F") for x in target])
        T = np.linalg.lstsq(np.stack(columns, axis=1), rhs, rcond=None)[0].reshape(n, n, order="F")
        Ti = np.linalg.inv(T)
        out[k] = (T @ Ak @ Ti, T @ Bk, Ck @ Ti, Dk)
    return out


def test_the_pairwise_form_is_the_same_walked_side_by_side(rng, monkeypatch):
    """Rejects a subtree aligned to the wrong neighbour, or its points given to others.

    Against the walk in order (the form as it was), on threads and on one
    core; 2 x 3 points on a grid give the root two subtrees of two and three.
    """
    true = lpvid.testing.synthetic_parametric(6)
    p = np.array([[a, b] for a in (0.02, 0.5, 1.0) for b in (0.0, 1.0)])
    models = []
    for q in p:  # each point in coordinates of its own
        A, B, C, D = true.at(float(q[0]))
        T = np.eye(6) + 0.3 * rng.standard_normal((6, 6))
        Ti = np.linalg.inv(T)
        models.append((T @ A @ Ti + 0.01 * q[1] * np.eye(6), T @ B, C @ Ti, D))
    want = _pairwise_in_order(models, p)
    monkeypatch.setattr(_spread, "THREAD_FLOPS", 1.0)
    threaded, notes = pairwise_form(models, p)
    monkeypatch.setattr(_spread, "cores", lambda: 1)
    alone, notes_alone = pairwise_form(models, p)
    assert notes == notes_alone
    for x, y, z in zip(threaded, alone, want, strict=True):
        for u, v, w in zip(x, y, z, strict=True):
            np.testing.assert_array_equal(u, v)
            np.testing.assert_allclose(u, w, rtol=1e-9, atol=1e-12)


def test_the_continuation_root_s_pole_uncertainties_are_the_same_side_by_side(monkeypatch):
    """Rejects a local model's pole uncertainty computed with another BLAS setting on a thread."""
    from lpvid.initial.continuation import best_determined

    ds = lpvid.datasets.gantry()
    local = lpvid.identify_lti(ds.identification, ds.order)
    monkeypatch.setattr(_spread, "THREAD_FLOPS", 1.0)

    def uncertainties() -> tuple[int, dict]:
        local._derived.clear()
        root = best_determined(local, ds.identification, fixed={"D": True})
        kept = {k: v[1] for k, v in local._derived.items() if k[0] == "least certain pole"}
        return root, kept

    threaded = uncertainties()
    monkeypatch.setattr(_spread, "cores", lambda: 1)
    alone = uncertainties()
    assert threaded[0] == alone[0]
    assert len(threaded[1]) >= 2
    assert {k: np.float64(v).tobytes() for k, v in threaded[1].items()} == {
        k: np.float64(v).tobytes() for k, v in alone[1].items()
    }
