"""Known systems for the subspace and SMILE tests (physical, not random)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag

from lpvid.testing import noisy_data, synthetic_parametric

Ss = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]

#: Scheduling points and band of the gantry-like system (tube side length in mm).
GANTRY_P = np.array([24.0, 30.0, 36.0, 42.0, 48.0])
GANTRY_MID = np.array([27.0, 33.0, 39.0, 45.0])
GANTRY_FREQS = np.linspace(40.0, 400.0, 300)


def gantry_like(p_mm: float, damping: float = 0.01) -> Ss:
    """A three-mass chain whose stiffness and masses grow with the tube size p (mm).

    Continuous time, 6 states, 1 input (force on mass 1), 2 outputs (the
    accelerations of masses 1 and 3, so D != 0). The three modes move from
    about 54/126/182 Hz at p = 24 to 98/228/329 Hz at p = 48 and have about
    1.6 %, 1.2 % and 0.7 % damping. The states are (w0 q, dq/dt) with w0 =
    2 pi 150 rad/s so that the entries of A are of one size.
    """
    s = float(p_mm) / 36.0
    m = np.array([1.0, 0.8, 0.6]) * (0.7 + 0.3 * s)
    k = np.array([1.0e6, 7.5e5, 5.0e5]) * s**2
    K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
    Minv = np.diag(1 / m)
    w = np.sqrt(np.sort(np.linalg.eigvals(Minv @ K).real))
    Cd = 2 * damping / w.mean() * K + 0.6 * damping * w[0] * np.diag(m)
    w0 = 2 * np.pi * 150.0
    A = np.block([[np.zeros((3, 3)), w0 * np.eye(3)], [-Minv @ K / w0, -Minv @ Cd]])
    B = np.concatenate([np.zeros((3, 1)), Minv[:, :1]])
    acc = np.concatenate([-Minv @ K / w0, -Minv @ Cd], axis=1)
    return A, B, acc[[0, 2]], Minv[[0, 2], :1]


def modal_system(freqs_hz, dampings, bs, cs, D) -> Ss:
    """Continuous-time model in real modal form: one 2 x 2 block per mode."""
    blocks = []
    for fr, ze in zip(freqs_hz, dampings, strict=True):
        w = 2 * np.pi * fr
        sig, wd = -ze * w, w * np.sqrt(1 - ze**2)
        blocks.append(np.array([[sig, wd], [-wd, sig]]))
    return block_diag(*blocks), np.concatenate(bs), np.concatenate(cs, axis=1), np.asarray(D)


def lti_frf(model: Ss, z: np.ndarray) -> np.ndarray:
    """FRF (M, l, r) of (A, B, C, D) at the points z by dense solves."""
    A, B, C, D = model
    n = A.shape[0]
    return np.array([C @ np.linalg.solve(zz * np.eye(n) - A, B) + D for zz in z])


def scramble(model: Ss, rng: np.random.Generator, spread: float = 1.0) -> Ss:
    """The model in random state coordinates, T = Q1 diag(exp(u)) Q2, |u| <= spread."""
    A, B, C, D = model
    n = A.shape[0]
    q1, _ = np.linalg.qr(rng.normal(size=(n, n)))
    q2, _ = np.linalg.qr(rng.normal(size=(n, n)))
    T = q1 @ np.diag(np.exp(rng.uniform(-spread, spread, n))) @ q2
    Ti = np.linalg.inv(T)
    return T @ A @ Ti, T @ B, C @ Ti, D.copy()


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    """||a - b|| / ||b||."""
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def close_modes(s: float, gap_hz: float = 0.3) -> Ss:
    """Two light modes (0.5 %, 0.6 % damping) gap_hz apart near 150-175 Hz, 2 x 2 MIMO.

    Both move with s in [0, 1]; their residues point in different directions.
    """
    return modal_system(
        [150.0 + 20.0 * s, 150.0 + gap_hz + 20.0 * s + 5.0 * s**2],
        [0.005, 0.006],
        [np.array([[1.0, 0.2], [0.3, 1.0]]), np.array([[0.5 + 0.3 * s, -0.4], [0.2, 0.7]])],
        [np.array([[1.0, 0.0], [0.2, 0.5]]), np.array([[0.3, 1.0], [-0.6, 0.4 * (1 + s)]])],
        np.zeros((2, 2)),
    )


#: Modes of :func:`heavily_damped`: natural frequencies (Hz) and damping ratios at s = 0 and 1.
DAMPED_FREQS = (6.6, 17.0, 45.0)
DAMPED_ZETA0 = (0.32, 0.47, 0.45)
DAMPED_ZETA1 = (0.39, 0.78, 0.88)


def heavily_damped(s: float) -> Ss:
    """Three heavily damped modes whose damping grows strongly with s in [0, 1] (SISO).

    Continuous time, 6 states, real modal blocks ``[[sigma, wd], [-wd, sigma]]``
    whose ``sigma`` and ``wd`` move linearly in s between the values of
    natural frequencies 6.6, 17 and 45 Hz with damping ratios 0.32, 0.47, 0.45
    (s = 0) and 0.39, 0.78, 0.88 (s = 1): the system is exactly affine in s
    (an LPV model with ``Polynomial(1)`` contains it). B and C are constant.
    """
    blocks = []
    for f, z0, z1 in zip(DAMPED_FREQS, DAMPED_ZETA0, DAMPED_ZETA1, strict=True):
        w = 2 * np.pi * f
        sig0, wd0 = -z0 * w, w * np.sqrt(1 - z0**2)
        sig1, wd1 = -z1 * w, w * np.sqrt(1 - z1**2)
        sig, wd = sig0 + (sig1 - sig0) * s, wd0 + (wd1 - wd0) * s
        blocks.append(np.array([[sig, wd], [-wd, sig]]))
    B = np.array([[0.36], [-0.66], [-0.62], [0.44], [-0.2], [-0.04]])
    C = np.array([[-2.5, -2.7, 0.34, 0.33, 1.4, 0.72]])
    return block_diag(*blocks), B, C, np.zeros((1, 1))


def first_order_frf():
    """Noisy FRFs of a one-state discrete-time system whose pole moves with p.

    Four points p = 0, 1/3, 2/3, 1 (pole 0.8 at the ends, 0.87 inside), 40
    lines up to Nyquist, 2 % noise; ``(data, validation)`` with validation
    at the two inner points (an lpvid.FrfData each).
    """
    import lpvid

    a = 0.9 - 0.1 * np.abs(2 * np.array([0.0, 1 / 3, 2 / 3, 1.0]) - 1)
    f = np.linspace(0.02, 0.5, 40)
    z = np.exp(2j * np.pi * f)
    G = (0.1 / (z[None, :] - a[:, None]))[:, :, None, None]
    rng = np.random.default_rng(3)
    sigma = 0.02 * np.abs(G)
    G = G + sigma * (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)) / np.sqrt(2)
    data = lpvid.FrfData([0.0, 1 / 3, 2 / 3, 1.0], f, G, sigma=sigma, Ts=1.0)
    return data, data.subset([1, 2])


#: The model-reduction community's synthetic parametric system as the
#: few-points tests measure it (issue 58): 120 lines log-spaced over
#: 10^0.5 to 10^3.5 rad/s, 1 % noise, D fixed, unseen values inside [0.02, 1].
SYNTHETIC = synthetic_parametric(10)
SYNTHETIC_FREQS = np.logspace(0.5, 3.5, 120) / (2 * np.pi)
SYNTHETIC_FIXED = {"D": True}
SYNTHETIC_UNSEEN = np.linspace(0.03, 0.99, 20)


def synthetic_data(p, seed=0):
    """:data:`SYNTHETIC` measured at ``p`` with 1 % noise of the given seed."""
    return noisy_data(SYNTHETIC, p, SYNTHETIC_FREQS, np.random.default_rng(seed), 0.01)
