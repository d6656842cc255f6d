"""Settings of the fits and of :func:`lpvid.identify`: their names, defaults and checks.

:class:`L21Settings` mirrors the Rust core's ``L21Settings`` (without
``gamma``, which :func:`lpvid.fit_l21`, :func:`lpvid.l21_path` and
:func:`lpvid.identify` take on their own); a test checks that the two agree
on names and defaults. :class:`LmSettings` holds the defaults of
:func:`lpvid.fit_nls`. :class:`PathSettings`, :class:`StartSettings` and
:class:`IdentifySettings` are the settings of :func:`lpvid.identify` that a
:class:`lpvid.Problem` holds; each checks its fields when it is made.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._checks import flag, positive_float, positive_int, real_array

__all__ = [
    "DEFAULT_GAMMAS",
    "FORMS",
    "FTOL",
    "LOCAL_FTOL",
    "ROUTES",
    "START_FTOL",
    "WEIGHTS",
    "IdentifySettings",
    "L21Settings",
    "LmSettings",
    "PathSettings",
    "StartSettings",
    "check_gammas",
]

#: The reweighting rules: (23) with the scale (25), (22), (21).
WEIGHTS = ("relative", "scaled", "plain")

#: A step that lowers the objective by less than this fraction of it ends a
#: fit of :func:`lpvid.identify`'s l2,1 path (by default,
#: :attr:`L21Settings.ftol`). Near the noise floor the objective is about
#: ``V_NLS / M``, so such a step buys less than ``1e-4 M`` in V_NLS, far
#: below the noise in V_NLS (``sqrt(M)``): what is left is the slow slide
#: along nearly flat directions that the data do not see. (The refit of the
#: chosen model runs to convergence: stopped by this rule it validated worse
#: on both built-in sets, the gantry 1.44 -> 1.59 times the floor; it is kept
#: only where the validation data say it is better,
#: :func:`lpvid.trust.support.judged_refit`.)
FTOL = 1e-4

#: A step that lowers V_NLS by less than this fraction of it ends a start's
#: Levenberg-Marquardt fit in the race of :func:`lpvid.identify`
#: (:attr:`StartSettings.ftol`, :func:`lpvid.initial_candidates`). Near the
#: floor that is ``3e-4 M`` in V_NLS, 0.02 to 0.08 of the noise in V_NLS
#: (``sqrt(M)``) from the gantry to the n = 32 rung of the scale ladder.
#: Measured against :data:`FTOL` (``docs/performance.md``): n = 16's starts
#: took 237 LM steps instead of 260 and the path from the start chosen 98
#: cone steps instead of 160 (4 groups instead of 5, a lower validation
#: V_NLS); the other rungs and built-in sets chose as before or a model
#: that validates better, and under 1e-12 changes of the data no choice
#: moved that did not move with :data:`FTOL` too (the starts' cost tie,
#: :data:`lpvid.fit.judge.COST_TIE`, is ten times this rule). At 1e-3 the
#: starts that end within the race's first round stay in it, and a 1e-12
#: change of the 9 x 9 grid's data brought one in that led to another model.
START_FTOL = 3e-4

#: A step that lowers V_NLS by less than this fraction of it ends the
#: refinement of a local model (:func:`lpvid.identify_lti`, the local models
#: of :func:`lpvid.identify`). At one point's floor ``F l r`` that is a
#: millionth of it in V_NLS, far below the noise there (``sqrt(F l r)``).
#: Run on to ``1e-10`` (:attr:`LmSettings.ftol`), 27 % of the small
#: system's local steps slid on along directions the point's data hardly
#: see, and the starts built on those models took longer in their turn
#: (the blocks route's fits 330 steps instead of 155): its identify 0.77
#: times the time, the same model. Over 320 draws of ``bench_few.py``
#: (both truths, 3-6 points) 258 models within 5 % of their error before,
#: 14 better and 15 worse by 1.5 times or more (``docs/performance.md``). At
#: :data:`FTOL` (1e-4) the few-points worst errors grew (the synthetic
#: system at three points: 90 % quantile 0.12 -> 0.17, worst 0.23 -> 2.1).
LOCAL_FTOL = 1e-6

#: Default sweep of the (normalised) regularisation weight, largest first.
DEFAULT_GAMMAS = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3)

#: Routes to initial models of :func:`lpvid.initial_candidates`.
ROUTES = ("plain", "continuation", "global")

#: The coherent forms :func:`lpvid.smile` offers, in the order ``"auto"`` tries them.
FORMS = ("observability", "controllability", "modal", "modal_input", "pairwise")


@dataclass(frozen=True)
class L21Settings:
    """How :func:`lpvid.fit_l21` runs Algorithm 1 (method.md section 4).

    Every field has the default the core uses; change a few with
    ``L21Settings(eps=1e-4)`` or ``settings.replace(max_outer=5)``, or pass
    them as keywords to the fitting functions (``fit_l21(..., eps=1e-4)``).

    Attributes
    ----------
    eps : float
        ``eps`` of the weights (21)-(23), > 0.
    weights : {"relative", "scaled", "plain"}
        Reweighting rule: (23) with the scale (25) (groups whose X(0) is
        zero or fixed fall back to (22)), (22), or (21).
    dtheta_min : float
        Inner loop ends when ``||d|| <= dtheta_min (||theta|| + dtheta_min)``.
    dphi_min : float
        Outer loop ends when the largest relative change of the weights is
        at most ``dphi_min``.
    dvnls_min : float
        Outer loop ends when the groups in use are unchanged and V_NLS
        changed by at most this fraction over the last reweighting.
    threshold : float
        Relative magnitude (23) below which a group counts as removed, > 0.
    cone_tol : float
        Accuracy of the cone solves (Clarabel's gap and feasibility
        tolerances), > 0.
    ftol : float
        Inner loop also ends when a step lowers the objective by less than
        ``ftol`` times its value. The objective is about ``V_NLS / M`` near
        the noise floor, so the default 1e-4 ends it when a step buys less
        than ``1e-4 M`` in V_NLS, far below the noise in V_NLS (``sqrt(M)``):
        on the built-in data sets, the heavily damped test case and the
        scale ladder it chose the same models as 1e-6 (or better validated
        ones) with 25-50 % fewer cone steps.
    max_outer, max_inner : int
        Iteration limits of the outer (reweighting) and inner (cone step)
        loops, >= 1. The outer loop's stopping tests are made once more
        after its last reweighting: a fit that settled there has converged.
    lambda0 : float
        Initial damping, > 0 (reset at every reweighting).

    Examples
    --------
    >>> from lpvid import L21Settings
    >>> L21Settings(eps=1e-4).replace(max_outer=5).max_outer
    5

    """

    eps: float = 1e-3
    weights: str = "relative"
    dtheta_min: float = 1e-6
    dphi_min: float = 1e-3
    dvnls_min: float = 1e-3
    threshold: float = 1e-6
    cone_tol: float = 1e-8
    ftol: float = FTOL
    max_outer: int = 20
    max_inner: int = 10
    lambda0: float = 1e-2

    def __post_init__(self) -> None:
        if self.weights not in WEIGHTS:
            raise ValueError(f"weights: expected one of {WEIGHTS}, got {self.weights!r}")
        for name in ("eps", "threshold", "cone_tol", "lambda0"):
            object.__setattr__(self, name, positive_float(getattr(self, name), name))
        for name in ("dtheta_min", "dphi_min", "dvnls_min", "ftol"):
            value = positive_float(getattr(self, name), name, allow_zero=True)
            object.__setattr__(self, name, value)
        for name in ("max_outer", "max_inner"):
            object.__setattr__(self, name, positive_int(getattr(self, name), name))

    def replace(self, **changes: Any) -> L21Settings:
        """A copy with some fields changed; an unknown name is a TypeError naming it."""
        return _replace(self, "the l2,1 fit", changes)  # type: ignore[no-any-return]

    def to_core(self, gamma: float | None = None) -> dict[str, Any]:
        """The settings as the core reads them (with ``gamma`` when given)."""
        out = dataclasses.asdict(self)
        if gamma is not None:
            out["gamma"] = float(gamma)
        return out

    @classmethod
    def of(cls, settings: L21Settings | None, **changes: Any) -> L21Settings:
        """``settings`` (default :class:`L21Settings()`) with ``changes`` applied, checked."""
        if settings is None:
            settings = cls()
        elif not isinstance(settings, cls):
            raise TypeError(f"settings: expected an L21Settings, got {type(settings).__name__}")
        return settings.replace(**changes) if changes else settings


def _replace(settings: Any, what: str, changes: dict[str, Any]) -> Any:
    """``dataclasses.replace`` that names an unknown field (the check of every ``replace``)."""
    known = {f.name for f in dataclasses.fields(settings)}
    for key in changes:
        if key not in known:
            raise TypeError(f"{key}: not a setting of {what}; expected one of {sorted(known)}")
    return dataclasses.replace(settings, **changes)


def _names(value: Any, name: str, known: tuple[str, ...], what: str) -> tuple[str, ...]:
    """A sequence of names among ``known`` (one string is one name), checked."""
    names = (value,) if isinstance(value, str) else tuple(value)
    for v in names:
        if v not in known:
            raise ValueError(f"{name}: unknown {what} {v!r}; choose from {known}")
    return names


def check_gammas(gammas: Any) -> NDArray[np.float64]:
    """The regularisation weights of :func:`lpvid.identify`, checked (default: DEFAULT_GAMMAS)."""
    gs = real_array(DEFAULT_GAMMAS if gammas is None else gammas, "gammas", ndim=1)
    if gs.size == 0 or np.any(gs <= 0):
        raise ValueError("gammas: needs at least one value, all > 0")
    return gs


@dataclass(frozen=True)
class LmSettings:
    """How :func:`lpvid.fit_nls` runs Levenberg-Marquardt: its defaults, in one place.

    Attributes
    ----------
    max_iter : int
        Most steps computed, accepted or not, >= 1.
    xtol : float
        Stop when ``||d|| <= xtol (||theta|| + xtol)``, >= 0.
    ftol : float
        Stop when an accepted step lowers V_NLS by less than ``ftol V_NLS``, >= 0.
    gtol : float
        Stop when the largest gradient entry is below ``gtol``, >= 0.
    lambda0 : float
        Initial damping, > 0.

    Examples
    --------
    >>> from lpvid.fit.settings import LmSettings
    >>> LmSettings(max_iter=20).to_core()["max_iter"]
    20

    """

    max_iter: int = 100
    xtol: float = 1e-10
    ftol: float = 1e-10
    gtol: float = 0.0
    lambda0: float = 1e-2

    def __post_init__(self) -> None:
        object.__setattr__(self, "max_iter", positive_int(self.max_iter, "max_iter"))
        for name in ("xtol", "ftol", "gtol"):
            value = positive_float(getattr(self, name), name, allow_zero=True)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "lambda0", positive_float(self.lambda0, "lambda0"))

    def replace(self, **changes: Any) -> LmSettings:
        """A copy with some fields changed; an unknown name is a TypeError naming it."""
        return _replace(self, "the Levenberg-Marquardt fit", changes)  # type: ignore[no-any-return]

    def to_core(self) -> dict[str, Any]:
        """The settings as the core reads them."""
        return dataclasses.asdict(self)


#: The l2,1 settings of the path of :func:`lpvid.identify` (the core's
#: defaults with at most 10 reweightings per gamma).
PATH_L21 = L21Settings(max_outer=10)


@dataclass(frozen=True)
class PathSettings:
    """The l2,1 path of :func:`lpvid.identify` and the choice on it.

    Attributes
    ----------
    gammas : tuple of float
        Regularisation weights (lpvid's normalised gamma, see
        :func:`lpvid.fit_l21`), all > 0; default :data:`DEFAULT_GAMMAS`. The
        path runs them largest first.
    tolerance : float
        Relative slack on the best validation V_NLS, >= 0: the choice keeps
        the simplest model within it, and a fit of a guarded path that
        validates more than this above the best so far is also tried pinned
        (:mod:`lpvid.pipeline.path`). Default 0.1.
    l21 : L21Settings
        Settings of every l2,1 fit on the path (and the threshold below
        which a group counts as dropped); default ``L21Settings(max_outer=10)``.

    Examples
    --------
    >>> from lpvid.fit.settings import PathSettings
    >>> PathSettings(gammas=[0.1, 0.01]).gammas
    (0.1, 0.01)

    """

    gammas: tuple[float, ...] = DEFAULT_GAMMAS
    tolerance: float = 0.1
    l21: L21Settings = PATH_L21

    def __post_init__(self) -> None:
        gammas = tuple(float(g) for g in check_gammas(self.gammas))
        object.__setattr__(self, "gammas", gammas)
        tol = positive_float(self.tolerance, "tolerance", allow_zero=True)
        object.__setattr__(self, "tolerance", tol)
        object.__setattr__(self, "l21", L21Settings.of(self.l21))

    def replace(self, **changes: Any) -> PathSettings:
        """A copy with some fields changed; an unknown name is a TypeError naming it."""
        return _replace(self, "the path", changes)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class StartSettings:
    """The initial models of :func:`lpvid.identify` and the race that refines them.

    Attributes
    ----------
    routes : tuple of str
        Routes to initial models, among ``"plain"``, ``"continuation"`` and
        ``"global"`` (:func:`lpvid.initial_candidates`); default all.
    forms : tuple of str
        Coherent forms of the SMILE routes; default all of :data:`FORMS`.
    max_iter : int
        Most Levenberg-Marquardt steps per start, >= 1 (default 100).
    ftol : float
        A start's fit ends when a step lowers V_NLS by less than ``ftol``
        times it, >= 0 (default :data:`START_FTOL`).
    halving : bool
        Race the starts by successive halving (:func:`lpvid.initial.race.race`),
        default True; False refines every start to convergence.

    Examples
    --------
    >>> from lpvid.fit.settings import StartSettings
    >>> StartSettings(routes="plain").routes
    ('plain',)

    """

    routes: tuple[str, ...] = ROUTES
    forms: tuple[str, ...] = FORMS
    max_iter: int = 100
    ftol: float = START_FTOL
    halving: bool = True

    def __post_init__(self) -> None:
        routes = _names(self.routes, "routes", ROUTES, "route")
        if not routes:
            raise ValueError("routes: needs at least one route")
        object.__setattr__(self, "routes", routes)
        forms = FORMS if self.forms is None else self.forms
        object.__setattr__(self, "forms", _names(forms, "forms", FORMS, "coherent form"))
        object.__setattr__(self, "max_iter", positive_int(self.max_iter, "max_iter"))
        object.__setattr__(self, "ftol", positive_float(self.ftol, "ftol", allow_zero=True))
        object.__setattr__(self, "halving", flag(self.halving, "halving"))

    def replace(self, **changes: Any) -> StartSettings:
        """A copy with some fields changed; an unknown name is a TypeError naming it."""
        return _replace(self, "the starts", changes)  # type: ignore[no-any-return]


@dataclass(frozen=True)
class IdentifySettings:
    """Everything :func:`lpvid.identify` does that is not data: its settings, with their defaults.

    Attributes
    ----------
    path : PathSettings
        The l2,1 path and the choice on it (default ``PathSettings()``).
    starts : StartSettings
        The initial models and their race (default ``StartSettings()``).
    stable : bool
        Keep every frozen model on the scheduling range stable (default
        False; see :func:`lpvid.identify`).
    refit : bool
        With validation data, refit the chosen model on its support and
        keep the refit when it validates better (default True).

    Examples
    --------
    >>> from lpvid.fit.settings import IdentifySettings
    >>> IdentifySettings().path.l21.max_outer
    10

    """

    path: PathSettings = field(default_factory=PathSettings)
    starts: StartSettings = field(default_factory=StartSettings)
    stable: bool = False
    refit: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.path, PathSettings):
            raise TypeError(f"path: expected a PathSettings, got {type(self.path).__name__}")
        if not isinstance(self.starts, StartSettings):
            raise TypeError(f"starts: expected a StartSettings, got {type(self.starts).__name__}")
        object.__setattr__(self, "stable", flag(self.stable, "stable"))
        object.__setattr__(self, "refit", flag(self.refit, "refit"))

    def replace(self, **changes: Any) -> IdentifySettings:
        """A copy with some fields changed; an unknown name is a TypeError naming it."""
        return _replace(self, "identify", changes)  # type: ignore[no-any-return]
