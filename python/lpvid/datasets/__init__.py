"""Built-in FRF data sets generated from physical models.

Two data sets in the spirit of the two cases of Turk, Gillis, Pipeleers and
Swevers (2018):

- :func:`gantry`: a flexible gantry (the paper's section 4), 6 states,
  1 input (motor torque), 2 outputs (accelerations), scheduled by the side
  length of the square tubes of its bridge; discrete time by default.
- :func:`positioning_stage`: a velocity-controlled positioning stage carrying
  a cantilever whose free length changes with the position of a second axis
  (the paper's section 5), 4 states, single input single output, ``D = 0``;
  continuous time by default.

Both are written here from first principles (lumped masses and springs; the
formulas are in the functions' docstrings), are exactly reproducible from a
seed, and come with their true frozen models, so that an identified model can
be judged against the noise floor and against the truth.

Examples
--------
>>> import lpvid
>>> ds = lpvid.datasets.gantry(seed=1)
>>> ds.identification
FrfData(N=5 points, F=300 lines 50-300 Hz, 2 outputs x 1 inputs, Ts=0.0005 s)
>>> ds.order, ds.basis
(6, Polynomial(4, domain=(24.0, 48.0)))

"""

from lpvid.datasets.container import Dataset
from lpvid.datasets.flexible_gantry import GANTRY, gantry
from lpvid.datasets.positioning import STAGE, positioning_stage

__all__ = ["Dataset", "gantry", "positioning_stage", "GANTRY", "STAGE"]
