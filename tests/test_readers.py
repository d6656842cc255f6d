"""Measured FRFs from files: UFF 58, CSV and MATLAB structs load to the arrays they hold."""

import json
import textwrap

import numpy as np
import pytest
from frf_files import (
    coherence_for,
    write_csv,
    write_manifest,
    write_mat,
    write_uff,
)

import lpvid
from lpvid.cli import main
from lpvid.readers import sigma_from_coherence
from lpvid.testing import noisy_data, random_lpv

AVERAGES = 20
OUTPUTS_BY_NODE = """
[[outputs]]
name = "head"
node = 3
dir = "+X"
unit = "m/s^2"
[[outputs]]
name = "carriage"
node = 2
[[inputs]]
name = "torque"
node = 1
dir = "+Z"
unit = "N m"
"""


@pytest.fixture(scope="module")
def gantry():
    return lpvid.datasets.gantry()


@pytest.fixture(scope="module")
def gantry_start(gantry):
    """One start for every fit below: SMILE on local models of the arrays."""
    local = lpvid.identify_lti(gantry.identification, gantry.order)
    return lpvid.smile(local, basis=gantry.basis)


def gantry_uff(folder, data, records="labels", averages=AVERAGES):
    """The gantry at its 5 points as UFF: even points ASCII, odd points binary.

    The coherence records are those of AVERAGES averages; the manifest says ``averages``.
    """
    coh = coherence_for(data.G, data.sigma, AVERAGES)
    points = []
    for q, p in enumerate(data.p):
        name = f"tube{int(p)}.uff"
        write_uff(folder / name, data.freqs_hz, data.G[q], binary=q % 2 == 1, coherence=coh[q])
        points.append((p, name))
    header = f'Ts = {data.Ts!r}\nrecords = "{records}"\n'
    header += f'sigma = {{ from = "coherence", averages = {averages} }}\n'
    header += 'parameters = ["tube side [mm]"]\n' + OUTPUTS_BY_NODE
    return write_manifest(folder / f"gantry-{records}.toml", header, points)


def test_uff_ascii_and_binary_load_the_gantry_data(tmp_path, gantry):
    data = gantry.identification
    loaded = lpvid.FrfData.from_files(gantry_uff(tmp_path, data))
    np.testing.assert_array_equal(loaded.p, data.p)
    assert loaded.Ts == data.Ts
    # The abscissa is written as E13.5: 6 significant digits, 5e-6 relative at most.
    np.testing.assert_allclose(loaded.freqs_hz, data.freqs_hz, rtol=5e-6, atol=0)
    assert not np.array_equal(loaded.freqs_hz, data.freqs_hz)  # the rounding is real
    # ASCII ordinates are E20.11 (12 significant digits); binary ones IEEE doubles.
    ascii_, binary = [0, 2, 4], [1, 3]
    np.testing.assert_allclose(loaded.G[ascii_], data.G[ascii_], rtol=5e-12, atol=0)
    np.testing.assert_array_equal(loaded.G[binary], data.G[binary])
    # sigma from coherence written to 12 digits: 1 - gamma^2 ~ 1e-5 here loses 5 of them.
    np.testing.assert_allclose(loaded.sigma, data.sigma, rtol=1e-6)
    np.testing.assert_allclose(loaded.sigma[binary], data.sigma[binary], rtol=1e-12)
    prov = loaded.provenance
    assert prov["outputs"] == ["head", "carriage"] and prov["inputs"] == ["torque"]
    assert prov["parameters"] == ["tube side [mm]"]
    assert prov["points"][1]["records"] == ["tube30.uff, record 1", "tube30.uff, record 3"]
    assert prov["points"][0]["sigma"] == f"coherence, {AVERAGES} averages"
    # The manifest's count of averages is used: the same coherence records said to come
    # from four times as many averages give half the sigma (Bendat-Piersol, 1 / sqrt(n)).
    more = lpvid.FrfData.from_files(gantry_uff(tmp_path, data, averages=4 * AVERAGES))
    np.testing.assert_allclose(more.sigma, loaded.sigma / 2, rtol=1e-12)
    assert more.provenance["points"][3]["sigma"] == f"coherence, {4 * AVERAGES} averages"


