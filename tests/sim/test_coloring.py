"""The REG edges' greedy colouring (wooddecay.sim.rods.color_edges): no two edges of a colour share
a particle, the colours are those of a plain-Python greedy pass, and a dense REG (a wide
connect_radius) may need more than the 256 colours the kernel once stopped at."""
from __future__ import annotations

import numpy as np

from wooddecay.sim.rods import color_edges


def greedy_reference(edges, fp):
    """First free colour per edge in edge order, a colour being free if none of the edge's four
    particles holds it yet."""
    taken: dict[int, set[int]] = {}
    colour = []
    for i, j in edges:
        parts = (fp[i], fp[i] + 1, fp[j], fp[j] + 1)
        busy = set().union(*(taken.get(p, set()) for p in parts))
        c = next(c for c in range(len(edges) + 1) if c not in busy)
        colour.append(c)
        for p in parts:
            taken.setdefault(p, set()).add(c)
    return np.array(colour)


def colours_of(ptr, order, m):
    colour = np.empty(m, dtype=np.int64)
    for c in range(len(ptr) - 1):
        colour[order[ptr[c]:ptr[c + 1]]] = c
    return colour


def test_a_dense_reg_is_coloured_like_the_reference_past_256_colours():
    rng = np.random.default_rng(3)
    n = 60  # elements of 60 one-element strands, each joined to all others: 1,770 edges
    fp = 2 * np.arange(n)
    edges = np.array([(i, j) for i in range(n) for j in range(i + 1, n)])
    edges = edges[rng.permutation(len(edges))]
    ptr, order = color_edges(edges, fp, 2 * n)
    colour = colours_of(ptr, order, len(edges))
    np.testing.assert_array_equal(colour, greedy_reference(edges, fp))
    assert colour.max() + 1 >= n - 1  # a clique of 60 needs at least 59 colours
    for c in range(colour.max() + 1):
        e = edges[colour == c]
        parts = np.concatenate([fp[e[:, 0]], fp[e[:, 0]] + 1, fp[e[:, 1]], fp[e[:, 1]] + 1])
        assert len(np.unique(parts)) == len(parts)


def test_more_than_256_colours():
    n = 300
    fp = 2 * np.arange(n)
    edges = np.array([(0, j) for j in range(1, n)])  # a star: every edge shares element 0
    ptr, order = color_edges(edges, fp, 2 * n)
    assert len(ptr) - 1 == n - 1 > 256
    np.testing.assert_array_equal(colours_of(ptr, order, len(edges)), greedy_reference(edges, fp))
