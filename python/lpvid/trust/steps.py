"""What :func:`lpvid.identify` adds for trust: stable replacements, refit, covariance, stability."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from lpvid.data.frf import FrfData
from lpvid.errors import ConvergenceWarning
from lpvid.fit.results import FitResult
from lpvid.model.layout import fixed_mask
from lpvid.model.lpv import LpvModel
from lpvid.stable.enforce import STABLE_TOL, stabilised
from lpvid.stable.scan import StabilityReport, format_p, stability
from lpvid.trust.support import Judged, dropped_mask, judged_refit, refit
from lpvid.trust.uncertainty import Covariance, covariance

__all__ = ["Finish", "finish", "stable_fit", "trust_lines"]


def stable_fit(
    fit: FitResult,
    data: FrfData,
    fixed: Any,
    threshold: float,
    p_range: Any,
    time_data: Any = None,
) -> FitResult:
    """``fit``, or for ``identify(..., stable=True)`` a stable replacement.

    When the fitted model has unstable frozen models on the range (or is
    closer to the boundary than :data:`lpvid.stable.enforce.STABLE_TOL`),
    it is made stable (:func:`lpvid.stable.enforce.stabilised`) and refitted
    on its support (its dropped groups fixed at zero) with stability kept.
    """
    rep = stability(fit.model, p_range, quadratic=False)
    if rep.stable and rep.margin >= STABLE_TOL:
        return fit
    start = stabilised(fit.model, p_range)
    out, _ = refit(
        start,
        data,
        fixed,
        threshold=threshold,
        p_range=p_range,
        stable=True,
        warn=False,
        time_data=time_data,
    )
    return out


@dataclass
class Finish:
    """What :func:`finish` adds to the chosen model.

    Attributes
    ----------
    model : LpvModel
        The model :func:`lpvid.identify` returns.
    refit : FitResult or None
        The refit on the support, kept or not (None when none was run).
    refitted : bool
        Whether :attr:`model` is that refit.
    note : str
        What was done about the refit, and why.
    fixed : ndarray of bool
        The parameters held in :attr:`model` (fixed ones and dropped groups).
    covariance : Covariance
        Of :attr:`model`, linearised on its support.
    stability : StabilityReport
        Of :attr:`model`'s frozen models over the range.
    """

    model: LpvModel
    refit: FitResult | None
    refitted: bool
    note: str
    fixed: np.ndarray
    covariance: Covariance
    stability: StabilityReport


def finish(
    model: LpvModel,
    gamma: float,
    data: FrfData,
    fixed: Any,
    threshold: float,
    *,
    validation: FrfData | None = None,
    validation_vnls: float | None = None,
    do_refit: bool = True,
    stable: bool = False,
    p_range: Any = None,
    time_data: Any = None,
) -> Finish:
    """The returned model (for gamma > 0 the judged refit), its covariance and stability.

    The refit on the support is run and kept as :func:`lpvid.trust.support.judged_refit`
    decides (with ``time_data`` it minimises the sum of the FRF and time
    costs). The covariance (that of the FRF fit alone) and the stability
    report describe the model returned, linearised on its support.

    Warns (:class:`lpvid.ConvergenceWarning`) when that model has unstable
    frozen models on the range.
    """
    if do_refit and gamma > 0:
        judged = judged_refit(
            model,
            data,
            validation,
            fixed,
            validation_vnls=validation_vnls,
            threshold=threshold,
            p_range=p_range,
            stable=stable,
            warn=False,
            time_data=time_data,
        )
    else:
        held = fixed_mask(model, fixed) | dropped_mask(model, threshold, p_range)
        why = "unregularised model chosen" if gamma == 0 else "refit=False"
        judged = Judged(model, None, False, held, f"not refitted ({why})")
    model = judged.model
    report = stability(model, p_range, quadratic=False)
    if not report.stable:
        warnings.warn(
            f"the chosen model has unstable frozen models on the scheduling range (at p = "
            f"{format_p(report.worst_p)}, margin {report.margin:.3g}); identify(..., stable=True) "
            "keeps them stable",
            ConvergenceWarning,
            stacklevel=3,
        )
    return Finish(
        model=model,
        refit=judged.fit,
        refitted=judged.kept,
        note=judged.note,
        fixed=judged.held,
        covariance=covariance(model, data, judged.held, warn=False),
        stability=report,
    )


def refit_line(entry: Any, refit_entry: Any, kept: bool) -> str:
    """One line on the refit: V_NLS (and validation V_NLS) of the path entry and of its refit."""
    line = (
        f"refit on the support (dropped groups fixed at zero): V_NLS {entry.vnls:.6g} -> "
        f"{refit_entry.vnls:.6g}"
    )
    before, after = entry.validation_vnls, refit_entry.validation_vnls
    if before is not None and after is not None:
        line += f"; validation V_NLS {before:.6g} -> {after:.6g}"
    return line + ("; kept" if kept else "; not kept, the path's model returned")


def trust_lines(
    entry: Any,
    refit_entry: Any,
    kept: bool,
    cov: Covariance | None,
    report: StabilityReport | None,
) -> list[str]:
    """Summary lines of :meth:`lpvid.IdentifyResult.summary` on the refit, covariance, stability."""
    lines = []
    if refit_entry is not None:
        lines.append(refit_line(entry, refit_entry, kept))
    if cov is not None and cov.n_unidentified:
        lines.append(
            f"covariance: rank {cov.rank}; {cov.n_unidentified} parameter direction(s) leave "
            "the FRF at every identification point unchanged (the data cannot tell them "
            "apart) and are left out: between the points the band may be too narrow"
        )
    if report is not None:
        lines.append(report.summary().splitlines()[0])
    return lines
