"""Figures: the plotted numbers are the model's and the data's, files are whole."""

from __future__ import annotations

import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import lpvid
from lpvid import plots
from lpvid.testing import direct_frf, noisy_data, random_lpv


def _db(x):
    return 20 * np.log10(np.abs(x))


def _line(fig, gid):
    found = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_gid() == gid]
    assert len(found) == 1, f"{gid}: found {len(found)} lines"
    return found[0]


def _data(rng, l=2, r=1, Ts=0.01, n_points=3, nb=2):
    model = random_lpv(rng, n=3, r=r, l=l, nb=nb, Ts=Ts)
    nyquist = 0.5 / Ts if Ts else 50.0
    f = np.linspace(0.02, 0.9, 12) * nyquist
    p = np.linspace(0.0, 1.0, n_points)
    return model, noisy_data(model, p, f, rng)


# ------------------------------------------------------------------------ frf_fit
@pytest.mark.parametrize("l, r, Ts", [(2, 1, 0.01), (1, 1, None), (2, 2, None)])
def test_frf_fit_draws_data_model_error_and_sigma(rng, l, r, Ts, plt):
    model, data = _data(rng, l=l, r=r, Ts=Ts)
    # The truth, independently of the plotting code and of the Rust core.
    Gm = direct_frf(model, data.freqs_hz, data.p[:, 0] if data.p.ndim == 2 else data.p)
    fig = plots.frf_fit(model, data, title="fit")
    assert isinstance(fig, plt.Figure)
    assert len(fig.axes) == l * r
    grid = np.array(fig.axes).reshape(l, r)
    for i in range(l):
        for j in range(r):
            ax = grid[i, j]
            assert len(ax.get_lines()) == 4 * data.n_points
            for q in range(data.n_points):
                got = {ln.get_gid(): ln for ln in ax.get_lines()}
                np.testing.assert_allclose(got[f"model/{q}"].get_xdata(), data.freqs_hz)
                np.testing.assert_allclose(
                    got[f"model/{q}"].get_ydata(), _db(Gm[q, :, i, j]), rtol=1e-9, atol=1e-9
                )
                np.testing.assert_allclose(
                    got[f"measured/{q}"].get_ydata(), _db(data.G[q, :, i, j]), rtol=1e-12
                )
                np.testing.assert_allclose(
                    got[f"error/{q}"].get_ydata(),
                    _db(data.G[q, :, i, j] - Gm[q, :, i, j]),
                    rtol=1e-7,
                    atol=1e-7,
                )
                np.testing.assert_allclose(
                    got[f"sigma/{q}"].get_ydata(), _db(data.sigma[q, :, i, j]), rtol=1e-12
                )
    assert fig.get_suptitle() == "fit"
    assert grid[-1, 0].get_xlabel() == "frequency [Hz]"
    assert "dB" in grid[0, 0].get_ylabel()


def test_frf_fit_chosen_points_kinds_and_names(rng, plt):
    model, data = _data(rng, l=2, r=1, n_points=4)
    fig = plots.frf_fit(
        model,
        data,
        points=[1, 3],
        kinds=("measured", "model"),
        outputs=["head [m/s^2]", "carriage [m/s^2]"],
        inputs=["torque [N m]"],
        p_label="load p [kg]",
    )
    ax = fig.axes[0]
    assert sorted(ln.get_gid() for ln in ax.get_lines()) == sorted(
        ["measured/1", "model/1", "measured/3", "model/3"]
    )
    assert ax.get_title() == "head [m/s²] per torque [N m]"
    # One legend entry per chosen point, labelled with its scheduling value.
    texts = [t.get_text() for lg in fig.legends for t in lg.get_texts()]
    assert "0.3333" in texts and "1" in texts and "0" not in texts
    assert any(lg.get_title().get_text() == "load p [kg]" for lg in fig.legends)


def test_frf_fit_phase_follows_the_model(rng, plt):
    model, data = _data(rng, l=2, r=2, Ts=0.01)
    Gm = direct_frf(model, data.freqs_hz, data.p)
    fig = plots.frf_fit(model, data, phase=True)
    assert len(fig.axes) == 2 * 2 * 2
    q, i, j = 2, 1, 0
    # The phase axes sit under the magnitude axes of output i.
    lines = {ln.get_gid(): ln for ln in fig.axes[(2 * i + 1) * 2 + j].get_lines()}
    model_phase = lines[f"model-phase/{q}"]
    measured_phase = lines[f"measured-phase/{q}"]
    # Unwrapped: the same angles as the FRF modulo whole turns, and continuous.
    turns = (model_phase.get_ydata() - np.degrees(np.angle(Gm[q, :, i, j]))) / 360
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    assert np.all(np.abs(np.diff(model_phase.get_ydata())) < 180)
    turns = (measured_phase.get_ydata() - np.degrees(np.angle(data.G[q, :, i, j]))) / 360
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)


