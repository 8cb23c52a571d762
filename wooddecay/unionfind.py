"""Union-find for connected components in numba kernels, labelled deterministically.

A root is always its tree's smallest node (:func:`union` joins under the smaller root), and
:func:`labels` numbers the components in order of their smallest node, the order scipy's
``connected_components`` gives, so a kernel built on it has scipy's labels for any input.
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def root(parent, i):
    """Root of ``i`` in the union-find forest, halving the path on the way."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@nb.njit(cache=True)
def union(parent, a, b):
    """Join the trees of ``a`` and ``b`` under the smaller root, so a root is its component's
    smallest node."""
    ra, rb = root(parent, a), root(parent, b)
    parent[max(ra, rb)] = min(ra, rb)


@nb.njit(cache=True)
def labels(parent):
    """Component label per node, in order of each component's smallest node (serial)."""
    n = len(parent)
    label = np.full(n, -1, dtype=np.int64)
    count = 0
    for i in range(n):
        r = root(parent, i)
        if label[r] < 0:
            label[r] = count
            count += 1
        label[i] = label[r]
    return label
