"""The choice of a start among the refined initial candidates."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from lpvid._checks import positive_float
from lpvid.fit.judge import VALIDATION_TIE, noise_slack, simplest, tied
from lpvid.initial.candidates import Candidate

__all__ = ["choose"]


def choose(
    candidates: Sequence[Candidate], tolerance: float = VALIDATION_TIE
) -> tuple[Candidate, str]:
    """The best initial candidate, and why.

    Only the candidates refined to convergence (:attr:`Candidate.refined`:
    not dropped by the race of the starts) whose frozen models are stable
    between the points (:attr:`Candidate.stable`) take part, when there are
    any: a model that
    fits the points and goes unstable between them is rarely what the data
    mean, however it fares at a few validation points.

    With validation data (every candidate has ``validation_vnls``): the
    lowest validation V_NLS; candidates within ``tolerance`` of it count
    as equal and the simplest of them wins: the least scheduling dependence
    (:attr:`Candidate.dependence`, the sum of the relative group
    magnitudes), then the lowest validation V_NLS (:func:`lpvid.fit.judge.simplest`).

    Without: the lowest identification V_NLS, where candidates within the
    noise of the best count as equal (:func:`lpvid.fit.judge.tied`: two
    standard deviations of V_NLS, ``2 sqrt(M)``, M the number of
    residuals) and the simplest wins as above. Candidates that fit the
    points equally well can differ wildly between them (with about as many
    parameters as the frozen FRFs determine, the unregularised model is not
    fixed between the points); the one that depends least on the scheduling
    is the one the l2,1 path can simplify, and the smoothest guess.

    Parameters
    ----------
    candidates : sequence of Candidate
    tolerance : float
        Relative slack on the best validation V_NLS.

    Returns
    -------
    Candidate, str

    """
    cands = list(candidates)
    if not cands:
        raise ValueError("candidates: needs at least one candidate")
    for k, c in enumerate(cands):
        if not isinstance(c, Candidate):
            raise TypeError(f"candidates[{k}]: expected a Candidate, got {type(c).__name__}")
    tol = positive_float(tolerance, "tolerance", allow_zero=True)
    finite = [c for c in cands if np.isfinite(c.vnls)] or cands
    refined = [c for c in finite if c.refined] or finite
    pool = [c for c in refined if c.stable] or refined
    dropped = len(refined) - len(pool)
    raced = len(finite) - len(refined)
    among = (
        f" among the {len(pool)} candidates whose frozen models are stable between the "
        f"points ({dropped} left out)"
        if dropped
        else ""
    )
    if raced:
        among += f"; {raced} start(s) dropped by the race of the starts"
    if all(c.validation_vnls is not None for c in pool):
        vals = {id(c): float(c.validation_vnls) for c in pool}  # type: ignore[arg-type]
        flags = tied([vals[id(c)] for c in pool], pool[0].validation_floor or 1, tol)
        ties = [c for c, f in zip(pool, flags, strict=True) if f]
        pick = ties[simplest([c.dependence for c in ties], [vals[id(c)] for c in ties])]
        reason = (
            f"lowest validation V_NLS ({vals[id(pick)]:.5g}, "
            f"{pick.validation_ratio:.3f} x its noise floor){among}"
        )
        if len(ties) > 1:
            reason += (
                f"; {len(ties)} candidates within {tol:.0%} of the best validation V_NLS, "
                f"the simplest (scheduling dependence {pick.dependence:.3g}) kept"
            )
        return pick, reason
    floor = pool[0].noise_floor
    flags = tied([c.vnls for c in pool], floor)
    ties = [c for c, f in zip(pool, flags, strict=True) if f] or pool
    pick = ties[simplest([c.dependence for c in ties], [c.vnls for c in ties])]
    reason = (
        f"no validation data; lowest identification V_NLS ({pick.vnls:.5g}, "
        f"{pick.ratio:.3f} x the noise floor){among}"
    )
    if len(ties) > 1:
        reason += (
            f"; {len(ties)} candidates within {noise_slack(floor):.3g} (2 sqrt(M)) of the "
            f"best, the simplest (scheduling dependence {pick.dependence:.3g}) kept"
        )
    return pick, reason
