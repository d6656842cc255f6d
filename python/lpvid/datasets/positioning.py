"""The positioning stage carrying a cantilever of varying length (the paper's section 5)."""

from __future__ import annotations

import math

import numpy as np

from lpvid._checks import positive_int, sample_time
from lpvid.data.basis import Polynomial
from lpvid.datasets.container import Dataset, _ranges
from lpvid.datasets.synthesis import Matrices, _generators, _measure, _snr

__all__ = ["STAGE", "positioning_stage"]


STAGE: dict[str, float] = {
    "carriage": 6.0,  # moving mass of the X stage (with the Y stage on it) [kg]
    "bandwidth": 10.0,  # velocity loop: Kp = 2 pi bandwidth * carriage [Hz]
    "integral": 2.0,  # PI corner: Ki = 2 pi integral * Kp [Hz]
    "E": 210e9,  # Young's modulus [Pa]
    "rho": 7850.0,  # density [kg/m^3]
    "width": 0.025,  # beam width [m]
    "thickness": 6e-3,  # beam thickness, in x [m]
    "tip": 0.1,  # end effector and accelerometer [kg]
    "length_at_zero": 0.6,  # free length at p = 0; free length = length_at_zero + p [m]
    "damping": 0.02,  # damping ratio of the beam on a fixed base
}


def _stage_parameters(p: float) -> dict[str, float]:
    """Lumped parameters of the stage at Y position ``p`` [m].

    Returns a dict with ``m1`` (carriage with the clamped beam part), ``m2``
    (tip mass: end effector plus 33/140 of the beam), ``k = 3 E I / L^3``,
    ``c = 2 zeta sqrt(k m2)``, ``kp``, ``ki`` and ``L``.
    """
    s = STAGE
    L = s["length_at_zero"] + p
    if not L >= 0.05:
        raise ValueError(
            f"p: the beam's free length {s['length_at_zero']:g} + p must be at least 0.05 m, "
            f"got p = {p}"
        )
    inertia = s["width"] * s["thickness"] ** 3 / 12
    m_beam = s["rho"] * s["width"] * s["thickness"] * L
    m2 = s["tip"] + 33 / 140 * m_beam
    k = 3 * s["E"] * inertia / L**3
    kp = 2 * math.pi * s["bandwidth"] * s["carriage"]
    return {
        "L": L,
        "m1": s["carriage"] + (1 - 33 / 140) * m_beam,
        "m2": m2,
        "k": k,
        "c": 2 * s["damping"] * math.sqrt(k * m2),
        "kp": kp,
        "ki": 2 * math.pi * s["integral"] * kp,
    }


def _stage_physics(p: float) -> Matrices:
    """Continuous-time 4-state model of the stage at Y position ``p`` [m].

    States: integral of the velocity error [m], beam deflection
    ``x1 - x2`` [m], carriage velocity and tip velocity [m/s].
    """
    q = _stage_parameters(p)
    m1, m2, k, c, kp, ki = q["m1"], q["m2"], q["k"], q["c"], q["kp"], q["ki"]
    A = np.array(
        [
            [0.0, 0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0, -1.0],
            [ki / m1, -k / m1, -(kp + c) / m1, c / m1],
            [0.0, k / m2, c / m2, -c / m2],
        ]
    )
    B = np.array([[1.0], [0.0], [kp / m1], [0.0]])
    C = np.array([[0.0, k / m2, c / m2, -c / m2]])
    D = np.zeros((1, 1))
    return A, B, C, D


