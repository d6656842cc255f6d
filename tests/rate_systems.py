"""Models with known stability under a bounded rate of variation (tests of issue 62).

**Conjugated by a nilpotent** (:func:`conjugated`): ``A(p) = T(p) A0 T(p)^-1``
with ``T(p) = I + sum_k p_k N_k`` and ``N_j N_k = 0`` for all ``j, k``, so
``T(p)^-1 = I - sum_k p_k N_k`` and ``A(p)`` is a polynomial of degree 2.
Every frozen model is similar to ``A0``. Along any scheduling, ``z =
T(p)^-1 x`` obeys the time-invariant-in-``p`` equation ``z' = (A0 - sum_k
v_k N_k) z`` (``v = dp/dt``), so a common Lyapunov matrix ``P0`` of the
vertices ``A0 - sum_k s_k nu_k N_k`` gives ``P(p) = T(p)^-T P0 T(p)^-1``, a
polynomial of degree 2 that certifies the rates ``nu``: a known *lower*
bound of what a degree-2 certificate must find. The constant-rate threshold
(``A0 - v N`` unstable) is *not* an upper bound here: on a bounded box a
constant rate ends at the box's edge, and sweeping back and forth does not
grow (the certificate finds 3.2 for ``A0 = [[-1, 0], [-1, -1]]``, ``N =
e_1 e_2^T`` on (0, 3), where ``A0 - v N`` is unstable for ``v > 1``).
Hence the rotation below, whose unstable scheduling is periodic.

**A rotation in two parameters** (:func:`rotating`): ``A(s) = a I + b J +
k (s_1 E_1 + s_2 E_2)`` (``s`` the mapped parameters, ``J`` the rotation
generator, ``E_1 = diag(1, -1)``, ``E_2 = [[0, 1], [1, 0]]``; ``J``
anticommutes with both). Frozen eigenvalues ``a +- sqrt(k^2 |s|^2 - b^2)``.
On the circle ``s = (cos 2 phi, sin 2 phi)``, ``A = R(phi) (a I + b J + k
E_1) R(phi)^T`` exactly, and along ``phi = w t`` the state ``z = R^T x``
obeys ``z' = (a I + (b - w) J + k E_1) z``: unstable when ``|b - w| <
sqrt(k^2 - a^2)``. That scheduling is periodic, stays in the box and moves
each ``s_k`` at most ``2 w`` per time unit: an instability witness, so a
known *upper* bound of any rate certificate.

**A known critical rate** (:func:`tilted`; the two constructions above
bracket the rotation's certificate within a factor of almost 4 only): the
nilpotent conjugation with ``A0 = [[-1, 1], [-1, -1]]`` (eigenvalues ``-1 +-
i``), ``N = e_1 e_2^T``, one parameter on ``(-3, 3)``. Its critical rate
lies in ``[NU_LO, NU_HI] = [4.7, 4.95]``, a factor 1.053, both ends proven
below. Here ``z' = (A0 - v N) z`` with ``A0 - v N = [[-1, 1 - v], [-1,
-1]]``: a saddle for ``v > 2``, a focus turning faster for ``v < 0``.

*Upper bound: a sweep.* ``p`` goes from -3 to 3 at ``v = +NU_HI`` (for
``TAU = 6 / NU_HI = 1.21`` time units) and back at ``v = -NU_HI``: the
scheduling stays in the box, moves at ``|dp/dt| = NU_HI``, is periodic
(period ``2 TAU``), and ``z`` gains ``M = expm((A0 + NU_HI N) TAU)
expm((A0 - NU_HI N) TAU)`` per period, spectral radius 1.005 (the same
sweep at 5.0 gives 1.020, at 4.9 0.990): on the way up the saddle
stretches ``z``, on the way down the focus turns it by about half a turn
back onto the stretched direction. ``x = T(p) z`` with ``p`` back at -3 after
a period, so ``x``'s monodromy is ``T(-3) M T(-3)^-1``: unstable. (The
first construction's ``A0`` has real eigenvalues and no turn, which is why
sweeping it back and forth does not grow.)

*Lower bound: a tilt.* A common ``P0`` of ``A0 -+ nu N`` (``q = 1`` below,
degree 2) exists only for ``nu < 2`` (``A0 - 2 N`` has a zero eigenvalue),
yet no scheduling that stays in the box holds ``v = 2`` for long. A
Lyapunov function ``exp(lambda p) z^T Q0 z`` prices that: its derivative is
that of ``z^T Q0 z`` for ``A0 - v N + (lambda v / 2) I``, so with ``lambda <
0`` the saddle (``v > 0``) is damped and the focus (``v < 0``) pays for it.
A polynomial stands in for the exponential: with ``V = q(p) z^T Q0 z``, i.e.
``P(p) = q(p) (I - p N)^T Q0 (I - p N)`` (a polynomial of degree ``2 + deg
q``),

    dV/dt = q z^T [(A0 - v N)^T Q0 + Q0 (A0 - v N) + (q'/q) v Q0] z.

The bracket is affine in ``v`` for each value of ``q'/q`` and affine in
``q'/q`` for each ``v``: with ``LAMBDA_1 <= q'/q <= LAMBDA_2`` on the box,
``q > 0`` and ``Q0 > 0``, it is negative on the box for every ``|v| <= nu``
as soon as it is at the four corners ``v = +-nu``, ``q'/q = LAMBDA_1,
LAMBDA_2``. ``TILT_Q`` (degree 4, so ``P`` of degree 6) keeps ``q'/q`` in
``[-0.424, -0.412]`` on ``(-3, 3)`` (``q`` nearly ``exp(-0.418 p)``; found
by a linear program on a grid, rounded, checked by the roots of ``q' -
LAMBDA_1 q`` and ``LAMBDA_2 q - q'``), and ``Q0 = diag(1, 5.684)`` makes the
four corners negative definite at ``nu = NU_LO = 4.7`` (smallest eigenvalue
of their negatives 6e-4, the largest 26): a degree-6 certificate exists at
4.7, so ``max_rate(..., degree=6)`` must find it up to the bisection's
tolerance (the sums of squares are exact for one parameter).

Measured beside, not used by the tests: with the exact ``exp(lambda p)`` a
``Q0`` exists up to ``nu = 4.82`` (Shorten and Narendra's test for a pair of
2 x 2 matrices, over ``lambda``), and the sweep is unstable from ``nu =
4.93`` when its half period is chosen best (``nu TAU <= 6``), so the
critical rate itself is known within 2.3 %; ``deg q = 2`` (``P`` of degree
4) gives no ``nu`` above 3.5 this way. lpvid's certificate finds 2.56 with
``P`` of degree 2, 4.60 with degree 4, 4.80 with degree 6 and with degree 8.
"""

