"""Built-in FRF data sets generated from physical models.

Two data sets in the spirit of the two cases of Turk, Gillis, Pipeleers and
Swevers (2018):

- :func:`gantry`: a flexible gantry (the paper's section 4), 6 states,
  1 input (motor torque), 2 outputs (accelerations), scheduled by the side
  length of the square tubes of its bridge; discrete time by default.
- :func:`positioning_stage`: a velocity-controlled positioning stage carrying
  a cantilever whose free length changes with the position of a second axis
  (the paper's section 5), 4 states, single input single output, ``D = 0``;
  continuous time by default.

Both are written here from first principles (lumped masses and springs; the
formulas are in the functions' docstrings), are exactly reproducible from a
seed, and come with their true frozen models, so that an identified model can
be judged against the noise floor and against the truth.

Examples
--------
>>> import lpvid
>>> ds = lpvid.datasets.gantry(seed=1)
>>> ds.identification
FrfData(N=5 points, F=300 lines 50-300 Hz, 2 outputs x 1 inputs, Ts=0.0005 s)
>>> ds.order, ds.basis
(6, Polynomial(4, domain=(24.0, 48.0)))

"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_int, real_array, sample_time
from lpvid.basis import Basis, Polynomial
from lpvid.data import FrfData, z_points

__all__ = ["Dataset", "gantry", "positioning_stage", "GANTRY", "STAGE"]

Matrices = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


# ---------------------------------------------------------------------------
# The data-set object
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Dataset:
    """A built-in identification problem: data, suggested settings, the truth.

    Attributes
    ----------
    name : str
        Short name (``"gantry"``, ``"positioning_stage"``).
    description : str
        A few lines for reports: the system, the data, the noise.
    identification : FrfData
        Data at the identification points.
    validation : FrfData
        Data at scheduling values between the identification points, with
        the same lines, noise level and sample time.
    order : int
        Number of states of the true system (the order to identify).
    basis : Basis
        A suggested basis, normalised to the identification range.
    fixed : dict or None
        Suggested fixed parameters, e.g. ``{"D": True}`` when the true
        system has no feedthrough; None when everything is free.
    snr_db : float or None
        The signal-to-noise ratio the noise was drawn at; None for
        noise-free data.
    inputs, outputs : tuple of str
        Names and units of the inputs and outputs, for plots.
    scheduling : str
        Name and unit of the scheduling parameter.
    physics : callable
        ``physics(p) -> (A, B, C, D)``: the continuous-time physical model
        at a scheduling value, before sampling. Prefer :meth:`true_system`.

    """

    name: str
    description: str
    identification: FrfData
    validation: FrfData
    order: int
    basis: Basis
    fixed: dict[str, bool] | None
    snr_db: float | None
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    scheduling: str
    physics: Callable[[float], Matrices] = field(repr=False, compare=False)

    @property
    def Ts(self) -> float | None:
        """Sample time of the data in seconds; None for continuous time."""
        return self.identification.Ts

    def continuous_system(self, p: float) -> Matrices:
        """The continuous-time physical model frozen at ``p``.

        Parameters
        ----------
        p : float
            Scheduling value (any value where the physics makes sense, not
            only the data's points).

        Returns
        -------
        (A, B, C, D) : tuple of ndarray
            ``dx/dt = A x + B u``, ``y = C x + D u``.

        """
        return self.physics(_scalar(p))

    def true_system(self, p: float) -> Matrices:
        """The true frozen model at ``p`` in the time domain of the data.

        Parameters
        ----------
        p : float
            Scheduling value.

        Returns
        -------
        (A, B, C, D) : tuple of ndarray
            Discrete time when the data are: zero-order-hold sampling of
            :meth:`continuous_system` with ``Ts``, then all states scaled by
            one number so that ``||B|| = ||C||``. Continuous time: the
            physical model itself.

        """
        return _sampled(self.physics(_scalar(p)), self.Ts)

    def true_frf(self, p: ArrayLike, freqs_hz: ArrayLike | None = None) -> NDArray[np.complex128]:
        """Noise-free FRF of the true system.

        Parameters
        ----------
        p : float or array_like, shape (N,)
            Scheduling values.
        freqs_hz : array_like, optional
            Frequencies in Hz; default the data's lines.

        Returns
        -------
        ndarray, shape (N, F, l, r), complex

        """
        ps = real_array(p, "p", ndim=(0, 1)).ravel()
        f = self.identification.freqs_hz if freqs_hz is None else freqs_hz
        f = real_array(f, "freqs_hz", ndim=(0, 1)).ravel()
        z = z_points(f, self.Ts)
        return np.stack([_frf(self.true_system(float(pq)), z) for pq in ps])

    def resonances_hz(self, p: float) -> NDArray[np.float64]:
        """Natural frequencies of the lightly damped modes at ``p``, ascending.

        The undamped natural frequencies ``|lambda| / (2 pi)`` of the poles
        of :meth:`continuous_system` with damping ratio below 0.3 and
        positive imaginary part.

        Parameters
        ----------
        p : float
            Scheduling value.

        Returns
        -------
        ndarray of float
            Frequencies in Hz.

        """
        lam = np.linalg.eigvals(self.continuous_system(p)[0])
        lam = lam[lam.imag > 0]
        light = lam[-lam.real / np.abs(lam) < 0.3]
        return np.sort(np.abs(light)) / (2 * np.pi)


# ---------------------------------------------------------------------------
# Shared helpers
# ---------------------------------------------------------------------------
def _scalar(p: Any) -> float:
    if isinstance(p, bool) or not isinstance(p, numbers.Real):
        arr = np.asarray(p)
        if arr.size != 1 or np.iscomplexobj(arr) or not np.issubdtype(arr.dtype, np.number):
            raise TypeError(f"p: expected one real scheduling value, got {p!r}")
        p = arr.item()
    v = float(p)
    if not math.isfinite(v):
        raise ValueError(f"p: expected a finite scheduling value, got {p}")
    return v


def _frf(sys: Matrices, z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """``C (zI - A)^-1 B + D`` at every point of ``z``, shape (F, l, r)."""
    A, B, C, D = sys
    n = A.shape[0]
    M = z[:, None, None] * np.eye(n) - A
    X = np.linalg.solve(M, np.broadcast_to(B, (z.size, *B.shape)).astype(complex))
    return C @ X + D


def _zoh(A: NDArray[np.float64], B: NDArray[np.float64], Ts: float) -> tuple[Any, Any]:
    """Zero-order-hold sampling: ``Ad = e^{A Ts}``, ``Bd = int_0^Ts e^{A s} ds B``."""
    import scipy.linalg

    n, r = B.shape
    big = np.zeros((n + r, n + r))
    big[:n, :n] = A
    big[:n, n:] = B
    e = scipy.linalg.expm(big * Ts)
    return e[:n, :n], e[:n, n:]


def _sampled(sys: Matrices, Ts: float | None) -> Matrices:
    """The model in the data's time domain.

    Continuous time: unchanged. Discrete time: zero-order-hold sampling, then
    every state multiplied by one number so that ``||B|| = ||C||`` (sampling
    scales B by about Ts).
    """
    A, B, C, D = sys
    if Ts is None:
        return A, B, C, D
    Ad, Bd = _zoh(A, B, Ts)
    return _balance_blocks((Ad, Bd, C, D), [slice(None)])


def _balance_blocks(sys: Matrices, blocks: list[slice]) -> Matrices:
    """Scale each block of states by one number so that its rows of B and columns of C match.

    A scalar per block commutes with a block-diagonal A, so the scaling can
    be applied before or after sampling alike.
    """
    A, B, C, D = (x.copy() for x in sys)
    for blk in blocks:
        nb, nc = np.linalg.norm(B[blk]), np.linalg.norm(C[:, blk])
        if nb > 0 and nc > 0:
            s = math.sqrt(nc / nb)
            B[blk] *= s
            C[:, blk] /= s
    return A, B, C, D


def _snr(snr_db: Any) -> float | None:
    if snr_db is None:
        return None
    if isinstance(snr_db, bool) or not isinstance(snr_db, numbers.Real):
        raise TypeError(f"snr_db: expected a number or None, got {type(snr_db).__name__}")
    v = float(snr_db)
    if math.isnan(v) or v == -math.inf:
        raise ValueError(f"snr_db: expected a finite number, inf or None, got {snr_db}")
    return None if v == math.inf else v


def _measure(
    physics: Callable[[float], Matrices],
    p: NDArray[np.float64],
    freqs_hz: NDArray[np.float64],
    Ts: float | None,
    snr_db: float | None,
    rng: np.random.Generator,
) -> FrfData:
    """True FRFs at ``p`` plus circular complex Gaussian noise of known sigma.

    ``sigma[q, :, i, j] = 10^(-snr_db / 20) * rms_k |G[q, k, i, j]|``, the
    same at every line; the noise ``sigma * (n1 + j n2) / sqrt(2)`` with
    n1, n2 standard normal has ``E|noise|^2 = sigma^2``. Without noise
    (``snr_db`` None) sigma is the rms magnitude itself.
    """
    z = z_points(freqs_hz, Ts)
    G = np.stack([_frf(_sampled(physics(float(pq)), Ts), z) for pq in p])
    rms = np.sqrt(np.mean(np.abs(G) ** 2, axis=1, keepdims=True))
    if snr_db is None:
        return FrfData(p, freqs_hz, G, np.broadcast_to(rms, G.shape), Ts)
    sigma = np.broadcast_to(rms * 10.0 ** (-snr_db / 20.0), G.shape)
    noise = rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)
    return FrfData(p, freqs_hz, G + sigma * noise / math.sqrt(2.0), sigma, Ts)


def _generators(seed: Any) -> tuple[np.random.Generator, np.random.Generator]:
    """Independent noise streams for identification and validation data."""
    s = positive_int(seed, "seed", minimum=0)
    ident, valid = np.random.SeedSequence(s).spawn(2)
    return np.random.default_rng(ident), np.random.default_rng(valid)


def _ranges(ds: Dataset) -> str:
    lo = ds.resonances_hz(ds.identification.p_range[0])
    hi = ds.resonances_hz(ds.identification.p_range[1])
    return ", ".join(f"{a:.0f} -> {b:.0f}" for a, b in zip(lo, hi, strict=True))


# ---------------------------------------------------------------------------
# Flexible gantry
# ---------------------------------------------------------------------------
#: Physical parameters of the gantry (SI units, steel tubes).
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


# ---------------------------------------------------------------------------
# Positioning stage with a cantilever
# ---------------------------------------------------------------------------
#: Physical parameters of the positioning stage (SI units, steel beam).
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
