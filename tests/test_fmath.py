"""wooddecay.fmath: the C library's bits, whatever numpy is installed, within 2 ulp of numpy's own
loops, with numpy's ufunc conventions."""
from __future__ import annotations

import ctypes
import ctypes.util
import math

import numpy as np
import pytest

from wooddecay import fmath as fm

LIBM = ctypes.CDLL(ctypes.util.find_library("m"))
CASES = (("sin", "sin", np.sin, (-20.0, 20.0)), ("cos", "cos", np.cos, (-20.0, 20.0)),
         ("arccos", "acos", np.arccos, (-1.0, 1.0)), ("exp", "exp", np.exp, (-30.0, 30.0)),
         ("arctan2", "atan2", np.arctan2, (-5.0, 5.0)), ("hypot", "hypot", np.hypot, (-5.0, 5.0)),
         ("power", "pow", np.power, (0.0, 5.0)))


def _libm(name: str, nargs: int):
    f = getattr(LIBM, name)
    f.restype, f.argtypes = ctypes.c_double, [ctypes.c_double] * nargs
    return f


def _ulps(a, b):
    return np.abs(a - b) / np.spacing(np.maximum(np.abs(a), np.abs(b)))


@pytest.mark.parametrize("name, c_name, numpy_fn, span", CASES)
def test_is_the_c_library(name, c_name, numpy_fn, span):
    rng = np.random.default_rng(1)
    nargs = numpy_fn.nin
    args = [rng.uniform(*span, 20_000) for _ in range(nargs)]
    got = getattr(fm, name)(*args)
    ref = _libm(c_name, nargs)
    assert np.array_equal(got, np.array([ref(*v) for v in zip(*args)]))
    assert _ulps(got, numpy_fn(*args)).max() <= 2.0


def test_ufunc_conventions():
    x = np.linspace(0.0, 3.0, 12).reshape(3, 4)
    assert fm.sin(x).shape == (3, 4)
    assert np.array_equal(fm.arctan2(x, 2.0), np.array([[math.atan2(v, 2.0) for v in row] for row in x]))
    out = np.full_like(x, -7.0)
    assert fm.exp(x, out=out) is out and np.array_equal(out, np.array([[math.exp(v) for v in row] for row in x]))
    assert fm.cos(np.arange(3)).dtype == np.float64  # integers are cast
    with np.errstate(invalid="ignore"):
        assert math.isnan(float(fm.arccos(2.0)))
    assert float(fm.cos(0.5)) == math.cos(0.5)
