"""The integrator contract shared by every scene (in the spirit of scipy.integrate._ivp).

A scene supplies a right-hand side `fun(t, y, p, iw, dy, aux)` (compiled, passed as an
argument); this module supplies
  * `take_step`: one explicit Runge-Kutta step of a method chosen by code, returning the
    weighted error estimate (0 for the fixed-step RK4 baseline);
  * `dense_coeffs` / `dense_eval`: the step's continuous extension
    y(t0 + theta h) = y0 + Q0 theta + Q1 theta^2 + Q2 theta^3 + Q3 theta^4;
  * `error_norm` and `next_step`: the standard step-size controller;
  * `bisect` and `peak_max`: an event locator (a predicate on the dense output) and a
    peak finder (a quantity maximised on the dense output, Brent's search).

Methods (numerics.py says which is the default and why):
  METHOD_DOPRI5  Dormand-Prince 5(4), FSAL, local extrapolation (Dormand & Prince 1980;
                 Hairer, Norsett & Wanner, Solving ODEs I, Table II.5.2); 4th-order dense
                 output of Shampine (1986), the coefficients scipy's RK45 uses.
  METHOD_RK4     classical RK4 (Kutta 1901) at a fixed step, cubic Hermite dense output
                 (Hairer et al. II.6, eq. 6.7): the baseline of the previous engine.
"""
from __future__ import annotations

import math

from fencesweep.kernel.jit import kernel

METHOD_DOPRI5, METHOD_RK4 = 0, 1
N_STAGES = 7  # stage vectors kept per step (DOPRI5: 6 + the FSAL stage f(t + h, y1))

# ---- Dormand-Prince 5(4): nodes c, coefficients a_ij, error weights e_j (5th minus 4th order),
# dense-output weights p_jk (scipy's RK45 `P`); scalars, so that Numba caches them as constants ----
C2, C3, C4, C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
A21 = 1 / 5
A31, A32 = 3 / 40, 9 / 40
A41, A42, A43 = 44 / 45, -56 / 15, 32 / 9
A51, A52, A53, A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
A61, A62, A63, A64, A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
B1, B3, B4, B5, B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84  # = a7j (FSAL)
DP_E = (-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40)
DP_P = (
    (1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432),
    (0.0, 0.0, 0.0, 0.0),
    (0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799),
    (0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072),
    (0.0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632),
    (0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844),
    (0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423),
)
DP_ORDER_EST = 4  # order of the error estimate: the controller's exponent is 1 / (4 + 1)


@kernel(inline="always")
def dopri5_step(fun, t, y, h, p, iw, K, tmp, y1, aux):
    """One DOPRI5 step from (t, y) with K[0] = f(t, y) given. Fills K[1..6] (K[6] is
    f(t + h, y1): the FSAL stage, also the error estimate's last stage) and y1."""
    n = y.shape[0]
    for m in range(n):
        tmp[m] = y[m] + h * A21 * K[0, m]
    fun(t + C2 * h, tmp, p, iw, K[1], aux)
    for m in range(n):
        tmp[m] = y[m] + h * (A31 * K[0, m] + A32 * K[1, m])
    fun(t + C3 * h, tmp, p, iw, K[2], aux)
    for m in range(n):
        tmp[m] = y[m] + h * (A41 * K[0, m] + A42 * K[1, m] + A43 * K[2, m])
    fun(t + C4 * h, tmp, p, iw, K[3], aux)
    for m in range(n):
        tmp[m] = y[m] + h * (A51 * K[0, m] + A52 * K[1, m] + A53 * K[2, m] + A54 * K[3, m])
    fun(t + C5 * h, tmp, p, iw, K[4], aux)
    for m in range(n):
        tmp[m] = y[m] + h * (A61 * K[0, m] + A62 * K[1, m] + A63 * K[2, m] + A64 * K[3, m] + A65 * K[4, m])
    fun(t + h, tmp, p, iw, K[5], aux)
    for m in range(n):
        y1[m] = y[m] + h * (B1 * K[0, m] + B3 * K[2, m] + B4 * K[3, m] + B5 * K[4, m] + B6 * K[5, m])
    fun(t + h, y1, p, iw, K[6], aux)


# ---- classical RK4 ----
RK4_C = (0.0, 0.5, 0.5, 1.0)
RK4_B = (1 / 6, 1 / 3, 1 / 3, 1 / 6)


@kernel(inline="always")
def rk4_step(fun, t, y, h, p, iw, K, tmp, y1, aux):
    """One classical RK4 step with K[0] = f(t, y) given; K[6] = f(t + h, y1) on return."""
    n = y.shape[0]
    for i in range(1, 4):
        for m in range(n):
            tmp[m] = y[m] + RK4_C[i] * h * K[i - 1, m]
        fun(t + RK4_C[i] * h, tmp, p, iw, K[i], aux)
    for m in range(n):
        y1[m] = y[m] + h * (RK4_B[0] * K[0, m] + RK4_B[1] * K[1, m] + RK4_B[2] * K[2, m] + RK4_B[3] * K[3, m])
    fun(t + h, y1, p, iw, K[6], aux)