def test_the_docstring_manifest_loads(tmp_path, gantry):
    """The example of FrfData.from_files (docs/data.md's: test_mixed_files.py)."""
    doc = lpvid.FrfData.from_files.__doc__
    block = doc.split("Example::\n", 1)[1].split("\n\n        Top-level keys")[0]
    text = textwrap.dedent(block)
    data = gantry.identification.subset([0, 1])
    coh = coherence_for(data.G, data.sigma, AVERAGES)
    for q, p in enumerate(data.p):
        write_uff(tmp_path / f"tube{int(p)}.uff", data.freqs_hz, data.G[q], coherence=coh[q])
    (tmp_path / "gantry.toml").write_text(text)
    loaded = lpvid.FrfData.from_files(tmp_path / "gantry.toml")
    np.testing.assert_allclose(loaded.G, data.G, rtol=5e-12)
    np.testing.assert_allclose(loaded.sigma[0], data.sigma[0], rtol=1e-6)
    assert loaded.Ts == data.Ts and loaded.provenance["outputs"] == ["head", "carriage"]


def test_uff_records_by_order_or_by_labels_agree(tmp_path, gantry):
    data = gantry.identification
    by_labels = lpvid.FrfData.from_files(gantry_uff(tmp_path, data, "labels"))
    by_order = lpvid.FrfData.from_files(gantry_uff(tmp_path, data, "output-major"))
    np.testing.assert_array_equal(by_order.G, by_labels.G)
    np.testing.assert_array_equal(by_order.sigma, by_labels.sigma)


def test_uff_data_give_the_same_model(tmp_path, gantry, gantry_start):
    data = gantry.identification
    loaded = lpvid.FrfData.from_files(gantry_uff(tmp_path, data))
    fits = []
    for d in (data, loaded):
        nls = lpvid.fit_nls(gantry_start, d)
        fits.append((nls, lpvid.fit_l21(nls.model, d, 1e-2)))
    (nls_a, reg_a), (nls_f, reg_f) = fits
    assert reg_f.nonzero_groups == reg_a.nonzero_groups
    # Only the frequency lines' 6-digit rounding (<= 5e-6 relative) moves V_NLS:
    # about 1e-4 relative on this lightly damped system.
    assert nls_f.vnls == pytest.approx(nls_a.vnls, rel=1e-3)
    assert reg_f.vnls == pytest.approx(reg_a.vnls, rel=1e-3)
    rounded = lpvid.FrfData(data.p, loaded.freqs_hz, data.G, data.sigma, data.Ts)
    assert lpvid.vnls(reg_f.model, loaded) == pytest.approx(
        lpvid.vnls(reg_f.model, rounded), rel=1e-7
    )


@pytest.mark.parametrize("layout", ["re/im", "mag/deg", "db/rad"])
def test_csv_loads_the_gantry_data(tmp_path, gantry, gantry_start, layout):
    data = gantry.identification
    points = []
    for q, p in enumerate(data.p):
        name = f"tube{int(p)}.csv"
        write_csv(
            tmp_path / name,
            data.freqs_hz,
            data.G[q],
            layout=layout,
            variance=data.sigma[q] ** 2,
            unit="m/s^2/N m",
        )
        points.append((p, name))
    header = f'Ts = {data.Ts!r}\nrecords = "labels"\nsigma = {{ from = "variance" }}\n'
    header += 'outputs = [{ name = "head", unit = "m/s^2" }, "carriage"]\n'
    header += 'inputs = [{ name = "torque", unit = "N m" }]\n'
    loaded = lpvid.FrfData.from_files(write_manifest(tmp_path / "m.toml", header, points))
    np.testing.assert_array_equal(loaded.freqs_hz, data.freqs_hz)
    if layout == "re/im":  # repr() round-trips every double
        np.testing.assert_array_equal(loaded.G, data.G)
    else:
        np.testing.assert_allclose(loaded.G, data.G, rtol=1e-13)
    np.testing.assert_allclose(loaded.sigma, data.sigma, rtol=1e-15)
    assert lpvid.vnls(gantry_start, loaded) == pytest.approx(
        lpvid.vnls(gantry_start, data), rel=1e-12
    )


