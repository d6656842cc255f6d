""":func:`lpvid.identify`: the whole identification, from checked problem to chosen model.

Modules
-------
problem
    :class:`lpvid.Problem`: data, order, basis and settings, checked once.
capacity
    How many parameters a data set can determine (the order check).
run
    The pipeline: local models, initial models, NLS, the l2,1 path, the choice.
path
    The l2,1 path of identify, kept from trading away interpolation.
result
    :class:`lpvid.IdentifyResult`: the models of the path and the choice.
"""
