"""Searches on a step's dense output: an event locator (bisection of a predicate), a root finder
(the Illinois method, for a guess at an event from a quantity that changes sign with it) and a
peak finder (Brent's search of a quantity's maximum). The predicate or quantity is a compiled
function `f(ctx, theta)` of the fraction theta of the step and a tuple `ctx` the caller packs
(the step's start, its dense output, the scene's parameters and work arrays): events and peaks
are passed in as data, as scipy.integrate._ivp passes its event functions. `bisector(pred,
name)`, `checker(pred, name)`, `root_finder(q, name)` and `peak_finder(q, name)` compile the templates with the scene's function bound
(kernel/jit.py specialise).
"""
from __future__ import annotations

import math

from fencesweep.kernel.jit import kernel, specialise

#: the scene's predicate in `bisect`, quantity in `root` and `peak_max`, bound by bisector,
#: root_finder and peak_finder
PRED = QUANTITY = None


def bisector(pred, name: str):
    """`bisect` with the predicate `pred`, compiled as the kernel function `name`."""
    return specialise(bisect, name, PRED=pred)


def checker(pred, name: str):
    """`checked` with the predicate `pred`, compiled as the kernel function `name`."""
    return specialise(checked, name, PRED=pred)


def peak_finder(q, name: str):
    """`peak_max` with the quantity `q`, compiled as the kernel function `name`."""
    return specialise(peak_max, name, QUANTITY=q)


def root_finder(q, name: str):
    """`root` with the quantity `q`, compiled as the kernel function `name`."""
    return specialise(root, name, QUANTITY=q)


def bisect(ctx, lo, hi, tol, a, b):
    """Event location: PRED(ctx, lo) is False and PRED(ctx, hi) is True; returns the final
    bracket (lo, hi), hi - lo <= tol, with the event in it (hi is just past the event). The
    caller may know more: PRED is False at a and True at b (a = lo, b = hi: nothing more), so
    that it is evaluated only at the midpoints inside (a, b), the others taken as False at or
    before a and True at or after b. For a PRED that changes once on [lo, hi] the bracket is the
    same, bit for bit, as with every midpoint evaluated. A template: PRED is the scene's
    (`bisector`)."""
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if mid >= b or (mid > a and PRED(ctx, mid)):
            hi = mid
        else:
            lo = mid
    return lo, hi


def checked(ctx, lo, hi, a, b, n):
    """A bracket (a, b) that `bisect` on [lo, hi] is to take as known (from a quantity whose sign
    change makes PRED's, `root`), checked where `bisect` would take PRED as known: at its ends
    (False at a, True at b; an end that fails cuts the bracket there, as the change is then
    outside it), then at the first n midpoints outside it. Where PRED is found otherwise at one,
    it changes more than once in [lo, hi], and the bracket returned is the one the bisection
    without (a, b) had reached there, with that midpoint's true value, so that `bisect` goes on
    from it as without (a, b). A template: PRED is the scene's (`checker`)."""
    if a > lo and PRED(ctx, a):
        return lo, a
    if b < hi and not PRED(ctx, b):
        return b, hi
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        if mid > a and mid < b:
            break
        hit = PRED(ctx, mid)
        if hit != (mid >= b):
            return (lo, mid) if hit else (mid, hi)
        if hit:
            hi = mid
        else:
            lo = mid
    return a, b


def root(ctx, a, b, qa, qb, tol, max_evals):
    """A bracket [a, b] of a sign change of QUANTITY(ctx, theta) from qa >= 0 at a to qb < 0 at b,
    shrunk by the Illinois method (regula falsi, the weight of an end kept twice in a row
    halved: Dahlquist & Bjorck, Numerical Methods, 1974, §6.2) until b - a <= tol or after
    max_evals evaluations; returns (a, b). An estimate within tol / 2 of an end is moved to tol / 2
    from it, so that once the estimates converge, the next lands past the root and closes the
    bracket (as Brent's zeroin does). A template: QUANTITY is the scene's (`root_finder`)."""
    kept = 0  # +1: a was kept by the last evaluation, -1: b was
    for _ in range(max_evals):
        if b - a <= tol:
            break
        c = a - qa * (b - a) / (qb - qa)  # = a where qa = 0: a root at a closes in one evaluation
        if not (c >= a and c <= b):
            c = 0.5 * (a + b)
        c = min(max(c, a + 0.5 * tol), b - 0.5 * tol)  # an estimate at an end steps over the root
        qc = QUANTITY(ctx, c)
        if qc >= 0.0:
            a, qa = c, qc
            if kept == -1:
                qb *= 0.5
            kept = -1
        else:
            b, qb = c, qc
            if kept == 1:
                qa *= 0.5
            kept = 1
    return a, b


#: (3 - sqrt 5) / 2: the golden-section fraction of Brent's search
CGOLD = 0.3819660112501051