def positioning_stage(
    seed: int = 0,
    n_lines: int = 385,
    snr_db: float | None = 40.0,
    Ts: float | None = None,
) -> Dataset:
    r"""Velocity-controlled stage carrying a cantilever of varying length (paper, section 5).

    **Physics.** An X stage (moving mass ``m1``, with the Y stage on it) is
    velocity controlled by a PI loop, force
    ``F = Kp (v_ref - v1) + Ki int (v_ref - v1) dt``. It carries a flat steel
    cantilever, bending in x, whose free length ``L = 0.6 m + p`` is set by
    the Y position ``p``; its first bending mode is a tip mass
    ``m2 = m_tip + 33/140 m_beam`` on a spring ``k = 3 E I / L^3`` with
    damper ``c = 2 zeta sqrt(k m2)`` (``zeta = 2 %``), so it gets softer
    and slower as the beam gets longer. Equations::

        m1 dv1/dt = F - k (x1 - x2) - c (v1 - v2)
        m2 dv2/dt =     k (x1 - x2) + c (v1 - v2)

    The input is the velocity reference [m/s], the output the end-effector
    acceleration ``dv2/dt`` [m/s^2], as in the paper. Four states: the
    integrator, the deflection ``x1 - x2``, ``v1`` and ``v2`` (rigid-body
    motion under the velocity loop plus one bending mode). The output is a
    function of the states alone, so ``D = 0``. Parameters in :data:`STAGE`;
    the velocity loop has a 10 Hz bandwidth. The bending resonance falls
    from about 19 Hz at ``p = -0.151`` m to about 10.6 Hz at ``p = 0.023`` m:
    a cubic in ``p`` interpolates it between the points to within the noise.

    **Data.** Identification at ``p = -0.151, -0.093, -0.035, 0.023`` m,
    validation at ``p = -0.0639`` m (the paper's points); ``n_lines``
    equally spaced lines from 3 to 50 Hz (385 by default, about the paper's
    0.1221 Hz resolution). Continuous time by default (``Ts=None``); with a
    sample time the model is sampled with a zero-order hold (still
    ``D = 0``).

    **Noise.** As in :func:`gantry`: circular complex Gaussian with known
    ``sigma[q, :, 0, 0] = 10^(-snr_db/20) * rms_k |G[q, k]|``. The paper
    does not state its noise level; its averaged multisine measurements
    show the standard deviation several tens of dB below the FRF, and 40 dB
    is our choice.

    Parameters
    ----------
    seed : int, optional
        Seed of the noise (non-negative).
    n_lines : int, optional
        Frequency lines per point (default 385).
    snr_db : float or None, optional
        Signal-to-noise ratio in dB (default 40); None or ``inf`` for
        noise-free data.
    Ts : float or None, optional
        Sample time in seconds; None (default) for continuous time.

    Returns
    -------
    Dataset
        With ``order=4``, ``basis=Polynomial(3, domain=(-0.151, 0.023))``
        and ``fixed={"D": True}``; ``p`` in m.

    Examples
    --------
    >>> import lpvid
    >>> ds = lpvid.datasets.positioning_stage()
    >>> ds.identification.n_points, ds.validation.p, ds.Ts
    (4, array([-0.0639]), None)

    """
    n_lines = positive_int(n_lines, "n_lines")
    snr = _snr(snr_db)
    Ts = sample_time(Ts)
    band = (3.0, 50.0)
    if Ts is not None and band[1] >= 0.5 / Ts:
        raise ValueError(f"Ts: the band reaches {band[1]:g} Hz, above the Nyquist frequency")
    rng_id, rng_val = _generators(seed)
    freqs = np.linspace(*band, n_lines)
    p_id = np.array([-0.151, -0.093, -0.035, 0.023])
    p_val = np.array([-0.0639])
    ident = _measure(_stage_physics, p_id, freqs, Ts, snr, rng_id)
    valid = _measure(_stage_physics, p_val, freqs, Ts, snr, rng_val)
    ds = Dataset(
        name="positioning_stage",
        description="",
        identification=ident,
        validation=valid,
        order=4,
        basis=Polynomial(3, domain=(-0.151, 0.023)),
        fixed={"D": True},
        snr_db=snr,
        inputs=("velocity reference [m/s]",),
        outputs=("end-effector acceleration [m/s^2]",),
        scheduling="Y position p [m]",
        physics=_stage_physics,
    )
    time = "continuous time" if Ts is None else f"Ts = {Ts * 1e3:g} ms (ZOH)"
    noise = "no noise" if snr is None else f"{snr:g} dB SNR, known sigma"
    text = (
        "Positioning stage: PI velocity loop on the X carriage carrying a cantilever "
        "whose free length is 0.6 m + p; 4 states, D = 0.\n"
        "1 input (velocity reference) -> 1 output (end-effector acceleration); "
        "scheduling: Y position p [m].\n"
        f"Identification p = -0.151, -0.093, -0.035, 0.023 m; validation p = -0.0639 m; "
        f"{n_lines} lines 3-50 Hz, {time}, {noise}.\n"
        f"Beam resonance from p = -0.151 to 0.023 m [Hz]: {_ranges(ds)}."
    )
    object.__setattr__(ds, "description", text)
    return ds
