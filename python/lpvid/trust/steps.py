"""What :func:`lpvid.identify` adds for trust: stable replacements, refit, covariance, stability."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from lpvid.data import FrfData
from lpvid.errors import ConvergenceWarning
from lpvid.layout import fixed_mask
from lpvid.model import LpvModel
from lpvid.results import FitResult
from lpvid.trust.covariance import Covariance, covariance
from lpvid.trust.enforce import STABLE_TOL, stabilised
from lpvid.trust.refit import dropped_mask, refit
from lpvid.trust.stability import StabilityReport, format_p, stability

__all__ = ["Finish", "finish", "identify_range", "stable_fit", "trust_lines"]


def identify_range(model: LpvModel, data: FrfData) -> Any:
    """The range the pipeline's stability statements cover: the model's, else the data's."""
    return model.p_range if model.p_range is not None else data.p_range


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
    closer to the boundary than :data:`lpvid.trust.enforce.STABLE_TOL`),
    it is made stable (:func:`lpvid.trust.enforce.stabilised`) and refitted
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
    """What :func:`finish` adds to the chosen model."""

    model: LpvModel
    refit: FitResult | None
    fixed: np.ndarray
    covariance: Covariance
    stability: StabilityReport


def finish(
    model: LpvModel,
    gamma: float,
    data: FrfData,
    fixed: Any,
    threshold: float,
    do_refit: bool,
    stable: bool,
    p_range: Any,
    time_data: Any = None,
) -> Finish:
    """Refit the chosen model on its support (for gamma > 0), its covariance and stability.

    With ``time_data`` the refit minimises the sum of the FRF and time costs;
    the covariance is that of the FRF fit alone.

    Warns (:class:`lpvid.ConvergenceWarning`) when the final model has
    unstable frozen models on the range.
    """
    refitted = None
    if do_refit and gamma > 0:
        refitted, held = refit(
            model,
            data,
            fixed,
            threshold=threshold,
            p_range=p_range,
            stable=stable,
            warn=False,
            time_data=time_data,
        )
        model = refitted.model
    else:
        held = fixed_mask(model, fixed) | dropped_mask(model, threshold, p_range)
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
        refit=refitted,
        fixed=held,
        covariance=covariance(model, data, held, warn=False),
        stability=report,
    )


def refit_line(entry: Any, refit_entry: Any) -> str:
    """One line on the refit: V_NLS (and validation V_NLS) of the path entry and of its refit."""
    line = (
        f"refit on the support (dropped groups fixed at zero): V_NLS {entry.vnls:.6g} -> "
        f"{refit_entry.vnls:.6g}"
    )
    before, after = entry.validation_vnls, refit_entry.validation_vnls
    if before is not None and after is not None:
        line += f"; validation V_NLS {before:.6g} -> {after:.6g}"
    return line


def trust_lines(
    entry: Any, refit_entry: Any, cov: Covariance | None, report: StabilityReport | None
) -> list[str]:
    """Summary lines of :meth:`lpvid.IdentifyResult.summary` on the refit, covariance, stability."""
    lines = []
    if refit_entry is not None:
        lines.append(refit_line(entry, refit_entry))
    if cov is not None and cov.n_unidentified:
        lines.append(
            f"covariance: rank {cov.rank}; {cov.n_unidentified} parameter direction(s) leave "
            "the FRF at every identification point unchanged (the data cannot tell them "
            "apart) and are left out: between the points the band may be too narrow"
        )
    if report is not None:
        lines.append(report.summary().splitlines()[0])
    return lines
