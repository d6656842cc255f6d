"""Memory: a fit too large is refused before any work, a failed allocation is a MemoryError.

The issue's case: ``fit_nls`` with n = 60, 2 outputs x 2 inputs, 4 basis
functions, under a 3 GB address-space limit, raised a PanicException (a Rust
panic crossing into Python), aborted the process, or hung. The tests with a
real limit run in a child process (``resource.setrlimit(RLIMIT_AS)``), never
in this one.
"""

import inspect
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import lpvid
import lpvid.fit.memory
from lpvid import _core

RLIMIT = pytest.importorskip("resource").RLIMIT_AS
LINUX = sys.platform.startswith("linux")


def large(n=60, l=2, r=2, nb=4, points=5, lines=400):
    """The issue's model size (n = 60, 2x2, Nb = 4) on FRF data at few lines: a quick build."""
    rng = np.random.default_rng(0)
    basis = lpvid.Polynomial(nb, domain=(-1.0, 1.0))
    A = np.zeros((nb + 1, n, n))
    A[0] = np.diag(np.linspace(0.2, 0.9, n))
    B = 0.1 * rng.standard_normal((nb + 1, n, r))
    C = 0.1 * rng.standard_normal((nb + 1, l, n))
    model = lpvid.LpvModel(A, B, C, np.zeros((nb + 1, l, r)), basis, Ts=1e-3)
    G = rng.standard_normal((points, lines, l, r)) + 1j * rng.standard_normal((points, lines, l, r))
    data = lpvid.FrfData(np.linspace(-1, 1, points), np.linspace(1, 400, lines), G, Ts=1e-3)
    return model, data


def child(code: str, limit_mb: float | None = None) -> dict:
    """Run ``code`` in a child process (its address space limited to what it uses + ``limit_mb``).

    The code sets ``out`` (JSON-ready); the child prints it.
    """
    prologue = textwrap.dedent(
        f"""
        import json, resource, re
        import numpy as np, lpvid
        def in_use():
            status = open("/proc/self/status").read()
            return int(re.search(r"VmSize:\\s+(\\d+)", status).group(1)) * 1024
        limit_mb = {limit_mb!r}
        if limit_mb is not None:
            # Start the core's threads first, and have each allocate: their
            # stacks and glibc's per-thread arenas (64 MB of address space
            # each, mapped at a thread's first allocation, which may come
            # after the call that started it) count.
            import lpvid.testing
            lpvid.available_memory()
            _rng = np.random.default_rng(0)
            _m = lpvid.testing.random_lpv(_rng, n=4, r=2, l=2, nb=1)
            _d = lpvid.testing.noisy_data(_m, [0.0, 0.5, 1.0], np.linspace(1, 40, 64), _rng)
            lpvid.fit_nls(_m, _d, max_iter=1, warn=False)
            hard = resource.getrlimit(resource.RLIMIT_AS)[1]
            resource.setrlimit(resource.RLIMIT_AS, (in_use() + int(limit_mb * 1e6), hard))
        """
    )
    helpers = textwrap.dedent(inspect.getsource(large))
    script = prologue + helpers + textwrap.dedent(code) + "\nprint(json.dumps(out))\n"
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    assert "PanicException" not in proc.stderr and "panicked" not in proc.stderr, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not LINUX, reason="the large-block allocator is the Linux build's")
def test_the_extension_keeps_freed_large_blocks_for_reuse_within_its_limit():
    # 980 free parameters: J^T J alone is 8 * 980^2 = 7.7 MB, above the 4 MB
    # from which the extension maps blocks whole (lpvid::memory::blocks).
    model, data = large(n=12, points=3, lines=40)
    fit = lpvid.fit_nls(model, data, max_iter=2, warn=False)
    assert np.isfinite(fit.vnls)
    kept, limit = _core._kept_blocks()
    assert 0 < kept <= limit == 1 << 30  # as lpvid.fit.memory.RESIDENT says


