"""Multisine design, FRF estimation from periodic records, FrfData.stack."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

import lpvid
from lpvid.testing import direct_frf


def lti(rng: np.random.Generator, n: int, r: int, l: int, Ts: float = 1e-3, radius: float = 0.8):
    """A random stable discrete-time LTI model (spectral radius `radius`)."""
    a = rng.normal(size=(n, n))
    a *= radius / np.max(np.abs(np.linalg.eigvals(a)))
    return lpvid.LpvModel(
        a, rng.normal(size=(n, r)), rng.normal(size=(l, n)), rng.normal(size=(l, r)), Ts=Ts
    )


def run(model: lpvid.LpvModel, u: np.ndarray) -> np.ndarray:
    """Simulate from rest with scipy (independent of lpvid's simulator)."""
    a, b, c, d = model.at(0.0)
    _, y, _ = signal.dlsim((a, b, c, d, model.Ts), u)
    return y


# ---------------------------------------------------------------- multisine
@pytest.mark.parametrize("grid", ["full", "odd"])
def test_multisine_rms_lines_and_flat_spectrum(grid):
    ms = lpvid.multisine(1000, 2000.0, (30.0, 410.0), rms=0.7, grid=grid, seed=3)
    assert ms.signal.shape == (1000,) and ms.period == 1000 and ms.n_inputs == 1
    assert np.sqrt(np.mean(ms.signal**2)) == pytest.approx(0.7, rel=1e-13)
    # lines: every (odd) bin of the band, nothing else
    want = np.arange(15, 206) if grid == "full" else np.arange(15, 206, 2)
    assert np.array_equal(ms.lines, want)
    assert np.allclose(ms.freqs_hz, want * 2.0)
    spectrum = np.abs(np.fft.rfft(ms.signal))
    others = np.setdiff1d(np.arange(spectrum.size), ms.lines)
    assert np.max(spectrum[others]) < 1e-12 * np.max(spectrum)
    assert np.ptp(spectrum[ms.lines]) < 1e-10 * np.max(spectrum)


def test_multisine_band_edges_and_nyquist():
    # band up to fs/2: the Nyquist bin and DC are never excited
    ms = lpvid.multisine(64, 64.0, (0.0, 32.0))
    assert np.array_equal(ms.lines, np.arange(1, 32))
    ms = lpvid.multisine(65, 65.0, (0.0, 32.5))
    assert np.array_equal(ms.lines, np.arange(1, 33))


def test_multisine_is_deterministic_given_a_seed():
    a = lpvid.multisine(256, 100.0, (1.0, 40.0), seed=11)
    b = lpvid.multisine(256, 100.0, (1.0, 40.0), seed=11)
    c = lpvid.multisine(256, 100.0, (1.0, 40.0), seed=12)
    assert np.array_equal(a.signal, b.signal)
    assert not np.allclose(a.signal, c.signal)
    g = lpvid.multisine(256, 100.0, (1.0, 40.0), seed=np.random.default_rng(11))
    assert np.array_equal(g.signal, a.signal)


@pytest.mark.parametrize("r", [2, 3])
def test_orthogonal_multisines(r):
    ms = lpvid.multisine(512, 1000.0, (10.0, 200.0), rms=2.0, n_inputs=r, seed=5)
    assert ms.signal.shape == (r, 512, r) and ms.n_inputs == r
    assert np.allclose(np.sqrt(np.mean(ms.signal**2, axis=1)), 2.0, rtol=1e-13)
    X = np.fft.rfft(ms.signal, axis=1)[:, ms.lines, :]  # (e, F, i)
    U = X.transpose(1, 0, 2)  # per line: experiments x inputs
    sv = np.linalg.svd(U, compute_uv=False)
    assert np.max(sv[:, 0] / sv[:, -1]) < 1 + 1e-10  # perfectly conditioned
    others = np.setdiff1d(np.arange(257), ms.lines)
    assert np.max(np.abs(np.fft.rfft(ms.signal, axis=1)[:, others])) < 1e-12 * np.abs(X).max()
    if r == 2:  # a Hadamard pattern: experiment 1 flips the sign of input 1
        assert np.allclose(ms.signal[1, :, 0], ms.signal[0, :, 0])
        assert np.allclose(ms.signal[1, :, 1], -ms.signal[0, :, 1])


def test_multisine_periodic():
    ms = lpvid.multisine(100, 10.0, (1.0, 3.0), seed=1)
    assert (
        repr(ms) == "Multisine(period=100, fs=10 Hz, 21 lines 1-3 Hz, full grid, rms=1, 1 input(s))"
    )
    assert np.array_equal(ms.periodic(3), np.concatenate([ms.signal] * 3))
    mimo = lpvid.multisine(100, 10.0, (1.0, 3.0), seed=1, n_inputs=2)
    assert mimo.periodic(2).shape == (2, 200, 2)


def test_multisine_bad_input():
    with pytest.raises(ValueError, match=r"^band_hz: \(10, 60\) Hz lies outside the Nyquist range"):
        lpvid.multisine(100, 100.0, (10.0, 60.0))
    with pytest.raises(ValueError, match=r"^band_hz: \(-1, 10\) Hz lies outside the Nyquist range"):
        lpvid.multisine(100, 100.0, (-1.0, 10.0))
    with pytest.raises(ValueError, match=r"^band_hz: expected f_lo <= f_hi"):
        lpvid.multisine(100, 100.0, (20.0, 10.0))
    with pytest.raises(ValueError, match=r"^band_hz: .* holds no excitable line of the full grid"):
        lpvid.multisine(100, 100.0, (10.2, 10.8))
    with pytest.raises(ValueError, match=r"^band_hz: .* holds no excitable line of the odd grid"):
        lpvid.multisine(100, 100.0, (2.0, 2.0), grid="odd")
    with pytest.raises(ValueError, match=r"^band_hz: contains NaN or Inf"):
        lpvid.multisine(100, 100.0, (1.0, np.nan))
    with pytest.raises(ValueError, match=r"^grid: expected one of \('full', 'odd'\)"):
        lpvid.multisine(100, 100.0, (1.0, 10.0), grid="random")
    with pytest.raises(ValueError, match=r"^rms: expected a finite number > 0"):
        lpvid.multisine(100, 100.0, (1.0, 10.0), rms=0.0)
    with pytest.raises(ValueError, match=r"^period: expected an integer >= 3"):
        lpvid.multisine(2, 100.0, (1.0, 10.0))
    with pytest.raises(
        TypeError,
        match=r"^seed: expected None, an int \(or sequence of ints\) or a numpy Generator",
    ):
        lpvid.multisine(100, 100.0, (1.0, 10.0), seed="abc")


# -------------------------------------------------------------- estimate_frf
def test_siso_noise_free_frf_is_exact(rng):
    model = lti(rng, 4, 1, 1)
    period, fs, P, M = 256, 1000.0, 3, 3
    ms = [lpvid.multisine(period, fs, (5.0, 300.0), seed=m) for m in range(M)]
    u = np.stack([m.periodic(P) for m in ms])
    y = np.stack([run(model, uu)[:, 0] for uu in u])
    data = lpvid.estimate_frf(u, y, period, fs, ms[0].freqs_hz, p=0.25, drop_periods=1)
    true = direct_frf(model, ms[0].freqs_hz, np.array([0.0]))
    assert data.G.shape == (1, ms[0].lines.size, 1, 1)
    assert data.Ts == 1e-3 and np.array_equal(data.p, [0.25])
    assert np.max(np.abs(data.G - true) / np.abs(true)) < 1e-10
    assert np.all(data.sigma < 1e-10 * np.abs(true))
    # the transient of the first period biases the estimate when kept
    kept = lpvid.estimate_frf(u, y, period, fs, ms[0].freqs_hz, p=0.25)
    assert np.max(np.abs(kept.G - true) / np.abs(true)) > 1e-6


def test_mimo_noise_free_frf_is_exact_with_orthogonal_multisines(rng):
    period, fs, P, M = 200, 500.0, 2, 2
    model = lti(rng, 5, 2, 3, Ts=1 / fs)
    records = []
    for m in range(M):
        ms = lpvid.multisine(period, fs, (2.0, 240.0), n_inputs=2, seed=m)
        records.extend(ms.periodic(P))  # experiments 0, 1 of realisation m
    u = np.stack(records)  # (M * r, T, r)
    y = np.stack([run(model, uu) for uu in u])
    data = lpvid.estimate_frf(u, y, period, fs, ms.freqs_hz, p=[1.0, 2.0], drop_periods=1)
    true = direct_frf(model, ms.freqs_hz, np.array([0.0]))
    assert data.G.shape == (1, ms.lines.size, 3, 2)
    assert data.p.shape == (1, 2)
    assert np.max(np.abs(data.G - true)) < 1e-10 * np.max(np.abs(true))


def steady_state(G: np.ndarray, lines: np.ndarray, u_period: np.ndarray) -> np.ndarray:
    """One period of the periodic steady-state output of a SISO G at the lines."""
    U = np.fft.rfft(u_period, axis=-1)
    Y = np.zeros_like(U)
    Y[..., lines] = G * U[..., lines]
    return np.fft.irfft(Y, n=u_period.shape[-1], axis=-1)


def test_sigma_matches_the_true_standard_deviation(rng):
    # Output noise of known level: over many seeds, the estimated variance
    # of the mean FRF agrees with the analytic one and with the actual
    # scatter of the estimates around the truth.
    model = lti(rng, 3, 1, 1)
    period, fs, P, M, s, runs = 128, 1000.0, 2, 4, 0.05, 300
    ms0 = lpvid.multisine(period, fs, (20.0, 300.0), seed=0)
    lines = ms0.lines
    G_true = direct_frf(model, ms0.freqs_hz, np.array([0.0]))[0, :, 0, 0]
    U_mag = np.abs(np.fft.rfft(ms0.signal)[lines])  # flat: the same for every seed
    var_true = period * s**2 / (P * M * U_mag**2)
    ratio_sigma, ratio_error = [], []
    for k in range(runs):
        sig = np.stack(
            [lpvid.multisine(period, fs, (20.0, 300.0), seed=(k, m)).signal for m in range(M)]
        )
        u = np.tile(sig, (1, P))
        y = np.tile(steady_state(G_true, lines, sig), (1, P)) + s * rng.normal(size=u.shape)
        data = lpvid.estimate_frf(u, y, period, fs, ms0.freqs_hz, p=0.0)
        ratio_sigma.append(data.sigma[0, :, 0, 0] ** 2 / var_true)
        ratio_error.append(np.abs(data.G[0, :, 0, 0] - G_true) ** 2 / var_true)
    # each ratio has mean 1; 300 runs x F lines make the means precise to ~1 %
    n_samples = runs * lines.size
    assert n_samples > 5000
    assert np.mean(ratio_sigma) == pytest.approx(1.0, abs=0.05)
    assert np.mean(ratio_error) == pytest.approx(1.0, abs=0.06)


def test_single_realisation_sigma_from_the_period_scatter(rng):
    model = lti(rng, 3, 1, 1)
    period, fs, P, s, runs = 128, 1000.0, 5, 0.05, 300
    ms = lpvid.multisine(period, fs, (20.0, 300.0), seed=1)
    G_true = direct_frf(model, ms.freqs_hz, np.array([0.0]))[0, :, 0, 0]
    U_mag = np.abs(np.fft.rfft(ms.signal)[ms.lines])
    var_true = period * s**2 / (P * U_mag**2)
    y0 = np.tile(steady_state(G_true, ms.lines, ms.signal), P)
    ratios, errors = [], []
    for _ in range(runs):
        y = y0 + s * rng.normal(size=y0.shape)
        data = lpvid.estimate_frf(ms.periodic(P)[None], y[None], period, fs, ms.freqs_hz, p=0.0)
        ratios.append(data.sigma[0, :, 0, 0] ** 2 / var_true)
        errors.append(np.abs(data.G[0, :, 0, 0] - G_true) ** 2 / var_true)
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.04)
    assert np.mean(errors) == pytest.approx(1.0, abs=0.06)


