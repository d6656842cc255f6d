"""Built-in data sets: reproducible, well posed, and true to their physics."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import lpvid
from lpvid.datasets import STAGE
from lpvid.datasets.flexible_gantry import _gantry_mechanics
from lpvid.datasets.positioning import _stage_parameters

MAKERS = {"gantry": lpvid.datasets.gantry, "stage": lpvid.datasets.positioning_stage}


def true_vnls(ds: lpvid.datasets.Dataset, data: lpvid.FrfData, shift: float = 0.0) -> float:
    """V_NLS of the true frozen models (one LTI model per point), optionally at p + shift."""
    total = 0.0
    for q in range(data.n_points):
        model = lpvid.LpvModel(*ds.true_system(data.p[q] + shift), Ts=data.Ts)
        total += lpvid.vnls(model, data.subset([q]))
    return total


# --------------------------------------------------------------- reproducible
@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKERS.keys())
def test_same_seed_same_data_other_seed_other_noise(make):
    a, b, c = make(seed=7), make(seed=7), make(seed=8)
    for part in ("identification", "validation"):
        da, db, dc = (getattr(x, part) for x in (a, b, c))
        np.testing.assert_array_equal(da.G, db.G)
        np.testing.assert_array_equal(da.sigma, db.sigma)
        # the noise changes with the seed, its level does not
        np.testing.assert_array_equal(da.sigma, dc.sigma)
        assert np.all(da.G != dc.G)
    # identification and validation noise are not the same draws
    ga = a.identification.G[0] - a.true_frf(a.identification.p[0])[0]
    va = a.validation.G[0] - a.true_frf(a.validation.p[0])[0]
    assert not np.allclose(ga / a.identification.sigma[0], va / a.validation.sigma[0])


def test_dataset_is_frozen():
    ds = lpvid.datasets.positioning_stage()
    with pytest.raises(dataclasses.FrozenInstanceError):
        ds.order = 3  # type: ignore[misc]
    with pytest.raises(ValueError):
        ds.identification.G[0, 0, 0, 0] = 0.0


# -------------------------------------------------------------- noise floor
@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKERS.keys())
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_true_system_sits_at_the_noise_floor(make, seed):
    ds = make(seed=seed)
    for data in (ds.identification, ds.validation):
        m = data.n_residuals
        # V_NLS at the truth is a sum of m unit exponentials: mean m, sd sqrt(m)
        assert abs(true_vnls(ds, data) - m) < 4 * math.sqrt(m)


@pytest.mark.parametrize(
    ("make", "shift"), [(lpvid.datasets.gantry, 1.0), (lpvid.datasets.positioning_stage, 0.003)]
)
def test_noise_floor_tells_a_neighbouring_system_apart(make, shift):
    # a 1 mm thicker tube, or a beam 3 mm longer, is far outside the noise
    ds = make()
    data = ds.identification
    assert true_vnls(ds, data, shift) > 5 * data.n_residuals


@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKERS.keys())
@pytest.mark.parametrize("snr_db", [20.0, 40.0])
def test_measured_snr_matches_the_request(make, snr_db):
    ds = make(seed=3, snr_db=snr_db)
    assert ds.snr_db == snr_db
    for data in (ds.identification, ds.validation):
        G0 = ds.true_frf(data.p)
        noise = data.G - G0
        F = data.n_lines
        signal_power = np.mean(np.abs(G0) ** 2, axis=1)
        noise_power = np.mean(np.abs(noise) ** 2, axis=1)
        # per entry: the mean of F unit exponentials, sd 1/sqrt(F), i.e. 4.34/sqrt(F) dB
        snr = 10 * np.log10(signal_power / noise_power)
        assert np.all(np.abs(snr - snr_db) < 4 * 4.343 / math.sqrt(F))
        # overall, against the known sigma
        ratio = np.sum(np.abs(noise) ** 2 / data.sigma**2) / data.n_residuals
        assert abs(ratio - 1) < 4 / math.sqrt(data.n_residuals)
        # sigma is constant over the lines and 10^(-snr/20) times the rms of the FRF
        np.testing.assert_allclose(data.sigma, data.sigma[:, :1].repeat(F, axis=1))
        np.testing.assert_allclose(
            data.sigma[:, 0], np.sqrt(signal_power) * 10 ** (-snr_db / 20), rtol=1e-12
        )


# ------------------------------------------------ noise-free FRFs, independently
def gantry_direct(p_mm: float, freqs_hz: np.ndarray) -> np.ndarray:
    """Acceleration FRF of the mass-spring model by a direct solve, (F, 2, 1)."""
    M, K, Cd, b, S = _gantry_mechanics(p_mm)
    out = []
    for f in freqs_hz:
        w = 2 * np.pi * f
        x = np.linalg.solve(K - w**2 * M + 1j * w * Cd, b)
        out.append((-(w**2)) * (S @ x))
    return np.array(out)[:, :, None]


def stage_direct(p: float, freqs_hz: np.ndarray) -> np.ndarray:
    """Tip acceleration / velocity reference from the equations of motion, (F, 1, 1)."""
    q = _stage_parameters(p)
    out = []
    for f in freqs_hz:
        s = 2j * np.pi * f
        ctrl = q["kp"] + q["ki"] / s  # force per unit velocity error
        beam = q["k"] + q["c"] * s
        # unknown positions X1, X2 for a unit velocity reference
        lhs = np.array([[q["m1"] * s**2 + ctrl * s + beam, -beam], [-beam, q["m2"] * s**2 + beam]])
        x1, x2 = np.linalg.solve(lhs, np.array([ctrl, 0.0]))
        out.append(s**2 * x2)
    return np.array(out)[:, None, None]


@pytest.mark.parametrize("snr_db", [None, math.inf])
def test_gantry_continuous_frf_is_the_mass_spring_model(snr_db):
    ds = lpvid.datasets.gantry(snr_db=snr_db, Ts=None, n_lines=120)
    assert ds.Ts is None and ds.snr_db is None
    for data in (ds.identification, ds.validation):
        for q, p in enumerate(data.p):
            np.testing.assert_allclose(
                data.G[q], gantry_direct(p, data.freqs_hz), rtol=1e-9, atol=1e-12
            )


def test_stage_continuous_frf_is_the_equations_of_motion():
    ds = lpvid.datasets.positioning_stage(snr_db=None)
    for data in (ds.identification, ds.validation):
        for q, p in enumerate(data.p):
            np.testing.assert_allclose(data.G[q], stage_direct(p, data.freqs_hz), rtol=1e-9)


@pytest.mark.parametrize(
    ("make", "Ts"), [(lpvid.datasets.gantry, 5e-4), (lpvid.datasets.positioning_stage, 1e-3)]
)
def test_discrete_frf_is_the_zoh_sampled_physics(make, Ts):
    control = pytest.importorskip("control")
    ds = make(snr_db=None, Ts=Ts)
    assert ds.Ts == Ts
    for data in (ds.identification, ds.validation):
        z = np.exp(2j * np.pi * data.freqs_hz * Ts)
        for q, p in enumerate(data.p):
            sysd = control.c2d(control.ss(*ds.continuous_system(p)), Ts, "zoh")
            expected = np.moveaxis(np.asarray(sysd(z)).reshape(data.G.shape[2:] + (-1,)), -1, 0)
            np.testing.assert_allclose(data.G[q], expected, rtol=1e-8, atol=1e-10)
            # and the sampled true model gives the same
            A, B, C, D = ds.true_system(p)
            direct = np.array([C @ np.linalg.solve(zk * np.eye(len(A)) - A, B) + D for zk in z])
            np.testing.assert_allclose(data.G[q], direct, rtol=1e-8, atol=1e-10)


def test_noise_free_sigma_is_the_rms_magnitude():
    ds = lpvid.datasets.gantry(snr_db=None)
    data = ds.identification
    np.testing.assert_allclose(
        data.sigma[:, 0], np.sqrt(np.mean(np.abs(data.G) ** 2, axis=1)), rtol=1e-12
    )


# ----------------------------------------------------------------- physics
def test_gantry_resonances_rise_with_tube_size_inside_the_band():
    ds = lpvid.datasets.gantry()
    grid = np.arange(24.0, 48.5, 1.0)
    freqs = []
    for p in grid:
        A = ds.true_system(p)[0]
        s = np.log(np.linalg.eigvals(A).astype(complex)) / ds.Ts  # back to continuous time
        s = s[s.imag > 0]
        assert s.size == 3
        freqs.append(np.sort(np.abs(s)) / (2 * np.pi))
        np.testing.assert_allclose(freqs[-1], ds.resonances_hz(p), rtol=1e-9)
    freqs = np.array(freqs)
    # a thicker tube stiffens the structure faster than it adds mass
    assert np.all(np.diff(freqs, axis=0) > 0)
    assert freqs.min() > 50 and freqs.max() < 300
    # and visibly: every resonance moves by more than 20 %
    assert np.all(freqs[-1] / freqs[0] > 1.2)


def test_stage_resonance_falls_as_the_beam_gets_longer():
    ds = lpvid.datasets.positioning_stage()
    grid = np.linspace(-0.151, 0.023, 30)
    res = np.array([ds.resonances_hz(p) for p in grid])
    assert res.shape == (30, 1)
    assert np.all(np.diff(res[:, 0]) < 0)
    assert res.min() > 3 and res.max() < 50
    # close to the beam on a fixed base, f = sqrt(3 E I / (L^3 m_tip_eff)) / (2 pi)
    inertia = STAGE["width"] * STAGE["thickness"] ** 3 / 12
    for p, f in zip(grid, res[:, 0], strict=True):
        L = STAGE["length_at_zero"] + p
        m_beam = STAGE["rho"] * STAGE["width"] * STAGE["thickness"] * L
        f_beam = math.sqrt(3 * STAGE["E"] * inertia / L**3 / (STAGE["tip"] + 33 / 140 * m_beam))
        assert abs(f / (f_beam / (2 * np.pi)) - 1) < 0.05


@pytest.mark.parametrize(
    ("make", "grid", "Ts"),
    [
        (lpvid.datasets.gantry, np.linspace(20.0, 52.0, 9), 5e-4),
        (lpvid.datasets.gantry, np.linspace(20.0, 52.0, 9), None),
        (lpvid.datasets.positioning_stage, np.linspace(-0.2, 0.05, 9), None),
        (lpvid.datasets.positioning_stage, np.linspace(-0.2, 0.05, 9), 1e-3),
    ],
)
def test_true_frozen_models_are_stable_and_sized(make, grid, Ts):
    ds = make(Ts=Ts)
    for p in grid:
        A, B, C, D = ds.true_system(p)
        assert A.shape == (ds.order, ds.order)
        assert B.shape == (ds.order, ds.identification.n_inputs)
        assert C.shape == (ds.identification.n_outputs, ds.order)
        lam = np.linalg.eigvals(A)
        if Ts is None:
            assert lam.real.max() < 0
        else:
            assert np.abs(lam).max() < 1
    if ds.fixed == {"D": True}:
        assert np.all(ds.true_system(grid[0])[3] == 0)


def test_gantry_feedthrough_only_on_the_carriage():
    # the motor force acts on the carriages, so only their acceleration jumps
    ds = lpvid.datasets.gantry()
    for p in (24.0, 48.0):
        D = ds.true_system(p)[3]
        assert D[0, 0] == pytest.approx(0.0, abs=1e-12)
        M, _, _, b, _ = _gantry_mechanics(p)
        assert D[1, 0] == pytest.approx(b[0] / M[0, 0], rel=1e-12)


def test_frf_magnitudes_are_reasonable():
    for make in MAKERS.values():
        ds = make()
        data = ds.identification
        mag = np.abs(ds.true_frf(data.p))
        # no entry spans more than 80 dB over the band
        assert np.all(mag.max(axis=1) < 1e4 * mag.min(axis=1))
        # at the default noise level most lines of every entry stand above the noise
        assert np.all(np.mean(mag > data.sigma, axis=1) > 0.7)


# ---------------------------------------------------------------- layout
def test_gantry_layout():
    ds = lpvid.datasets.gantry()
    ident, valid = ds.identification, ds.validation
    np.testing.assert_array_equal(ident.p, [24, 30, 36, 42, 48])
    np.testing.assert_array_equal(valid.p, [27, 33, 39, 45])
    assert np.all((valid.p > ident.p[:-1]) & (valid.p < ident.p[1:]))
    for data in (ident, valid):
        assert (data.n_lines, data.n_outputs, data.n_inputs) == (300, 2, 1)
        assert data.freqs_hz[0] == 50 and data.freqs_hz[-1] == 300
        np.testing.assert_allclose(np.diff(data.freqs_hz), 250 / 299)
        assert data.Ts == 5e-4
    assert ident.n_residuals == 3000
    assert ds.order == 6 and ds.fixed is None and ds.name == "gantry"
    assert ds.basis == lpvid.Polynomial(4, domain=(24.0, 48.0))
    assert ds.basis.domain[0] == ident.p_range
    assert len(ds.outputs) == 2 and len(ds.inputs) == 1
    assert "40 dB" in ds.description and "24" in ds.description
    assert lpvid.datasets.gantry(n_lines=50).identification.n_lines == 50


def test_stage_layout():
    ds = lpvid.datasets.positioning_stage()
    ident, valid = ds.identification, ds.validation
    np.testing.assert_array_equal(ident.p, [-0.151, -0.093, -0.035, 0.023])
    np.testing.assert_array_equal(valid.p, [-0.0639])
    for data in (ident, valid):
        assert (data.n_lines, data.n_outputs, data.n_inputs) == (385, 1, 1)
        assert data.freqs_hz[0] == 3 and data.freqs_hz[-1] == 50
        assert data.Ts is None
    assert ds.order == 4 and ds.fixed == {"D": True}
    assert ds.basis == lpvid.Polynomial(3, domain=(-0.151, 0.023))
    assert ds.basis.domain[0] == ident.p_range
    assert ds.Ts is None


def test_datasets_save_and_load(tmp_path):
    data = lpvid.datasets.positioning_stage().identification
    back = lpvid.FrfData.load(data.save(tmp_path / "stage.npz"))
    np.testing.assert_array_equal(back.G, data.G)
    np.testing.assert_array_equal(back.sigma, data.sigma)


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize("make", MAKERS.values(), ids=MAKERS.keys())
def test_bad_arguments_name_themselves(make):
    with pytest.raises(ValueError, match=r"^seed: expected an integer >= 0"):
        make(seed=-1)
    with pytest.raises(TypeError, match=r"^seed: expected an integer, got float"):
        make(seed=1.5)
    with pytest.raises(ValueError, match=r"^n_lines: expected an integer >= 1"):
        make(n_lines=0)
    with pytest.raises(TypeError, match=r"^snr_db: expected a number or None, got str"):
        make(snr_db="40")
    with pytest.raises(
        ValueError, match=r"^snr_db: expected a finite number, inf or None, got nan"
    ):
        make(snr_db=math.nan)
    with pytest.raises(
        ValueError, match=r"^Ts: the band reaches \d+ Hz, above the Nyquist frequency"
    ):
        make(Ts=0.02)
    with pytest.raises(ValueError, match=r"^Ts: expected a finite number > 0"):
        make(Ts=-1e-3)


def test_true_system_refuses_impossible_scheduling():
    gantry, stage = lpvid.datasets.gantry(), lpvid.datasets.positioning_stage()
    with pytest.raises(ValueError, match=r"^p: the tube side must exceed twice the wall"):
        gantry.true_system(3.0)  # thinner than two walls
    with pytest.raises(ValueError, match=r"^p: the beam's free length .* must be at least 0.05 m"):
        stage.true_system(-0.58)  # beam shorter than 5 cm
    with pytest.raises(ValueError, match=r"^p: expected a finite scheduling value"):
        gantry.true_system(math.nan)
    with pytest.raises(TypeError, match=r"^p: expected one real scheduling value"):
        gantry.true_system([24.0, 30.0])
    # a one-element array is one value
    A1, A2 = gantry.true_system(np.array([30.0]))[0], gantry.true_system(30)[0]
    np.testing.assert_array_equal(A1, A2)
