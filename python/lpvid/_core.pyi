"""Type stub of the compiled core (private).

Checked against the compiled module by ``python -m mypy.stubtest lpvid._core``
(CI runs it).
"""

from collections.abc import Callable
from typing import Any, final

import numpy as np
from numpy.typing import NDArray
from typing_extensions import Self

__all__ = [
    "__version__",
    "__target_features__",
    "kernel_route",
    "SingularModelError",
    "ModelView",
    "frequency_response",
    "Problem",
    "TimeProblem",
    "SumProblem",
    "FitOutcome",
    "PathOutcome",
    "ConeStep",
    "cone_step",
    "fit_nls",
    "fit_l21",
    "FrozenRange",
    "lti_jacobian",
    "stability_margin",
    "l21_defaults",
    "l21_path",
    "simulate",
    "fit_memory",
    "_fail_allocation_after",
    "_kept_blocks",
    "_loops_here",
]

__version__: str
# "lpvid-target-features:avx,avx2,...;" (lpvid._cpu reads it from the file)
__target_features__: str

def kernel_route() -> str: ...
def _loops_here(here: bool) -> bool: ...

class SingularModelError(ArithmeticError): ...

_Shape = tuple[int, int, int, int]

@final
class ModelView:
    def __new__(
        cls, shape: _Shape, theta: NDArray[np.float64], basis: NDArray[np.float64]
    ) -> Self: ...
    @property
    def shape(self) -> _Shape: ...
    @property
    def n_points(self) -> int: ...

def frequency_response(view: ModelView, z: NDArray[np.complex128]) -> NDArray[np.complex128]: ...
def simulate(
    view: ModelView,
    u: NDArray[np.float64],
    x0: NDArray[np.float64],
    dt: float | None = None,
    states: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, int | None]: ...

@final
class Problem:
    def __new__(
        cls,
        view: ModelView,
        z: NDArray[np.complex128],
        g: NDArray[np.complex128],
        sigma: NDArray[np.float64],
    ) -> Self: ...
    @property
    def n_residuals(self) -> int: ...
    def residual(self, theta: NDArray[np.float64]) -> NDArray[np.complex128]: ...
    def vnls(self, theta: NDArray[np.float64]) -> float: ...
    def gauss_newton(
        self, theta: NDArray[np.float64], free: NDArray[np.bool_] | None = None
    ) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]: ...

@final
class TimeProblem:
    def __new__(
        cls,
        shape: _Shape,
        u: list[NDArray[np.float64]],
        psi: list[NDArray[np.float64]],
        y: list[NDArray[np.float64]],
        sigma: list[NDArray[np.float64]],
        dt: float | None = None,
        x0: str = "estimate",
        x0_values: NDArray[np.float64] | None = None,
        skip: int = 0,
    ) -> Self: ...
    @property
    def n_residuals(self) -> int: ...
    def vnls(self, theta: NDArray[np.float64]) -> float: ...
    def residual(self, theta: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def initial_states(self, theta: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def gauss_newton(
        self, theta: NDArray[np.float64], free: NDArray[np.bool_] | None = None
    ) -> tuple[float, NDArray[np.float64], NDArray[np.float64], dict[str, float]]: ...

@final
class SumProblem:
    def __new__(cls, frf: Problem, time: TimeProblem) -> Self: ...
    @property
    def n_residuals(self) -> int: ...
    def vnls(self, theta: NDArray[np.float64]) -> float: ...
    def gauss_newton(
        self, theta: NDArray[np.float64], free: NDArray[np.bool_] | None = None
    ) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]: ...

_AnyProblem = Problem | TimeProblem | SumProblem

@final
class FrozenRange:
    def __new__(
        cls, view: ModelView, stride: int, discrete: bool, tol: float, floor: float = ...
    ) -> Self: ...
    def __len__(self) -> int: ...
    def margins(self, theta: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def worst(self, theta: NDArray[np.float64]) -> tuple[int, float]: ...

def lti_jacobian(view: ModelView, z: NDArray[np.complex128]) -> NDArray[np.complex128]: ...
def stability_margin(poles: NDArray[np.complex128], discrete: bool) -> float: ...

_Settings = dict[str, float | int | str]
_Callback = Callable[[dict[str, Any]], Any] | None

@final
class FitOutcome:
    @property
    def theta(self) -> NDArray[np.float64]: ...
    @property
    def vnls(self) -> float: ...
    @property
    def objective(self) -> float: ...
    @property
    def stop(self) -> str: ...
    @property
    def message(self) -> str: ...
    @property
    def converged(self) -> bool: ...
    @property
    def interrupted(self) -> bool: ...
    @property
    def outer_iterations(self) -> int: ...
    @property
    def n_rejected(self) -> int: ...
    @property
    def lm_iter_s(self) -> float: ...
    @property
    def socp_iter_s(self) -> float: ...
    @property
    def total_s(self) -> float: ...
    @property
    def history(self) -> list[dict[str, Any]]: ...
    @property
    def weights(self) -> NDArray[np.float64]: ...

@final
class PathOutcome:
    @property
    def gammas(self) -> list[float]: ...
    @property
    def fits(self) -> list[FitOutcome]: ...
    def __len__(self) -> int: ...

@final
class ConeStep:
    @property
    def step(self) -> NDArray[np.float64] | None: ...
    @property
    def objective(self) -> float: ...
    @property
    def status(self) -> str: ...
    @property
    def phi(self) -> NDArray[np.float64]: ...
    @property
    def varphi(self) -> NDArray[np.float64]: ...

def fit_nls(
    problem: _AnyProblem,
    theta: NDArray[np.float64],
    free: NDArray[np.bool_] | None,
    settings: _Settings,
    callback: _Callback = None,
    stable: FrozenRange | None = None,
) -> FitOutcome: ...
def fit_l21(
    problem: _AnyProblem,
    theta: NDArray[np.float64],
    sup_norms: NDArray[np.float64],
    free: NDArray[np.bool_] | None,
    settings: _Settings,
    callback: _Callback = None,
    stable: FrozenRange | None = None,
    pinned: tuple[NDArray[np.float64], NDArray[np.float64], float] | None = None,
) -> FitOutcome: ...
def l21_path(
    problem: _AnyProblem,
    theta: NDArray[np.float64],
    sup_norms: NDArray[np.float64],
    gammas: NDArray[np.float64],
    free: NDArray[np.bool_] | None,
    settings: _Settings,
    callback: _Callback = None,
    stable: FrozenRange | None = None,
) -> PathOutcome: ...
def l21_defaults() -> dict[str, float | int | str]: ...
def cone_step(
    problem: _AnyProblem,
    theta: NDArray[np.float64],
    sup_norms: NDArray[np.float64],
    free: NDArray[np.bool_] | None,
    settings: _Settings,
    mu: float,
) -> ConeStep: ...
def fit_memory(
    shape: _Shape,
    method: str,
    free: NDArray[np.bool_] | None = None,
    frf: tuple[int, int] | None = None,
    records: list[int] | None = None,
    hold: bool = False,
    estimate_x0: bool = False,
    pinned: bool = False,
) -> dict[str, int]: ...
def _fail_allocation_after(count: int | None = None) -> None: ...
def _kept_blocks() -> tuple[int, int] | None: ...