def test_frf_fit_draws_into_a_given_figure(rng, plt):
    model, data = _data(rng, l=2, r=1)
    fig = plt.figure()
    fig.add_subplot(1, 1, 1).plot([0, 1])
    out = plots.frf_fit(model, data, fig=fig)
    assert out is fig
    assert len(fig.axes) == 2


def test_frf_fit_refuses_mismatched_input(rng, plt):
    model, data = _data(rng, l=2, r=1, Ts=0.01)
    other, _ = _data(rng, l=1, r=1, Ts=0.01)
    with pytest.raises(ValueError, match=r"^data: has 2 outputs x 1 inputs, the model 1 x 1"):
        plots.frf_fit(other, data)
    cont = lpvid.LpvModel(model.A, model.B, model.C, model.D, model.basis, Ts=None)
    with pytest.raises(
        ValueError, match=r"^data: sample time Ts=0.01 differs from the model's Ts=None"
    ):
        plots.frf_fit(cont, data)
    with pytest.raises(
        ValueError, match=r"^kinds: expected some of \['measured', 'model', 'error', 'sigma'\]"
    ):
        plots.frf_fit(model, data, kinds=["bode"])
    with pytest.raises(ValueError, match=r"^points: not a valid selection of 3 points"):
        plots.frf_fit(model, data, points=[7])
    with pytest.raises(ValueError, match=r"^outputs: expected 2 names, got 1"):
        plots.frf_fit(model, data, outputs=["one"])
    with pytest.raises(TypeError, match=r"^data: expected an FrfData, got ndarray"):
        plots.frf_fit(model, data.G)
    two = lpvid.FrfData(np.c_[data.p, data.p], data.freqs_hz, data.G, data.sigma, Ts=data.Ts)
    with pytest.raises(ValueError, match=r"^data: has 2 scheduling parameter\(s\)"):
        plots.frf_fit(model, two)


# -------------------------------------------------------------- magnitude surface
@pytest.mark.parametrize("Ts", [None, 0.01])
def test_magnitude_surface_is_the_model_frf_on_the_grid(rng, Ts, plt):
    model = random_lpv(rng, n=3, r=2, l=2, nb=2, Ts=Ts)
    f = np.linspace(0.5, 40.0, 30)
    p = np.linspace(0.0, 1.0, 7)
    G = direct_frf(model, f, p)[:, :, 1, 0]
    fig = plots.magnitude_surface(
        model, f, p, output=1, input=0, p_label="position [m]", p_marks=[0.25, 0.75]
    )
    meshes = {m.get_gid(): m for ax in fig.axes for m in ax.collections if m.get_gid()}
    assert set(meshes) == {"magnitude", "phase"}
    np.testing.assert_allclose(
        np.asarray(meshes["magnitude"].get_array()).reshape(7, 30), _db(G), rtol=1e-9, atol=1e-9
    )
    phase = np.asarray(meshes["phase"].get_array()).reshape(7, 30)
    np.testing.assert_allclose(np.exp(1j * np.radians(phase)), G / np.abs(G), atol=1e-9)
    # Two panels, each with its colour bar.
    assert len(fig.axes) == 4
    assert meshes["magnitude"].axes.get_ylabel() == "position [m]"
    assert fig.get_suptitle() == "output 2 per input 1"
    marks = [ln.get_ydata()[0] for ln in meshes["magnitude"].axes.get_lines()]
    assert marks == [0.25, 0.75]


def test_magnitude_surface_without_phase_and_bad_input(rng, plt):
    model = random_lpv(rng, n=2, r=1, l=1, nb=1, Ts=None)
    f = np.linspace(1.0, 10.0, 5)
    fig = plots.magnitude_surface(model, f, [0.0, 0.5, 1.0], phase=False)
    assert len(fig.axes) == 2
    assert fig.get_suptitle() == ""
    with pytest.raises(ValueError, match=r"^output: expected 0 <= output < 1"):
        plots.magnitude_surface(model, f, [0.0, 1.0], output=1)
    with pytest.raises(ValueError, match=r"^p: expected at least two strictly increasing values"):
        plots.magnitude_surface(model, f, [1.0, 0.0])
    with pytest.raises(
        ValueError, match=r"^freqs_hz: expected at least two strictly increasing values"
    ):
        plots.magnitude_surface(model, [1.0], [0.0, 1.0])


