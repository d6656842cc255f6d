"""The flexible gantry scheduled by the tube size of its bridge (the paper's section 4)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_int, sample_time
from lpvid.data.basis import Polynomial
from lpvid.datasets.container import Dataset, _ranges
from lpvid.datasets.synthesis import (
    Matrices,
    _balance_blocks,
    _generators,
    _measure,
    _snr,
)

__all__ = ["GANTRY", "gantry"]


GANTRY: dict[str, float] = {
    "E": 210e9,  # Young's modulus [Pa]
    "rho": 7850.0,  # density [kg/m^3]
    "t": 2e-3,  # tube wall thickness [m]
    "span": 1.5,  # bridge span between the two carriages [m]
    "chord_gap": 0.036,  # distance in x between the two chords of the truss [m]
    "tube_per_span": 3.0,  # metres of tube in the truss per metre of span
    "arm": 0.26,  # length of the vertical arm that carries the head [m]
    "head": 4.0,  # head mass [kg]
    "bracket": 1.0,  # mass of the head bracket at mid-span [kg]
    "end_plates": 2.0,  # both end plates of the bridge [kg]
    "carriages": 5.0,  # both carriages together [kg]
    "rotor_inertia": 2.5e-4,  # motor rotor and pinion inertia, per motor [kg m^2]
    "pinion_radius": 0.02,  # [m]
    "guide_stiffness": 8e6,  # carriage guides in x, both sides [N/m]
    "post": 0.15,  # height of the end posts (same tube) between carriage and bridge [m]
    "damping": 0.02,  # modal damping ratio of every flexible mode
}


def _tube(p_m: float, t: float) -> tuple[float, float]:
    """Area and second moment of area of a square tube of side ``p_m``, wall ``t``."""
    inner = p_m - 2 * t
    return p_m**2 - inner**2, (p_m**4 - inner**4) / 12.0


def _gantry_mechanics(p_mm: float) -> tuple[NDArray[np.float64], ...]:
    """Mass, stiffness and damping matrices, force vector and output rows of the gantry.

    Returns ``(M, K, Cd, b, S)`` for ``M x'' + Cd x' + K x = b u`` with
    ``x = (carriages, bridge ends, bridge middle, head)`` displacements in x,
    ``u`` the torque of each motor and ``y = S x''`` (head, carriages).
    """
    import scipy.linalg

    g = GANTRY
    t = g["t"]
    if not p_mm > 2e3 * t:
        raise ValueError(
            f"p: the tube side must exceed twice the wall ({2e3 * t:g} mm), got {p_mm}"
        )
    area, inertia = _tube(p_mm * 1e-3, t)
    E, rho, L = g["E"], g["rho"], g["span"]
    m_bridge = rho * area * g["tube_per_span"] * L
    m_arm = rho * area * g["arm"]
    r = g["pinion_radius"]
    masses = [
        g["carriages"] + 2 * g["rotor_inertia"] / r**2,
        0.62 * m_bridge + g["end_plates"],
        0.38 * m_bridge + g["bracket"] + (1 - 33 / 140) * m_arm,
        g["head"] + 33 / 140 * m_arm,
    ]
    k_posts = 2 * 3 * E * inertia / g["post"] ** 3
    springs = [
        1 / (1 / g["guide_stiffness"] + 1 / k_posts),
        192 * E * (2 * inertia + area * g["chord_gap"] ** 2 / 2) / L**3,
        3 * E * inertia / g["arm"] ** 3,
    ]
    M = np.diag(masses)
    K = np.zeros((4, 4))
    for i, k in enumerate(springs):
        K[i : i + 2, i : i + 2] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    w2, phi = scipy.linalg.eigh(K, M)  # mass-normalised: phi' M phi = I
    w = np.sqrt(np.clip(w2, 0.0, None))
    flex = phi[:, 1:]
    Cd = M @ flex @ np.diag(2 * g["damping"] * w[1:]) @ flex.T @ M
    b = np.array([2 / r, 0.0, 0.0, 0.0])
    S = np.array([[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0]])
    return M, K, Cd, b, S


def _gantry_physics(p_mm: float) -> Matrices:
    """Continuous-time 6-state modal model of the gantry at tube side ``p_mm``."""
    import scipy.linalg

    M, K, _, b, S = _gantry_mechanics(p_mm)
    zeta = GANTRY["damping"]
    w2, phi = scipy.linalg.eigh(K, M)
    A = np.zeros((6, 6))
    B = np.zeros((6, 1))
    C = np.zeros((2, 6))
    for j in range(3):
        w = math.sqrt(w2[j + 1])
        v = phi[:, j + 1]
        v = v if v[3] >= 0 else -v  # sign convention: the head moves positively
        s = slice(2 * j, 2 * j + 2)
        A[s, s] = [[0.0, w], [-w, -2 * zeta * w]]
        B[2 * j + 1, 0] = v @ b
        C[:, s] = np.outer(S @ v, [-w, -2 * zeta * w])
    D = (S @ np.linalg.solve(M, b))[:, None]
    return _balance_blocks((A, B, C, D), [slice(0, 2), slice(2, 4), slice(4, 6)])


def gantry(
    seed: int = 0,
    n_lines: int = 300,
    snr_db: float | None = 40.0,
    Ts: float | None = 5e-4,
) -> Dataset:
    r"""Flexible gantry scheduled by the tube size of its bridge (paper, section 4).

    **Physics.** A bridge moves in x on two rails, driven at each end by a
    motor through a pinion on a rack; both motors get the same torque. The
    bridge is a truss of square steel tubes of side ``p`` and wall
    ``t = 2 mm`` (cross-section area ``A = p^2 - (p - 2t)^2``, second moment
    ``I = (p^4 - (p - 2t)^4) / 12``). The head hangs at mid-span from a
    vertical arm of the same tube. Four lumped masses move in x:

    1. carriages: both carriages plus the rotor and pinion inertia of both
       motors seen at the rack, ``2 J / r^2`` (rack and pinion taken rigid);
       the motor force ``2 u / r`` acts here;
    2. bridge ends: the end plates plus 62 % of the bridge mass;
    3. bridge middle: 38 % of the bridge mass (the share of a
       clamped-clamped beam's first mode), the head bracket and 107/140 of
       the arm mass;
    4. head: the head plus 33/140 of the arm mass.

    They are linked in a chain by springs: between carriages and bridge
    ends the carriage guides in series with two end posts of the same tube
    bending as cantilevers (``2 * 3 E I / h^3``), the bridge bending in x
    (clamped-clamped, load at mid-span, ``192 E I_truss / L^3`` with
    ``I_truss = 2 I + A d^2 / 2`` for two chords ``d`` apart) and the arm
    bending (cantilever, ``3 E I / l_arm^3``). Masses grow with ``A``,
    stiffnesses with ``A`` and ``I``; the parameters are in :data:`GANTRY`.
    Every flexible mode gets 2 % modal damping. The input is the torque of
    each motor [N m], the outputs the accelerations [m/s^2] of the head and
    of the carriages (as in the paper).

    In modal coordinates (mass-normalised modes ``phi_k`` of ``K phi = w^2
    M phi``) the accelerations are ``y = S sum_k phi_k phi_k' b s^2 /
    (s^2 + 2 zeta w_k s + w_k^2) u``; the rigid-body mode (``w_0 = 0``) only
    adds the constant ``S phi_0 phi_0' b``. Writing each flexible term as
    its high-frequency limit minus a strictly proper part gives 6 states
    (per mode ``(w q, dq/dt)``, scaled so that B and C match in size) and
    ``D = S M^-1 b``: zero for the head, ``2 / (r m_1)`` for the carriages,
    on which the motor force acts. The three resonances lie inside
    50-300 Hz at every ``p`` from 24 to 48 mm and all rise with ``p``
    (stiffness grows faster than mass): about 56 -> 125, 124 -> 214 and
    185 -> 262 Hz. At p = 24 mm the lowest mode is mostly the head swinging
    on its arm, the middle one the bridge bending, the highest the bridge
    ends against the carriages; the shapes mix as ``p`` grows.

    **Data.** Identification at ``p = 24, 30, 36, 42, 48`` mm, validation at
    ``27, 33, 39, 45`` mm; ``n_lines`` equally spaced lines from 50 to
    300 Hz; the continuous model is sampled with a zero-order hold at
    ``Ts`` (default 0.5 ms, 2 kHz), as in the paper whose data were
    discrete.

    **Noise.** Circular complex Gaussian, independent per point, line,
    output and input, with known standard deviation
    ``sigma[q, :, i, j] = 10^(-snr_db/20) * rms_k |G[q, k, i, j]|`` (the same
    at every line): the SNR is the ratio of the mean power of each true FRF
    entry over the lines to the noise power. ``E|noise|^2 = sigma^2``, so the
    true system's V_NLS is about ``n_residuals`` (standard deviation
    ``sqrt(n_residuals)``).

    Parameters
    ----------
    seed : int, optional
        Seed of the noise (non-negative). The identification and validation
        noise come from independent streams of one ``numpy.random.SeedSequence``.
    n_lines : int, optional
        Frequency lines per point (default 300).
    snr_db : float or None, optional
        Signal-to-noise ratio in dB (default 40). None or ``inf`` gives
        noise-free data whose sigma is the rms magnitude of each FRF entry.
    Ts : float or None, optional
        Sample time in seconds (default 5e-4); None gives continuous-time
        data of the physical model.

    Returns
    -------
    Dataset
        With ``order=6``, ``basis=Polynomial(4, domain=(24, 48))`` and
        ``fixed=None``; ``p`` in mm.

    Examples
    --------
    >>> import lpvid
    >>> ds = lpvid.datasets.gantry()
    >>> ds.identification.p
    array([24., 30., 36., 42., 48.])
    >>> ds.validation.p
    array([27., 33., 39., 45.])

    """
    n_lines = positive_int(n_lines, "n_lines")
    snr = _snr(snr_db)
    Ts = sample_time(Ts)
    band = (50.0, 300.0)
    if Ts is not None and band[1] >= 0.5 / Ts:
        raise ValueError(f"Ts: the band reaches {band[1]:g} Hz, above the Nyquist frequency")
    rng_id, rng_val = _generators(seed)
    freqs = np.linspace(*band, n_lines)
    p_id = np.array([24.0, 30.0, 36.0, 42.0, 48.0])
    p_val = np.array([27.0, 33.0, 39.0, 45.0])
    ident = _measure(_gantry_physics, p_id, freqs, Ts, snr, rng_id)
    valid = _measure(_gantry_physics, p_val, freqs, Ts, snr, rng_val)
    ds = Dataset(
        name="gantry",
        description="",
        identification=ident,
        validation=valid,
        order=6,
        basis=Polynomial(4, domain=(24.0, 48.0)),
        fixed=None,
        snr_db=snr,
        inputs=("motor torque [N m]",),
        outputs=("head acceleration [m/s^2]", "carriage acceleration [m/s^2]"),
        scheduling="tube side p [mm]",
        physics=_gantry_physics,
    )
    time = "continuous time" if Ts is None else f"Ts = {Ts * 1e3:g} ms (ZOH)"
    noise = "no noise" if snr is None else f"{snr:g} dB SNR, known sigma"
    text = (
        "Flexible gantry: 4 lumped masses (carriages, bridge ends, bridge middle, head), "
        "2 % modal damping, 6 states.\n"
        "1 input (motor torque) -> 2 outputs (head and carriage acceleration); "
        "scheduling: tube side p [mm].\n"
        f"Identification p = 24, 30, 36, 42, 48 mm; validation p = 27, 33, 39, 45 mm; "
        f"{n_lines} lines 50-300 Hz, {time}, {noise}.\n"
        f"Resonances from p = 24 to 48 mm [Hz]: {_ranges(ds)}."
    )
    object.__setattr__(ds, "description", text)
    return ds
