"""Helpers to build random LPV models and noisy FRF data for tests and examples.

Import it as ``import lpvid.testing``. Numpy only: the frequency responses
here are computed by dense numpy solves, independently of lpvid's Rust core,
so that a test can compare the two.

Examples
--------
>>> import numpy as np
>>> import lpvid.testing
>>> rng = np.random.default_rng(0)
>>> model = lpvid.testing.random_lpv(rng, n=2, r=1, l=1, nb=1)
>>> data = lpvid.testing.noisy_data(model, [0.0, 0.5, 1.0], np.linspace(1, 40, 8), rng)
>>> data.G.shape
(3, 8, 1, 1)

"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lpvid._checks import positive_float, positive_int, real_array
from lpvid._rod import diffusion_rod  # a heat rod whose conductivity spans decades
from lpvid._threads import single_blas
from lpvid.data.basis import Polynomial
from lpvid.data.frf import FrfData
from lpvid.data.noise import circular_noise
from lpvid.model.lpv import LpvModel

__all__ = [
    "random_lpv",
    "modal_lpv",
    "one_group_lpv",
    "crossing_lpv",
    "synthetic_parametric",
    "diffusion_rod",
    "direct_frf",
    "noisy_data",
    "worst_relative_error",
]


def _generator(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(
            f"rng: expected a numpy Generator (np.random.default_rng(seed)), "
            f"got {type(rng).__name__}"
        )
    return rng


def random_lpv(
    rng: np.random.Generator,
    n: int = 3,
    r: int = 2,
    l: int = 2,
    nb: int = 2,
    Ts: float | None = 0.01,
    domain: tuple[float, float] = (0.0, 1.0),
) -> LpvModel:
    """A random LPV model whose frozen models are stable on the domain.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the random numbers.
    n, r, l : int, optional
        Numbers of states, inputs and outputs.
    nb : int, optional
        Degree of the :class:`lpvid.Polynomial` basis on ``domain`` (the
        number of basis functions; 0 gives an LTI model).
    Ts : float or None, optional
        Sample time; None for continuous time.
    domain : (lo, hi), optional
        Scheduling range of the basis.

    Returns
    -------
    LpvModel
        ``A(0)`` is ``0.3 I`` (discrete time) or ``-1.5 I`` (continuous time)
        plus small random entries, so that every frozen model on the domain
        is stable; B, C, D are standard normal.

    """
    gen = _generator(rng)
    n = positive_int(n, "n")
    r = positive_int(r, "r")
    l = positive_int(l, "l")
    nb = positive_int(nb, "nb", minimum=0)
    basis = Polynomial(nb, domain=domain)
    A = 0.1 * gen.normal(size=(nb + 1, n, n)) / np.sqrt(n)
    if Ts is None:
        A[0] -= 1.5 * np.eye(n)
    else:
        A[0] += 0.3 * np.eye(n)
    B = gen.normal(size=(nb + 1, n, r))
    C = gen.normal(size=(nb + 1, l, n))
    D = gen.normal(size=(nb + 1, l, r))
    return LpvModel(A, B, C, D, basis, Ts=Ts)


def modal_lpv(
    freqs_hz: ArrayLike,
    damping: float = 0.02,
    l: int = 2,
    r: int = 1,
    domain: tuple[float, float] = (0.0, 1.0),
) -> LpvModel:
    """A known continuous-time LPV model: lightly damped modes whose frequencies follow p.

    Mode ``k`` has the natural frequency ``f_k(s) = sum_i freqs_hz[k, i] s^i``
    (Hz), ``s`` the scheduling value mapped from ``domain`` to [-1, 1], and
    the relative damping ``damping``; in real modal form its 2 x 2 block of
    ``A(p)`` is linear in ``f_k``, so the model is exact over
    ``Polynomial(degree, domain)`` with ``degree = freqs_hz.shape[1] - 1``
    and only ``A`` depends on p. ``B``, ``C`` and ``D`` are constant and
    fixed (no random numbers): every input drives every mode, every output
    sees it.

    Parameters
    ----------
    freqs_hz : array_like, shape (modes, degree + 1)
        Polynomial coefficients of each mode's frequency; keep every
        frequency positive on the domain.
    damping : float
        Relative damping of every mode.
    l, r : int
        Outputs and inputs.
    domain : (lo, hi)
        Scheduling range of the basis.

    Returns
    -------
    LpvModel
        Of order ``2 modes``.

    Examples
    --------
    >>> import lpvid.testing
    >>> m = lpvid.testing.modal_lpv([[10.0, 2.0, 0.0, 1.0], [25.0, -3.0, 1.0, 0.0]])
    >>> m.n_states, len(m.basis)
    (4, 3)

    """
    coef = real_array(freqs_hz, "freqs_hz", ndim=2)
    zeta = positive_float(damping, "damping")
    if zeta >= 1:
        raise ValueError(f"damping: expected a value in (0, 1), got {zeta}")
    l = positive_int(l, "l")
    r = positive_int(r, "r")
    modes, k = coef.shape
    basis = Polynomial(k - 1, domain=domain)
    n = 2 * modes
    A = np.zeros((k, n, n))
    w = 2 * np.pi * coef  # coefficients of each mode's angular frequency
    sig, wd = -zeta * w, w * np.sqrt(1 - zeta**2)
    for m in range(modes):
        for i in range(k):
            A[i, 2 * m : 2 * m + 2, 2 * m : 2 * m + 2] = [
                [sig[m, i], wd[m, i]],
                [-wd[m, i], sig[m, i]],
            ]
    B = np.zeros((k, n, r))
    B[0, 1::2, :] = w[:, :1] * (1.0 + 0.5 * np.cos(np.arange(r))[None, :])
    C = np.zeros((k, l, n))
    rows, cols = np.arange(l)[:, None], np.arange(n)[None, :]
    C[0] = np.cos(0.7 * rows + 1.3 * cols) + 0.5
    D = np.zeros((k, l, r))
    D[0] = 0.1
    return LpvModel(A, B, C, D, basis)


def _modal_blocks(freqs_hz: NDArray[np.float64], damping: float) -> NDArray[np.float64]:
    """Block-diagonal real modal form, one 2 x 2 block per frequency (linear in it)."""
    n = 2 * freqs_hz.size
    out = np.zeros((n, n))
    for k, f in enumerate(freqs_hz):
        w = 2 * np.pi * f
        out[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[-damping * w, w], [-w, -damping * w]]
    return out


def one_group_lpv(seed: int = 0, n: int = 10) -> LpvModel:
    """A known continuous-time SISO model whose scheduling dependence is one group, A(1).

    ``A(mu) = A0 + mu A1`` with ``B``, ``C`` constant and ``D = 0``, written
    in random (dense) state coordinates: ``n/2`` modes at 8-60 Hz whose
    frequencies move by up to 25 % over ``mu`` in [0, 1], 3 % damping,
    coupled by a small random part of ``A1``. Over
    ``Polynomial(2, domain=(0, 1))`` its groups are ``A(1)`` only
    (``A(2) = 0``): a sparse truth for the l2,1 path to keep. Its frozen
    models are stable on [0, 1] for the seeds the tests use (check with
    :func:`lpvid.stability`).

    Parameters
    ----------
    seed : int
        Seed of the random numbers.
    n : int
        Number of states (even).

    Returns
    -------
    LpvModel

    Examples
    --------
    >>> import lpvid.testing
    >>> m = lpvid.testing.one_group_lpv(0)
    >>> m.group_norms().count()
    1

    """
    n = positive_int(n, "n", minimum=2)
    if n % 2:
        raise ValueError(f"n: expected an even number of states, got {n}")
    rng = np.random.default_rng(seed)
    modes = n // 2
    f0 = np.sort(rng.uniform(8, 60, modes))
    df = rng.uniform(-0.25, 0.25, modes) * f0
    T = np.eye(n) + 0.3 * rng.normal(size=(n, n))
    Ti = np.linalg.inv(T)
    A0 = T @ _modal_blocks(f0, 0.03) @ Ti
    coupling = rng.normal(size=(n, n)) * 0.3 * 2 * np.pi * np.abs(df).mean() / np.sqrt(n)
    A1 = T @ (_modal_blocks(df, 0.03) + coupling) @ Ti
    B = T @ rng.normal(size=(n, 1)) * 2 * np.pi * 20
    C = rng.normal(size=(1, n)) @ Ti

    def only(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.stack([x, 0 * x, 0 * x])

    A = np.stack([A0 + A1 / 2, A1 / 2, 0 * A1])  # mu = (s + 1) / 2
    return LpvModel(A, only(B), only(C), np.zeros((3, 1, 1)), Polynomial(2, domain=(0.0, 1.0)))


def crossing_lpv(
    n_params: int = 3, seed: int = 0, modes: int = 5, damping: float = 0.02
) -> LpvModel:
    """A known continuous-time MIMO model on several scheduling parameters with crossing modes.

    ``2 modes`` states, 3 outputs x 2 inputs, ``D = 0``, ``n_params`` (2 or
    3) scheduling parameters on [0, 1] each, over ``Polynomial(2,
    domain=[(0, 1)] * n_params)`` (every monomial of total degree 1-2). In
    its own real modal coordinates: every mode's frequency moves linearly
    with ``p1`` and the first two cross along it (18 -> 30 Hz and 30 -> 18
    Hz, equal at ``p1 = 0.5``); the third (45 Hz) also moves with ``p2``,
    linearly and quadratically; the input shapes move linearly with
    ``p2``, and with 3 parameters the output shapes move linearly with
    ``p3``. Written in random state coordinates (a constant
    transformation), it uses 4 groups with two parameters (A: s1, s2,
    s2^2; B: s2) and 5 with three (and C: s3).

    Parameters
    ----------
    n_params : int
        2 or 3.
    seed : int
        Seed of the random state coordinates and shapes.
    modes : int
        Number of modes, 3 to 5 (the others at 9 and 70 Hz).
    damping : float
        Relative damping of every mode.

    Returns
    -------
    LpvModel

    Examples
    --------
    >>> import lpvid.testing
    >>> m = lpvid.testing.crossing_lpv(3)
    >>> m.n_states, m.n_outputs, m.n_inputs, m.basis.n_params, m.group_norms().count()
    (10, 3, 2, 3, 5)

    """
    n_params = positive_int(n_params, "n_params", minimum=2)
    if n_params > 3:
        raise ValueError(f"n_params: expected 2 or 3, got {n_params}")
    modes = positive_int(modes, "modes", minimum=3)
    if modes > 5:
        raise ValueError(f"modes: expected 3 to 5, got {modes}")
    zeta = positive_float(damping, "damping")
    rng = np.random.default_rng(seed)
    basis = Polynomial(2, domain=[(0.0, 1.0)] * n_params)
    names = basis.names
    # Frequencies in Hz as polynomials in the scaled s in [-1, 1], per monomial.
    const = np.array([24.0, 24.0, 45.0, 9.0, 70.0])[:modes]
    coef = {
        "s1": np.array([-6.0, 6.0, 3.0, 1.5, -4.0])[:modes],
        "s2": np.array([0.0, 0.0, 5.0, 0.0, 0.0])[:modes],
        "s2^2": np.array([0.0, 0.0, 3.0, 0.0, 0.0])[:modes],
    }
    n, l, r, nb = 2 * modes, 3, 2, len(names)
    T = np.eye(n) + 0.3 * rng.normal(size=(n, n))
    Ti = np.linalg.inv(T)
    A = np.zeros((nb + 1, n, n))
    A[0] = _modal_blocks(const, zeta)
    for name, c in coef.items():
        A[1 + names.index(name)] = _modal_blocks(c, zeta)
    B = np.zeros((nb + 1, n, r))
    B[0, 1::2] = rng.normal(size=(modes, r)) * 2 * np.pi * 30
    B[1 + names.index("s2"), 1::2] = 0.3 * rng.normal(size=(modes, r)) * 2 * np.pi * 30
    C = np.zeros((nb + 1, l, n))
    C[0] = rng.normal(size=(l, n))
    if n_params == 3:
        C[1 + names.index("s3")] = 0.3 * rng.normal(size=(l, n))
    A = np.einsum("ij,kjl,lm->kim", T, A, Ti)
    B = np.einsum("ij,kjl->kil", T, B)
    C = np.einsum("kij,jl->kil", C, Ti)
    return LpvModel(A, B, C, np.zeros((nb + 1, l, r)), basis)


def synthetic_parametric(n: int = 10, domain: tuple[float, float] = (0.02, 1.0)) -> LpvModel:
    """The model-reduction community's synthetic parametric model, of order ``n``.

    From MORwiki ("Synthetic parametric model", modelreduction.org): a
    continuous-time SISO system in real modal form, ``n/2`` complex pole
    pairs ``mu a_k +- j b_k`` with ``a_k = -b_k`` and ``b_k`` equally spaced
    in [10, 1000] rad/s, residues 1 (``B = [2, 0, 2, 0, ...]^T``,
    ``C = [1, 0, 1, 0, ...]``), ``D = 0``; the parameter ``mu`` scales the
    real parts, from light damping (2 % at ``mu = 0.02``) to heavy (71 % at
    ``mu = 1``). ``A(mu) = A_0 + mu A_1`` with ``B``, ``C`` constant: over
    ``Polynomial(2, domain)`` its only group is ``A(1)``. Its frequency band
    is about 10^0.5 to 10^3.5 rad/s.

    Parameters
    ----------
    n : int
        Number of states (even; MORwiki's own is 100).
    domain : (lo, hi)
        Range of ``mu`` for the basis (MORwiki's is [1/50, 1]).

    Returns
    -------
    LpvModel

    Examples
    --------
    >>> import numpy as np, lpvid.testing
    >>> m = lpvid.testing.synthetic_parametric(10)
    >>> m.group_norms().nonzero()["A"], bool(np.allclose(m.at(0.5)[1].ravel(), [2, 0] * 5))
    ([1], True)

    """
    n = positive_int(n, "n", minimum=2)
    if n % 2:
        raise ValueError(f"n: expected an even number of states, got {n}")
    k = n // 2
    b = np.linspace(10.0, 1000.0, k)
    A0 = np.zeros((n, n))
    A1 = np.zeros((n, n))
    for i in range(k):
        A0[2 * i, 2 * i + 1], A0[2 * i + 1, 2 * i] = b[i], -b[i]
        A1[2 * i, 2 * i] = A1[2 * i + 1, 2 * i + 1] = -b[i]
    B = np.zeros((n, 1))
    B[0::2] = 2.0
    C = np.zeros((1, n))
    C[0, 0::2] = 1.0
    lo, hi = domain
    mid, half = (lo + hi) / 2, (hi - lo) / 2  # mu = mid + half s

    def only(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.stack([x, 0 * x, 0 * x])

    A = np.stack([A0 + mid * A1, half * A1, 0 * A1])
    return LpvModel(A, only(B), only(C), np.zeros((3, 1, 1)), Polynomial(2, domain=(lo, hi)))


@single_blas
def direct_frf(model: LpvModel, freqs_hz: ArrayLike, p: ArrayLike) -> NDArray[np.complex128]:
    """Frequency response by a dense numpy solve at every point and frequency.

    Independent of lpvid's core (:meth:`lpvid.LpvModel.frf`), which it can
    check. numpy's BLAS runs on one thread here (as in lpvid's entry
    points), so that the data simulated from a model are the same to the
    last bit on any number of cores: on two threads OpenBLAS solved the
    101-state heat rod's systems to other last bits than on one.

    Parameters
    ----------
    model : LpvModel
    freqs_hz : array_like, shape (F,)
        Frequencies in Hz.
    p : array_like, shape (N,) or (N, Np)
        Scheduling values.

    Returns
    -------
    ndarray, shape (N, F, l, r), complex
        ``C(p) (zI - A(p))^-1 B(p) + D(p)`` with ``z = exp(j w Ts)`` or ``j w``.

    """
    if not isinstance(model, LpvModel):
        raise TypeError(f"model: expected an LpvModel, got {type(model).__name__}")
    freqs = real_array(freqs_hz, "freqs_hz", ndim=1)
    points = real_array(p, "p", ndim=(1, 2))
    out = np.zeros((len(points), freqs.size, model.n_outputs, model.n_inputs), complex)
    n = model.n_states
    for q, pq in enumerate(points):
        a, b, c, d = model.at(pq)
        for k, f in enumerate(freqs):
            w = 2 * np.pi * f
            z = 1j * w if model.Ts is None else np.exp(1j * w * model.Ts)
            out[q, k] = c @ np.linalg.solve(z * np.eye(n) - a, b) + d
    return out


def noisy_data(
    model: LpvModel,
    p: ArrayLike,
    freqs_hz: ArrayLike,
    rng: np.random.Generator,
    rel_noise: float = 0.05,
) -> FrfData:
    """FRF data of a model with complex Gaussian noise of random, known sigma.

    Parameters
    ----------
    model : LpvModel
    p : array_like, shape (N,) or (N, Np)
        Scheduling values of the measurements.
    freqs_hz : array_like, shape (F,)
        Frequencies in Hz.
    rng : numpy.random.Generator
        Source of the noise.
    rel_noise : float, optional
        Noise level: ``sigma = rel_noise (0.5 + U(0, 1)) (|G| + 0.1)`` per
        entry, and the noise is circular complex Gaussian with that standard
        deviation, so that V_NLS at the true model has mean ``M`` (the number
        of real residuals).

    Returns
    -------
    FrfData
        With ``sigma`` set and ``Ts`` that of the model.

    """
    gen = _generator(rng)
    level = positive_float(rel_noise, "rel_noise")
    G = direct_frf(model, freqs_hz, p)
    sigma = level * (0.5 + gen.random(G.shape)) * (np.abs(G) + 0.1)
    return FrfData(p, freqs_hz, G + circular_noise(sigma, gen), sigma, Ts=model.Ts)


def worst_relative_error(
    model: LpvModel, true: LpvModel, freqs_hz: ArrayLike, p: ArrayLike
) -> float:
    """The worst, over the scheduling values ``p``, of the relative FRF error against ``true``.

    At every ``p[q]``: ``||G(p[q]) - G_true(p[q])|| / ||G_true(p[q])||``,
    Frobenius norms over every line, output and input.

    Parameters
    ----------
    model, true : LpvModel
    freqs_hz : array_like, shape (F,)
    p : array_like, shape (N,) or (N, Np)

    Returns
    -------
    float

    """
    G, Gt = model.frf(freqs_hz, p), true.frf(freqs_hz, p)
    err = np.linalg.norm((G - Gt).reshape(len(G), -1), axis=1)
    ref = np.linalg.norm(Gt.reshape(len(Gt), -1), axis=1)
    return float(np.max(err / ref))