def test_mat_structs_load_the_gantry_data(tmp_path, gantry, gantry_start):
    data = gantry.identification
    points = []
    for q, p in enumerate(data.p):
        name = f"tube{int(p)}.mat"
        # idfrd saved with struct(sys): frequencies in rad/s (MATLAB's default unit),
        # CovarianceData; every other point by hand as top-level variables in Hz.
        by_hand = q % 2 == 1
        write_mat(
            tmp_path / name,
            data.freqs_hz,
            data.G[q],
            Ts=data.Ts,
            variance=data.sigma[q] ** 2,
            unit="Hz" if by_hand else None,
            struct=not by_hand,
        )
        points.append((p, name))
    header = 'sigma = { from = "variance" }\noutputs = ["head", "carriage"]\ninputs = ["torque"]\n'
    loaded = lpvid.FrfData.from_files(write_manifest(tmp_path / "m.toml", header, points))
    assert loaded.Ts == data.Ts  # from the files: the manifest gives none
    np.testing.assert_allclose(loaded.freqs_hz, data.freqs_hz, rtol=1e-15)
    np.testing.assert_array_equal(loaded.G, data.G)
    np.testing.assert_allclose(loaded.sigma, data.sigma, rtol=1e-15)
    assert lpvid.vnls(gantry_start, loaded) == pytest.approx(
        lpvid.vnls(gantry_start, data), rel=1e-12
    )


def siso_points(folder, freqs_per_point, G_per_point):
    points = []
    for q, (f, g) in enumerate(zip(freqs_per_point, G_per_point, strict=True)):
        name = f"p{q}.csv"
        write_csv(folder / name, f, g[:, None, None], coherence=None)
        points.append((float(q), name))
    header = (
        'outputs = ["head"]\ninputs = ["torque"]\nsigma = { from = "relative", level = 0.02 }\n'
    )
    return write_manifest(folder / "m.toml", header, points)


def test_frequency_lines_that_differ_name_the_point(tmp_path, rng):
    f = np.linspace(10.0, 40.0, 31)
    G = [rng.normal(size=31) + 1j * rng.normal(size=31) for _ in range(3)]
    moved = f.copy()
    moved[7] += 0.5
    manifest = siso_points(tmp_path, [f, f, moved], G)
    with pytest.raises(ValueError, match=r"points\[2\] \(p=2.0\): p2.csv.*line 8: 17.5 Hz"):
        lpvid.FrfData.from_files(manifest)


def test_common_lines_keep_the_shared_lines(tmp_path, rng):
    f = np.linspace(10.0, 40.0, 31)
    G = [rng.normal(size=31) + 1j * rng.normal(size=31) for _ in range(3)]
    keep1 = np.ones(31, bool)
    keep1[[0, 5]] = False  # point 1 lacks two lines
    keep2 = np.ones(31, bool)
    keep2[[5, 30]] = False  # point 2 lacks two, one of them the same
    manifest = siso_points(tmp_path, [f, f[keep1], f[keep2]], [G[0], G[1][keep1], G[2][keep2]])
    pattern = r"kept the 28 .*dropped 3 at points\[0\].*, 1 at points\[1\].*, 1 at points\[2\]"
    with pytest.warns(UserWarning, match=pattern):
        loaded = lpvid.FrfData.from_files(manifest, lines="common")
    shared = keep1 & keep2
    np.testing.assert_array_equal(loaded.freqs_hz, f[shared])
    for q in range(3):
        np.testing.assert_array_equal(loaded.G[q, :, 0, 0], G[q][shared])
    np.testing.assert_allclose(loaded.sigma, 0.02 * np.abs(loaded.G), rtol=1e-15)
    assert loaded.provenance["lines"] == {"mode": "common", "kept": 28, "dropped": [3, 1, 1]}
    with pytest.raises(
        ValueError, match=r"^lines: expected one of \('same', 'common'\), got 'all'"
    ):
        lpvid.FrfData.from_files(manifest, lines="all")


