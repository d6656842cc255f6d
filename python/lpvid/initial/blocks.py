"""Starts in block-diagonal (modal) form, held through every fit: the blocks route.

A frozen model with distinct poles is, in its own modal coordinates, a set
of modes: ``A`` block diagonal (a 2 x 2 block per complex pole pair, real
poles two to a block), ``B`` and ``C`` the modes' input and output shapes.
An LPV model in that form, ``A(p)`` block diagonal at every ``p`` and
``B(p)``, ``C(p)`` full, describes modes whose frequency and damping move
with the scheduling and whose shapes change: the usual physics of
mechanical and electrical systems, without the couplings between modes
that a full ``A(p)`` can hold and that no frozen FRF shows. Those couplings
are what the measured points leave open when they are few
(:mod:`lpvid.trust.silent`): holding the form removes them, so that few
points determine the model between them. The form is held by fixing every
entry of every ``A(i)`` outside the blocks at zero: a structure mask,
kept by the path, the refit and the covariance.

The start is built by continuation along the scheduling: the local model
at one point in block form as a constant LPV model, fitted to that point
and its nearest neighbour with the first-degree groups free, then to one
more point at a time with the groups of each degree freed once there are
more points than functions up to that degree, and last to every point
(:func:`block_start`). It starts at the best-determined point
(:func:`lpvid.initial.best_determined`) and at the ends of the range; each
is a :class:`~lpvid.initial.Candidate` named ``"blocks:<q>"`` (``q`` the
index of its first point) with its :attr:`~lpvid.initial.Candidate.structure`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._spread import Piece, Spread
from lpvid._threads import single_blas
from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData
from lpvid.data.schedule import model_range, range_fraction, range_pairs
from lpvid.fit.fits import fit_nls, raise_if_interrupted
from lpvid.fit.results import FitResult
from lpvid.fit.settings import START_FTOL
from lpvid.initial.candidates import Candidate, fitted_candidate
from lpvid.initial.continuation import best_determined
from lpvid.initial.globalstart import _group_mask, degree_levels
from lpvid.initial.localmodels import LocalModels
from lpvid.model.layout import fixed_mask, strictly_proper
from lpvid.model.lpv import LpvModel

__all__ = [
    "BlockPieces",
    "block_form",
    "block_start",
    "block_structure",
    "hand_out_blocks",
    "start_points",
]

#: Largest condition number of the modal transformation for which a local
#: model is put in block form (beyond it, poles too close to tell apart).
MAX_CONDITION = 1e10


def block_form(
    A: NDArray[np.float64], B: NDArray[np.float64], C: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], list[int]]:
    """An LTI model in real block-diagonal (modal) form, and its block sizes.

    Complex pole pairs get a 2 x 2 block each (``[[a, b], [-b, a]]`` from the
    real and imaginary parts of the eigenvector), real poles share 2 x 2
    diagonal blocks two by two (one alone when their number is odd), each
    kind from the slowest pole on.

    Raises
    ------
    ValueError
        When the eigenvectors are too ill-conditioned (:data:`MAX_CONDITION`).
    """
    lam, V = np.linalg.eig(A)
    order = np.argsort(np.abs(lam), kind="stable")
    complex_cols: list[NDArray] = []
    real_cols: list[NDArray] = []
    for k in order:
        if lam[k].imag > 0:
            v = V[:, k] / np.linalg.norm(V[:, k])
            complex_cols += [v.real, v.imag]
        elif lam[k].imag == 0:
            real_cols.append(V[:, k].real / np.linalg.norm(V[:, k].real))
    sizes = (
        [2] * (len(complex_cols) // 2) + [2] * (len(real_cols) // 2) + [1] * (len(real_cols) % 2)
    )
    T = np.array(complex_cols + real_cols).T
    if T.shape != A.shape or not np.all(np.isfinite(T)) or np.linalg.cond(T) > MAX_CONDITION:
        raise ValueError("the local model's modes are too close to put it in block form")
    Ti = np.linalg.inv(T)
    Ab = Ti @ A @ T
    mask = _off_blocks(sizes)
    Ab[mask] = 0.0  # rounding outside the blocks
    return Ab, Ti @ B, C @ T, sizes


def _off_blocks(sizes: Sequence[int]) -> NDArray[np.bool_]:
    n = int(sum(sizes))
    out = np.ones((n, n), dtype=bool)
    k = 0
    for s in sizes:
        out[k : k + s, k : k + s] = False
        k += s
    return out


def block_structure(model: LpvModel, sizes: Sequence[int], fixed: Any = None) -> NDArray[np.bool_]:
    """The fixed mask that holds ``model`` in block form: ``fixed`` and all off the blocks."""
    off = np.broadcast_to(_off_blocks(sizes), model.A.shape)
    return fixed_mask(model, fixed) | fixed_mask(model, {"A": off})


def _allowed(levels: Sequence[int], k: int) -> set[int]:
    """The basis functions (0-based) free with ``k`` points.

    Every one up to the highest degree whose functions (with the constant)
    are no more than the points.
    """
    allowed: list[int] = []
    for level in sorted(set(levels)):
        upto = [j for j, d in enumerate(levels) if d <= level]
        if len(upto) + 1 <= k:
            allowed = upto
    return set(allowed)


def _scaled_points(data: FrfData, model: LpvModel) -> NDArray[np.float64]:
    """The data's points as fractions of the model's range, on the basis's scales."""
    rng = model.p_range if model.p_range is not None else data.p_range
    pairs = range_pairs(rng, model.basis.n_params)
    return range_fraction(data.p_rows, pairs, model.basis.scales)