def test_mimo_sigma_matches_the_scatter_of_the_estimates(rng):
    period, fs, P, M, s, runs = 64, 100.0, 2, 3, 0.02, 200
    model = lti(rng, 3, 2, 2, Ts=1 / fs)
    ms0 = lpvid.multisine(period, fs, (5.0, 40.0), n_inputs=2)
    G_true = direct_frf(model, ms0.freqs_hz, np.array([0.0]))[0]  # (F, l, r)
    sig2, err2 = [], []
    for k in range(runs):
        u, y = [], []
        for m in range(M):
            ms = lpvid.multisine(period, fs, (5.0, 40.0), n_inputs=2, seed=(k, m))
            for e in range(2):
                U = np.fft.rfft(ms.signal[e], axis=0)  # (bins, r)
                Y = np.zeros((U.shape[0], 2), complex)
                Y[ms.lines] = np.einsum("fji,fi->fj", G_true, U[ms.lines])
                ye = np.fft.irfft(Y, n=period, axis=0)
                u.append(np.tile(ms.signal[e], (P, 1)))
                y.append(np.tile(ye, (P, 1)) + s * rng.normal(size=(P * period, 2)))
        data = lpvid.estimate_frf(np.stack(u), np.stack(y), period, fs, ms0.freqs_hz, p=0.0)
        sig2.append(data.sigma[0] ** 2)
        err2.append(np.abs(data.G[0] - G_true) ** 2)
    # mean estimated variance against mean squared error, per entry (l, r)
    ratio = np.mean(sig2, axis=(0, 1)) / np.mean(err2, axis=(0, 1))
    assert np.allclose(ratio, 1.0, atol=0.1)