# -------------------------------------------------------------------- group norms
def test_group_norm_bars_are_the_relative_magnitudes(rng, plt):
    m1 = random_lpv(rng, n=3, r=1, l=2, nb=3, Ts=0.01)
    B = np.array(m1.B)
    B[2] = 0.0  # a removed group: drawn at the floor
    m2 = lpvid.LpvModel(m1.A, B, m1.C, m1.D, m1.basis, Ts=0.01)
    fig = plots.group_norms({"SMILE": m1, "chosen": m2}, floor=1e-12)
    assert len(fig.axes) == 4
    for ax, name in zip(fig.axes, "ABCD", strict=True):
        assert ax.get_title() == name
        assert ax.get_yscale() == "log"
        for label, m in (("SMILE", m1), ("chosen", m2)):
            x = m.matrices()[name]
            # Polynomial on domain (0, 1): sup |s^i| = 1 on the range.
            want = [np.linalg.norm(x[i]) / np.linalg.norm(x[0]) for i in (1, 2, 3)]
            bars = [b for b in ax.patches if b.get_gid() == f"{name}/{label}"]
            assert len(bars) == 3
            tops = [b.get_y() + b.get_height() for b in bars]
            np.testing.assert_allclose(tops, np.maximum(want, 1e-12), rtol=1e-12)
        threshold = [ln for ln in ax.get_lines() if np.allclose(ln.get_ydata(), 1e-6)]
        assert len(threshold) == 1
    bars = [b for b in fig.axes[1].patches if b.get_gid() == "B/chosen"]
    assert bars[1].get_height() == 1e-12
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == ["$s$", "$s^{2}$", "$s^{3}$"]


def test_group_norms_of_one_model_and_bad_input(rng, plt):
    m = random_lpv(rng, n=2, r=1, l=1, nb=2)
    fig = plots.group_norms(m)
    assert len(fig.axes[0].patches) == 2
    lti = lpvid.LpvModel(m.A[0], m.B[0], m.C[0], m.D[0], Ts=m.Ts)
    with pytest.raises(
        ValueError, match=r"^models: LTI models \(no basis function\) have no groups to draw"
    ):
        plots.group_norms({"lti": lti})
    other = random_lpv(rng, n=2, r=1, l=1, nb=3)
    with pytest.raises(
        ValueError, match=r"^models: the models differ in their number of basis functions"
    ):
        plots.group_norms({"a": m, "b": other})
    with pytest.raises(ValueError, match=r"^models: expected an LpvModel or a non-empty dict"):
        plots.group_norms({})
    with pytest.raises(ValueError, match=r"^floor: expected a positive number"):
        plots.group_norms(m, floor=0.0)


# ------------------------------------------------------------------ accuracy path
def test_accuracy_path_points_are_vnls_over_the_noise_floor(rng, plt):
    model = random_lpv(rng, n=2, r=1, l=1, nb=2, Ts=None)
    f = np.linspace(0.05, 1.0, 15)
    data = noisy_data(model, np.array([0.0, 0.3, 0.6, 1.0]), f, rng)
    val = noisy_data(model, np.array([0.15, 0.8]), f, rng)
    path = lpvid.l21_path(model, data, [1e-1, 1e-2, 1e-3])
    vval = np.array([lpvid.vnls(r.model, val) for r in path])
    fig = plots.accuracy_path(
        path, validation_vnls=vval, chosen=1, validation_floor=val.n_residuals
    )
    ident = _line(fig, "identification")
    np.testing.assert_array_equal(ident.get_xdata(), path.n_groups)
    want = [lpvid.vnls(r.model, data) / data.n_residuals for r in path]
    np.testing.assert_allclose(ident.get_ydata(), want, rtol=1e-9)
    np.testing.assert_allclose(_line(fig, "validation").get_ydata(), vval / val.n_residuals)
    chosen = _line(fig, "chosen")
    np.testing.assert_array_equal(chosen.get_xdata(), [path.n_groups[1]] * 2)
    np.testing.assert_allclose(
        chosen.get_ydata(), [path.vnls[1] / data.n_residuals, vval[1] / val.n_residuals]
    )
    np.testing.assert_allclose(_line(fig, "identification-gamma").get_xdata(), path.gammas)
    np.testing.assert_array_equal(_line(fig, "groups-gamma").get_ydata(), path.n_groups)
    # every line drawn has a legend entry: the grey groups line too, in its own axes
    legends = {
        text.get_text()
        for axes in fig.axes
        if axes.get_legend() is not None
        for text in axes.get_legend().get_texts()
    }
    assert "groups kept (right axis)" in legends
    with pytest.raises(ValueError, match=r"^validation_floor: needed with validation_vnls"):
        plots.accuracy_path(path, validation_vnls=vval)
    with pytest.raises(ValueError, match=r"^validation_vnls: expected 3 values \(one per entry\)"):
        plots.accuracy_path(path, validation_vnls=vval[:2], validation_floor=10)
    with pytest.raises(ValueError, match=r"^chosen: expected an index into 3 entries"):
        plots.accuracy_path(path, chosen=3)


