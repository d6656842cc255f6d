"""Trusting a model between the points: parameter covariance, FRF bands, stability over the range.

The functions are exported at the top level: :func:`lpvid.covariance`,
:func:`lpvid.stability`, :func:`lpvid.refit`, :func:`lpvid.next_points`; ``stable=True`` of
:func:`lpvid.fit_nls`, :func:`lpvid.fit_l21` and :func:`lpvid.identify`
keeps stability during a fit.

Modules
-------
covariance
    :class:`Covariance`: the first-order parameter covariance, FRF and pole
    standard deviations, and its rank rule.
refit
    Refit on the support of an l2,1 estimate (dropped groups fixed at zero).
stability
    :class:`StabilityReport`: stability of every frozen model on the
    continuum of the scheduling range.
lyapunov
    :class:`LyapunovCertificate`: a common quadratic Lyapunov function over
    the range as a linear matrix inequality, and what it certifies.
enforce
    How fits keep the frozen models stable.
ranges
    Scheduling ranges for stability statements, and ``A(p)`` as a polynomial.
steps
    The steps :func:`lpvid.identify` adds (stable start, refit, covariance).
nextpoints
    :func:`lpvid.next_points`, :func:`lpvid.suggest_points`: where one more
    FRF measurement would shrink the model's bands most.
design
    The information algebra behind it (frozen information, low-rank updates).

The package lies on both sides of :mod:`lpvid.fit`, one way: ``ranges``,
``lyapunov``, ``stability``, ``enforce``, ``covariance`` and ``design`` do
not use the fits, and :mod:`lpvid.fit` imports ``enforce`` for
``stable=True``; ``refit``, ``steps`` and ``nextpoints`` depend on the fits
(``nextpoints`` through :mod:`lpvid.identified`). No module of the first
group imports one of the second, and this file imports only the first group.
"""

from lpvid.trust.covariance import Covariance, band_radius
from lpvid.trust.lyapunov import LyapunovCertificate
from lpvid.trust.stability import StabilityReport

__all__ = ["Covariance", "LyapunovCertificate", "StabilityReport", "band_radius"]
