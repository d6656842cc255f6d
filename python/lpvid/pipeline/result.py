"""What :func:`lpvid.identify` returns: the models of the path and the choice among them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from lpvid.data.frf import FrfData
from lpvid.fit.cost import vnls
from lpvid.fit.results import FitResult, PathResult
from lpvid.fit.timecost import TimeCost, total_vnls
from lpvid.initial.candidates import Candidate
from lpvid.initial.localmodels import LocalModels
from lpvid.model.lpv import LpvModel
from lpvid.pipeline.between import Between
from lpvid.stable.scan import StabilityReport
from lpvid.trust.steps import trust_lines
from lpvid.trust.uncertainty import Covariance

if TYPE_CHECKING:
    from lpvid.pipeline.problem import Problem

__all__ = ["IdentifyResult", "PathEntry", "path_entry"]


@dataclass
class PathEntry:
    """One model of the accuracy-versus-simplicity curve.

    Attributes
    ----------
    gamma : float
        Regularisation weight (0 for the unregularised model).
    model : LpvModel
    vnls, noise_floor : float, int
        V_NLS on the identification data and its noise floor.
    validation_vnls, validation_floor : float or None, int or None
        The same on the validation data, when given.
    n_groups : int
        Groups kept (relative magnitude above the threshold).
    nonzero_groups : dict
        Basis indices kept per matrix.
    seconds : float
        Time the fit took.
    converged : bool
        Whether the fit met a convergence test (False: it stopped at its
        iteration limit; :attr:`message` says so).
    message : str
        Why the fit stopped.
    pinned : bool
        Whether the fit kept its steps off the directions that are flat at
        the data (``fit_l21(..., pinned=True)``, see :mod:`lpvid.pipeline.path`).
    """

    gamma: float
    model: LpvModel
    vnls: float
    noise_floor: int
    validation_vnls: float | None
    validation_floor: int | None
    n_groups: int
    nonzero_groups: dict[str, list[int]]
    seconds: float
    converged: bool = True
    message: str = ""
    pinned: bool = False


@dataclass
class IdentifyResult:
    """Outcome of :func:`identify`.

    Attributes
    ----------
    model : LpvModel
        The model of the chosen entry, or its refit on the support when
        validation data show that the refit interpolates better
        (:attr:`refitted`; see :func:`lpvid.trust.support.judged_refit`).
        It never validates worse than the chosen entry.
    chosen : int
        The chosen entry's index in :attr:`entries`.
    reason : str
        Why it was chosen, and whether it was refitted.
    entries : list of PathEntry
        The unregularised model (gamma = 0) and the model kept at every
        gamma of the l2,1 path, with V_NLS, groups kept and timings.
    initial : LpvModel
        The model the unregularised fit started from (for a SMILE start,
        the SMILE model with its coherent form in ``info["form"]``).
    start : str
        Name of the chosen start (route and form, e.g. ``"smile:modal"``,
        ``"continuation+smile:observability"``, ``"global:all"``).
    candidates : list of lpvid.initial.Candidate
        Every initial model tried, refined by fit_nls.
    initial_reason : str
        Why that starting point was chosen.
    local : LocalModels
        The local LTI models.
    nls : FitResult
        The unregularised fit.
    path : PathResult
        The l2,1 fits kept along the path (one per gamma; see
        :mod:`lpvid.pipeline.path` for when a fit is pinned).
    data, validation : FrfData, FrfData or None
        The data used.
    time_data : TimeCost or None
        The time records fitted beside the FRF data, when given: then the
        unregularised fit, the path, V_NLS and the noise floors of
        :attr:`entries` are those of both costs summed.
    timings : dict
        Seconds per stage: ``"local_s"`` (the plain local models),
        ``"smile_s"`` (every route to an initial model, not SMILE alone:
        the SMILE models from the plain local models, the local models by
        continuation and their SMILE models, the global starts, the race
        of all the starts by Levenberg-Marquardt and the choice of one),
        ``"nls_s"`` (the
        chosen start's fits, within ``"smile_s"``), ``"path_s"``,
        ``"few_points_s"`` (without validation data, the count of what the
        points leave open, and the other routes when they leave the model
        open or it is a misfit: :mod:`lpvid.pipeline.fewpoints`),
        ``"finish_s"`` (the refit, the covariance and the stability of the
        model returned), ``"total_s"``.
    refit : FitResult or None
        The chosen model refitted by Levenberg-Marquardt with its dropped
        groups fixed at zero (``identify(..., refit=True)``, for a chosen
        gamma > 0 and with validation data), kept or not.
    refit_entry : PathEntry or None
        V_NLS (and validation V_NLS) of that refit.
    refitted : bool
        Whether :attr:`model` is the refit.
    covariance : Covariance or None
        First-order parameter covariance of :attr:`model` (dropped groups
        and fixed parameters held): FRF bands through
        ``covariance.frf_std(freqs_hz, p)``.
    stability : StabilityReport or None
        Stability of the frozen models of :attr:`model` over the scheduling
        range (the model's, else the data's); ``lpvid.stability(result.model)``
        adds the quadratic (common Lyapunov) test.
    between : Between or None
        What the measured points leave open between them: how many
        directions of :attr:`model`'s structure they do not see (and how
        many more points would), the other fits within the noise, and a
        spread between the points (:class:`lpvid.pipeline.between.Between`).
    problem : Problem or None
        The checked problem identified (data, order, basis, fixed
        parameters, settings): what :func:`lpvid.resampled` identifies
        again on simulated data. None in a result made by hand.
    """

    model: LpvModel
    chosen: int
    reason: str
    entries: list[PathEntry]
    initial: LpvModel
    start: str
    candidates: list[Candidate]
    initial_reason: str
    local: LocalModels
    nls: FitResult
    path: PathResult
    data: FrfData
    validation: FrfData | None
    timings: dict[str, float] = field(default_factory=dict)
    time_data: TimeCost | None = None
    refit: FitResult | None = None
    refit_entry: PathEntry | None = None
    refitted: bool = False
    covariance: Covariance | None = None
    stability: StabilityReport | None = None
    between: Between | None = None
    problem: Problem | None = field(default=None, repr=False)

    @property
    def entry(self) -> PathEntry:
        """The chosen entry."""
        return self.entries[self.chosen]

    @property
    def final(self) -> PathEntry:
        """The entry of :attr:`model`: the refit when it was kept, else the chosen entry."""
        return self.refit_entry if self.refitted and self.refit_entry is not None else self.entry

    def table(self) -> str:
        """The accuracy-versus-simplicity table, the chosen model marked."""
        val = self.validation is not None
        head = f"{'':2}{'gamma':>9} {'groups':>6} {'V_NLS':>11} {'V/floor':>8}"
        if val:
            head += f" {'val V_NLS':>11} {'val/floor':>9}"
        lines = [head]
        for k, e in enumerate(self.entries):
            mark = "->" if k == self.chosen else ""
            line = (
                f"{mark:2}{e.gamma:9.3g} {e.n_groups:6d} {e.vnls:11.5g} "
                f"{e.vnls / e.noise_floor:8.4f}"
            )
            if val and e.validation_vnls is not None and e.validation_floor:
                line += f" {e.validation_vnls:11.5g} {e.validation_vnls / e.validation_floor:9.4f}"
            if e.pinned:
                line += "  (pinned)"
            if not e.converged:
                line += "  (iteration limit)"
            lines.append(line)
        return "\n".join(lines)

    def summary(self) -> str:
        """A few lines for people."""
        e = self.final
        lines = [
            f"start: {self.start} ({self.initial_reason})",
            *(
                []
                if self.time_data is None
                else [
                    f"data: FRFs at {self.data.n_points} points and "
                    f"{self.time_data.data.n_records} time record(s); V_NLS and the noise "
                    "floor below are the sums of both costs"
                ]
            ),
            f"chosen: gamma = {e.gamma:g}, {e.n_groups} groups kept "
            f"(the start uses {self.initial.group_norms().count()}); {self.reason}",
            f"V_NLS = {e.vnls:.6g} on identification data (noise floor {e.noise_floor}, "
            f"ratio {e.vnls / e.noise_floor:.3f})",
        ]
        if e.validation_vnls is not None and e.validation_floor:
            lines.append(
                f"V_NLS = {e.validation_vnls:.6g} on validation data (noise floor "
                f"{e.validation_floor}, ratio {e.validation_vnls / e.validation_floor:.3f})"
            )
        lines += trust_lines(
            self.entry, self.refit_entry, self.refitted, self.covariance, self.stability
        )
        if self.between is not None:
            lines += self.between.summary().splitlines()
        lines.append(f"time: {self.timings.get('total_s', float('nan')):.2f} s")
        return "\n".join(lines)

    def __repr__(self) -> str:
        e = self.entry
        return (
            f"IdentifyResult(gamma={e.gamma:g}, groups={e.n_groups}, "
            f"V/floor={e.vnls / e.noise_floor:.3f})"
        )


def path_entry(
    gamma: float,
    fit: FitResult,
    data: FrfData,
    validation: FrfData | None,
    threshold: float,
    time_cost: TimeCost | None = None,
    *,
    pinned: bool = False,
) -> PathEntry:
    """The entry of ``fit`` (at ``gamma``) for the table of :func:`lpvid.identify`."""
    model = fit.model
    norms = model.group_norms()
    time_floor = 0 if time_cost is None else time_cost.n_residuals
    return PathEntry(
        gamma=float(gamma),
        model=model,
        vnls=total_vnls(model, data, time_cost),
        noise_floor=data.n_residuals + time_floor,
        validation_vnls=None if validation is None else vnls(model, validation),
        validation_floor=None if validation is None else validation.n_residuals,
        n_groups=norms.count(threshold),
        nonzero_groups=norms.nonzero(threshold),
        seconds=float(fit.timings["total_s"]),
        converged=fit.converged,
        message=fit.message,
        pinned=pinned,
    )
