"""identify(), reports, model files and the command line, end to end."""

import importlib.util
import json
import re
import warnings

import numpy as np
import pytest
from scipy.io import loadmat

import lpvid
from lpvid.cli import main
from lpvid.testing import noisy_data, random_lpv


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo as a user runs it: `lpvid demo --out DIR`."""
    out = tmp_path_factory.mktemp("demo")
    # Warnings are checked in test_unconverged_fits_are_said, not here.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        code = main(["demo", "--out", str(out), "--quiet"])
    return code, out


@pytest.fixture(scope="module")
def gantry_run():
    ds = lpvid.datasets.gantry(n_lines=120)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = lpvid.identify(ds.identification, ds.order, ds.basis, validation=ds.validation)
    return ds, result, caught


@pytest.fixture(scope="module")
def gantry_result(gantry_run):
    return gantry_run[:2]


def test_unconverged_fits_are_said(gantry_run):
    """Every fit on the path that stopped at its limit is warned about and marked in the table."""
    _, result, caught = gantry_run
    said = [str(w.message) for w in caught if issubclass(w.category, lpvid.ConvergenceWarning)]
    others = [w for w in caught if not issubclass(w.category, lpvid.ConvergenceWarning)]
    assert not others, [str(w.message) for w in others]
    rows = result.table().splitlines()[1:]
    for k, e in enumerate(result.entries):
        marked = "(iteration limit)" in rows[k]
        warned = (
            any(f"gamma = {e.gamma:g} stopped" in m for m in said)
            if k
            else any("unregularised" in m for m in said)
        )
        assert marked == (not e.converged)
        if warned:
            assert not e.converged


def test_demo_writes_its_files(demo):
    code, out = demo
    assert code == 0
    for name in ("report.md", "model.json", "model.mat", "result.json"):
        assert (out / name).is_file(), name
    numbers = json.loads((out / "result.json").read_text())
    model = lpvid.LpvModel.load(out / "model.json")
    # model.mat holds the same numbers in its MATLAB arrays (read here without
    # lpvid), and lpvid reads them back from there
    raw = loadmat(out / "model.mat")
    for name, arr in model.matrices().items():
        np.testing.assert_array_equal(np.moveaxis(raw[name], -1, 0), arr)
    np.testing.assert_array_equal(raw["basis_domain"], model.basis.domain)
    assert raw["Ts"].item() == model.Ts
    from_mat = lpvid.LpvModel.load(out / "model.mat")
    for name, arr in model.matrices().items():
        np.testing.assert_array_equal(getattr(from_mat, name), arr)
    assert from_mat.basis == model.basis and from_mat.p_range == model.p_range
    ds = lpvid.datasets.gantry()
    # the numbers in the report are those of the model written
    assert numbers["vnls"] == pytest.approx(lpvid.vnls(model, ds.identification), rel=1e-12)
    assert numbers["validation_vnls"] == pytest.approx(lpvid.vnls(model, ds.validation), rel=1e-12)
    assert numbers["groups_chosen"] == model.group_norms().count()
    report = (out / "report.md").read_text()
    assert f"{numbers['vnls']:.6g}" in report
    assert f"{numbers['groups_chosen']} groups kept" in report
    if importlib.util.find_spec("matplotlib") is not None:
        # drawn by the demo's worker processes: every figure the report shows is there
        shown = re.findall(r"\]\((figures/[^)]+\.png)\)", report)
        assert len(shown) == 8, shown
        for rel in shown:
            assert (out / rel).read_bytes().startswith(b"\x89PNG"), rel


def test_demo_model_is_accurate_and_simpler(demo):
    _, out = demo
    n = json.loads((out / "result.json").read_text())
    # at the noise floor: three standard deviations, sqrt(M) each (seen: 17 below)
    assert abs(n["vnls"] - n["noise_floor"]) <= 3 * np.sqrt(n["noise_floor"])
    # the tutorial (docs/tutorial.md): the chosen model validates better than the unregularised one
    assert n["validation_vnls"] <= n["validation_vnls_unregularised"]
    assert n["groups_chosen"] < n["groups_smile"]


def test_identify_result_is_consistent(gantry_result):
    ds, res = gantry_result
    # refit=True (the default): the chosen model refitted on its support
    assert res.refit is not None and res.model is res.refit.model is res.final.model
    assert res.final.n_groups == res.entry.n_groups
    assert res.entries[0].gamma == 0 and len(res.entries) == 1 + len(res.path)
    for e in res.entries:
        assert e.vnls == pytest.approx(lpvid.vnls(e.model, ds.identification), rel=1e-12)
        assert e.validation_vnls == pytest.approx(lpvid.vnls(e.model, ds.validation), rel=1e-12)
        assert e.n_groups == e.model.group_norms().count()
    # the choice: the simplest within the tolerance of the best validation V_NLS
    vals = np.array([e.validation_vnls for e in res.entries])
    ok = [e for e in res.entries if e.validation_vnls <= 1.1 * vals.min()]
    assert res.entry.n_groups == min(e.n_groups for e in ok)
    assert "validation" in res.reason
    # the start: among starts stable between the points, one that validated
    # within 2 % of the best
    names = [c.name for c in res.candidates]
    assert any(n.startswith("smile:") for n in names)
    assert any(n.startswith("continuation+smile:") for n in names)
    assert any(n.startswith("global:") for n in names)
    chosen = next(c for c in res.candidates if c.name == res.start)
    assert chosen.stable
    assert chosen.validation_vnls <= 1.02 * min(
        c.validation_vnls for c in res.candidates if c.stable
    )
    assert res.nls.model is chosen.model
    assert set(res.timings) >= {"local_s", "smile_s", "path_s", "total_s"}
    assert str(res.entry.n_groups) in res.summary() and "->" in res.table()


def test_identify_without_validation_takes_the_knee(gantry_result):
    ds, _ = gantry_result
    with warnings.catch_warnings():  # test_unconverged_fits_are_said checks them
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        res = lpvid.identify(ds.identification, ds.order, ds.basis, gammas=[0.1, 0.01, 0.001])
    assert "knee" in res.reason or "noise" in res.reason
    assert res.validation is None and res.entry.validation_vnls is None
    # the chosen model fits the identification data at the noise floor
    assert res.entry.vnls <= 1.1 * res.entry.noise_floor


def test_identify_bad_input(gantry_result):
    ds, _ = gantry_result
    data = ds.identification
    with pytest.raises(TypeError, match=r"^basis: expected an lpvid basis"):
        lpvid.identify(data, 6, "poly")
    with pytest.raises(ValueError, match=r"^order: expected an integer >= 1"):
        lpvid.identify(data, 0, ds.basis)
    with pytest.raises(
        ValueError, match=r"^basis: 5 basis functions need at least 6 scheduling points"
    ):
        lpvid.identify(data, 6, lpvid.Polynomial(5, domain=(24, 48)))
    with pytest.raises(ValueError, match=r"^gammas: needs at least one value, all > 0"):
        lpvid.identify(data, 6, ds.basis, gammas=[0.1, -1])
    with pytest.raises(
        ValueError,
        match=r"^validation: has 1 outputs x 1 inputs, .*; the data have 2 outputs",
    ):
        stage = lpvid.datasets.positioning_stage()
        lpvid.identify(data, 6, ds.basis, validation=stage.validation)


def test_identify_continuous_time_with_d_fixed():
    """A continuous-time system with A affine in p and D = 0, identified with D fixed."""
    rng = np.random.default_rng(12345)
    m = random_lpv(rng, n=2, r=1, l=2, nb=1, Ts=None)
    B, C = m.B.copy(), m.C.copy()
    B[1:], C[1:] = 0.0, 0.0
    true = lpvid.LpvModel(m.A, B, C, np.zeros_like(m.D), m.basis, Ts=None)
    f = np.logspace(-2, 1, 30)
    data = noisy_data(true, np.linspace(0, 1, 4), f, rng, rel_noise=0.01)
    val = noisy_data(true, np.array([0.2, 0.6, 0.9]), f, rng, rel_noise=0.01)
    res = lpvid.identify(
        data,
        2,
        lpvid.Polynomial(2, domain=(0, 1)),
        validation=val,
        fixed={"D": True},
        gammas=[0.1, 0.01],
    )
    assert res.model.Ts is None
    assert all(not np.any(e.model.D) for e in res.entries)  # D stays exactly zero
    e, m_id, m_val = res.entry, data.n_residuals, val.n_residuals
    # at the noise floor on the points and between them: 3 sigma of the floor
    assert e.vnls <= m_id + 3 * np.sqrt(m_id)
    assert e.validation_vnls <= m_val + 3 * np.sqrt(m_val)
    # The model depends on p; D has no group; simpler than the unregularised model
    assert e.n_groups >= 1 and e.nonzero_groups["D"] == []
    assert e.n_groups < res.entries[0].n_groups
    # Which of A(1) and C(1) carries the dependency, the data (4 points, 1 %
    # noise) cannot tell on this system: over 12 noise seeds either is kept
    # about as often, at the same V_NLS. What they do fix: the frozen FRFs
    # between the points, here within 0.3 % of the true system's (RMS over a
    # grid of 41 values of p; the noise is 1 % per line).
    grid = np.linspace(0, 1, 41)
    G_true = true.frf(f, grid)
    err = np.abs(res.model.frf(f, grid) - G_true)
    assert np.sqrt(np.mean(err**2) / np.mean(np.abs(G_true) ** 2)) < 3e-3


def test_identify_with_two_scheduling_parameters():
    """A depends on p1 and p2 (affine), B, C, D constant; a 3 x 3 grid of points."""
    rng = np.random.default_rng(2)
    basis = lpvid.Polynomial(1, domain=[(0, 1), (0, 1)])
    A = 0.1 * rng.normal(size=(3, 2, 2))
    A[0] += 0.5 * np.eye(2)
    B, C, D = np.zeros((3, 2, 1)), np.zeros((3, 1, 2)), np.zeros((3, 1, 1))
    B[0], C[0], D[0] = rng.normal(size=(2, 1)), rng.normal(size=(1, 2)), 0.3
    true = lpvid.LpvModel(A, B, C, D, basis, Ts=0.01)
    grid = np.array([(a, b) for a in (0.0, 0.5, 1.0) for b in (0.0, 0.5, 1.0)])
    f = np.linspace(1, 45, 25)
    data = noisy_data(true, grid, f, rng, rel_noise=0.01)
    val = noisy_data(true, np.array([[0.25, 0.75], [0.7, 0.3]]), f, rng, rel_noise=0.01)
    res = lpvid.identify(data, 2, basis, validation=val, gammas=[0.1, 0.01])
    assert res.model.basis.n_params == 2 and res.model.basis == basis
    e, m_id, m_val = res.entry, data.n_residuals, val.n_residuals
    assert e.vnls <= m_id + 3 * np.sqrt(m_id)
    assert e.validation_vnls <= m_val + 3 * np.sqrt(m_val)
    assert e.nonzero_groups == {"A": [1, 2], "B": [], "C": [], "D": []}
    # the model between the grid points is the true one, to the noise level
    between = np.array([[0.4, 0.6], [0.9, 0.1]])
    err = res.model.frf(f, between) - true.frf(f, between)
    assert np.max(np.abs(err)) <= 0.05 * np.max(np.abs(true.frf(f, between)))


def test_report_without_figures(tmp_path, gantry_result):
    _, res = gantry_result
    path = lpvid.report.markdown.write_report(res, tmp_path, figures=False)
    text = path.read_text()
    assert "## Figures" not in text
    assert res.table() in text
    assert str(res.initial.group_norms()) in text


@pytest.fixture(scope="module")
def small_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("data")
    ds = lpvid.datasets.gantry(n_lines=80)
    ds.identification.save(folder / "id.npz")
    ds.validation.save(folder / "val.mat")
    return folder


def test_fit_command_end_to_end(small_files, capsys):
    out = small_files / "fit"
    args = [str(small_files / "id.npz"), "--order", "6", "--basis", "poly:4"]
    args += ["--validation", str(small_files / "val.mat"), "--gamma", "0.1", "0.01"]
    code = main(["fit", *args, "--out", str(out), "--no-figures"])
    assert code == 0
    printed = capsys.readouterr().out
    numbers = json.loads((out / "result.json").read_text())
    assert len(numbers["path"]) == 3
    model = lpvid.LpvModel.load(out / "model.json")
    data = lpvid.FrfData.load(small_files / "id.npz")
    assert numbers["vnls"] == pytest.approx(lpvid.vnls(model, data), rel=1e-12)
    assert f"{numbers['vnls']:.6g}" in printed
    assert model.basis == lpvid.Polynomial(4, domain=data.p_range)
