"""lpvid.select: the grid of orders and bases, the choice, executors, Ctrl-C, the CLI."""

import os
import pickle
import signal
import subprocess
import sys
import threading
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import lpvid
import lpvid.testing
from lpvid.cli import main
from lpvid.initial.subspace import singular_values
from lpvid.selection.grid import held_out_points

# A known system: two modes (order 4) whose frequencies are quadratic in p.
QUADRATIC = [[12.0, 3.0, 2.0], [30.0, -4.0, 3.0]]
FREQS = np.linspace(4, 60, 40)


@pytest.fixture(scope="module")
def quadratic():
    true = lpvid.testing.modal_lpv(QUADRATIC, damping=0.03)
    rng = np.random.default_rng(3)
    data = lpvid.testing.noisy_data(true, np.linspace(0, 1, 5), FREQS, rng, 0.01)
    val = lpvid.testing.noisy_data(true, np.linspace(0.125, 0.875, 4), FREQS, rng, 0.01)
    return true, data, val


@pytest.fixture(scope="module")
def grid(quadratic):
    """select(orders 2..6, degrees 1..3) with validation data, on the default threads."""
    _, data, val = quadratic
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        return lpvid.select(data, range(2, 7), range(1, 4), validation=val)


@pytest.fixture(scope="module")
def small():
    """One mode (order 2), linear in p, at 3 points: cheap runs."""
    true = lpvid.testing.modal_lpv([[10.0, 3.0]])
    rng = np.random.default_rng(0)
    f = np.linspace(2, 30, 40)
    data = lpvid.testing.noisy_data(true, [0.0, 0.5, 1.0], f, rng, 0.01)
    val = lpvid.testing.noisy_data(true, [0.25, 0.75], f, rng, 0.01)
    return true, data, val


