"""lpvid: LPV state-space models from frequency-response data.

Identifies linear parameter-varying state-space models from FRF data
measured at frozen operating points and simplifies their scheduling
dependency with reweighted l2,1-norm regularisation (Turk, Gillis,
Pipeleers and Swevers, 2018).
"""

from lpvid import datasets, plots, report, robust
from lpvid._core import SingularModelError
from lpvid._core import __version__ as __version__
from lpvid.basis import Basis, CustomBasis, Legendre, Polynomial
from lpvid.cost import residual, vnls
from lpvid.data import FrfData
from lpvid.fit import fit_l21, fit_nls, l21_path
from lpvid.groups import GroupNorms
from lpvid.layout import fixed_mask, free_mask
from lpvid.local import LocalModels, identify_lti
from lpvid.measure import Multisine, estimate_frf, multisine
from lpvid.model import LpvModel
from lpvid.pipeline import IdentifyResult, identify
from lpvid.results import FitResult, L21Result, PathResult
from lpvid.robust import Consistency, consistency, global_start, initial_candidates
from lpvid.smile import smile, smile_candidates
from lpvid.subspace import fd_subspace

__all__ = [
    "Basis",
    "Consistency",
    "CustomBasis",
    "FitResult",
    "FrfData",
    "GroupNorms",
    "IdentifyResult",
    "L21Result",
    "Legendre",
    "LocalModels",
    "LpvModel",
    "Multisine",
    "PathResult",
    "Polynomial",
    "SingularModelError",
    "datasets",
    "report",
    "robust",
    "consistency",
    "global_start",
    "initial_candidates",
    "estimate_frf",
    "fd_subspace",
    "fit_l21",
    "fit_nls",
    "fixed_mask",
    "identify",
    "free_mask",
    "identify_lti",
    "l21_path",
    "multisine",
    "plots",
    "residual",
    "smile",
    "smile_candidates",
    "vnls",
]