def test_total_variance_contains_nonlinear_distortion(rng):
    # A noise-free static nonlinearity after an LTI system: periods repeat
    # exactly (no noise variance) but the realisations disagree.
    model = lti(rng, 3, 1, 1)
    period, fs, P, M = 256, 1000.0, 3, 6
    ms = [lpvid.multisine(period, fs, (5.0, 300.0), seed=m) for m in range(M)]
    u = np.stack([m.periodic(P) for m in ms])
    lin = np.stack([run(model, uu)[:, 0] for uu in u])
    y = lin + 0.2 * lin**3
    total = lpvid.estimate_frf(u, y, period, fs, ms[0].freqs_hz, p=0.0, drop_periods=1)
    noise = lpvid.estimate_frf(u[:1], y[:1], period, fs, ms[0].freqs_hz, p=0.0, drop_periods=1)
    scale = np.abs(total.G).max()
    assert np.median(total.sigma) > 1e-3 * scale
    assert np.max(noise.sigma) < 1e-9 * scale


def test_estimate_frf_bad_input(rng):
    ms = lpvid.multisine(100, 100.0, (1.0, 30.0), seed=0)
    u = np.stack([ms.periodic(3)] * 2)
    y = u.copy()
    f = ms.freqs_hz
    cases = [
        (dict(u=u[:, :-1], y=y[:, :-1]), "u", "whole number of periods"),
        (dict(y=y[:1]), "y", "expected R=2 records"),
        (dict(y=y[:, :200]), "y", "records"),
        (dict(drop_periods=3), "drop_periods", "leaves no period"),
        (dict(freqs_hz=f + 0.3), "freqs_hz", "grid"),
        (dict(freqs_hz=[50.0]), "freqs_hz", "Nyquist"),
        (dict(freqs_hz=[0.0, 1.0]), "freqs_hz", "Nyquist"),
        (dict(freqs_hz=[31.0]), "u", "no energy"),
        (dict(y=np.where(y > 1, np.nan, y)), "y", "NaN"),
        (dict(u=u[:1], y=y[:1], drop_periods=2), "u", "variance"),
        (dict(u=u[0], y=y[0]), "u", "single record"),
        (dict(u=np.stack([ms.periodic(3)[:, None]] * 3), y=y[:1]), "y", "records"),
    ]
    for change, name, text in cases:
        kwargs = dict(u=u, y=y, period=100, fs=100.0, freqs_hz=f, p=0.0) | change
        with pytest.raises(ValueError, match=f"^{name}:.*{text}"):
            lpvid.estimate_frf(**kwargs)
    # MIMO: records must make whole realisations, inputs must be independent
    mimo = lpvid.multisine(100, 100.0, (1.0, 30.0), n_inputs=2, seed=0).periodic(2)
    with pytest.raises(
        ValueError, match=r"^u: R=1 records do not make whole realisations of r=2 experiments"
    ):
        lpvid.estimate_frf(mimo[:1], mimo[:1], 100, 100.0, f, p=0.0)
    same = np.stack([mimo[0], mimo[0]])
    with pytest.raises(
        ValueError,
        match=r"^u: the inputs of the 2 experiments of realisation 0 are .* linearly dependent",
    ):
        lpvid.estimate_frf(same, same, 100, 100.0, f, p=0.0)