@kernel(inline="always")
def take_step(method, fun, t, y, h, p, iw, K, tmp, y1, aux, atol, rtol, n_ctrl):
    """One step of `method`; returns the error norm of the step (acceptable when <= 1;
    0 for the fixed-step RK4, which has no estimate)."""
    if method == METHOD_RK4:
        rk4_step(fun, t, y, h, p, iw, K, tmp, y1, aux)
        return 0.0
    dopri5_step(fun, t, y, h, p, iw, K, tmp, y1, aux)
    return error_norm(K, h, y, y1, atol, rtol, n_ctrl)


@kernel()
def error_norm(K, h, y0, y1, atol, rtol, n_ctrl):
    """RMS over the first n_ctrl components of e_i / sc_i, with e = h sum_k E_k K_k the
    difference of the 5th- and 4th-order solutions and sc_i = atol_i + rtol max(|y0_i|, |y1_i|)
    (Hairer et al. II.4, eq. 4.11). A component with atol_i = inf is not controlled."""
    acc = 0.0
    for m in range(n_ctrl):
        e = 0.0
        for k in range(N_STAGES):
            e += DP_E[k] * K[k, m]
        r = h * e / (atol[m] + rtol * max(abs(y0[m]), abs(y1[m])))
        acc += r * r
    return math.sqrt(acc / n_ctrl)


@kernel()
def dense_coeffs(method, K, h, y0, y1, Q, n):
    """Coefficients Q[0..3] of the step's continuous extension (module docstring)."""
    if method == METHOD_RK4:
        for m in range(n):  # cubic Hermite of (y0, f0, y1, f1) in powers of theta
            d = y1[m] - y0[m]
            Q[0, m] = h * K[0, m]
            Q[1, m] = 3.0 * d - h * (2.0 * K[0, m] + K[6, m])
            Q[2, m] = -2.0 * d + h * (K[0, m] + K[6, m])
            Q[3, m] = 0.0
        return
    for j in range(4):
        for m in range(n):
            acc = 0.0
            for k in range(N_STAGES):
                acc += K[k, m] * DP_P[k][j]
            Q[j, m] = h * acc


@kernel(inline="always")
def dense_eval(y0, Q, theta, out, n):
    """y(t0 + theta h) on the first n components (Horner in theta)."""
    for m in range(n):
        out[m] = y0[m] + theta * (Q[0, m] + theta * (Q[1, m] + theta * (Q[2, m] + theta * Q[3, m])))


@kernel(inline="always")
def next_step(h, err, safety, fac_min, fac_max):
    """Step after one with error norm err (II.4, eq. 4.13): h (1/err)^(1/5), damped by a
    safety factor and kept within [fac_min, fac_max] times h."""
    if err == 0.0:
        return h * fac_max
    fac = safety * err ** (-1.0 / (DP_ORDER_EST + 1))
    return h * min(fac_max, max(fac_min, fac))


@kernel(inline="always")
def bisect(pred, ctx, lo, hi, tol):
    """Event location: pred(ctx, lo) is False and pred(ctx, hi) is True; returns the final
    bracket (lo, hi), hi - lo <= tol, with the event in it (hi is just past the event)."""
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if pred(ctx, mid):
            hi = mid
        else:
            lo = mid
    return lo, hi


#: (3 - sqrt 5) / 2: the golden-section fraction of Brent's search
CGOLD = 0.3819660112501051


@kernel(inline="always")
def peak_max(q, ctx, lo, hi, tol):
    """Maximum of a unimodal q(ctx, theta) on [lo, hi] to within tol in theta, by Brent's
    search (Brent 1973, "Algorithms for Minimization without Derivatives", ch. 5, procedure
    localmin, applied to -q): successive parabolic interpolation through the three best
    points, falling back to a golden-section step whenever the parabola's step is not
    acceptable, so it never takes many more evaluations than golden-section search and, on
    a smooth peak, converges superlinearly (~10 evaluations to 1e-6 of the step against
    ~30). Returns (theta, q) of the best point seen."""
    a = lo
    b = hi
    x = a + CGOLD * (b - a)  # the best point; w the second best, v the previous w
    w = x
    v = x
    fx = -q(ctx, x)
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
        fu = -q(ctx, u)
        a, b, x, w, v, fx, fw, fv = _brent_keep(a, b, x, w, v, fx, fw, fv, u, fu)
    return x, -fx


@kernel(inline="always")
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


@kernel(inline="always")
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


@kernel(inline="always")
def hermite_basis(s, h):
    """Weights of y0, h f0, y1, h f1 (the last two scaled by h) in the cubic Hermite
    interpolant at fraction s of an interval of size h: h00 = 2s^3 - 3s^2 + 1,
    h10 = s^3 - 2s^2 + s, h01 = -2s^3 + 3s^2, h11 = s^3 - s^2 (the drive table's interpolant)."""
    s2 = s * s
    s3 = s2 * s
    return 2.0 * s3 - 3.0 * s2 + 1.0, (s3 - 2.0 * s2 + s) * h, -2.0 * s3 + 3.0 * s2, (s3 - s2) * h
