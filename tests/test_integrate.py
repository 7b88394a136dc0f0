"""The integrator contract's peak finder (integrate.peak_max, Brent's search) on closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from fencesweep.kernel import integrate as I

TOL = 1e-6
#: Golden-section search needs log(TOL) / log(0.618) ~ 29 evaluations to reach TOL; Brent's
#: parabolic steps must do a smooth peak in well under that.
SMOOTH_EVALS = 15


@njit
def _parabola(ctx, x):
    ctx[1] += 1.0
    return 1.0 - 3.0 * (x - ctx[0]) ** 2


@njit
def _sine(ctx, x):
    ctx[1] += 1.0
    return math.sin(3.0 * x + ctx[0])


@njit
def _kink(ctx, x):
    ctx[1] += 1.0
    return -abs(x - ctx[0])


@njit
def _narrow(ctx, x):
    ctx[1] += 1.0
    return 1.0 / (1.0 + 400.0 * (x - ctx[0]) ** 2)


@njit
def _run(q, ctx):
    return I.peak_max(q, ctx, 0.0, 1.0, TOL)


CASES = [  # (function, its parameter, where its maximum on [0, 1] is, smooth there)
    (_parabola, 0.3, 0.3, True),
    (_parabola, 0.999, 0.999, True),
    (_parabola, 1.7, 1.0, False),  # the maximum at an end of the window
    (_parabola, -0.5, 0.0, False),
    (_sine, 0.2, (math.pi / 2 - 0.2) / 3, True),
    (_kink, 0.61, 0.61, False),  # no parabola fits a kink: the golden-section fallback
    (_narrow, 0.05, 0.05, True),
]


@pytest.mark.parametrize("q, c, where, smooth", CASES)
def test_peak_max_finds_the_maximum(q, c, where, smooth):
    ctx = np.array([c, 0.0])
    x, value = _run(q, ctx)
    assert abs(x - where) <= TOL
    ctx2 = np.array([c, 0.0])
    assert value == q.py_func(ctx2, x)  # the value returned is the one at x
    if smooth:
        assert ctx[1] <= SMOOTH_EVALS, f"{ctx[1]:.0f} evaluations"
    else:
        assert ctx[1] <= 2 * math.log(TOL) / math.log(1.0 - I.CGOLD) + 5, f"{ctx[1]:.0f} evaluations"