# ---------------------------------------------------------------- FrfData.stack
def test_stack_combines_single_point_estimates(rng):
    model = lti(rng, 3, 1, 2)
    period, fs = 128, 1000.0
    ms = [lpvid.multisine(period, fs, (10.0, 200.0), seed=m) for m in range(3)]
    u = np.stack([m.periodic(3) for m in ms])
    y = np.stack([run(model, uu) for uu in u])
    parts = [
        lpvid.estimate_frf(u, g * y, period, fs, ms[0].freqs_hz, p=pq, drop_periods=1)
        for pq, g in [(0.0, 1.0), (0.5, 2.0), (1.0, 3.0)]
    ]
    data = lpvid.FrfData.stack(parts)
    assert data.n_points == 3 and np.array_equal(data.p, [0.0, 0.5, 1.0])
    for q, part in enumerate(parts):
        assert np.array_equal(data.G[q], part.G[0])
        assert np.array_equal(data.sigma[q], part.sigma[0])
    assert np.allclose(data.G[2], 3 * data.G[0], rtol=1e-12)
    assert data.Ts == parts[0].Ts
    again = lpvid.FrfData.stack([data.subset(q) for q in range(3)])
    assert np.array_equal(again.G, data.G) and np.array_equal(again.p, data.p)
    two = lpvid.FrfData.stack([data.subset([0, 1]), data.subset(2)])
    assert np.array_equal(two.G, data.G)


