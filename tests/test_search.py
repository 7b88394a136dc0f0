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
    return _find(ctx, 0.0, 1.0, tol, 0.0, 1.0)


@pytest.mark.parametrize("where", [0.0, 0.25, 1.0 / 3.0, 0.999999])
def test_bisect_brackets_the_event_to_the_tolerance(where):
    ctx = np.array([where, 0.0])
    lo, hi = _locate(ctx, 1e-12)
    assert lo <= where <= hi and hi - lo <= 1e-12
    assert ctx[1] <= math.ceil(math.log2(1.0 / 1e-12)) + 1  # one halving a predicate call


@entry()
def _locate_knowing(ctx, tol, a, b):
    return _find(ctx, 0.0, 1.0, tol, a, b)


@pytest.mark.parametrize("where", [0.25, 1.0 / 3.0, 0.7])
def test_bisect_that_knows_a_bracket_ends_bit_for_bit_where_it_would_with_fewer_calls(where):
    """Given a False at a and True at b, the bisection's final bracket is the one it finds when it
    evaluates every midpoint, and it evaluates only those inside (a, b)."""
    full = np.array([where, 0.0])
    lo, hi = _locate(full, 1e-12)
    for half_width in (1e-3, 1e-9, 1e-12):
        known = np.array([where, 0.0])
        assert _locate_knowing(known, 1e-12, where - half_width, where + half_width) == (lo, hi)
        assert known[1] <= max(0.0, math.log2(2.0 * half_width / 1e-12)) + 2, (half_width, known[1])
        assert known[1] < full[1]


@kernel()
def _excursion(ctx, x):
    """True on [ctx[0], ctx[1]) and from ctx[2] on: a change, a change back, and a change again."""
    ctx[3] += 1.0
    return (x >= ctx[0] and x < ctx[1]) or x >= ctx[2]


_find_excursion = S.bisector(_excursion, "test_bisect_excursion")
_check_excursion = S.checker(_excursion, "test_check_excursion")


@entry()
def _locate_checked(ctx, tol, a, b, n):
    a, b = _check_excursion(ctx, 0.0, 1.0, a, b, n)
    return _find_excursion(ctx, 0.0, 1.0, tol, a, b)


@pytest.mark.parametrize("first, back, n, same_as", [
    (1e-6, 0.4, 3, "plain"),  # the excursion holds the second midpoint, 0.25: tested
    (0.40, 0.44, 3, "trusting"),  # it holds only the fourth, 0.4375: not tested with 3
    (0.40, 0.44, 4, "plain"),
])
def test_a_checked_bracket_finds_the_change_the_bisection_finds_where_the_predicate_changes_back(
        first, back, n, same_as):
    """A bracket (a, b) of the last of three changes, at 0.45 (as a slot's margin brackets its own
    change, not another slot's change and change back before it): the bisection that trusts it
    ends there, the one that evaluates every midpoint at the excursion [first, back). With its
    first n midpoints outside (a, b) tested (search.checked), the bisection ends where the one
    without (a, b) does wherever the excursion holds one of them, and on (a, b) where not."""
    last = 0.45
    plain = _locate_checked(np.array([first, back, last, 0.0]), 1e-12, 0.0, 1.0, 0)
    trusting = _locate_checked(np.array([first, back, last, 0.0]), 1e-12, last - 1e-12, last + 1e-12, 0)
    checked = _locate_checked(np.array([first, back, last, 0.0]), 1e-12, last - 1e-12, last + 1e-12, n)
    assert plain[0] <= first <= plain[1] and trusting[0] <= last <= trusting[1]
    assert checked == (plain if same_as == "plain" else trusting)


@kernel()
def _cubic(ctx, x):
    ctx[1] += 1.0
    return ctx[0] - x - 4.0 * x ** 3


_root = S.root_finder(_cubic, "test_root_cubic")


@entry()
def _bracket(ctx, tol, max_evals):
    return _root(ctx, 0.0, 1.0, _cubic(ctx, 0.0), _cubic(ctx, 1.0), tol, max_evals)


@pytest.mark.parametrize("c", [0.01, 0.5, 2.0, 4.9])
def test_root_brackets_a_sign_change_to_the_tolerance_in_few_evaluations(c):
    """The Illinois method closes a bracket of the root of c - x - 4 x^3 on [0, 1] (q >= 0 at 0,
    < 0 at 1) to 1e-12 in well under the bisection's 40 evaluations."""
    ctx = np.array([c, 0.0])
    a, b = _bracket(ctx, 1e-12, 40)
    assert b - a <= 1e-12
    assert c - a - 4.0 * a ** 3 >= 0.0 > c - b - 4.0 * b ** 3
    assert ctx[1] - 2 <= 15, ctx[1]


def test_root_stops_after_its_evaluations_with_a_bracket():
    ctx = np.array([0.5, 0.0])
    a, b = _bracket(ctx, 1e-12, 2)
    assert ctx[1] - 2 == 2
    assert 0.0 <= a < b <= 1.0 and 0.5 - a - 4.0 * a ** 3 >= 0.0 > 0.5 - b - 4.0 * b ** 3


def test_root_at_the_bracket_s_start_closes_in_one_evaluation():
    """A quantity that is 0 at a and negative after it (a contact at zero depth that starts to
    penetrate at the step's start) has its root at a: one evaluation, tol / 2 past it, closes the
    bracket, where bisecting towards a would take all of max_evals."""
    ctx = np.array([0.0, 0.0])
    a, b = _bracket(ctx, 1e-12, 40)
    assert a == 0.0 and 0.0 < b <= 1e-12
    assert ctx[1] - 2 == 1


@pytest.mark.parametrize("a, b", [(0.5, 0.6), (0.1, 0.2)])
def test_a_bracket_that_misses_the_change_is_cut_at_the_end_that_fails(a, b):
    """search.checked tests the bracket's ends first: PRED already True at a (the change lies
    before it) or still False at b (after it); the bisection then ends where it ends without a
    bracket."""
    ctx = np.array([0.0, 0.0, 0.3, 0.0])  # one change, at 0.3
    plain = _locate_checked(ctx.copy(), 1e-12, 0.0, 1.0, 0)
    assert plain[0] <= 0.3 <= plain[1]
    assert _locate_checked(ctx.copy(), 1e-12, a, b, 0) == plain