def test_accuracy_path_of_pipeline_entries_in_path_order(plt):
    # Like IdentifyResult.entries: the unregularised model first, then gamma decreasing.
    rows = [
        SimpleNamespace(
            gamma=g, vnls=v, n_groups=k, noise_floor=100, validation_vnls=w, validation_floor=50
        )
        for g, v, k, w in [
            (0.0, 98.0, 16, 84.0),
            (1e-1, 103.0, 5, 81.0),
            (1e-2, 99.0, 6, 67.0),
            (1e-3, 98.5, 7, 69.0),
        ]
    ]
    fig = plots.accuracy_path(rows, chosen=2, title="path")
    ident = _line(fig, "identification")
    np.testing.assert_array_equal(ident.get_xdata(), [5, 6, 7, 16])
    np.testing.assert_allclose(ident.get_ydata(), [1.03, 0.99, 0.985, 0.98])
    np.testing.assert_allclose(_line(fig, "validation").get_ydata(), [1.62, 1.34, 1.38, 1.68])
    # The gamma panel leaves out gamma = 0 (no place on a log axis).
    np.testing.assert_allclose(_line(fig, "identification-gamma").get_xdata(), [1e-1, 1e-2, 1e-3])
    np.testing.assert_allclose(_line(fig, "chosen-gamma").get_xdata(), [1e-2, 1e-2])
    # Only the left panel when axes are given.
    fig2, ax = plt.subplots()
    assert plots.accuracy_path(rows, ax=ax) is fig2
    assert len(fig2.axes) == 1


# --------------------------------------------------------------------------- save
def test_save_writes_readable_png_and_svg_and_closes(rng, tmp_path, plt):
    model, data = _data(rng, l=1, r=1)
    fig = plots.frf_fit(model, data)
    target = plots.save(fig, tmp_path / "fit.png")
    assert not plt.fignum_exists(fig.number)
    raw = target.read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n"
    image = plt.imread(target)
    assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
    svg = plots.save(plots.group_norms(model), tmp_path / "groups.svg").read_text()
    assert svg.lstrip().startswith("<?xml") and "<svg" in svg
    assert sorted(os.listdir(tmp_path)) == ["fit.png", "groups.svg"]


def test_save_leaves_no_partial_file(rng, tmp_path, monkeypatch, plt):
    model, data = _data(rng, l=1, r=1)
    target = tmp_path / "fit.png"
    target.write_bytes(b"old")
    fig = plots.frf_fit(model, data)

    def broken(fh, **kwargs):
        fh.write(b"\x89PNG partial")
        raise OSError("disk full")

    monkeypatch.setattr(fig, "savefig", broken)
    with pytest.raises(OSError, match=r"^disk full$"):
        plots.save(fig, target)
    assert target.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["fit.png"]
    assert not plt.fignum_exists(fig.number)
    with pytest.raises(
        ValueError, match=r"^path: expected a \.png or \.svg file, got '.*fit\.pdf'"
    ):
        plots.save(plots.frf_fit(model, data), tmp_path / "fit.pdf")


# ------------------------------------------------------------------ missing extra
def test_missing_matplotlib_names_the_extra(rng, monkeypatch):
    model, data = _data(rng, l=1, r=1)
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(
        ImportError,
        match=r'^lpvid\.plots needs matplotlib, an optional extra: pip install "lpvid\[plot\]"$',
    ):
        plots.frf_fit(model, data)
    with pytest.raises(ImportError, match=r"^lpvid\.plots needs matplotlib, .*lpvid\[plot\]"):
        plots.group_norms(model)


def test_import_lpvid_does_not_import_matplotlib():
    code = "import sys, lpvid; lpvid.plots; print('matplotlib' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == "False"
