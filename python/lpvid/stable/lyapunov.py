"""A common quadratic Lyapunov function over the scheduling range, as a linear matrix inequality.

For ``A(t) = sum_k A_k t^k``, ``t`` in [-1, 1] (the range mapped affinely),
a symmetric ``P`` with ``P > 0`` and

- continuous time: ``F(t) = -(A(t)^T P + P A(t)) > 0``,
- discrete time: ``F(t) = [[P, A(t)^T P], [P A(t), P]] > 0`` (by a Schur
  complement, ``P - A(t)^T P A(t) > 0``),

for every ``t`` makes ``V(x) = x^T P x`` decrease along every trajectory of
the LPV system for any variation of the scheduling inside the range, however
fast: the model is *quadratically stable* there, which implies that every
frozen model is stable.

``F(t)`` is a matrix polynomial of the degree ``d`` of ``A(t)``, linear in
``P``. Its positivity on [-1, 1] is written exactly (Lukacs' theorem, which
holds for matrix polynomials of one variable) as a weighted sum of squares:
``F(t) - eps I = Z_m(t)^T Q0 Z_m(t) + (1 - t^2) Z_{m-1}(t)^T Q1 Z_{m-1}(t)``
for ``d = 2m``, ``(1 + t) Z_m^T Q0 Z_m + (1 - t) Z_m^T Q1 Z_m`` for
``d = 2m + 1``, with ``Q0, Q1 >= 0`` and ``Z_m(t) = [I; t I; ...; t^m I]``
(for ``d = 1`` these are the vertex conditions). The semidefinite program
maximises ``eps`` over ``I <= P <= kappa I``; it is solved with the Python
package clarabel (``pip install "lpvid[lmi]"``).

**What is certified.** From the solver's ``P, Q0, Q1, eps`` the identity's
residual ``R_k`` (per power of ``t``) and the smallest eigenvalues of ``Q0``,
``Q1`` and ``P`` are recomputed in floating point, giving the bound
``F(t) >= mu I`` for every ``t`` in [-1, 1] with
``mu = eps - sum_k ||R_k|| - w (m0 + 1) max(0, -lambda_min(Q0)) - ...``
(``w`` the largest value of the weight ``1``, ``1 - t^2`` or ``1 +- t`` on
[-1, 1]). ``quadratic`` is True only when ``mu > 0`` and ``P > 0``: a
certificate that does not rest on the solver's tolerances. It is False when
the optimal ``eps`` is negative by more than a millionth of the scale of
``F`` at the solution: then no ``P`` with condition number
at most ``kappa`` exists (the representation is exact, so this is not a
relaxation gap). Otherwise (solver failure, ``eps`` within its accuracy of 0)
it is None.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["LyapunovCertificate", "quadratic_stability", "KAPPA", "NO_CLARABEL"]

#: What a certificate says when the clarabel package is missing.
NO_CLARABEL = 'not decided: the LMI needs the clarabel package (pip install "lpvid[lmi]")'
#: Largest condition number of the Lyapunov matrix searched: ``I <= P <= KAPPA I``.
KAPPA = 1e6
#: Largest side of the semidefinite blocks attempted (larger LMIs give None).
MAX_BLOCK = 400
#: The optimal eps counts as negative below ``-_EPS_TOL ||P|| (1 + sum_k ||A_k||)``:
#: well beyond the solver's accuracy at the scale of the solution.
_EPS_TOL = 1e-6


@dataclass(frozen=True)
class LyapunovCertificate:
    """A common quadratic Lyapunov function over the range and its check.

    Attributes
    ----------
    P : ndarray, shape (n, n)
        The Lyapunov matrix (``V(x) = x^T P x``), with ``I <= P <= kappa I``
        up to the solver's accuracy.
    mu : float
        Certified lower bound of the smallest eigenvalue of ``F`` (module
        notes, in the model's units) over the range (positive: certified).
    eps : float
        The solver's optimal ``eps``.
    residual : float
        ``sum_k ||R_k||`` of the weighted sum-of-squares identity, recomputed.
    degree : int
        Degree of ``A(t)`` in the scheduling variable.
    discrete : bool
        Discrete time (the Stein form) or continuous time.
    kappa : float
        Bound on the condition number of ``P`` searched.
    """

    P: NDArray[np.float64]
    mu: float
    eps: float
    residual: float
    degree: int
    discrete: bool
    kappa: float

    def inequality(self, A: NDArray[np.float64]) -> NDArray[np.float64]:
        """``F`` of the module notes for one frozen ``A(p)``: ``>= mu I`` on the certified range.

        Continuous time ``-(A^T P + P A)``; discrete time ``[[P, A^T P], [P A, P]]``.
        """
        return _F(np.asarray(A, dtype=float), self.P, self.discrete)


def _F(A: NDArray[np.float64], P: NDArray[np.float64], discrete: bool) -> NDArray[np.float64]:
    if discrete:
        return np.block([[P, A.T @ P], [P @ A, P]])
    return -(A.T @ P + P @ A)


def _svec_index(q: int) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """Rows and columns of the upper triangle, column by column (clarabel's PSD triangle order)."""
    r, c = np.tril_indices(q)
    return c, r


def _mat(x: NDArray[np.float64], q: int) -> NDArray[np.float64]:
    """The symmetric matrix of a scaled upper-triangle vector (off-diagonals times sqrt 2)."""
    i, j = _svec_index(q)
    v = np.where(i == j, x, x / np.sqrt(2.0))
    M = np.zeros((q, q))
    M[i, j] = v
    M[j, i] = v
    return M


def _svec(M: NDArray[np.float64]) -> NDArray[np.float64]:
    i, j = _svec_index(M.shape[0])
    return np.where(i == j, M[i, j], np.sqrt(2.0) * M[i, j])


def _weights(d: int) -> list[tuple[int, list[tuple[int, float]]]]:
    """Per Gram matrix: its number of blocks ``m + 1``, its weight as (power, coefficient)."""
    if d == 0:
        return [(1, [(0, 1.0)])]
    m = d // 2
    if d % 2 == 0:
        return [(m + 1, [(0, 1.0)]), (m, [(0, 1.0), (2, -1.0)])]
    return [(m + 1, [(0, 1.0), (1, 1.0)]), (m + 1, [(0, 1.0), (1, -1.0)])]


def _gram_part(Q: NDArray[np.float64], blocks: int, q: int, d: int, weight: Any) -> NDArray:
    """Coefficients (per power of t) of ``w(t) Z^T Q Z``, shape (d + 1, q, q)."""
    out = np.zeros((d + 1, q, q))
    for bi in range(blocks):
        for bj in range(blocks):
            blk = Q[bi * q : (bi + 1) * q, bj * q : (bj + 1) * q]
            for power, c in weight:
                out[bi + bj + power] += c * blk
    return out


def quadratic_stability(
    coef: NDArray[np.float64], discrete: bool, kappa: float = KAPPA
) -> tuple[bool | None, LyapunovCertificate | None, str]:
    """Decide quadratic stability of ``A(t) = sum_k coef[k] t^k`` on [-1, 1] (module notes).

    Parameters
    ----------
    coef : ndarray, shape (d + 1, n, n)
        Coefficients of ``A(t)`` in powers of ``t``.
    discrete : bool
        Discrete time.
    kappa : float
        Bound on the condition number of ``P``.

    Returns
    -------
    quadratic : bool or None
    certificate : LyapunovCertificate or None
        When ``quadratic`` is True (and, for the record, when it is False).
    note : str
        What was decided and how.
    """
    try:
        import clarabel
        import scipy.sparse as sp
    except ImportError:
        return None, None, NO_CLARABEL
    A = np.asarray(coef, dtype=float)
    d, n = A.shape[0] - 1, A.shape[1]
    scale = 1.0
    if not discrete:
        scale = max(float(max(np.linalg.norm(a, 2) for a in A)), 1e-300)
        A = A / scale
    q = 2 * n if discrete else n
    grams = _weights(d)
    if max(b * q for b, _ in grams) > MAX_BLOCK:
        return None, None, f"not decided: the LMI is too large (blocks over {MAX_BLOCK})"

    # Variables: svec(P), svec(Q0), svec(Q1), eps.
    nP = n * (n + 1) // 2
    sizes = [b * q for b, _ in grams]
    nQ = [s * (s + 1) // 2 for s in sizes]
    offsets = np.cumsum([0, nP, *nQ])
    n_var = int(offsets[-1]) + 1
    i_eps = n_var - 1
    n_eq = (d + 1) * (q * (q + 1) // 2)

    # F_k(P) - eps [k = 0] I - sum of Gram parts = 0, one row per power of t and
    # upper-triangle entry, one column per variable.
    ui, uj = _svec_index(q)
    row_of = np.full((q, q), -1)
    row_of[ui, uj] = np.arange(ui.size)
    row_of[uj, ui] = np.arange(ui.size)
    Aeq = np.zeros((n_eq, n_var))
    pi, pj = _svec_index(n)
    units = np.zeros((nP, n, n))
    cols = np.arange(nP)
    units[cols, pi, pj] = np.where(pi == pj, 1.0, 1.0 / np.sqrt(2.0))
    units[cols, pj, pi] = units[cols, pi, pj]
    for k in range(d + 1):
        Fk = _F_batch(A[k], units, discrete, constant=(k == 0))
        Aeq[k * ui.size : (k + 1) * ui.size, :nP] = Fk[:, ui, uj].T
    Aeq[: ui.size, i_eps] = -(ui == uj).astype(float)
    for g, ((_, weight), size) in enumerate(zip(grams, sizes, strict=True)):
        gi, gj = _svec_index(size)
        val = np.where(gi == gj, 1.0, 1.0 / np.sqrt(2.0))
        bi, a_in = np.divmod(gi, q)
        bj, b_in = np.divmod(gj, q)
        # Entry (gi, gj) and its mirror land in blocks (bi, bj) and (bj, bi): both in the
        # coefficient of t^(bi + bj), at (a, b) and (b, a), i.e. on the same equality row,
        # twice when gi != gj; once on the diagonal.
        mult = np.where(gi == gj, 1.0, 2.0) * np.where((a_in == b_in) | (gi == gj), 1.0, 0.5)
        rows = row_of[a_in, b_in]
        cols_g = offsets[1 + g] + np.arange(gi.size)
        for power, c in weight:
            k = bi + bj + power
            np.add.at(Aeq, (k * ui.size + rows, cols_g), -c * val * mult)

    blocks_A = [sp.csc_matrix(Aeq)]
    b = [np.zeros(n_eq)]
    cones = [clarabel.ZeroConeT(n_eq)]
    sel = sp.lil_matrix((nP, n_var))
    for c in range(nP):
        sel[c, c] = 1.0
    sel = sel.tocsc()
    I_n = _svec(np.eye(n))
    blocks_A += [-sel, sel]  # P - I >= 0, kappa I - P >= 0
    b += [-I_n, kappa * I_n]
    cones += [clarabel.PSDTriangleConeT(n), clarabel.PSDTriangleConeT(n)]
    for g, size in enumerate(sizes):
        s = sp.lil_matrix((nQ[g], n_var))
        for c in range(nQ[g]):
            s[c, offsets[1 + g] + c] = -1.0
        blocks_A.append(s.tocsc())
        b.append(np.zeros(nQ[g]))
        cones.append(clarabel.PSDTriangleConeT(size))
    Acon = sp.vstack(blocks_A).tocsc()
    qvec = np.zeros(n_var)
    qvec[i_eps] = -1.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solver = clarabel.DefaultSolver(
        sp.csc_matrix((n_var, n_var)), qvec, Acon, np.concatenate(b), cones, settings
    )
    sol = solver.solve()
    status = str(sol.status)
    x = np.asarray(sol.x, dtype=float)
    if not np.all(np.isfinite(x)) or status not in ("Solved", "AlmostSolved"):
        return None, None, f"not decided: the LMI solver stopped with status {status}"
    P = _mat(x[:nP], n)
    eps = float(x[i_eps])
    Qs = [_mat(x[offsets[1 + g] : offsets[2 + g]], sizes[g]) for g in range(len(grams))]
    # The identity, recomputed from the matrices (independent of the assembly above).
    R = np.zeros((d + 1, q, q))
    for k in range(d + 1):
        R[k] = _F(A[k], P, discrete) if (k == 0 or not discrete) else _off(A[k], P)
    R[0] -= eps * np.eye(q)
    for (blocks, weight), Q in zip(grams, Qs, strict=True):
        R -= _gram_part(Q, blocks, q, d, weight)
    residual = float(sum(np.linalg.norm(Rk, 2) for Rk in R))
    mu = eps - residual
    for (blocks, weight), Q in zip(grams, Qs, strict=True):
        w = 2.0 if any(p == 1 for p, _ in weight) else 1.0
        mu -= w * blocks * max(0.0, -float(np.linalg.eigvalsh(Q)[0]))
    # Continuous time: F was computed for A / scale; in the model's units it is scale F.
    cert = LyapunovCertificate(
        P=P,
        mu=float(mu * scale),
        eps=float(eps * scale),
        residual=float(residual * scale),
        degree=d,
        discrete=discrete,
        kappa=float(kappa),
    )
    p_min = float(np.linalg.eigvalsh(P)[0])
    form = "P - A(p)^T P A(p)" if discrete else "-(A(p)^T P + P A(p))"
    if mu > 0 and p_min > 0:
        inequality = (
            f"[[P, A(p)^T P], [P A(p), P]] >= {cert.mu:.3g} I (hence P - A(p)^T P A(p) > 0)"
            if discrete
            else f"-(A(p)^T P + P A(p)) >= {cert.mu:.3g} I"
        )
        return (
            True,
            cert,
            (
                f"quadratically stable: a Lyapunov matrix P with I <= P <= {kappa:g} I and "
                f"{inequality} for every p in the range (certified from the recomputed "
                f"sum-of-squares identity, A(p) of degree {d})"
            ),
        )
    size = float(np.linalg.norm(P, 2)) * (1.0 + sum(float(np.linalg.norm(a, 2)) for a in A))
    if eps < -_EPS_TOL * size:
        return (
            False,
            cert,
            (
                f"not quadratically stable: no Lyapunov matrix with I <= P <= {kappa:g} I makes "
                f"{form} positive over the range (best eps = {cert.eps:.3g}; the sum-of-squares "
                "form is exact for polynomial dependence on one parameter)"
            ),
        )
    return (
        None,
        None,
        (
            f"not decided: the best eps ({eps:.3g}) is within the solver's accuracy of 0 "
            f"(certified bound {mu:.3g})"
        ),
    )


def _F_batch(
    Ak: NDArray[np.float64], P: NDArray[np.float64], discrete: bool, constant: bool
) -> NDArray[np.float64]:
    """``F_k`` for a stack of symmetric matrices ``P`` (shape (m, n, n)): shape (m, q, q)."""
    AtP = Ak.T @ P
    PA = P @ Ak
    if not discrete:
        return -(AtP + PA)
    m, n = P.shape[0], P.shape[1]
    out = np.zeros((m, 2 * n, 2 * n))
    if constant:
        out[:, :n, :n] = P
        out[:, n:, n:] = P
    out[:, :n, n:] = AtP
    out[:, n:, :n] = PA
    return out


def _off(Ak: NDArray[np.float64], P: NDArray[np.float64]) -> NDArray[np.float64]:
    """Discrete time, power k >= 1: only the off-diagonal blocks ``A_k^T P`` and ``P A_k``."""
    n = P.shape[0]
    Z = np.zeros((n, n))
    return np.block([[Z, Ak.T @ P], [P @ Ak, Z]])