def test_several_scheduling_parameters_and_input_major_order(tmp_path, rng):
    f = np.linspace(1.0, 5.0, 5)
    G = rng.normal(size=(2, 5, 2, 2)) + 1j * rng.normal(size=(2, 5, 2, 2))
    points = []
    for q in range(2):
        name = f"p{q}.uff"
        # An analyzer that exports reference by reference: input-major order.
        write_uff(tmp_path / name, f, np.transpose(G[q], (0, 2, 1)))
        points.append(([0.1 * q, 20.0 + q], name))
    header = 'records = "input-major"\nparameters = ["x", "temperature"]\n'
    header += 'outputs = ["y1", "y2"]\ninputs = ["u1", "u2"]\n'
    loaded = lpvid.FrfData.from_files(write_manifest(tmp_path / "m.toml", header, points))
    np.testing.assert_array_equal(loaded.p, [[0.0, 20.0], [0.1, 21.0]])
    np.testing.assert_allclose(loaded.G, G, rtol=5e-12)
    np.testing.assert_array_equal(loaded.sigma, 1.0)


def test_sigma_from_coherence_matches_a_simulated_experiment():
    """H1 estimates from n averaged noisy records of a known SISO system.

    Each record is a block of white-noise input u through a known FIR
    system (circular, i.e. in steady state over the block) plus white output
    noise. Over many repeated experiments, the spread of the H1 estimate
    about the true FRF is its true standard deviation; the coherence-based
    sigma of each experiment must match it within 25 %. (The expected ratio
    is sqrt((n - 1) / n) = 0.97 for Gaussian input: E[1 / sum |U|^2] is
    1 / ((n - 1) S_uu), the residual variance estimate has n - 1 degrees of
    freedom. Half the variance, Bendat and Piersol's for the magnitude alone,
    would give 0.69 and fail.)
    """
    rng = np.random.default_rng(7)
    runs, n, block = 400, 16, 128
    t = np.arange(block)
    h = np.exp(-t / 12.0) * np.cos(0.6 * t)  # a damped resonance
    H = np.fft.fft(h)
    u = rng.normal(size=(runs, n, block))
    y = np.fft.ifft(H * np.fft.fft(u, axis=-1), axis=-1).real
    y += 0.8 * rng.normal(size=y.shape)
    lines = slice(1, block // 2)
    U = np.fft.fft(u, axis=-1)[..., lines]
    Y = np.fft.fft(y, axis=-1)[..., lines]
    Suu = np.mean(np.abs(U) ** 2, axis=1)
    Syy = np.mean(np.abs(Y) ** 2, axis=1)
    Syu = np.mean(Y * np.conj(U), axis=1)
    H1 = Syu / Suu
    coherence = np.abs(Syu) ** 2 / (Suu * Syy)
    assert coherence.min() < 0.5 < 0.99 < coherence.max()  # low and high SNR lines
    true_std = np.sqrt(np.mean(np.abs(H1 - H[lines]) ** 2, axis=0))
    sigma = sigma_from_coherence(H1, coherence, n)
    ratio = np.sqrt(np.mean(sigma**2, axis=0)) / true_std
    assert np.all(np.abs(ratio - 1) < 0.25), ratio
    assert np.median(ratio) == pytest.approx(np.sqrt((n - 1) / n), abs=0.05)


def test_sigma_helpers_values_and_where_they_fail():
    from lpvid.readers import sigma_from_variance, sigma_relative

    G = np.array([[3.0 + 4.0j, 1.0], [2.0, 0.5j]])
    np.testing.assert_allclose(sigma_relative(G, 0.1), [[0.5, 0.1], [0.2, 0.05]], rtol=1e-15)
    np.testing.assert_allclose(sigma_from_variance([4.0, 0.25]), [2.0, 0.5], rtol=1e-15)
    # Arrays name the index, records the line (1-based); the default names of each helper.
    with pytest.raises(
        ValueError, match=r"^G: the FRF is 0j at index \(1, 0\), which gives sigma 0 "
    ):
        sigma_relative(np.array([[1.0, 2.0], [0.0j, 1.0]]), 0.1)
    with pytest.raises(ValueError, match=r"^rec: the FRF is 0.0 at line 2, which gives sigma 0 "):
        sigma_relative([1.0, 0.0], 0.1, where="rec")
    with pytest.raises(ValueError, match=r"^variance: variance must be > 0; found 0 at line 2$"):
        sigma_from_variance([1.0, 0.0])
    with pytest.raises(ValueError, match=r"^v: variance must be > 0; found -1 at index \(0, 1\)$"):
        sigma_from_variance([[1.0, -1.0]], where="v")
    with pytest.raises(
        ValueError, match=r"^coherence: coherence must lie in \(0, 1\); found 1 at index \(0, 1\) "
    ):
        sigma_from_coherence([[1.0, 2.0]], [[0.5, 1.0]], 10)


def test_sigma_from_coherence_checks_its_arguments():
    with pytest.raises(ValueError, match=r"coherence must lie in \(0, 1\); found 1 at line 2"):
        sigma_from_coherence([1.0, 2.0], [0.5, 1.0], 10)
    with pytest.raises(ValueError, match=r"^averages: expected an integer >= 2"):
        sigma_from_coherence([1.0], [0.5], 1)
    with pytest.raises(
        ValueError, match=r"^coherence: the FRF is 0\.0 at line 1, which gives sigma 0"
    ):
        sigma_from_coherence([0.0], [0.5], 10)


@pytest.fixture
def small_manifest(tmp_path):
    """A small SISO LPV system measured at 4 points, as CSV files and a manifest."""
    rng = np.random.default_rng(3)
    model = random_lpv(rng, n=2, r=1, l=1, nb=1, Ts=None)
    data = noisy_data(model, np.linspace(0.0, 1.0, 4), np.linspace(0.05, 2.0, 25), rng)
    points = []
    for q, p in enumerate(data.p):
        write_csv(tmp_path / f"p{q}.csv", data.freqs_hz, data.G[q], variance=data.sigma[q] ** 2)
        points.append((p, f"p{q}.csv"))
    header = 'outputs = ["head"]\ninputs = ["torque"]\nsigma = { from = "variance" }\n'
    header += 'parameters = ["load [kg]"]\n'
    return write_manifest(tmp_path / "exp.toml", header, points), data


def test_fit_command_on_a_manifest(tmp_path, small_manifest, capsys):
    manifest, data = small_manifest
    out = tmp_path / "fit"
    args = ["fit", str(manifest), "--order", "2", "--basis", "poly:1", "--gamma", "0.01"]
    code = main([*args, "--out", str(out), "--no-figures", "--quiet"])
    assert code == 0
    assert "exp.toml" in (out / "report.md").read_text()
    model = lpvid.LpvModel.load(out / "model.json")
    numbers = json.loads((out / "result.json").read_text())
    assert numbers["vnls"] == pytest.approx(lpvid.vnls(model, data), rel=1e-12)
    # The data are noisy measurements of an order-2 system: the model fits to the noise.
    assert lpvid.vnls(model, data) < 2 * data.n_residuals
    capsys.readouterr()


def test_fit_command_names_a_bad_file_of_a_manifest(tmp_path, small_manifest, capsys):
    manifest, _ = small_manifest
    (manifest.parent / "p2.csv").unlink()
    code = main(["fit", str(manifest), "--order", "2", "--out", str(tmp_path / "o"), "--quiet"])
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "exp.toml: points[2].file: no such file: p2.csv" in err


@pytest.mark.parametrize(
    "unit, per_hz", [("Hz", 1.0), ("kHz", 1e-3), ("rad/s", 2 * np.pi), ("rpm", 60.0)]
)
def test_frequency_units_become_hz(tmp_path, unit, per_hz):
    f = np.linspace(10.0, 40.0, 7)
    G = (1.0 + np.arange(7.0))[:, None, None] * (1 + 1j)
    write_csv(tmp_path / "a.csv", f * per_hz, G, freq_unit=unit)
    manifest = write_manifest(
        tmp_path / "m.toml", 'outputs = ["y"]\ninputs = ["u"]', [(0, "a.csv")]
    )
    np.testing.assert_allclose(lpvid.FrfData.from_files(manifest).freqs_hz, f, rtol=1e-14)
