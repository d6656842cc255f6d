"""lpvid: LPV state-space models from frequency-response data.

Identifies linear parameter-varying state-space models from FRF data
measured at frozen operating points and simplifies their scheduling
dependency with reweighted l2,1-norm regularisation (Turk, Gillis,
Pipeleers and Swevers, 2018).
"""

# First: refuses a processor that lacks what the compiled core was built for,
# before anything loads the core.
from lpvid import _cpu  # noqa: F401

# isort: split
from lpvid import datasets, initial, plots, readers, report, trust
from lpvid._core import __version__ as __version__
from lpvid._cpu import kernel_route
from lpvid.data.basis import Basis, CustomBasis, Legendre, Polynomial
from lpvid.data.frf import FrfData
from lpvid.data.measure import Multisine, estimate_frf, multisine
from lpvid.data.timedata import TimeData
from lpvid.errors import ConvergenceWarning, SingularModelError
from lpvid.experiment.nextpoints import Suggestion, next_points, suggest_points
from lpvid.fit import judge
from lpvid.fit.cost import residual, vnls
from lpvid.fit.fits import fit_l21, fit_nls, l21_path
from lpvid.fit.memory import available_memory, fit_memory
from lpvid.fit.results import FitResult, L21Result, PathResult
from lpvid.fit.settings import (
    IdentifySettings,
    L21Settings,
    LmSettings,
    PathSettings,
    StartSettings,
)
from lpvid.fit.timecost import TimeCost, initial_states, time_residual, time_vnls
from lpvid.fit.timefit import fit_time
from lpvid.initial import (
    Consistency,
    LocalModels,
    consistency,
    fd_subspace,
    global_start,
    identify_lti,
    initial_candidates,
    smile_candidates,
)
from lpvid.initial.interpolation import smile
from lpvid.initial.orders import OrderHints, order_hints
from lpvid.model import handoff
from lpvid.model.groups import GroupNorms
from lpvid.model.layout import fixed_mask, free_mask
from lpvid.model.lpv import LpvModel
from lpvid.pipeline.between import Between
from lpvid.pipeline.problem import Problem
from lpvid.pipeline.resample import resampled
from lpvid.pipeline.result import IdentifyResult
from lpvid.pipeline.run import identify
from lpvid.selection.grid import select
from lpvid.selection.result import GridRow, SelectResult
from lpvid.stable.rates import RateBound, RateCertificate, max_rate, rate_stability
from lpvid.stable.scan import stability
from lpvid.trust import Covariance, LyapunovCertificate, StabilityReport
from lpvid.trust.silent import SilentCount
from lpvid.trust.support import refit
from lpvid.trust.uncertainty import covariance

__all__ = [
    "Basis",
    "Between",
    "Consistency",
    "ConvergenceWarning",
    "Covariance",
    "CustomBasis",
    "FitResult",
    "FrfData",
    "GridRow",
    "GroupNorms",
    "IdentifyResult",
    "IdentifySettings",
    "L21Result",
    "L21Settings",
    "Legendre",
    "LmSettings",
    "LocalModels",
    "LpvModel",
    "LyapunovCertificate",
    "Multisine",
    "OrderHints",
    "PathResult",
    "PathSettings",
    "Polynomial",
    "Problem",
    "RateBound",
    "RateCertificate",
    "SelectResult",
    "SilentCount",
    "SingularModelError",
    "StabilityReport",
    "StartSettings",
    "Suggestion",
    "TimeCost",
    "TimeData",
    "__version__",
    "available_memory",
    "consistency",
    "covariance",
    "datasets",
    "estimate_frf",
    "fd_subspace",
    "fit_l21",
    "fit_memory",
    "fit_nls",
    "fit_time",
    "fixed_mask",
    "free_mask",
    "global_start",
    "handoff",
    "identify",
    "identify_lti",
    "initial",
    "initial_candidates",
    "initial_states",
    "judge",
    "kernel_route",
    "l21_path",
    "max_rate",
    "multisine",
    "next_points",
    "order_hints",
    "plots",
    "rate_stability",
    "readers",
    "refit",
    "report",
    "resampled",
    "residual",
    "select",
    "smile",
    "smile_candidates",
    "stability",
    "suggest_points",
    "time_residual",
    "time_vnls",
    "trust",
    "vnls",
]
