"""The LPV state-space model and what is read from it.

Modules
-------
lpv
    :class:`lpvid.LpvModel` (method.md (1)-(5)).
layout
    Free and fixed parameters (the mask over theta).
groups
    Group magnitudes: the paper's Tables 1-4.
frozen
    Frozen LTI models: matrices, poles, stability, frequency response.
similarity
    The directions in which a realisation moves without changing its response.
file
    The versioned JSON model file.
handoff
    The model handed on: python-control, MATLAB.

``_protocol`` (what the helpers read from a model), ``_view`` (the core's
view of a model) and ``_simulate`` (the body of ``LpvModel.simulate``) are
private.
"""