def peak_max(ctx, lo, hi, tol):
    """Maximum of a unimodal QUANTITY(ctx, theta) on [lo, hi] to within tol in theta, by Brent's
    search (Brent 1973, "Algorithms for Minimization without Derivatives", ch. 5, procedure
    localmin, applied to -q): successive parabolic interpolation through the three best
    points, falling back to a golden-section step whenever the parabola's step is not
    acceptable, so it never takes many more evaluations than golden-section search and, on
    a smooth peak, converges superlinearly (~10 evaluations to 1e-6 of the step against
    ~30). Returns (theta, q) of the best point seen. A template: QUANTITY is the scene's
    (`peak_finder`)."""
    a = lo
    b = hi
    x = a + CGOLD * (b - a)  # the best point; w the second best, v the previous w
    w = x
    v = x
    fx = -QUANTITY(ctx, x)
    fw = fx
    fv = fx
    d = 0.0  # the last step, and e the one before it
    e = 0.0
    tol1 = 0.5 * tol  # x ends within 2 tol1 = tol of both ends of the final bracket
    while abs(x - 0.5 * (a + b)) > 2.0 * tol1 - 0.5 * (b - a):
        d, e = _brent_step(a, b, x, w, v, fx, fw, fv, d, e, tol1)
        if abs(d) >= tol1:
            u = x + d
        else:
            u = x + tol1 if d > 0.0 else x - tol1
        fu = -QUANTITY(ctx, u)
        a, b, x, w, v, fx, fw, fv = _brent_keep(a, b, x, w, v, fx, fw, fv, u, fu)
    return x, -fx


@kernel(inline=True)
def _brent_step(a, b, x, w, v, fx, fw, fv, d, e, tol1):
    """peak_max's next step from x and the step before it (the new (d, e)): the vertex of the
    parabola through (v, fv), (w, fw), (x, fx) when it lies inside [a, b] and moves less than
    half the step before last, else a golden-section step into the larger part of [a, b]."""
    m = 0.5 * (a + b)
    if abs(e) > tol1:
        r = (x - w) * (fx - fv)
        qq = (x - v) * (fx - fw)
        pp = (x - v) * qq - (x - w) * r
        qq = 2.0 * (qq - r)
        if qq > 0.0:
            pp = -pp
        else:
            qq = -qq
        if abs(pp) < abs(0.5 * qq * e) and pp > qq * (a - x) and pp < qq * (b - x):
            step = pp / qq
            if x + step - a < 2.0 * tol1 or b - (x + step) < 2.0 * tol1:
                step = tol1 if x < m else -tol1
            return step, d
    e = (b - x) if x < m else (a - x)
    return CGOLD * e, e


@kernel(inline=True)
def _brent_keep(a, b, x, w, v, fx, fw, fv, u, fu):
    """peak_max's bracket [a, b] and its three best points after evaluating u (fu = -q)."""
    if fu <= fx:
        if u < x:
            b = x
        else:
            a = x
        return a, b, u, x, w, fu, fx, fw
    if u < x:
        a = u
    else:
        b = u
    if fu <= fw or w == x:
        return a, b, x, u, w, fx, fu, fw
    if fu <= fv or v == x or v == w:
        return a, b, x, w, u, fx, fw, fu
    return a, b, x, w, v, fx, fw, fv


@kernel(inline=True)
def hermite_max(q0, d0, q1, d1):
    """The largest interior maximum on (0, 1) of the cubic with q(0) = q0, q'(0) = d0, q(1) = q1,
    q'(1) = d1 (derivatives in the unit of the interval), -inf when it has none. With the
    values and rates of a quantity at a step's ends, it says whether the step can hold a
    maximum above them (a minimum below them, of -q), and about how high: the cubic is the
    quantity to O(h^4) (docs/model.md (15.9))."""
    c2 = 3.0 * (q1 - q0) - 2.0 * d0 - d1
    c3 = 2.0 * (q0 - q1) + d0 + d1
    best = -math.inf
    # q'(s) = d0 + 2 c2 s + 3 c3 s^2 = 0, a maximum where q''(s) = 2 c2 + 6 c3 s < 0
    a, b, c = 3.0 * c3, 2.0 * c2, d0
    if abs(a) <= 1e-12 * (abs(b) + abs(c)):
        roots = (-c / b if b != 0.0 else -1.0, -1.0)
    else:
        disc = b * b - 4.0 * a * c
        if disc < 0.0:
            return best
        r = math.sqrt(disc)
        roots = ((-b - r) / (2.0 * a), (-b + r) / (2.0 * a))
    for s in roots:
        if 0.0 < s < 1.0 and 2.0 * c2 + 6.0 * c3 * s < 0.0:
            best = max(best, q0 + s * (d0 + s * (c2 + s * c3)))
    return best
