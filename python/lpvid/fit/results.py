"""Result objects of the fitting routines."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lpvid._core import FitOutcome
from lpvid.model.groups import GroupNorms
from lpvid.model.lpv import LpvModel

__all__ = ["FitResult", "L21Result", "PathResult"]


@dataclass
class FitResult:
    """Outcome of :func:`lpvid.fit_nls`.

    Attributes
    ----------
    model : LpvModel
        The fitted model (the best point reached).
    vnls : float
        V_NLS of ``model`` on the data.
    noise_floor : int
        Number of complex residuals: the expected V_NLS at the true system
        when sigma is right.
    objective : float
        The minimised objective (V_NLS for Levenberg-Marquardt).
    history : list of dict
        One row per computed step (accepted or not): ``kind`` ("lm" or
        "socp"), ``outer`` (reweighting iteration), ``vnls``, ``objective``,
        ``step_norm``, ``lambda`` (damping), ``accepted``, ``gain_ratio``,
        ``status`` (of the linear or cone solve), ``solver_iterations``
        (Clarabel's), ``seconds``.
    timings : dict
        Mean seconds per LM iteration ``"lm_iter_s"``, per SOCP step
        ``"socp_iter_s"`` (NaN when there was none) and the total
        ``"total_s"``.
    converged : bool
        Whether a convergence test stopped the fit.
    stop : str
        Short code of the reason for stopping.
    message : str
        The reason in words.
    interrupted : bool
        True when the callback or Ctrl-C stopped the fit.
    n_rejected : int
        Steps computed and not taken.
    """

    model: LpvModel
    vnls: float
    noise_floor: int
    objective: float
    history: list[dict[str, Any]]
    timings: dict[str, float]
    converged: bool
    stop: str
    message: str
    interrupted: bool
    n_rejected: int

    @property
    def n_iter(self) -> int:
        """Number of steps computed."""
        return len(self.history)

    @classmethod
    def _from_core(cls, raw: FitOutcome, model: LpvModel, noise_floor: int, **extra: Any):
        return cls(
            model=model.with_theta(raw.theta),
            vnls=float(raw.vnls),
            noise_floor=int(noise_floor),
            objective=float(raw.objective),
            history=list(raw.history),
            timings={
                "lm_iter_s": float(raw.lm_iter_s),
                "socp_iter_s": float(raw.socp_iter_s),
                "total_s": float(raw.total_s),
            },
            converged=bool(raw.converged),
            stop=str(raw.stop),
            message=str(raw.message),
            interrupted=bool(raw.interrupted),
            n_rejected=int(raw.n_rejected),
            **extra,
        )

    def summary(self) -> str:
        """A few lines for people."""
        return (
            f"V_NLS = {self.vnls:.6g} (noise floor {self.noise_floor}, "
            f"ratio {self.vnls / self.noise_floor:.3f}); {self.n_iter} steps, "
            f"{self.n_rejected} rejected, {self.timings['total_s']:.3g} s; {self.message}"
        )

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.summary()})"


@dataclass(repr=False)
class L21Result(FitResult):
    """Outcome of :func:`lpvid.fit_l21`: a :class:`FitResult` with the regularisation.

    Attributes
    ----------
    gamma : float
        The (normalised) regularisation weight.
    weights : ndarray
        Final reweighting weights ``phi``, one per group in the order A(1..Nb),
        B(1..Nb), C(1..Nb), D(1..Nb).
    group_norms : GroupNorms
        Group magnitudes of the fitted model (the paper's tables).
    threshold : float
        Relative magnitude below which a group counts as removed.
    outer_iterations : int
        Reweighting iterations run.
    """

    gamma: float = 0.0
    weights: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    group_norms: GroupNorms | None = None
    threshold: float = 1e-6
    outer_iterations: int = 0

    @property
    def nonzero_groups(self) -> dict[str, list[int]]:
        """Basis indices ``i`` of the groups kept, per matrix: ``{"A": [1, 2], "B": [], ...}``."""
        assert self.group_norms is not None
        return self.group_norms.nonzero(self.threshold)

    @property
    def n_groups(self) -> int:
        """Number of groups kept (relative magnitude above the threshold)."""
        assert self.group_norms is not None
        return self.group_norms.count(self.threshold)

    def summary(self) -> str:
        """A few lines for people."""
        kept = ", ".join(f"{x}{v}" for x, v in self.nonzero_groups.items())
        return f"gamma = {self.gamma:g}: {self.n_groups} groups kept ({kept}); " + super().summary()


@dataclass
class PathResult:
    """Outcome of :func:`lpvid.l21_path`: one :class:`L21Result` per gamma, largest first."""

    results: list[L21Result]

    @property
    def gammas(self) -> NDArray[np.float64]:
        """The gammas, largest first."""
        return np.array([r.gamma for r in self.results])

    @property
    def vnls(self) -> NDArray[np.float64]:
        """V_NLS of each model."""
        return np.array([r.vnls for r in self.results])

    @property
    def n_groups(self) -> NDArray[np.int64]:
        """Number of groups kept by each model."""
        return np.array([r.n_groups for r in self.results])

    def __len__(self) -> int:
        return len(self.results)

    def __iter__(self) -> Iterator[L21Result]:
        return iter(self.results)

    def __getitem__(self, k: int) -> L21Result:
        return self.results[k]

    def table(self) -> str:
        """One line per gamma: V_NLS, its ratio to the noise floor, groups kept."""
        lines = [f"{'gamma':>10} {'V_NLS':>12} {'V/floor':>8} {'groups':>6}"]
        for r in self.results:
            lines.append(
                f"{r.gamma:10.3g} {r.vnls:12.6g} {r.vnls / r.noise_floor:8.4f} {r.n_groups:6d}"
            )
        return "\n".join(lines)
