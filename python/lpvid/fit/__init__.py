"""The fits: costs, Levenberg-Marquardt, the reweighted l2,1 fit, on FRFs and time records.

Modules
-------
cost
    V_NLS and its derivatives on FRF data (method.md (7), section 3).
fits
    :func:`lpvid.fit_nls`, :func:`lpvid.fit_l21`, :func:`lpvid.l21_path`.
timecost, timefit
    The output error on time records, and :func:`lpvid.fit_time`.
settings
    The typed settings of every fit and of :func:`lpvid.identify`, their defaults.
results
    :class:`lpvid.FitResult`, :class:`lpvid.L21Result`, :class:`lpvid.PathResult`.
judge
    How models are told apart: near-ties by the noise, then simplicity.
memory
    What a fit needs, what the process may still allocate (``_limits``).
"""
