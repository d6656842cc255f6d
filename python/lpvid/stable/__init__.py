"""Stability over the scheduling range: the check, the certificate, and how fits keep it.

Modules
-------
scan
    :func:`lpvid.stability` and :class:`lpvid.StabilityReport`: every frozen
    model on the continuum of the range (grid, guardian-map crossings, refinement).
lyapunov
    :class:`lpvid.LyapunovCertificate`: a common quadratic Lyapunov function
    over the range as a linear matrix inequality.
multi
    Quadratic stability on a box of two or three parameters (a sum of squares).
rates
    :func:`lpvid.rate_stability`, :func:`lpvid.max_rate`: a parameter-dependent
    Lyapunov function for a bounded rate of variation (continuous time).
boxsos
    The matrix sums of squares on the box, their check, their size.
ranges
    Scheduling ranges for stability statements; ``A(p)`` as a polynomial.
enforce
    How the fits keep the frozen models stable (``stable=True``).
"""