def quiet_select(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        return lpvid.select(*args, **kwargs)


def test_known_system_gives_its_order_and_degree(grid):
    assert grid.rule == "validation"
    assert (grid.order, grid.basis.degree) == (4, 2), grid.table()
    assert grid.best is grid.row.result and grid.model is grid.best.model
    assert grid.model.n_states == 4 and len(grid.model.basis) == 2
    # the rule as documented: within tolerance of the best, the fewest free parameters
    vals = [r.validation_vnls for r in grid.grid if r.validation_vnls is not None]
    best = min(vals)
    assert grid.row.validation_vnls <= 1.1 * best
    within = [r for r in grid.grid if r.ok and r.validation_vnls <= 1.1 * best]
    assert grid.row.n_free == min(r.n_free for r in within)
    # every lower order misses the data by far; the order hint says 4
    assert all(r.vnls > 100 * r.noise_floor for r in grid.grid if r.order < 4)
    assert grid.hints.orders[0] == 4
    assert "order 4, poly:2" in grid.summary() and "order hints" in grid.summary()
    table = grid.table().splitlines()
    assert len(table) == 1 + 15 + 1 and sum(line.startswith("->") for line in table) == 1
    # the last line: the scale rule's verdict (p in [0, 1] reaches zero: no log twin)
    assert table[-1].startswith("scale: the bases as given (no log twin): p in [0, 1] reaches zero")


def test_rows_hold_each_pairs_identify_result(grid, quadratic):
    _, data, val = quadratic
    assert [(r.order, r.basis.degree) for r in grid.grid] == [
        (n, d) for n in range(2, 7) for d in range(1, 4)
    ]
    for r in grid.grid:
        assert r.error is None and r.ok
        e = r.result.final
        assert r.vnls == e.vnls == pytest.approx(lpvid.vnls(r.result.model, data), rel=1e-9)
        assert r.validation_vnls == pytest.approx(lpvid.vnls(r.result.model, val), rel=1e-9)
        assert r.noise_floor == data.n_residuals and r.validation_floor == val.n_residuals
        # free parameters in use, counted independently: constant parts and kept groups
        m = r.result.model
        size = {x: getattr(m, x)[0].size for x in "ABCD"}
        expected = sum(size[x] * (1 + len(e.nonzero_groups[x])) for x in "ABCD")
        assert r.n_free == expected


def test_pickles_for_a_worker(grid, quadratic):
    _, data, _ = quadratic
    for obj in (data, lpvid.Polynomial(3, domain=(0, 1)), lpvid.Legendre(2, domain=(0, 1))):
        back = pickle.loads(pickle.dumps(obj))
        assert back == obj if isinstance(obj, lpvid.Basis) else np.array_equal(back.G, obj.G)
    model = pickle.loads(pickle.dumps(grid.model))
    assert np.array_equal(model.theta, grid.model.theta) and model.basis == grid.model.basis
    np.testing.assert_array_equal(model.frf(FREQS, [0.3]), grid.model.frf(FREQS, [0.3]))
    best = pickle.loads(pickle.dumps(grid.best))
    assert best.final.vnls == grid.best.final.vnls and best.reason == grid.best.reason
    sel = pickle.loads(pickle.dumps(grid))
    assert sel.table() == grid.table() and sel.order == grid.order


def test_dask_cluster_gives_the_thread_result_exactly(grid, quadratic):
    distributed = pytest.importorskip("distributed")
    _, data, val = quadratic
    orders, degrees = [4, 5], [1, 2]
    threads = quiet_select(data, orders, degrees, validation=val)
    with (
        distributed.LocalCluster(
            n_workers=2, processes=True, threads_per_worker=1, dashboard_address=":0"
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        on_dask = quiet_select(data, orders, degrees, validation=val, executor=client)
    assert on_dask.chosen == threads.chosen and on_dask.reason == threads.reason
    full = {(r.order, r.basis.degree): r for r in grid.grid}
    for a, b in zip(threads.grid, on_dask.grid, strict=True):
        assert b.error is None
        assert (a.vnls, a.validation_vnls, a.n_groups, a.n_free) == (
            b.vnls,
            b.validation_vnls,
            b.n_groups,
            b.n_free,
        )
        assert np.array_equal(a.result.model.theta, b.result.model.theta)
        assert b.vnls == full[(b.order, b.basis.degree)].vnls  # and the same as in the big grid


def test_a_failing_pair_is_recorded_and_the_others_go_on(small):
    _, data, val = small

    def every_7th_line(d):  # 6 lines: order 9 is beyond what the data determine
        return lpvid.FrfData(d.p, d.freqs_hz[::7], d.G[:, ::7], d.sigma[:, ::7])

    few = every_7th_line(data)
    sel = quiet_select(few, [2, 9], [1], validation=every_7th_line(val))
    bad = sel.grid[1]
    assert bad.order == 9 and not bad.ok and bad.result is None
    assert bad.error.startswith("ValueError: order: 9") and bad.vnls is None
    assert sel.order == 2 and sel.grid[0].ok
    assert "failed" in sel.summary() and "ValueError: order: 9" in sel.table()
    with pytest.raises(ValueError, match="no pair of the grid could be identified: order 9"):
        quiet_select(few, [9, 10], [1])


def test_held_out_rotation_without_validation(small):
    true = lpvid.testing.modal_lpv([[10.0, 3.0]])
    rng = np.random.default_rng(5)
    f = np.linspace(2, 30, 20)
    data = lpvid.testing.noisy_data(true, np.linspace(0, 1, 5), f, rng, 0.01)
    assert held_out_points(data, [lpvid.Polynomial(1)]) == [1, 2, 3]
    assert held_out_points(data, [lpvid.Polynomial(3)]) == []  # N > Nb + 2 is needed
    sel = quiet_select(data, [1, 2], [1])
    assert sel.rule == "held-out" and sel.order == 2
    row = sel.row
    assert row.validation_floor == 3 * f.size * 2
    # the rotation, recomputed: each interior point left out in turn and judged
    total = 0.0
    for q in (1, 2, 3):
        keep = [k for k in range(5) if k != q]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
            fit = lpvid.identify(data.subset(keep), 2, row.basis)
        total += lpvid.vnls(fit.model, data.subset([q]))
    assert row.validation_vnls == pytest.approx(total, rel=1e-9)
    assert "held-out" in sel.reason and "held-out" in sel.table()
    # The options of select reach the held-out runs too.
    opts = dict(gammas=[0.3, 3e-2, 3e-3], fixed={"D": True}, tolerance=3.0)
    sel = quiet_select(data, [2], [1], **opts)
    total = 0.0
    for q in (1, 2, 3):
        keep = [k for k in range(5) if k != q]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
            fit = lpvid.identify(
                data.subset(keep),
                2,
                sel.row.basis,
                opts["gammas"],
                None,
                opts["fixed"],
                tolerance=opts["tolerance"],
            )
        total += lpvid.vnls(fit.model, data.subset([q]))
    assert sel.row.validation_vnls == pytest.approx(total, rel=1e-9)


def test_noise_floor_rule_with_no_point_to_spare(small):
    _, data, _ = small
    sel = quiet_select(data, [1, 2, 3], [1])
    assert sel.rule == "noise floor" and sel.order == 2
    m = sel.row.noise_floor
    assert sel.row.vnls <= m + 2 * np.sqrt(m)
    assert all(r.vnls > m + 2 * np.sqrt(m) for r in sel.grid if r.order < 2)


def test_each_pair_is_identify_with_selects_options(small):
    import time

    _, data, val = small
    opts = dict(gammas=[0.3, 3e-2, 3e-3], tolerance=3.0)
    t0 = time.perf_counter()
    sel = quiet_select(data, [2], [1], validation=val, **opts)
    elapsed = time.perf_counter() - t0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        alone = lpvid.identify(data, 2, sel.row.basis, opts["gammas"], val, tolerance=3.0)
    np.testing.assert_array_equal(sel.model.theta, alone.model.theta)
    assert sel.row.result.final.gamma == alone.final.gamma
    assert 0 < sel.row.seconds <= elapsed


def test_fixed_for_every_pair_and_per_pair(small):
    _, data, val = small
    sel = quiet_select(data, [2], [1, 2], validation=val, fixed={"D": True})
    for r in sel.grid:
        assert np.all(r.result.model.D == 0)
        m, e = r.result.model, r.result.final
        size = {x: getattr(m, x)[0].size for x in "ABC"}
        assert r.n_free == sum(size[x] * (1 + len(e.nonzero_groups[x])) for x in "ABC")
    seen = []

    def fixed(order, basis):
        seen.append((order, basis.degree))
        return {"A": [0]} if basis.degree == 2 else None

    per_pair = quiet_select(data, [2], [1, 2], validation=val, fixed=fixed)
    assert sorted(seen) == [(2, 1), (2, 2)]
    assert np.array_equal(per_pair.grid[1].result.model.A[0], per_pair.grid[1].result.initial.A[0])


def test_ctrl_c_returns_what_is_done(small):
    _, data, val = small
    messages = []

    def progress(message):
        messages.append(message)
        if "(1/" in message:
            raise KeyboardInterrupt

    with ThreadPoolExecutor(1) as pool:
        sel = quiet_select(
            data, [1, 2, 3], [1, 2], validation=val, executor=pool, progress=progress
        )
    assert sel.interrupted
    done = [r for r in sel.grid if r.ok]
    cancelled = [r for r in sel.grid if r.error == "cancelled"]
    assert len(done) >= 1 and len(cancelled) >= 3 and len(done) + len(cancelled) == 6
    assert sel.row.ok and sel.summary().startswith("interrupted (Ctrl-C)")


def test_ctrl_c_before_any_pair_is_done(small, python_sigint):
    _, data, val = small
    gate = threading.Event()
    with ThreadPoolExecutor(1) as pool:
        pool.submit(gate.wait, 30)  # the only worker is busy: the pairs wait in the queue
        # Ctrl-C delivered to another thread (the timer's), as a terminal's SIGINT may be:
        # the main thread, waiting for the pairs, must still see it before the gate opens.
        timer = threading.Timer(
            0.5, lambda: signal.pthread_kill(threading.get_ident(), signal.SIGINT)
        )
        timer.start()
        try:
            with pytest.raises(KeyboardInterrupt, match="before any pair was done"):
                quiet_select(data, [1, 2], [1], validation=val, executor=pool)
        finally:
            timer.cancel()
            gate.set()


def test_warnings_are_collected_per_pair_and_the_filters_restored(small):
    _, data, val = small
    filters, show = list(warnings.filters), warnings.showwarning
    # order 5 for a system of order 2: a spare pole lands outside the stable region
    with pytest.warns(lpvid.ConvergenceWarning, match="^order 5, poly:1: the chosen model has"):
        sel = lpvid.select(data, [5], [1], validation=val)
    assert warnings.filters == filters and warnings.showwarning is show
    assert sel.row.warnings and all(c is lpvid.ConvergenceWarning for c, _ in sel.row.warnings)
    assert "warning(s)" in sel.table()


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (dict(orders=[]), ValueError, "orders: needs at least one"),
        (dict(orders=[2, 2]), ValueError, r"orders: \[2\] given twice"),
        (dict(orders=[0]), ValueError, "orders"),
        (dict(orders=2), TypeError, "orders: expected a sequence"),
        (dict(bases=[]), ValueError, "bases: needs at least one"),
        (dict(bases=["poly"]), TypeError, "bases"),
        (dict(bases=[1, 1]), ValueError, "bases: poly:1 given twice"),
        (dict(bases=[lpvid.Polynomial(1, n_params=2)]), ValueError, "bases: poly:1 takes 2"),
        (dict(validation="v.npz"), TypeError, "validation: expected an FrfData"),
        (dict(gammas=[-1.0]), ValueError, "gammas"),
        (dict(tolerance=-0.1), ValueError, "tolerance"),
        (dict(executor="threads"), TypeError, "executor: expected a concurrent.futures"),
        (dict(progress=3), TypeError, "progress: expected a callable"),
        (dict(fixed=np.zeros(20, dtype=bool)), TypeError, "fixed: a boolean mask over theta"),
        (dict(fixed={"A": [2]}), ValueError, r"fixed: for order 2, poly:1: fixed\['A'\]"),
        (dict(fixed={"E": True}), ValueError, "fixed: for order 2, poly:1: fixed: unknown"),
    ],
)
def test_bad_arguments_raise_named_errors(small, kwargs, error, match):
    _, data, _ = small
    args = dict(orders=[2], bases=[1]) | kwargs
    with pytest.raises(error, match=match):
        lpvid.select(data, **args)


def test_order_hints_see_the_order_and_not_the_noise(quadratic):
    true, data, _ = quadratic
    # noise-free: exactly 4 singular values above rounding at every point
    exact = lpvid.FrfData(data.p, FREQS, lpvid.testing.direct_frf(true, FREQS, data.p))
    s = singular_values(FREQS, exact.G[2], None, None, n_rows=10)
    assert s[4] / s[3] < 1e-6 and s[3] / s[0] > 1e-4
    # pure noise of known sigma: no drop above the noise level
    rng = np.random.default_rng(1)
    sigma = data.sigma
    noise = sigma * (rng.normal(size=sigma.shape) + 1j * rng.normal(size=sigma.shape)) / np.sqrt(2)
    hints = lpvid.order_hints(lpvid.FrfData(data.p, FREQS, noise, sigma))
    assert hints.orders == [] and "none" in str(hints)
    assert np.all(hints.singular_values < 2.0)  # NOISE_LEVEL
    with pytest.raises(TypeError, match="data: expected an FrfData"):
        lpvid.order_hints(data.G)


def test_select_grid_figure(grid):
    pytest.importorskip("matplotlib")
    fig = lpvid.plots.select_grid(grid, title="quadratic")
    lines = {ln.get_gid(): ln for ln in fig.axes[0].get_lines()}
    assert {"basis/poly:1", "basis/poly:2", "basis/poly:3", "chosen"} <= set(lines)
    x, y = lines["basis/poly:2"].get_data()
    assert list(x) == [2, 3, 4, 5, 6]
    row = grid.row
    assert y[2] == pytest.approx(row.validation_vnls / row.validation_floor)
    assert lines["chosen"].get_data()[0][0] == 4
    with pytest.raises(TypeError, match="sel: expected"):
        lpvid.plots.select_grid(grid.best)
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_cli_select_writes_the_grid_and_the_report(small, tmp_path, capsys):
    _, data, val = small
    data.save(tmp_path / "d.npz")
    val.save(tmp_path / "v.npz")
    out = tmp_path / "out"
    code = main(
        [
            "select",
            str(tmp_path / "d.npz"),
            "--orders",
            "1:3",
            "--degrees",
            "1,2",
            "--validation",
            str(tmp_path / "v.npz"),
            "--out",
            str(out),
            "--no-figures",
            "--quiet",
        ]
    )
    printed = capsys.readouterr().out
    assert code == 0
    assert "-> " in printed and "chosen: order 2, poly:1" in printed
    for name in ("select.md", "grid.json", "report.md", "model.json", "model.mat"):
        assert (out / name).exists(), name
    import json

    numbers = json.loads((out / "grid.json").read_text())
    assert numbers["chosen"] == {"order": 2, "basis": "poly:1", "index": 2}
    assert len(numbers["grid"]) == 6 and numbers["rule"] == "validation"
    assert lpvid.LpvModel.load(out / "model.json").n_states == 2


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--orders", "4:x", "--degrees", "1"], "--orders: expected LO:HI"),
        (["--orders", "5:4", "--degrees", "1"], "--orders: LO:HI needs LO <= HI"),
        (["--orders", "2", "--degrees", "1:3"], "--degrees: degree 3 has 3 basis functions"),
        (["--orders", "2", "--degrees", "1", "--tolerance", "-1"], "--tolerance: expected"),
        (["--orders", "2", "--degrees", "1", "--validation", "nope.npz"], "--validation: no such"),
        (["--orders", "2,2", "--degrees", "1"], "--orders: a value is given twice"),
    ],
)
def test_cli_select_misuse_is_one_line_and_exit_2(small, tmp_path, capsys, extra, message):
    _, data, _ = small
    data.save(tmp_path / "d.npz")
    code = main(["select", str(tmp_path / "d.npz"), *extra, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert err[0].startswith(f"lpvid select: error: {message}")
    assert not (tmp_path / "o").exists()


def test_cli_select_ctrl_c_exits_130_with_what_is_done(small, tmp_path):
    _, data, val = small
    data.save(tmp_path / "d.npz")
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "lpvid.cli.commands", "select", str(tmp_path / "d.npz")]
    cmd += ["--orders", "1:6", "--degrees", "1", "--out", str(out), "--no-figures"]
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    assert proc.stdout is not None
    for line in proc.stdout:  # wait until the first pair is done
        if "(1/6)" in line:
            break
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err.strip().splitlines()[-1]
    assert (out / "select.md").exists() and "interrupted (Ctrl-C)" in (
        out / "select.md"
    ).read_text()