def test_the_issue_case_is_refused_before_any_work(monkeypatch):
    model, data = large()
    called = []
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (3 * 10**9, "a 3 GB test"))
    monkeypatch.setattr(_core, "fit_nls", lambda *a, **k: called.append(1))
    with pytest.raises(MemoryError) as info:
        lpvid.fit_nls(model, data, callback=lambda row: called.append(row))
    assert not called  # refused before the core started
    message = str(info.value)
    need = lpvid.fit_memory(model, data)
    # J^T J alone of its 19220 free parameters is 2.96 GB.
    assert need > 2 * 8 * 19220**2
    assert f"{need} bytes" in message and lpvid.fit.memory.human(need) in message
    assert "3.00 GB" in message and "a 3 GB test" in message
    assert "19220 free parameters" in message and "N = 5 points, F = 400 lines" in message


def test_every_entry_point_checks_before_any_work(monkeypatch):
    model, data = large(n=40, nb=2, lines=100)
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (10**8, "a 100 MB test"))
    for name in ("fit_nls", "fit_l21", "l21_path"):
        monkeypatch.setattr(_core, name, lambda *a, **k: pytest.fail("the core was called"))
    td = lpvid.TimeData(np.zeros((300, 2)), np.zeros(300), np.zeros((300, 2)), dt=1e-3)
    runs = {
        "fit_nls": lambda: lpvid.fit_nls(model, data),
        "fit_l21": lambda: lpvid.fit_l21(model, data, 0.01),
        "l21_path": lambda: lpvid.l21_path(model, data, [0.1, 0.01]),
        "fit_time": lambda: lpvid.fit_time(model, td),
        "identify": lambda: lpvid.identify(data, 40, model.basis),
        "covariance": lambda: lpvid.covariance(model, data),
    }
    for name, run in runs.items():
        with pytest.raises(MemoryError, match=rf"^{name} needs about .* a 100 MB test"):
            run()
    # select: no pair of the grid fits.
    with pytest.raises(MemoryError, match="select: every run needs more memory"):
        lpvid.select(data, [30, 40], [1, 2])


def test_select_runs_fewer_pairs_at_once_when_together_they_would_not_fit(monkeypatch):
    needs = [400, 300, 200, 100]
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (650, "a test"))
    # The two largest together (700) do not fit; one at a time then.
    assert lpvid.fit.memory.runs_at_once(needs, 2, "select") == 1
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (700, "a test"))
    assert lpvid.fit.memory.runs_at_once(needs, 2, "select") == 2
    # A run too large alone does not count (identify refuses it by itself).
    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (350, "a test"))
    assert lpvid.fit.memory.runs_at_once(needs, 2, "select") == 1
    with pytest.raises(MemoryError, match="smallest about"):
        lpvid.fit.memory.runs_at_once([400, 500], 2, "select")


