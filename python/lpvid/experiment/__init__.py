"""Where to measure next, from an identified model's covariance.

Modules
-------
nextpoints
    :func:`lpvid.next_points`, :func:`lpvid.suggest_points`: the scheduling
    values whose FRF would shrink the model's bands most.
design
    The information algebra behind it (frozen information, low-rank updates).
"""
