"""The integrator contract's searches (kernel/search.py) on closed forms: Brent's peak finder,
compiled as the scenes compile it (a template with the quantity bound), and the bisection."""
from __future__ import annotations

import math

import numpy as np
import pytest
from fencesweep.kernel import search as S
from fencesweep.kernel.jit import entry, kernel

pytestmark = pytest.mark.plain_python  # also run without Numba's JIT: tests/test_plain_python.py

TOL = 1e-6
#: Golden-section search needs log(TOL) / log(0.618) ~ 29 evaluations to reach TOL; Brent's
#: parabolic steps must do a smooth peak in well under that.
SMOOTH_EVALS = 15


@kernel()
def _parabola(ctx, x):
    ctx[1] += 1.0
    return 1.0 - 3.0 * (x - ctx[0]) ** 2


@kernel()
def _sine(ctx, x):
    ctx[1] += 1.0
    return math.sin(3.0 * x + ctx[0])


@kernel()
def _kink(ctx, x):
    ctx[1] += 1.0
    return -abs(x - ctx[0])


@kernel()
def _narrow(ctx, x):
    ctx[1] += 1.0
    return 1.0 / (1.0 + 400.0 * (x - ctx[0]) ** 2)


FINDERS = {q: S.peak_finder(q, f"test_peak{getattr(q, 'py_func', q).__name__}") for q in (_parabola, _sine, _kink, _narrow)}


def _entry(finder):
    """An entry point that Python can call around a compiled peak finder."""
    @entry()
    def run(ctx):
        return finder(ctx, 0.0, 1.0, TOL)
    return run


RUNS = {q: _entry(f) for q, f in FINDERS.items()}


def _run(q, ctx):
    return RUNS[q](ctx)


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
    assert value == getattr(q, "py_func", q)(ctx2, x)  # the value returned is the one at x
    if smooth:
        assert ctx[1] <= SMOOTH_EVALS, f"{ctx[1]:.0f} evaluations"
    else:
        assert ctx[1] <= 2 * math.log(TOL) / math.log(1.0 - S.CGOLD) + 5, f"{ctx[1]:.0f} evaluations"


@kernel()
def _past(ctx, x):
    ctx[1] += 1.0
    return x >= ctx[0]


_find = S.bisector(_past, "test_bisect_past")


@entry()
def _locate(ctx, tol):
    return _find(ctx, 0.0, 1.0, tol)


@pytest.mark.parametrize("where", [0.0, 0.25, 1.0 / 3.0, 0.999999])
def test_bisect_brackets_the_event_to_the_tolerance(where):
    ctx = np.array([where, 0.0])
    lo, hi = _locate(ctx, 1e-12)
    assert lo <= where <= hi and hi - lo <= 1e-12
    assert ctx[1] <= math.ceil(math.log2(1.0 / 1e-12)) + 1  # one halving a predicate call
