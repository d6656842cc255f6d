"""Lyapunov inequalities on the box [-1, 1]^Np as matrix sums of squares, and their check.

The scheduling box is mapped affinely onto ``[-1, 1]^Np`` (``t``); ``A(t) =
sum_g A_g t^g`` is a matrix polynomial of total degree ``d`` and the
Lyapunov matrix ``P(t) = sum_b P_b t^b`` one of total degree ``e`` (``e =
0``: a common ``P``). Each inequality ``F(t) > 0`` (continuous time ``F =
-(A^T P + P A + sum_k r_k s_k dP/dt_k)`` at a vertex ``s`` of the rate box,
``r_k`` the rate in ``t`` units; discrete time, ``e = 0``, ``F = [[P, A^T P],
[P A, P]]``) is replaced by the Putinar form on the box::

    F(t) - eps I = Z_m(t)^T Q_0 Z_m(t) + sum_k (1 - t_k^2) Z_{m-1}(t)^T Q_k Z_{m-1}(t)

with ``Q_j >= 0``, ``Z_m(t) = [t^a I]`` over the monomials ``t^a`` of total
degree at most ``m = ceil((d + e) / 2) + extra``; ``P(t) - I`` gets the same
form (``m = ceil(e / 2) + extra``). The semidefinite program maximises
``eps`` with ``P_0 <= kappa I`` and ``-kappa I <= P_b <= kappa I`` (``b !=
0``).

**What is certified.** From the solver's numbers only: the identity's
residual ``R_a`` per monomial is recomputed (``F`` from the ``A_g`` and
``P_b`` by matrix products, not from the program's rows), and with the
smallest eigenvalue of every Gram matrix, ``F(t) >= mu I`` for every ``t``
in the box, ``mu = eps - sum_a ||R_a|| - sum_j N_j max(0, -lambda_min(Q_j))``:
on the box ``|t^a| <= 1``, ``0 <= 1 - t_k^2 <= 1`` and ``Z^T Z <= N_j I``
(``N_j`` monomials in ``Z``). The same bound for ``P(t) - I`` gives ``P(t)
>= mu_P I``. ``F`` is affine in the rate, so ``mu`` (the smallest over the
rate box's vertices) holds for every rate in the box.

**What it may miss.** For one parameter and ``m`` as above the form is exact
(Lukacs' theorem for matrix polynomials); for two or three it is a
relaxation: ``F > 0`` on the box may need a larger ``extra``. And ``P(t)``
is sought among polynomials of degree ``e`` only. A failure is therefore
"not decided", never a proof.

**Size.** ``M(k) = C(k + Np, Np)`` monomials of degree ``<= k``; ``q = n``
(continuous time) or ``2 n``; ``V = 2^Np`` rate vertices (one when ``e =
0``). Per inequality a Gram block of side ``q M(m)`` and ``Np`` of side ``q
M(m - 1)``, and ``q (q + 1) / 2 M(2 m)`` equations; ``n (n + 1) / 2 M(e)``
unknowns of ``P``. The interior-point solver's memory grows as the sum over
blocks of ``(s (s + 1) / 2)^2`` (a dense scaling block per cone): a block of
side ``s`` over :data:`MAX_BLOCK`, or an estimate over what the process may
allocate, is a :class:`MemoryError` before any work.

Measured (``benches/bench_stability.py``, two shared cores, clarabel 0.11):
``A(p)`` of degree 2 and ``P(p)`` of degree 2, one rate program takes 0.06 s
for ``n = 4``, one parameter; 8 s for ``n = 8``, two parameters (blocks of
48, about 400 MiB at the peak) and for ``n = 4``, three (blocks of 40); the
bisection of :func:`lpvid.max_rate` solves 7 to 10 of them (about 170 s and
100 s for the last two). ``n = 8`` with three parameters (blocks of 80, an
estimate of 6.5 GB) is refused.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from math import ceil, comb
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid.stable.lyapunov import _mat, _svec, _svec_index

__all__ = ["MAX_BLOCK", "MAX_BYTES", "BoxSolution", "monomials", "program_size", "solve_box"]

#: Largest side of a semidefinite block attempted (larger programs raise MemoryError).
MAX_BLOCK = 400
#: Largest memory estimate of a program attempted (bytes).
MAX_BYTES = 4 * 2**30
#: Bytes per entry of the solver's dense cone blocks, its factorisation's fill counted
#: (measured: n = 8, two parameters, about 400 MiB at the peak for an estimate of 500).
_BYTES_PER_ENTRY = 8 * 8

Exp = tuple[int, ...]


def monomials(degree: int, n_vars: int) -> list[Exp]:
    """Exponents of total degree ``<= degree`` in ``n_vars`` variables, graded."""
    if degree < 0:
        return []
    out: list[Exp] = []
    for total in range(degree + 1):
        level = [e for e in itertools.product(range(total + 1), repeat=n_vars) if sum(e) == total]
        out.extend(sorted(level, reverse=True))
    return out


def _add(a: Exp, b: Exp) -> Exp:
    return tuple(x + y for x, y in zip(a, b, strict=True))


@dataclass(frozen=True)
class _Ineq:
    """One inequality: ``A(t)`` terms, the rate term's weights, the SOS half-degree."""

    A: dict[Exp, NDArray[np.float64]]
    rates: NDArray[np.float64]  # r_k s_k (zero: no derivative term)
    lyapunov: bool  # F of A (with eps) or P(t) - I


