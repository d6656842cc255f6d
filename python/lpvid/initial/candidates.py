"""Initial LPV models by every route, each refined by fit_nls: the candidates for a start.

SMILE (:mod:`lpvid.initial.interpolation`) trusts every local model. When modes are
heavily damped or close and the FRFs carry noise, a local model can fit its
own data at the noise floor and still have another pole structure than its
neighbours. The routes here are SMILE from the plain local models, SMILE
from local models by continuation (:mod:`lpvid.initial.continuation`) and
global starts (:mod:`lpvid.initial.globalstart`); :func:`lpvid.initial.choose`
picks one.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import positive_float, positive_int
from lpvid._threads import single_blas
from lpvid.data.basis import Basis
from lpvid.data.frf import FrfData
from lpvid.data.schedule import between_points
from lpvid.fit.cost import vnls_value as vnls
from lpvid.fit.judge import dependence
from lpvid.fit.results import FitResult
from lpvid.fit.settings import ROUTES, START_FTOL
from lpvid.initial.continuation import best_determined, continue_local
from lpvid.initial.diagnosis import Consistency, consistency
from lpvid.initial.globalstart import (
    constant_start,
    degree_levels,
    finish_global,
    global_runner,
)
from lpvid.initial.interpolation import smile_candidates
from lpvid.initial.local import check_local_order, local_models
from lpvid.initial.localmodels import LocalModels
from lpvid.initial.race import Runner, Stage, race, run_out
from lpvid.model.frozen import frozen_stable
from lpvid.model.layout import fixed_mask, strictly_proper
from lpvid.model.lpv import LpvModel

__all__ = ["ROUTES", "Candidate", "candidates_of", "fitted_candidate", "initial_candidates"]


@dataclass
class Candidate:
    """An initial LPV model refined by :func:`lpvid.fit_nls` on the identification data.

    Attributes
    ----------
    name : str
        Route and variant: ``"smile:<form>"`` (plain local models),
        ``"continuation+smile:<form>"``, ``"global:all"``, ``"global:degree"``.
    model : LpvModel
        The refined model; ``model.info`` says how its start was built.
    vnls : float
        V_NLS on the identification data.
    noise_floor : int
        Number of complex residuals of the identification data.
    validation_vnls : float or None
        V_NLS on the validation data, None without them.
    validation_floor : int or None
        Their number of complex residuals.
    seconds : float
        Time spent on this candidate (building the start and the fit; the
        local models, shared by several candidates, are not counted).
    constant_groups : int
        Groups (of 4 Nb) that the SMILE start left constant (relative
        magnitude below 1e-6, its ``info["constant_groups"]``): the
        simplicity the start offers the l2,1 path. For a global start, the
        groups still constant in the refined model (usually 0: its last
        stage frees every group).
    stable : bool
        Whether the frozen models are stable at the identification points
        and at 7 values between every two neighbouring points
        (:func:`lpvid.data.schedule.between_points`,
        :func:`lpvid.model.frozen.frozen_stable`). An LPV model that fits the
        points but has unstable frozen models between them is usually
        interpolating mismatched local models.
    dependence : float
        The refined model's scheduling dependence (the sum of its groups'
        relative magnitudes, :meth:`lpvid.model.groups.GroupNorms.dependence`):
        among candidates that fit equally well, the smaller the simpler.
    note : str
        What was done, in words.
    fit : FitResult or None
        The last :func:`lpvid.fit_nls` run (its history and timings).
    refined : bool
        Whether it was refined to convergence (or to its step limit); False
        when the race of the starts (:func:`lpvid.initial.race.race`)
        dropped it on the way, its figures then those of a partial fit.
    start : LpvModel or None
        The model that run started from: the SMILE model (with its
        ``info["form"]``), or for a global start the model before its last
        stage (for ``"global:all"``, the constant model).
    structure : ndarray of bool or None
        Parameters the candidate holds fixed beyond the problem's own
        (:mod:`lpvid.initial.blocks`: the entries of ``A`` off its blocks),
        as a fixed mask that includes the problem's; the path, the refit and
        the covariance keep it. None: only the problem's.
    """

    name: str
    model: LpvModel
    vnls: float
    noise_floor: int
    validation_vnls: float | None
    validation_floor: int | None
    seconds: float
    constant_groups: int
    stable: bool = True
    dependence: float = 0.0
    note: str = ""
    fit: FitResult | None = None
    start: LpvModel | None = None
    refined: bool = True
    structure: NDArray[np.bool_] | None = field(default=None, repr=False)

    @property
    def ratio(self) -> float:
        """V_NLS relative to the noise floor."""
        return self.vnls / self.noise_floor

    @property
    def validation_ratio(self) -> float | None:
        """Validation V_NLS relative to its noise floor (None without validation data)."""
        if self.validation_vnls is None or not self.validation_floor:
            return None
        return self.validation_vnls / self.validation_floor

    def __str__(self) -> str:
        val = self.validation_ratio
        v = "" if val is None else f", validation V/floor {val:.3f}"
        st = "" if self.stable else ", unstable between the points"
        dropped = "" if self.refined else ", dropped before convergence"
        return f"{self.name}: V/floor {self.ratio:.3f}{v}{st}{dropped}, {self.seconds:.2f} s"


def _candidate(
    runner: Runner, data: FrfData, validation: FrfData | None, seconds: float
) -> Candidate:
    """A raced runner as a candidate: its model evaluated, its start labelled."""
    fit, start = runner.fit, runner.start
    assert fit is not None and start is not None
    model = fit.model
    if model is not start and "method" not in model.info:
        # A refined SMILE model: say where it came from.
        model.info.update({"method": "fit_nls", "start": dict(start.info)})
    model.info["candidate"] = runner.name
    nb = model.n_basis
    if "constant_groups" in start.info:  # a SMILE start
        const = int(start.info["constant_groups"])
    elif nb and model.p_range is not None:
        const = 4 * nb - model.group_norms().count(1e-6)
    else:
        const = 0
    note = runner.note
    if runner.dropped is not None:
        note += f"; dropped from the race of the starts after {runner.dropped} steps"
    return Candidate(
        name=runner.name,
        model=model,
        vnls=float(fit.vnls),
        noise_floor=data.n_residuals,
        validation_vnls=None if validation is None else vnls(model, validation),
        validation_floor=None if validation is None else validation.n_residuals,
        seconds=runner.seconds + seconds,
        constant_groups=int(const),
        stable=frozen_stable(model, between_points(data.p)),
        dependence=dependence(model, data),
        note=note,
        fit=fit,
        start=start,
        refined=runner.dropped is None,
    )


def fitted_candidate(
    name: str,
    fit: FitResult,
    start: LpvModel,
    data: FrfData,
    validation: FrfData | None,
    *,
    seconds: float,
    note: str,
    structure: NDArray[np.bool_] | None = None,
) -> Candidate:
    """A candidate refined outside the race: ``fit`` from ``start``, evaluated on the data."""
    model = fit.model
    model.info["candidate"] = name
    return Candidate(
        name=name,
        model=model,
        vnls=float(fit.vnls),
        noise_floor=data.n_residuals,
        validation_vnls=None if validation is None else vnls(model, validation),
        validation_floor=None if validation is None else validation.n_residuals,
        seconds=seconds,
        constant_groups=0,
        stable=frozen_stable(model, between_points(data.p)),
        dependence=dependence(model, data),
        note=note,
        fit=fit,
        start=start,
        structure=structure,
    )


@single_blas
def initial_candidates(
    data: FrfData,
    order: int,
    basis: Basis,
    fixed: Any = None,
    validation: FrfData | None = None,
    routes: Sequence[str] = ROUTES,
    *,
    forms: Sequence[str] | None = None,
    local: LocalModels | None = None,
    diagnosis: Consistency | None = None,
    max_iter: int = 100,
    ftol: float = START_FTOL,
    halving: bool = True,
    executor: Executor | None = None,
) -> list[Candidate]:
    """Initial LPV models by several routes, each refined by :func:`lpvid.fit_nls`.

    - ``"plain"``: :func:`lpvid.identify_lti`, then :func:`lpvid.smile_candidates`
      in every coherent form (``"smile:<form>"``);
    - ``"continuation"``: the local models by continuation
      (:func:`lpvid.initial.continue_local`), then every coherent form
      (``"continuation+smile:<form>"``);
    - ``"global"``: :func:`lpvid.global_start` from the best-determined local
      model, groups freed all at once (``"global:all"``) and one degree at
      a time (``"global:degree"``, left out when the basis has one degree
      only, where it would repeat ``"global:all"``).

    Parameters
    ----------
    data : FrfData
        Identification data.
    order : int
        Number of states.
    basis : Basis
        Basis functions of the LPV model.
    fixed : optional
        Fixed parameters (see :func:`lpvid.fixed_mask`); ``{"D": True}``
        makes the local models strictly proper.
    validation : FrfData, optional
        Data at other scheduling values; every candidate is evaluated on them.
    routes : sequence of str
        Which routes to take, among ``"plain"``, ``"continuation"``, ``"global"``.
    forms : sequence of str, optional
        Coherent forms for the SMILE routes (default all of
        :data:`lpvid.initial.interpolation.FORMS`).
    local : LocalModels, optional
        Plain local models, when already identified.
    diagnosis : Consistency, optional
        :func:`lpvid.consistency` of ``local``, when already computed
        (default ``local.consistency``, else computed here once).
    max_iter : int
        Most Levenberg-Marquardt steps per fit.
    ftol : float
        A fit ends when a step lowers V_NLS by less than ``ftol`` times it
        (default :data:`lpvid.fit.settings.START_FTOL`: the rest is a slide along
        directions the data hardly see; see :func:`lpvid.fit_nls`).
    halving : bool
        Race the starts (:func:`lpvid.initial.race.race`): every start gets
        a few steps, the worse half is dropped, the rest twice as many, and
        so on, until the best few are refined to convergence (default).
        False refines every start to convergence.
    executor : concurrent.futures.Executor, optional
        Where the independent fits run (the local models when they are
        identified here, the runners of every round of the race, the
        starts without the race): see :func:`lpvid.identify`. Default
        here, one after the other; the candidates are the same either way.

    Returns
    -------
    list of Candidate
        In the order of ``routes``; a coherent form that cannot be built for
        a set of local models is left out (the reason is in the notes of
        that route's candidates). Starts dropped by the race have
        ``refined`` False.

    """
    if not isinstance(data, FrfData):
        raise TypeError(f"data: expected an FrfData, got {type(data).__name__}")
    if not isinstance(basis, Basis):
        raise TypeError(f"basis: expected an lpvid basis, got {type(basis).__name__}")
    n = positive_int(order, "order")
    if isinstance(routes, str):
        routes = (routes,)
    for r in routes:
        if r not in ROUTES:
            raise ValueError(f"routes: unknown route {r!r}; choose from {ROUTES}")
    if not routes:
        raise ValueError("routes: needs at least one route")
    if validation is not None and not isinstance(validation, FrfData):
        raise TypeError(f"validation: expected an FrfData, got {type(validation).__name__}")
    ftol = positive_float(ftol, "ftol", allow_zero=True)
    if local is None:
        check_local_order(n, data)
    elif not isinstance(local, LocalModels):
        raise TypeError(f"local: expected LocalModels, got {type(local).__name__}")
    return candidates_of(
        data,
        n,
        basis,
        fixed,
        validation=validation,
        routes=routes,
        forms=forms,
        local=local,
        diagnosis=diagnosis,
        max_iter=max_iter,
        ftol=ftol,
        halving=halving,
        executor=executor,
    )


def candidates_of(
    data: FrfData,
    n: int,
    basis: Basis,
    fixed: Any,
    *,
    validation: FrfData | None,
    routes: Sequence[str],
    forms: Sequence[str] | None,
    local: LocalModels | None,
    diagnosis: Consistency | None,
    max_iter: int,
    ftol: float,
    halving: bool,
    executor: Executor | None,
) -> list[Candidate]:
    """:func:`initial_candidates` on checked arguments (checked there or by a Problem)."""
    proper = strictly_proper(fixed)
    t = time.perf_counter()
    if local is None:
        local = local_models(data, n, strictly_proper=proper, executor=executor)
    local_s = time.perf_counter() - t
    runners: list[tuple[Runner, float]] = []  # with the time spent building the start
    # The diagnosis and the best-determined point serve the continuation and
    # the global starts alike: computed once.
    root = None
    if len(local) > 1 and ("continuation" in routes or "global" in routes):
        if diagnosis is None:
            diagnosis = local.consistency or consistency(local)
        root = best_determined(local, data, diagnosis, {"D": True} if proper else None)

    def smile_route(prefix: str, models: Any, shared: str) -> None:
        t0 = time.perf_counter()
        starts = smile_candidates(models, basis=basis, forms=forms, loo=False)
        build = (time.perf_counter() - t0) / max(len(starts), 1)
        failed = next(iter(starts.values())).info.get("unavailable", {}) if starts else {}
        missing = f"; forms not built: {', '.join(failed)}" if failed else ""
        for form, m0 in starts.items():
            note = f"SMILE ({form} form) of {shared}, refined by fit_nls{missing}"
            mask = fixed_mask(m0, fixed)
            stage = Stage("all groups", mask)
            runner = Runner(
                f"{prefix}smile:{form}", m0, [stage], max_iter=max_iter, ftol=ftol, note=note
            )
            runners.append((runner, build))

    globals_: list[tuple[Runner, Any, str]] = []
    for route in routes:
        if route == "plain":
            smile_route("", local, f"the plain local models ({local_s:.2f} s)")
        elif route == "continuation":
            t0 = time.perf_counter()
            cont = continue_local(
                data,
                local,
                root=root,
                strictly_proper=proper,
                max_iter=max_iter,
                diagnosis=diagnosis,
                executor=executor,
            )
            which = ", ".join(f"{q}: {s}" for q, s in enumerate(cont.starts))
            smile_route(
                "continuation+",
                cont,
                f"the local models by continuation ({time.perf_counter() - t0:.2f} s; {which})",
            )
        else:
            levels = len(set(degree_levels(basis)))
            t0 = time.perf_counter()
            const = constant_start(
                data, n, basis, fixed, local=local, point=root, max_iter=max_iter, ftol=ftol
            )
            shared = time.perf_counter() - t0
            for stages in ("all", "degree") if levels > 1 else ("all",):
                runner = global_runner(const, fixed, stages, max_iter, ftol)
                runners.append((runner, shared))
                globals_.append((runner, const, stages))
    if halving:
        race([r for r, _ in runners], data, validation, executor=executor)
    else:
        run_out([r for r, _ in runners], data, executor)
    for runner, const, stages in globals_:
        m = finish_global(runner, const, stages)
        steps = "; ".join(
            f"{h['free_groups']}: V/floor {h['vnls'] / data.n_residuals:.3f}"
            for h in m.info["history"]
        )
        runner.note = (
            f"constant model from local model {m.info['point']}, then groups "
            f"freed ({stages}): {steps}"
        )
    return [_candidate(r, data, validation, shared) for r, shared in runners]
