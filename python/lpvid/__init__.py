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
from lpvid import datasets, handoff, initial, judge, plots, readers, report, trust
from lpvid._core import __version__ as __version__
from lpvid.basis import Basis, CustomBasis, Legendre, Polynomial
from lpvid.cost import residual, vnls
from lpvid.data import FrfData
from lpvid.errors import ConvergenceWarning, SingularModelError
from lpvid.fit import fit_l21, fit_nls, l21_path
from lpvid.groups import GroupNorms
from lpvid.identified import IdentifyResult
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
from lpvid.initial.orders import OrderHints, order_hints
from lpvid.initial.smile import smile
from lpvid.layout import fixed_mask, free_mask
from lpvid.measure import Multisine, estimate_frf, multisine
from lpvid.memory import available_memory, fit_memory
from lpvid.model import LpvModel
from lpvid.pipeline import identify
from lpvid.problem import Problem
from lpvid.results import FitResult, L21Result, PathResult
from lpvid.selected import GridRow, SelectResult
from lpvid.selection import select
from lpvid.settings import IdentifySettings, L21Settings, LmSettings, PathSettings, StartSettings
from lpvid.timecost import TimeCost, initial_states, time_residual, time_vnls
from lpvid.timedata import TimeData
from lpvid.timefit import fit_time
from lpvid.trust import Covariance, LyapunovCertificate, StabilityReport
from lpvid.trust.covariance import covariance
from lpvid.trust.nextpoints import Suggestion, next_points, suggest_points
from lpvid.trust.refit import refit
from lpvid.trust.stability import stability

__all__ = [
    "Basis",
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
    "SelectResult",
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
    "l21_path",
    "multisine",
    "next_points",
    "order_hints",
    "plots",
    "readers",
    "refit",
    "report",
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
