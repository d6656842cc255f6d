"""Initial estimates: the route from FRFs to a start for the LPV fit.

The modules, in the order the route takes them (each imports only those
before it):

- :mod:`lpvid.initial.subspace`: frequency-domain subspace estimates of an
  LTI model (:func:`lpvid.fd_subspace`);
- :mod:`lpvid.initial.localmodels`: the container of local models
  (:class:`lpvid.LocalModels`) and its checks;
- :mod:`lpvid.initial.poles`: pole coordinates, matching and uncertainty;
- :mod:`lpvid.initial.diagnosis`: are the local models on one branch
  (:func:`lpvid.consistency`)?
- :mod:`lpvid.initial.continuation`: local models by continuation from the
  best-determined point;
- :mod:`lpvid.initial.local`: one LTI model per point
  (:func:`lpvid.identify_lti`);
- :mod:`lpvid.initial.coherent` and :mod:`lpvid.initial.interpolation`: coherent
  state coordinates and the SMILE interpolation (:func:`lpvid.smile`);
- :mod:`lpvid.initial.globalstart`: a constant model fitted to all points,
  then freed (:func:`lpvid.global_start`);
- :mod:`lpvid.initial.orders`: hints at the order from the subspace
  singular values (:func:`lpvid.order_hints`);
- :mod:`lpvid.initial.candidates` and :mod:`lpvid.initial.choice`: every
  route refined by :func:`lpvid.fit_nls` (:func:`lpvid.initial_candidates`)
  and the choice of a start (:func:`lpvid.initial.choose`).

This package re-exports the names of its modules that are not themselves
module names, so that ``lpvid.initial.interpolation`` stays the module.
"""

from lpvid.initial.candidates import ROUTES, Candidate, initial_candidates
from lpvid.initial.choice import choose
from lpvid.initial.coherent import CoherenceError
from lpvid.initial.continuation import best_determined, continuation_order, continue_local
from lpvid.initial.diagnosis import Consistency, consistency
from lpvid.initial.globalstart import constant_start, free_groups, global_start
from lpvid.initial.interpolation import FORMS, smile_candidates
from lpvid.initial.local import identify_lti
from lpvid.initial.localmodels import LocalModels, is_stable, lti_models
from lpvid.initial.orders import OrderHints, order_hints
from lpvid.initial.poles import pole_coordinates, pole_uncertainty
from lpvid.initial.subspace import fd_subspace

__all__ = [
    "FORMS",
    "ROUTES",
    "Candidate",
    "CoherenceError",
    "Consistency",
    "LocalModels",
    "OrderHints",
    "best_determined",
    "choose",
    "consistency",
    "constant_start",
    "continuation_order",
    "continue_local",
    "fd_subspace",
    "free_groups",
    "global_start",
    "identify_lti",
    "initial_candidates",
    "is_stable",
    "lti_models",
    "order_hints",
    "pole_coordinates",
    "pole_uncertainty",
    "smile_candidates",
]