def block_start(
    data: FrfData,
    basis: Basis,
    fixed: Any,
    local: LocalModels,
    point: int,
    *,
    max_iter: int = 100,
    ftol: float = START_FTOL,
) -> tuple[FitResult, NDArray[np.bool_], LpvModel]:
    """The block-form start from the local model at ``point`` (module notes).

    Returns
    -------
    fit : FitResult
        The last fit, on every point.
    structure : ndarray of bool
        The fixed mask that holds the block form (``fixed`` included).
    start : LpvModel
        The local model in block form as a constant LPV model.

    Raises
    ------
    ValueError
        When the local model cannot be put in block form.
    """
    lm = local[point]
    A, B, C, sizes = block_form(lm.A[0], lm.B[0], lm.C[0])
    nb = len(basis)

    def constant(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.concatenate([x[None], np.zeros((nb, *x.shape))])

    start = LpvModel(
        constant(A),
        constant(B),
        constant(C),
        constant(lm.D[0]),
        basis=basis,
        Ts=data.Ts,
        p_range=model_range(data.p),
    )
    structure = block_structure(start, sizes, fixed)
    where = _scaled_points(data, start)
    order = np.argsort(np.linalg.norm(where - where[point], axis=1), kind="stable")
    model = start
    for k in range(2, data.n_points):
        allowed = _allowed(degree_levels(basis), k)
        held = structure | _group_mask(model, [i + 1 for i in range(nb) if i not in allowed])
        subset = data.subset(sorted(int(q) for q in order[:k]))
        fit = fit_nls(model, subset, held, max_iter=max_iter, ftol=ftol, warn=False)
        model = raise_if_interrupted(fit).model
    fit = raise_if_interrupted(
        fit_nls(model, data, structure, max_iter=max_iter, ftol=ftol, warn=False)
    )
    fit.model.info.update({"method": "blocks", "point": int(point), "sizes": list(sizes)})
    return fit, structure, start


def start_points(data: FrfData, local: LocalModels, fixed: Any) -> list[int]:
    """The points the blocks route starts from: the best-determined one and the ends of the range.

    The ends: the points of the smallest and the largest first scheduling parameter.
    """
    proper = {"D": True} if strictly_proper(fixed) else None
    first = data.p_rows[:, 0]
    best = best_determined(local, data, fixed=proper) if len(local) > 1 else 0
    out: list[int] = []
    for q in (best, int(np.argmin(first)), int(np.argmax(first))):
        if q not in out:
            out.append(q)
    return out


@dataclass
class BlockPieces:
    """The blocks route's fits handed out (:func:`hand_out_blocks`): to take, or to drop."""

    spread: Spread
    pieces: list[Piece]
    #: What each piece's ``after`` made of its candidates (:func:`hand_out_blocks`),
    #: merged once taken.
    after: dict[str, Any] = field(default_factory=dict)

    def take(self) -> list[Candidate]:
        """The candidates, in the order of their start points (waiting for them)."""
        out = []
        for found, made in self.spread.take_all(self.pieces):
            out += found
            self.after.update(made)
        return out

    def drop(self) -> None:
        """Drop the fits not taken (:meth:`lpvid._spread.Spread.drop`)."""
        self.spread.drop()


def hand_out_blocks(
    data: FrfData,
    basis: Basis,
    fixed: Any,
    local: LocalModels,
    *,
    validation: FrfData | None = None,
    points: Sequence[int] | None = None,
    max_iter: int = 100,
    ftol: float = START_FTOL,
    executor: Executor | None = None,
    pieces: int | None = None,
    after: Callable[[list[Candidate]], dict[str, Any]] | None = None,
) -> BlockPieces:
    """The blocks route's candidates, one per start point (module notes), handed out now.

    A point whose local model cannot be put in block form gives no
    candidate. ``pieces``: into how many pieces the start points are cut
    (neighbours in their order, fitted one after the other in a piece;
    None: one piece per point), side by side on ``executor`` (see
    :func:`lpvid.identify`; without one each piece runs when taken), the
    candidates the same either way. ``.take()`` waits for them;
    :func:`lpvid.identify` hands them out before its main path, whose
    outcome decides whether it takes them or drops them
    (:func:`lpvid.pipeline.opening.open_routes`). ``after``: run in each
    piece on its candidates once fitted (the work likely wanted next, done
    where the piece runs); what it returns is merged into
    :attr:`BlockPieces.after` when taken.
    """
    where = [int(q) for q in (start_points(data, local, fixed) if points is None else points)]
    cut = len(where) if pieces is None else max(1, min(pieces, len(where)))
    groups = [where[k * len(where) // cut : (k + 1) * len(where) // cut] for k in range(cut)]
    how = (basis, fixed, local, validation, max_iter, ftol)
    spread = Spread(executor)
    return BlockPieces(
        spread, spread.hand_out(_block_candidates_at, [(data, g, after, *how) for g in groups])
    )


@single_blas
def _block_candidates_at(
    data: FrfData,
    points: Sequence[int],
    after: Callable[[list[Candidate]], dict[str, Any]] | None,
    *how: Any,
) -> tuple[list[Candidate], dict[str, Any]]:
    """The blocks route's candidates from ``points``, one after the other, and ``after`` of them.

    ``how``: the rest of :func:`_block_candidate`'s arguments.
    """
    found = [c for c in (_block_candidate(data, q, *how) for q in points) if c is not None]
    return found, ({} if after is None or not found else after(found))


def _block_candidate(
    data: FrfData,
    point: int,
    basis: Basis,
    fixed: Any,
    local: LocalModels,
    validation: FrfData | None,
    max_iter: int,
    ftol: float,
) -> Candidate | None:
    """The blocks route's candidate from one point, None when its model has no block form."""
    t0 = time.perf_counter()
    try:
        fit, structure, start = block_start(
            data, basis, fixed, local, point, max_iter=max_iter, ftol=ftol
        )
    except ValueError:
        return None
    note = (
        f"local model {point} in block (modal) form, fitted by continuation along the "
        "scheduling with the form held"
    )
    seconds = time.perf_counter() - t0
    return fitted_candidate(
        f"blocks:{point}",
        fit,
        start,
        data,
        validation,
        seconds=seconds,
        note=note,
        structure=structure,
    )