def test_the_estimate_grows_with_the_sizes_as_the_formula_says():
    def total(**kw):
        sizes = dict(n=20, l=2, r=2, nb=2, frf=(5, 200))
        sizes.update(kw)
        n, l, r, nb = sizes.pop("n"), sizes.pop("l"), sizes.pop("r"), sizes.pop("nb")
        return lpvid.fit.memory.sizes_memory(n, l, r, nb, **sizes)

    base = total()
    P = 3 * 22 * 22
    # Levenberg-Marquardt holds J^T J, factors a copy, and evaluates with it
    # held: at least three P x P matrices.
    assert base["held"] >= 8 * P * P and base["step"] >= 8 * P * P
    assert base["total"] >= base["held"] + base["evaluation"]
    assert base["evaluation"] >= 8 * P * P
    # Fixing parameters shrinks it; more lines or points never do.
    free = np.ones(P, dtype=bool)
    free[: P // 2] = False
    assert total(free=free)["total"] < base["total"]
    assert total(frf=(5, 4000))["total"] > base["total"]
    assert total(frf=(50, 200))["total"] > base["total"]
    # The cone programs of the l2,1 fit need more than a Levenberg-Marquardt step.
    assert total(method="l21")["total"] > base["total"]
    with pytest.raises(ValueError, match="method"):
        total(method="newton")


@pytest.mark.skipif(not LINUX, reason="reads /proc")
def test_available_memory_reads_the_address_space_limit():
    out = child(
        """
        room, source = lpvid.available_memory()
        out = {"room": room, "source": source}
        """,
        limit_mb=300,
    )
    # What is left under the limit: 300 MB less what the child mapped since.
    assert 200e6 < out["room"] <= 300e6, out
    assert "RLIMIT_AS" in out["source"]


@pytest.mark.skipif(not LINUX, reason="RLIMIT_AS and /proc")
def test_the_issue_case_under_an_address_space_limit_raises_memory_error():
    """As the issue ran it, in a child under a real limit: refused, not a panic or a hang."""
    out = child(
        """
        model, data = large(lines=4000)
        try:
            lpvid.fit_nls(model, data)
            out = {"raised": None}
        except MemoryError as exc:
            out = {"raised": str(exc)}
        """,
        limit_mb=1000,
    )
    assert out["raised"] is not None and "estimated from its sizes" in out["raised"]
    assert "RLIMIT_AS" in out["raised"]


@pytest.mark.skipif(not LINUX, reason="RLIMIT_AS and /proc")
def test_an_allocation_that_fails_in_the_core_raises_memory_error_with_its_size():
    """The check switched off: the core's own allocation fails under the limit, and says so."""
    out = child(
        """
        import lpvid.fit.memory
        lpvid.fit.memory.available_memory = lambda: (None, "unknown")
        model, data = large(n=40, l=1, r=1, nb=1, points=2, lines=64)
        try:
            lpvid.fit_nls(model, data, max_iter=2)
            out = {"raised": None}
        except MemoryError as exc:
            out = {"raised": str(exc)}
        # The process goes on: a small fit still runs.
        small, data = large(n=2, l=1, r=1, nb=1, points=3, lines=20)
        out["after"] = lpvid.fit_nls(small, data, max_iter=2, warn=False).vnls
        """,
        limit_mb=60,
    )
    assert out["raised"] is not None, "the fit ran under a 60 MB limit"
    assert out["raised"].startswith("out of memory: could not allocate"), out
    assert np.isfinite(out["after"])


@pytest.mark.parametrize("after", [0, 3, 11, 40])
def test_a_forced_allocation_failure_is_a_memory_error_and_the_next_fit_runs(after):
    ds = lpvid.datasets.gantry(n_lines=40)
    start = lpvid.smile(lpvid.identify_lti(ds.identification, ds.order), basis=ds.basis)
    _core._fail_allocation_after(after)
    try:
        with pytest.raises(MemoryError, match=r"^out of memory: could not allocate \d+"):
            lpvid.fit_l21(start, ds.identification, 1e-3, max_outer=2)
    finally:
        _core._fail_allocation_after(None)
    fit = lpvid.fit_l21(start, ds.identification, 1e-3, max_outer=2, warn=False)
    assert np.isfinite(fit.vnls)


def test_a_forced_failure_inside_identify_stops_it_with_memory_error():
    ds = lpvid.datasets.gantry(n_lines=40)
    # Well past the local models and SMILE, inside the race's fits.
    _core._fail_allocation_after(200)
    try:
        with pytest.raises(MemoryError, match="out of memory"):
            lpvid.identify(ds.identification, ds.order, ds.basis, routes=["plain"])
    finally:
        _core._fail_allocation_after(None)


def test_the_command_line_says_memory_error_in_one_line(monkeypatch, tmp_path, capsys):
    from lpvid.cli import main

    monkeypatch.setattr(lpvid.fit.memory, "available_memory", lambda: (10**6, "a 1 MB test"))
    assert main(["demo", "--out", str(tmp_path / "o"), "--no-figures", "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lpvid demo: error: identify needs about")
    assert not (tmp_path / "o").exists()