from __future__ import annotations

import numpy as np

import lpvid
from lpvid.model.frozen import frozen_A

J = np.array([[0.0, -1.0], [1.0, 0.0]])
E1 = np.diag([1.0, -1.0])
E2 = np.array([[0.0, 1.0], [1.0, 0.0]])


def _io(nb: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    B = np.zeros((nb, n, 1))
    B[0, 0, 0] = 1.0
    C = np.zeros((nb, 1, n))
    C[0, 0, 0] = 1.0
    return B, C


def model_of(f, n: int, basis: lpvid.Basis) -> lpvid.LpvModel:
    """The LpvModel whose ``A(p)`` is ``f(p)`` (exactly in the basis' span), B, C fixed."""
    pairs = basis.domain
    rng = np.random.default_rng(0)
    p = np.stack([rng.uniform(lo, hi, 80) for lo, hi in pairs], axis=1)
    w = np.hstack([np.ones((len(p), 1)), basis(p if len(pairs) > 1 else p[:, 0])])
    vals = np.array([f(x).ravel() for x in p])
    X, *_ = np.linalg.lstsq(w, vals, rcond=None)
    X = X.reshape(-1, n, n)
    assert np.allclose(w @ X.reshape(len(X), -1), vals, atol=1e-10), "f outside the basis"
    B, C = _io(len(X), n)
    return lpvid.LpvModel(X, B, C, basis=basis)


def conjugated(A0, Ns, pairs) -> tuple[lpvid.LpvModel, callable]:
    """``A(p) = (I + sum p_k N_k) A0 (I - sum p_k N_k)``, Polynomial(2) basis on ``pairs``."""
    A0 = np.asarray(A0, dtype=float)
    n = A0.shape[0]

    def f(p):
        S = sum(pk * N for pk, N in zip(p, Ns, strict=True))
        return (np.eye(n) + S) @ A0 @ (np.eye(n) - S)

    basis = lpvid.Polynomial(2, domain=pairs[0] if len(pairs) == 1 else pairs)
    return model_of(f, n, basis), f


def rotating(a=-1.0, b=3.0, k=2.0, shift=None, pairs=None) -> lpvid.LpvModel:
    """The rotation model (module notes); ``shift`` adds ``shift s_3 I`` (a third parameter)."""
    n_params = 2 if shift is None else 3
    pairs = pairs or [(-1.0, 1.0)] * n_params
    basis = lpvid.Polynomial(1, domain=pairs)
    lo = np.array([x for x, _ in pairs])
    hi = np.array([y for _, y in pairs])

    def f(p):
        s = 2.0 * (np.asarray(p) - lo) / (hi - lo) - 1.0
        out = a * np.eye(2) + b * J + k * (s[0] * E1 + s[1] * E2)
        return out + (shift * s[2] * np.eye(2) if shift is not None else 0.0)

    return model_of(f, 2, basis)


def witness_rate(a=-1.0, b=3.0, k=2.0) -> float:
    """The slowest rotation (largest ``|ds_k/dt|``) of the module notes that is unstable."""
    return 2.0 * (b - np.sqrt(k**2 - a**2))


def grows_on_the_circle(model: lpvid.LpvModel, w: float, t_end: float, extra=()) -> float:
    """``|x(t_end)| / |x(0)|`` along ``s = (cos 2 w t, sin 2 w t, *extra)`` (RK4, small steps)."""
    pairs = model.basis.domain
    lo = np.array([x for x, _ in pairs])
    hi = np.array([y for _, y in pairs])

    def A(t):
        s = np.array([np.cos(2 * w * t), np.sin(2 * w * t), *extra])
        return frozen_A(model, (lo + (s + 1) * (hi - lo) / 2)[None, :])[0]

    x = np.array([1.0, 0.0])
    h = 1e-3
    for i in range(int(round(t_end / h))):
        t = i * h
        k1 = A(t) @ x
        k2 = A(t + h / 2) @ (x + h / 2 * k1)
        k3 = A(t + h / 2) @ (x + h / 2 * k2)
        k4 = A(t + h) @ (x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return float(np.linalg.norm(x))


def sampled_worst(model: lpvid.LpvModel, cert, rng, count: int = 2000) -> float:
    """Smallest eigenvalue of ``-(A^T P + P A + sum_k dP/dp_k v_k)`` at random ``p`` and
    vertices ``v`` of the certified rate box, ``dP/dp`` by central differences of
    ``cert.P_at`` (not the certificate's own chain rule)."""
    pairs = cert.p_range
    lo = np.array([x for x, _ in pairs])
    hi = np.array([y for _, y in pairs])
    worst = np.inf
    h = 1e-6 * (hi - lo)
    for _ in range(count):
        p = rng.uniform(lo, hi)
        v = cert.rate * rng.choice([-1.0, 1.0], size=len(pairs))
        A = frozen_A(model, p[None, :])[0]
        P = cert.P_at(p)
        dP = sum(
            v[k]
            * (cert.P_at(p + h[k] * np.eye(len(p))[k]) - cert.P_at(p - h[k] * np.eye(len(p))[k]))
            / (2 * h[k])
            for k in range(len(p))
        )
        worst = min(worst, float(np.linalg.eigvalsh(-(A.T @ P + P @ A + dP)).min()))
    return worst


TILT_A0 = np.array([[-1.0, 1.0], [-1.0, -1.0]])
TILT_N = np.array([[0.0, 1.0], [0.0, 0.0]])
#: The box of :func:`tilted` (the sweep of the witness goes from one end to the other).
TILT_RANGE = (-3.0, 3.0)
#: ``q(p) = sum_j TILT_Q[j] p^j``, nearly ``exp(-0.418 p)`` on the box (module notes).
TILT_Q = (1.0, -0.417, 0.0905, -0.0137, 0.00116)
#: Bounds of ``q'/q`` on the box.
LAMBDA_1, LAMBDA_2 = -0.424, -0.412
TILT_Q0 = np.diag([1.0, 5.684])
#: The rate certified by ``P(p) = q(p) (I - p N)^T Q0 (I - p N)`` (degree 6).
NU_LO = 4.7
#: The rate of the unstable sweep (from one end of the box to the other and back).
NU_HI = 4.95


def tilted() -> lpvid.LpvModel:
    """The model whose critical rate lies in ``[NU_LO, NU_HI]`` (module notes).

    Returns
    -------
    LpvModel
        ``A(p) = (I + p N) A0 (I - p N)`` on ``TILT_RANGE``, a Polynomial(2) basis.
    """
    return conjugated(TILT_A0, [TILT_N], [TILT_RANGE])[0]


def tilted_P(p: float) -> tuple[np.ndarray, np.ndarray]:
    """The explicit ``P(p)`` of the lower bound and its derivative ``dP/dp``.

    Parameters
    ----------
    p : float
        A scheduling value.

    Returns
    -------
    P, dP : ndarray, shape (2, 2)
        ``q(p) (I - p N)^T Q0 (I - p N)`` and its derivative in ``p``.
    """
    q = np.polynomial.Polynomial(TILT_Q)
    Ti = np.eye(2) - p * TILT_N
    core = Ti.T @ TILT_Q0 @ Ti
    dcore = -(TILT_N.T @ TILT_Q0 @ Ti + Ti.T @ TILT_Q0 @ TILT_N)
    return q(p) * core, q.deriv()(p) * core + q(p) * dcore


def sweep_monodromy(model: lpvid.LpvModel, nu: float) -> np.ndarray:
    """Monodromy of ``x' = A(p(t)) x`` over one period of the sweep of the box at rate ``nu``.

    ``p`` goes from ``lo`` to ``hi`` at ``dp/dt = nu`` and back at ``-nu``
    (a triangle wave that stays in the box), ``A(p)`` from the model itself;
    integrated by ``scipy.integrate.solve_ivp`` (tolerances 1e-11).

    Parameters
    ----------
    model : LpvModel
        A model with one scheduling parameter.
    nu : float
        The rate ``|dp/dt|`` of the sweep.

    Returns
    -------
    ndarray, shape (n, n)
        ``Phi`` with ``x(2 T) = Phi x(0)``, ``T = (hi - lo) / nu``.
    """
    from scipy.integrate import solve_ivp

    (lo, hi), n = model.basis.domain[0], model.n_states
    half = (hi - lo) / nu

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        p = lo + nu * t if t <= half else hi - nu * (t - half)
        A = frozen_A(model, np.array([[p]]))[0]
        return (A @ y.reshape(n, n)).ravel()

    phi = np.eye(n).ravel()
    for t0, t1 in ((0.0, half), (half, 2 * half)):  # the corner of p(t) at ``half``
        sol = solve_ivp(rhs, (t0, t1), phi, rtol=1e-11, atol=1e-13, method="DOP853")
        phi = sol.y[:, -1]
    return phi.reshape(n, n)
