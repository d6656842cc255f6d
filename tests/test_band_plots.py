"""Uncertainty figures and the report's section on trust: the drawn numbers are the covariance's."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from systems import first_order_frf

import lpvid
from lpvid import plots
from lpvid.testing import noisy_data, random_lpv
from lpvid.trust.uncertainty import band_radius


def _db(x):
    return 20 * np.log10(np.abs(x))


@pytest.fixture
def fitted(rng):
    true = random_lpv(rng, n=2, r=1, l=2, nb=1, Ts=0.01)
    f = np.linspace(1.0, 45.0, 15)
    data = noisy_data(true, np.array([0.0, 0.3, 0.7, 1.0]), f, rng)
    fit = lpvid.fit_nls(true, data)
    return data, lpvid.covariance(fit.model, data, warn=False)


def test_frf_band_draws_the_band_around_the_model(fitted, plt):
    data, cov = fitted
    fig = plots.frf_band(cov, data, title="id", outputs=["a [m]", "b [m]"], p_label="p [-]")
    assert len(fig.axes) == 2 and fig.get_suptitle() == "id"
    Gm = cov.model.frf(data.freqs_hz, data.p)
    rad = band_radius(0.95) * cov.frf_std(data.freqs_hz, data.p)
    i, q = 1, 2
    ax = fig.axes[i]
    band = [c for c in ax.collections if c.get_gid() == f"band/{q}"]
    assert len(band) == 1
    verts = band[0].get_paths()[0].vertices
    upper = _db(np.abs(Gm[q, :, i, 0]) + rad[q, :, i, 0])
    lower = _db(np.maximum(np.abs(Gm[q, :, i, 0]) - rad[q, :, i, 0], 1e-3 * np.abs(Gm[q, :, i, 0])))
    for k, f in enumerate(data.freqs_hz):
        ys = verts[np.isclose(verts[:, 0], f), 1]
        assert np.min(np.abs(ys - upper[k])) < 1e-9 and np.min(np.abs(ys - lower[k])) < 1e-9
    lines = {ln.get_gid(): ln for ln in ax.get_lines()}
    np.testing.assert_allclose(lines[f"model/{q}"].get_ydata(), _db(Gm[q, :, i, 0]))
    np.testing.assert_allclose(lines[f"measured/{q}"].get_ydata(), _db(data.G[q, :, i, 0]))
    with pytest.raises(TypeError, match=r"^cov: expected an lpvid\.Covariance, got LpvModel"):
        plots.frf_band(cov.model, data)


def test_frf_std_map_is_the_relative_band(fitted, plt):
    data, cov = fitted
    f = np.linspace(2.0, 40.0, 30)
    p = np.linspace(0.0, 1.0, 21)
    fig = plots.frf_std_map(cov, f, p, output=1, p_marks=data.p, p_label="p [-]")
    mesh = [c for c in fig.axes[0].collections if c.get_gid() == "relative-band"]
    assert len(mesh) == 1
    want = _db(
        band_radius(0.95) * cov.frf_std(f, p)[:, :, 1, 0] / np.abs(cov.model.frf(f, p)[:, :, 1, 0])
    )
    np.testing.assert_allclose(np.asarray(mesh[0].get_array()).reshape(want.shape), want)
    # The band is narrowest at the identification points.
    at = cov.frf_std(f, data.p[1:3])
    between = cov.frf_std(f, [0.5])
    assert np.median(between) > np.median(at)
    with pytest.raises(ValueError, match=r"^output: expected 0 <= output < 2, got 2"):
        plots.frf_std_map(cov, f, p, output=2)
    with pytest.raises(ValueError, match=r"^p: expected at least two strictly increasing values"):
        plots.frf_std_map(cov, f, p[::-1])


def test_report_has_the_trust_section_and_figures(tmp_path, monkeypatch, plt):
    # Rasterising eight figures takes most of a second each; the figures are built
    # (their numbers are checked above), the files written by a stand-in.
    def save(fig, path):
        path.write_bytes(b"png")
        return path

    monkeypatch.setattr(plots, "save", save)
    data, val = first_order_frf()
    basis = lpvid.Polynomial(2, domain=(0.0, 1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        res = lpvid.identify(data, 1, basis, validation=val, fixed={"D": True}, gammas=[0.1])
    path = lpvid.report.markdown.write_report(res, tmp_path)
    text = path.read_text()
    assert "## Between the points: uncertainty and stability" in text
    assert "parameter covariance" in text and "frozen models stable" in text
    # A small continuous-time model: the largest certified rate is in the stability lines.
    assert "- bounded rate: " in text
    for name in ("band_identification.png", "band_validation.png", "band_map.png"):
        assert (tmp_path / "figures" / name).is_file(), name
        assert f"figures/{name}" in text
    numbers = json.loads((tmp_path / "result.json").read_text())
    model = lpvid.LpvModel.load(tmp_path / "model.json")
    assert numbers["vnls"] == pytest.approx(lpvid.vnls(model, data), rel=1e-12)
    assert numbers["stable"] is True and numbers["covariance_rank"] == res.covariance.rank


def test_the_trust_page_example_runs(monkeypatch, capsys):
    text = (Path(__file__).resolve().parents[1] / "docs" / "trust.md").read_text()
    code = text.split("```python", 1)[1].split("```", 1)[0]
    scope: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        exec(compile(code, "docs/trust.md", "exec"), scope)
    assert scope["std"].shape == scope["result"].model.frf(scope["f"], scope["p"]).shape
    np.testing.assert_allclose(scope["band"], band_radius(0.95) * scope["std"])
    rep = scope["rep"]
    assert rep.stable and rep.quadratic is True  # as docs/trust.md says of the stage
    assert scope["safe"].stability.stable
    assert "frozen models stable over p in" in capsys.readouterr().out
