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
