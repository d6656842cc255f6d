""":func:`lpvid.select`: the order and the basis chosen over a grid of identify runs.

Modules
-------
grid
    The runs over the grid of (order, basis) pairs, on any executor.
result
    :class:`lpvid.SelectResult` and :class:`lpvid.GridRow`: the grid and the choice.
"""