def _degree(terms: dict[Exp, Any]) -> int:
    return max((sum(e) for e in terms), default=0)


def program_size(
    n: int,
    n_params: int,
    deg_a: int,
    deg_p: int,
    discrete: bool,
    extra: int = 0,
    count: int | None = None,
) -> dict[str, Any]:
    """Sides of the semidefinite blocks, equations and a memory estimate (bytes).

    ``count`` inequalities of ``F`` (default: the ``2^Np`` rate vertices when
    ``deg_p > 0``, else one).

    Returns
    -------
    dict
        ``blocks`` (list of sides), ``equations``, ``unknowns``, ``bytes``.
    """
    q = 2 * n if discrete else n
    vertices = count if count is not None else (2**n_params if deg_p > 0 else 1)
    blocks: list[int] = []
    eqs = 0
    groups = [(q, ceil((deg_a + deg_p) / 2) + extra, vertices)]
    if deg_p > 0:
        groups.append((n, ceil(deg_p / 2) + extra, 1))
    for side, m, count in groups:
        for _ in range(count):
            blocks.append(side * comb(m + n_params, n_params))
            if m >= 1:
                blocks += [side * comb(m - 1 + n_params, n_params)] * n_params
            eqs += side * (side + 1) // 2 * comb(2 * m + n_params, n_params)
    unknowns = n * (n + 1) // 2 * comb(deg_p + n_params, n_params)
    unknowns += sum(s * (s + 1) // 2 for s in blocks)
    need = _BYTES_PER_ENTRY * sum((s * (s + 1) // 2) ** 2 for s in blocks)
    need += _BYTES_PER_ENTRY * 4 * (eqs + unknowns) * max(blocks, default=1)
    return {"blocks": blocks, "equations": eqs, "unknowns": unknowns, "bytes": int(need)}


def check_size(size: dict[str, Any], what: str) -> None:
    """Raise :class:`MemoryError` before any work when the program cannot fit."""
    said = (
        f"semidefinite blocks up to {max(size['blocks'])} x {max(size['blocks'])}, "
        f"{len(size['blocks'])} blocks, {size['equations']} equations, "
        f"{size['unknowns']} unknowns"
    )
    if max(size["blocks"]) > MAX_BLOCK:
        raise MemoryError(
            f"{what}: the program is too large ({said}; blocks are limited to "
            f"{MAX_BLOCK}): fewer states, a lower degree of P(p) or fewer parameters"
        )
    room, source = _room()
    if size["bytes"] > room:
        raise MemoryError(
            f"{what}: the program needs about {size['bytes'] / 2**20:.0f} MiB in the solver "
            f"({said}), estimated before any work, over {room / 2**20:.0f} MiB ({source}): "
            "fewer states, a lower degree of P(p) or fewer parameters"
        )


def _room() -> tuple[int, str]:
    """What the solver may take: :data:`MAX_BYTES`, or less when the system has less available."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    free = int(line.split()[1]) * 1024
                    if free < MAX_BYTES:
                        return free, "the system's available memory"
    except OSError:
        pass
    return MAX_BYTES, "lpvid.stable.boxsos.MAX_BYTES"


@dataclass(frozen=True)
class BoxSolution:
    """The solver's numbers and the recomputed bounds (module notes), in the program's units.

    Attributes
    ----------
    P : dict
        ``P_b`` per exponent ``b``.
    eps : float
        The solver's ``eps``.
    mu : float
        Certified ``F(t) >= mu I`` on the box, every rate vertex (module notes).
    mu_p : float
        Certified ``P(t) >= mu_p I`` on the box.
    residual : float
        Largest ``sum_a ||R_a||`` over the inequalities.
    status : str
        The solver's status.
    """

    P: dict[Exp, NDArray[np.float64]]
    eps: float
    mu: float
    mu_p: float
    residual: float
    status: str


def lyapunov_terms(
    A: dict[Exp, NDArray[np.float64]],
    P: dict[Exp, NDArray[np.float64]],
    rates: NDArray[np.float64],
    discrete: bool,
) -> dict[Exp, NDArray[np.float64]]:
    """Coefficients of ``F(t)`` (module notes) for given ``P_b``: matrix products only."""
    out: dict[Exp, NDArray[np.float64]] = {}
    n = next(iter(P.values())).shape[0]
    q = 2 * n if discrete else n

    def put(e: Exp, M: NDArray[np.float64]) -> None:
        out[e] = out.get(e, np.zeros((q, q))) + M

    for b, Pb in P.items():
        for g, Ag in A.items():
            if discrete:
                Z = np.zeros((n, n))
                put(_add(b, g), np.block([[Z, Ag.T @ Pb], [Pb @ Ag, Z]]))
            else:
                put(_add(b, g), -(Ag.T @ Pb + Pb @ Ag))
        if discrete:
            Z = np.zeros((n, n))
            put(b, np.block([[Pb, Z], [Z, Pb]]))
        for k, r in enumerate(rates):
            if b[k] > 0 and r != 0.0:
                e = tuple(x - (i == k) for i, x in enumerate(b))
                put(e, -r * b[k] * Pb)
    return out


def _grams(m: int, n_params: int) -> list[tuple[list[Exp], list[tuple[Exp, float]]]]:
    """Per Gram matrix: its monomials ``Z`` and its weight as (exponent, coefficient)."""
    zero = (0,) * n_params
    out = [(monomials(m, n_params), [(zero, 1.0)])]
    if m >= 1:
        for k in range(n_params):
            two = tuple(2 * (i == k) for i in range(n_params))
            out.append((monomials(m - 1, n_params), [(zero, 1.0), (two, -1.0)]))
    return out


def _gram_terms(
    Q: NDArray[np.float64], Z: list[Exp], weight: list[tuple[Exp, float]], q: int
) -> dict[Exp, NDArray[np.float64]]:
    """Coefficients of ``w(t) Z^T Q Z`` by blocks (the check's own sum, not the rows)."""
    out: dict[Exp, NDArray[np.float64]] = {}
    for i, zi in enumerate(Z):
        for j, zj in enumerate(Z):
            blk = Q[i * q : (i + 1) * q, j * q : (j + 1) * q]
            for e, c in weight:
                key = _add(_add(zi, zj), e)
                out[key] = out.get(key, np.zeros((q, q))) + c * blk
    return out


def solve_box(
    cases: list[tuple[dict[Exp, NDArray[np.float64]], NDArray[np.float64]]],
    n_params: int,
    deg_p: int,
    discrete: bool,
    kappa: float,
    extra: int = 0,
    what: str = "stability",
) -> BoxSolution | str:
    """Build, solve and check the program of the module notes.

    Parameters
    ----------
    cases : list of (dict, ndarray)
        One inequality ``F > 0`` each, sharing ``P``: ``A_g`` per exponent
        (tuples of ``n_params`` ints) and ``r_k s_k`` (the rate vertex; zeros
        for a common ``P``).
    n_params : int
    deg_p : int
        Total degree of ``P(t)``.
    discrete : bool
    kappa : float
    extra : int
        Degrees added to every ``m``.
    what : str
        For the MemoryError's message.

    Returns
    -------
    BoxSolution, or str saying why there is no solution (clarabel missing,
    solver failure).
    """
    import clarabel
    import scipy.sparse as sp

    n = next(iter(cases[0][0].values())).shape[0]
    q = 2 * n if discrete else n
    deg_a = max(_degree(A) for A, _ in cases)
    size = program_size(n, n_params, deg_a, deg_p, discrete, extra, len(cases))
    check_size(size, what)
    p_exps = monomials(deg_p, n_params)
    ineqs = [_Ineq(A, np.asarray(v, dtype=float), True) for A, v in cases]
    if deg_p > 0:
        ineqs.append(_Ineq({}, np.zeros(n_params), False))
    nPb = n * (n + 1) // 2
    n_pvar = nPb * len(p_exps)
    pi, pj = _svec_index(n)
    units = np.zeros((nPb, n, n))
    cols = np.arange(nPb)
    units[cols, pi, pj] = np.where(pi == pj, 1.0, 1.0 / np.sqrt(2.0))
    units[cols, pj, pi] = units[cols, pi, pj]

    rows_i: list[NDArray] = []
    cols_i: list[NDArray] = []
    vals: list[NDArray] = []
    rhs_parts: list[NDArray] = []
    gram_specs: list[tuple[int, int, list[Exp], list[tuple[Exp, float]], int, int]] = []
    n_var = n_pvar
    n_row = 0
    for c, ineq in enumerate(ineqs):
        side = q if ineq.lyapunov else n
        deg = _degree(ineq.A) + deg_p if ineq.lyapunov else deg_p
        m = ceil(deg / 2) + extra
        exps = monomials(2 * m, n_params)
        index = {e: i for i, e in enumerate(exps)}
        ui, uj = _svec_index(side)
        nu = ui.size
        row_of = np.full((side, side), -1)
        row_of[ui, uj] = np.arange(nu)
        row_of[uj, ui] = np.arange(nu)
        # P's part: each unknown's coefficient matrices, one unit at a time.
        for bi, b in enumerate(p_exps):
            one = {b: np.zeros((n, n))}
            for u in range(nPb):
                one[b] = units[u]
                if ineq.lyapunov:
                    terms = lyapunov_terms(ineq.A, one, ineq.rates, discrete)
                else:
                    terms = {b: units[u]}
                for e, M in terms.items():
                    nz = np.nonzero(M[ui, uj])[0]
                    rows_i.append(n_row + index[e] * nu + nz)
                    cols_i.append(np.full(nz.size, bi * nPb + u))
                    vals.append(M[ui[nz], uj[nz]])
        rhs = np.zeros(len(exps) * nu)
        diag = np.nonzero(ui == uj)[0]
        if ineq.lyapunov:
            rows_i.append(n_row + diag)
            cols_i.append(np.full(diag.size, -1))  # eps, placed last below
            vals.append(-np.ones(diag.size))
        else:
            rhs[diag] = 1.0  # P(t) - I
        rhs_parts.append(rhs)
        for Z, weight in _grams(m, n_params):
            size = side * len(Z)
            gi, gj = _svec_index(size)
            val = np.where(gi == gj, 1.0, 1.0 / np.sqrt(2.0))
            zi, a_in = np.divmod(gi, side)
            zj, b_in = np.divmod(gj, side)
            mult = np.where(gi == gj, 1.0, np.where(a_in == b_in, 2.0, 1.0))
            rows = row_of[a_in, b_in]
            for e, coef in weight:
                pairs = zip(zi, zj, strict=True)
                mono = np.array([index[_add(_add(Z[x], Z[y]), e)] for x, y in pairs])
                rows_i.append(n_row + mono * nu + rows)
                cols_i.append(n_var + np.arange(gi.size))
                vals.append(-coef * val * mult)
            gram_specs.append((c, n_var, Z, weight, size, side))
            n_var += gi.size
        n_row += len(exps) * nu
    i_eps = n_var
    n_var += 1
    cols_all = np.concatenate(cols_i)
    cols_all[cols_all == -1] = i_eps
    Aeq = sp.csc_matrix(
        (np.concatenate(vals), (np.concatenate(rows_i), cols_all)), shape=(n_row, n_var)
    )
    blocks = [Aeq]
    b = [np.concatenate(rhs_parts)]
    cones: list[Any] = [clarabel.ZeroConeT(n_row)]
    I_n = _svec(np.eye(n))

    def select(start: int, count: int, sign: float) -> Any:
        return sp.csc_matrix(
            (np.full(count, sign), (np.arange(count), start + np.arange(count))),
            shape=(count, n_var),
        )

    for bi, _ in enumerate(p_exps):
        blocks.append(select(bi * nPb, nPb, 1.0))  # kappa I - P_b >= 0
        b.append(kappa * I_n)
        cones.append(clarabel.PSDTriangleConeT(n))
        if deg_p == 0:  # P - I >= 0
            blocks.append(select(0, nPb, -1.0))
            b.append(-I_n)
            cones.append(clarabel.PSDTriangleConeT(n))
        elif bi > 0:  # P_b + kappa I >= 0
            blocks.append(select(bi * nPb, nPb, -1.0))
            b.append(kappa * I_n)
            cones.append(clarabel.PSDTriangleConeT(n))
    for _, start, _, _, size, _ in gram_specs:
        count = size * (size + 1) // 2
        blocks.append(select(start, count, -1.0))
        b.append(np.zeros(count))
        cones.append(clarabel.PSDTriangleConeT(size))
    qvec = np.zeros(n_var)
    qvec[i_eps] = -1.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solver = clarabel.DefaultSolver(
        sp.csc_matrix((n_var, n_var)),
        qvec,
        sp.vstack(blocks).tocsc(),
        np.concatenate(b),
        cones,
        settings,
    )
    sol = solver.solve()
    status = str(sol.status)
    x = np.asarray(sol.x, dtype=float)
    if x.size != n_var or not np.all(np.isfinite(x)):
        return f"the solver stopped with status {status} and no finite solution"
    P = {e: _mat(x[i * nPb : (i + 1) * nPb], n) for i, e in enumerate(p_exps)}
    eps = float(x[i_eps])
    return _check(ineqs, P, x, eps, gram_specs, discrete, status)


def _check(
    ineqs: list[_Ineq],
    P: dict[Exp, NDArray[np.float64]],
    x: NDArray[np.float64],
    eps: float,
    gram_specs: list[Any],
    discrete: bool,
    status: str,
) -> BoxSolution:
    """The bounds of the module notes, recomputed from ``P``, ``eps`` and the Gram matrices."""
    n = next(iter(P.values())).shape[0]
    mu = np.inf
    mu_p = float(np.linalg.eigvalsh(P[next(iter(P))])[0]) if len(P) == 1 else np.inf
    worst_res = 0.0
    for c, ineq in enumerate(ineqs):
        if ineq.lyapunov:
            F = lyapunov_terms(ineq.A, P, ineq.rates, discrete)
            side = 2 * n if discrete else n
            zero = next(iter(ineq.A))
            shift = eps
        else:
            F = {e: M.copy() for e, M in P.items()}
            side = n
            zero = next(iter(P))
            shift = 1.0
        zero = tuple(0 for _ in zero)
        F[zero] = F.get(zero, np.zeros((side, side))) - shift * np.eye(side)
        bound = shift
        for cc, start, Z, weight, size, _ in gram_specs:
            if cc != c:
                continue
            Q = _mat(x[start : start + size * (size + 1) // 2], size)
            for e, M in _gram_terms(Q, Z, weight, side).items():
                F[e] = F.get(e, np.zeros((side, side))) - M
            bound -= len(Z) * max(0.0, -float(np.linalg.eigvalsh(Q)[0]))
        res = float(sum(np.linalg.norm(M, 2) for M in F.values()))
        worst_res = max(worst_res, res)
        bound -= res
        if ineq.lyapunov:
            mu = min(mu, bound)
        else:
            mu_p = bound
    return BoxSolution(
        P=P, eps=eps, mu=float(mu), mu_p=float(mu_p), residual=worst_res, status=status
    )
