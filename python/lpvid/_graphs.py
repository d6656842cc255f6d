"""Two small graph algorithms on dense numpy arrays: assignment and spanning tree.

Written here rather than taken from scipy.optimize and scipy.sparse.csgraph,
whose imports cost more than a second of the demo on a loaded 2-core machine
for problems of a few dozen nodes (poles to pair, scheduling points to join).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["assignment", "spanning_tree_walk"]


def assignment(cost: ArrayLike) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """Rows and columns of a minimum-cost perfect matching of a square cost matrix.

    The shortest augmenting path method with potentials (Hungarian algorithm
    in the form of Jonker and Volgenant), O(n^3); the same answer as
    ``scipy.optimize.linear_sum_assignment`` up to ties.

    Parameters
    ----------
    cost : array_like, shape (n, n)
        Finite costs.

    Returns
    -------
    rows, cols : ndarray of int
        ``rows = arange(n)`` and the column matched to each row.

    Examples
    --------
    >>> assignment([[4.0, 1.0], [2.0, 3.0]])[1]
    array([1, 0])

    """
    c = np.asarray(cost, dtype=float)
    if c.ndim != 2 or c.shape[0] != c.shape[1]:
        raise ValueError(f"cost: expected a square matrix, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        raise ValueError("cost: contains NaN or Inf")
    n = c.shape[0]
    u = np.zeros(n + 1)  # row potentials (1-based, 0 is the virtual row)
    v = np.zeros(n + 1)  # column potentials
    match = np.zeros(n + 1, dtype=int)  # match[j]: row matched to column j (0: none)
    way = np.zeros(n + 1, dtype=int)
    for i in range(1, n + 1):
        match[0] = i
        j0 = 0
        minv = np.full(n + 1, np.inf)
        used = np.zeros(n + 1, dtype=bool)
        while True:
            used[j0] = True
            i0 = match[j0]
            free = ~used[1:]
            cur = c[i0 - 1] - u[i0] - v[1:]
            better = free & (cur < minv[1:])
            minv[1:][better] = cur[better]
            way[1:][better] = j0
            cand = np.where(free, minv[1:], np.inf)
            j1 = int(np.argmin(cand)) + 1
            delta = cand[j1 - 1]
            u[match[used]] += delta
            v[used] -= delta
            minv[1:][free] -= delta
            j0 = j1
            if match[j0] == 0:
                break
        while j0:
            j1 = way[j0]
            match[j0] = match[j1]
            j0 = j1
    cols = np.empty(n, dtype=int)
    cols[match[1:] - 1] = np.arange(n)
    return np.arange(n), cols


def spanning_tree_walk(dist: ArrayLike, root: int) -> tuple[NDArray[np.int_], NDArray[np.int_]]:
    """Breadth-first walk from ``root`` of the minimum spanning tree of a distance matrix.

    Parameters
    ----------
    dist : array_like, shape (N, N)
        Symmetric distances (Prim's algorithm, O(N^2)).
    root : int

    Returns
    -------
    order : ndarray of int
        Points in visiting order, ``root`` first.
    parent : ndarray of int
        ``parent[k]``: the neighbour of point k on the tree nearer the root
        (-1 for the root).
    """
    d = np.asarray(dist, dtype=float)
    N = d.shape[0]
    tree_parent = np.full(N, -1)
    best = d[0].copy()
    link = np.zeros(N, dtype=int)
    inside = np.zeros(N, dtype=bool)
    inside[0] = True
    for _ in range(N - 1):
        k = int(np.argmin(np.where(inside, np.inf, best)))
        inside[k] = True
        tree_parent[k] = link[k]
        closer = ~inside & (d[k] < best)
        best[closer] = d[k][closer]
        link[closer] = k
    neighbours: list[list[int]] = [[] for _ in range(N)]
    for k in range(1, N):
        neighbours[k].append(int(tree_parent[k]))
        neighbours[int(tree_parent[k])].append(k)
    order, parent = [root], np.full(N, -1)
    seen = np.zeros(N, dtype=bool)
    seen[root] = True
    for k in order:  # grows while walking
        for m in sorted(neighbours[k]):
            if not seen[m]:
                seen[m] = True
                parent[m] = k
                order.append(m)
    return np.array(order), parent
