"""Distinct rows of a 2-D array, without numpy's structured comparisons.

``numpy.unique(a, axis=0)`` compares the rows as structured values, and a
Ctrl-C that arrives during that comparison comes out of numpy as a
``TypeError`` ("Cannot compare structured arrays unless they have a common
dtype"): ``lpvid demo`` then exited 1 with that message where it must exit
130 (seen once in ``tests/test_interrupt.py``, the signal landing in
:func:`lpvid.consistency`). Here the rows are sorted by ``numpy.lexsort``
and compared entry by entry, plain float comparisons that let the
interrupt through.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["unique_rows"]


def unique_rows(a: ArrayLike) -> tuple[NDArray, NDArray[np.intp], NDArray[np.intp]]:
    """The distinct rows of ``a``, where each first occurs, and how often.

    As ``numpy.unique(a, axis=0, return_index=True, return_counts=True)``:
    the rows in lexicographic order (rows equal entry by entry count as one,
    ``-0.0`` as ``0.0``), the index of each one's first occurrence, its count.
    """
    arr = np.asarray(a)
    if arr.ndim != 2:
        raise ValueError(f"unique_rows: expected a 2-dimensional array, got shape {arr.shape}")
    n = arr.shape[0]
    # lexsort sorts by its last key first, and stably: equal rows keep
    # their order, so the first of each run is its first occurrence.
    order = np.lexsort(arr.T[::-1]) if arr.shape[1] else np.arange(n)
    ranked = arr[order]
    starts = np.ones(n, dtype=bool)
    starts[1:] = np.any(ranked[1:] != ranked[:-1], axis=1)
    first = np.flatnonzero(starts)
    counts = np.diff(np.append(first, n))
    return ranked[first], order[first], counts
