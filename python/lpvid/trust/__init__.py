"""Trusting a model between the points: covariance, FRF bands, refit, identify's trust steps.

The functions are exported at the top level: :func:`lpvid.covariance`,
:func:`lpvid.refit`; stability over the range is :mod:`lpvid.stable`
(:func:`lpvid.stability`, re-exported here with the certificate's class), and
where to measure next is :mod:`lpvid.experiment`.

Modules
-------
uncertainty
    :func:`lpvid.covariance` and :class:`Covariance`: the first-order parameter
    covariance, FRF and pole standard deviations, and its rank rule.
support
    :func:`lpvid.refit`: refit on the support of an l2,1 estimate (dropped
    groups fixed at zero).
steps
    The steps :func:`lpvid.identify` adds (stable start, refit, covariance,
    stability).
silent
    The directions of a model the measured points hardly see (what they
    leave open) and the covariance on those they see.
profile
    That covariance's band checked beyond first order along its leading
    directions (the spread between the points).
relative
    The relative FRF's sensitivity over a grid of scheduling values (the
    band's form over the range).
"""

from lpvid.stable.lyapunov import LyapunovCertificate
from lpvid.stable.scan import StabilityReport
from lpvid.trust.uncertainty import Covariance, band_radius

__all__ = ["Covariance", "LyapunovCertificate", "StabilityReport", "band_radius"]