def test_stack_bad_input():
    G = np.ones((1, 2, 1, 1))
    a = lpvid.FrfData([0.0], [1.0, 2.0], G, Ts=0.1)
    with pytest.raises(ValueError, match=r"^parts: needs at least one FrfData"):
        lpvid.FrfData.stack([])
    with pytest.raises(
        TypeError, match=r"^parts: expected a sequence of FrfData, got a single FrfData"
    ):
        lpvid.FrfData.stack(a)
    with pytest.raises(TypeError, match=r"^parts\[1\]: expected FrfData, got ndarray"):
        lpvid.FrfData.stack([a, G])
    for other, text in [
        (lpvid.FrfData([1.0], [1.0, 2.0], G, Ts=0.2), "Ts"),
        (lpvid.FrfData([1.0], [1.0, 2.0], G), "Ts"),
        (lpvid.FrfData([1.0], [1.0, 3.0], G, Ts=0.1), "frequency lines"),
        (lpvid.FrfData([1.0], [1.0], G[:, :1], Ts=0.1), "frequency lines"),
        (lpvid.FrfData([1.0], [1.0, 2.0], np.ones((1, 2, 2, 1)), Ts=0.1), "outputs"),
        (lpvid.FrfData([[1.0, 2.0]], [1.0, 2.0], G, Ts=0.1), "scheduling parameters"),
    ]:
        with pytest.raises(ValueError, match=rf"^parts\[1\]:.*{text}"):
            lpvid.FrfData.stack([a, other])
    with pytest.raises(ValueError, match=r"^parts: p: scheduling values must be distinct"):
        lpvid.FrfData.stack([a, a])
    # (N,) and (N, 1) scheduling values mix
    b = lpvid.FrfData([[1.0]], [1.0, 2.0], G, Ts=0.1)
    assert lpvid.FrfData.stack([a, b]).p.shape == (2, 1)
