"""Searches on a step's dense output: an event locator (bisection of a predicate) and a peak
finder (Brent's search of a quantity's maximum). The predicate or quantity is a compiled
function `f(ctx, theta)` of the fraction theta of the step and a tuple `ctx` the caller packs
(the step's start, its dense output, the scene's parameters and work arrays): events and peaks
are passed in as data, as scipy.integrate._ivp passes its event functions. `bisector(pred,
name)` and `peak_finder(q, name)` compile the two templates with the scene's function bound
(kernel/jit.py specialise).
"""
from __future__ import annotations

from fencesweep.kernel.jit import kernel, specialise

#: the scene's predicate in `bisect` and quantity in `peak_max`, bound by bisector / peak_finder
PRED = QUANTITY = None


def bisector(pred, name: str):
    """`bisect` with the predicate `pred`, compiled as the kernel function `name`."""
    return specialise(bisect, name, PRED=pred)


def peak_finder(q, name: str):
    """`peak_max` with the quantity `q`, compiled as the kernel function `name`."""
    return specialise(peak_max, name, QUANTITY=q)


def bisect(ctx, lo, hi, tol):
    """Event location: PRED(ctx, lo) is False and PRED(ctx, hi) is True; returns the final
    bracket (lo, hi), hi - lo <= tol, with the event in it (hi is just past the event). A
    template: PRED is the scene's (`bisector`)."""
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if PRED(ctx, mid):
            hi = mid
        else:
            lo = mid
    return lo, hi


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
