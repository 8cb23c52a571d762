"""Transcendental functions with the same bits under every numpy: numba ufuncs that call the C
library (``math`` in nopython mode compiles to libm's sin, cos, hypot, ...; Python's own
``math.hypot`` is not libm's).

numpy's own loops for sin, cos, arccos, arctan2, hypot, exp and power changed between 1.26 and 2.x
(vectorised implementations): the same scene built 1-2 ulp apart in thousands of elements, and a
bake's bits then hung on which numpy the machine had (docs/decisions.md, "One libm for every
numpy"). These ufuncs (broadcasting, ``out=``; not ``where=``) take numpy's place on the paths
that build the model and simulate it; integer powers there are products instead of ``**``.
"""
from __future__ import annotations

import math

import numba as nb

_F1 = ["float64(float64)"]
_F2 = ["float64(float64, float64)"]


@nb.vectorize(_F1, cache=True)
def sin(x):
    return math.sin(x)


@nb.vectorize(_F1, cache=True)
def cos(x):
    return math.cos(x)


@nb.vectorize(_F1, cache=True)
def arccos(x):
    return math.acos(x)


@nb.vectorize(_F2, cache=True)
def arctan2(y, x):
    return math.atan2(y, x)


@nb.vectorize(_F2, cache=True)
def hypot(x, y):
    return math.hypot(x, y)


@nb.vectorize(_F1, cache=True)
def exp(x):
    return math.exp(x)


@nb.vectorize(_F2, cache=True)
def power(x, y):
    return math.pow(x, y)
