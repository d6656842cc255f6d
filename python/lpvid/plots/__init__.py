"""Figures for papers and reports (matplotlib, an optional extra).

Every function returns the :class:`matplotlib.figure.Figure` it drew, so
that it can be shown (``plt.show()``), adjusted or written with
:func:`save`. matplotlib is imported only when a figure is drawn; install it
with ``pip install "lpvid[plot]"``. Without a display (a server, CI) the
non-interactive Agg backend is selected, unless a backend was chosen already.

Each curve and surface carries a ``gid`` naming what it shows (for example
``"model/2"`` for the model FRF at the third point), so that scripts and
tests can find it again.

Functions
---------
frf_fit
    Measured FRF, model FRF, error ``|G - Gm|`` and sigma against frequency
    (the paper's Figs. 2, 5 and 8).
magnitude_surface
    Magnitude and phase of the model over frequency and scheduling (Figs. 3
    and 7).
frf_band
    Model FRF with its uncertainty band (from :func:`lpvid.covariance`) and
    the measured FRF, at identification or validation points.
frf_std_map
    The band relative to the model FRF over frequency and scheduling: how
    the uncertainty grows between the measured points.
suggested_points
    The band over the scheduling range now and after the points
    :func:`lpvid.suggest_points` suggests, with the measured points.
group_norms
    Relative group magnitudes of one or several models, per matrix and basis
    function.
accuracy_path
    Accuracy against simplicity along an l2,1 path.
select_grid
    V_NLS against the model order, one line per basis, for
    :func:`lpvid.select`.
save
    Write a figure to PNG or SVG, whole or not at all.
"""

from lpvid.plots.band import frf_band, frf_std_map
from lpvid.plots.bars import group_norms
from lpvid.plots.files import save
from lpvid.plots.frf import frf_fit
from lpvid.plots.grid import select_grid
from lpvid.plots.nextpoints import suggested_points
from lpvid.plots.path import accuracy_path
from lpvid.plots.surface import magnitude_surface

__all__ = [
    "accuracy_path",
    "frf_band",
    "frf_fit",
    "frf_std_map",
    "group_norms",
    "magnitude_surface",
    "save",
    "select_grid",
    "suggested_points",
]
