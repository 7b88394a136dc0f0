"""Scene `impact` (paper §4.1, MODEL.md §8): a material point m1 hits the fence's point at
distance R from the pivot with normal speed w.

The fence is rigid (I2 = inf), flexible (Kelvin element B2, K2 to a drive at rest) or free
(B2 = K2 = 0). For a small rotation theta the contact point moves R theta along the impact
normal, so
  D = y_p - R theta,  m1 y_p'' = -N,  I2 theta'' = N R - B2 theta' - K2 theta.
The impact ends at the first return of N to 0 after the onset, located on the dense output.
State: [y_p, y_p', theta, theta', impulse] (theta unused when rigid). The scene `freefall`
(scenes/freefall.py) is this one on a rigid wall.
"""
from __future__ import annotations

import math

import numpy as np
from fencesweep.kernel.jit import allocating, kernel

from fencesweep.kernel import integrate as I
from fencesweep.model import layout as Lp
from fencesweep.kernel import numerics as NU
from fencesweep.model import results as Rs
from fencesweep.model.contact import kelvin_force, pulse_time

N_STATE = 5
IW_RIGID, IW_FREE = 0, 1


@kernel(inline="always")
def penetration(y, p, rigid):
    """D and D' of the point against the fence point R theta (module docstring)."""
    if rigid:
        return y[0], y[1]
    return y[0] - p[Lp.R] * y[2], y[1] - p[Lp.R] * y[3]


@kernel()
def impact_rhs(t, y, p, iw, dy, aux):
    """Right-hand side while the point is in contact; aux[0] = the Kelvin force N (MODEL.md §4;
    the run ends where it returns to 0, so it is not clipped here)."""
    rigid = iw[IW_RIGID] != 0
    D, Dd = penetration(y, p, rigid)
    N = kelvin_force(max(D, 0.0), Dd, p[Lp.KC], p[Lp.CD], p[Lp.LAW])[0]
    dy[0] = y[1]
    dy[1] = -N / p[Lp.M1]
    dy[2] = 0.0
    dy[3] = 0.0
    if not rigid:
        free = iw[IW_FREE] != 0
        b2 = 0.0 if free else p[Lp.B2]
        k2 = 0.0 if free else p[Lp.K2]
        dy[2] = y[3]
        dy[3] = (N * p[Lp.R] - b2 * y[3] - k2 * y[2]) / p[Lp.I2]  # (A1)_4 with the drive at rest
    dy[4] = N
    aux[0] = N


@kernel()
def _force_at(ctx, theta):
    """The Kelvin force on the dense output (peak_max, and bisect of its return to 0)."""
    y0, Q, p, iw, tmp, dy, aux = ctx
    I.dense_eval(y0, Q, theta, tmp, N_STATE)
    impact_rhs(0.0, tmp, p, iw, dy, aux)
    return aux[0]


@kernel()
def _released(ctx, theta):
    return _force_at(ctx, theta) <= 0.0


@allocating()
def impact_kernel(p, rigid, free, w, out):
    """Integrate one impact from D = 0, D' = w until N first returns to 0 (the integrator of
    integrate.py at the tolerance p[TOL]); writes IMPACT_RESULTS into out."""
    for i in range(Rs.N_IMPACT_RESULTS):
        out[i] = math.nan
    y = np.zeros(N_STATE)
    y1 = np.zeros(N_STATE)
    tmp = np.zeros(N_STATE)
    dy = np.zeros(N_STATE)
    K = np.zeros((I.N_STAGES, N_STATE))
    Q = np.zeros((4, N_STATE))
    aux = np.zeros(1)
    iw = np.array([1 if rigid else 0, 1 if free else 0])
    m = p[Lp.M1] if rigid else 1.0 / (1.0 / p[Lp.M1] + p[Lp.R] ** 2 / p[Lp.I2])
    tp = pulse_time(p[Lp.LAW], m, p[Lp.KC], w)
    tol = p[Lp.TOL]
    rr = p[Lp.R] if p[Lp.R] > 0.0 else 1.0  # (a rigid wall has no R)
    atol = np.empty(N_STATE)  # scales: the pulse's penetration w tp, the speed w, the impulse m1 w
    for i, sc in enumerate((w * tp, w, w * tp / rr, w / rr, p[Lp.M1] * w)):
        atol[i] = tol * sc
    y[1] = w
    impact_rhs(0.0, y, p, iw, K[0], aux)
    peak = aux[0]  # the linear law jumps to b w at contact
    half_side = 0.5 * min(p[Lp.LL], p[Lp.AA])
    t, h, dmax, status, steps = 0.0, 1e-3 * tp, 0.0, Rs.ST_MAXSTEPS, 0
    while steps < NU.MAX_STEPS:
        err = I.take_step(I.METHOD_DOPRI5, impact_rhs, t, y, h, p, iw, K, tmp, y1, aux, atol, tol, N_STATE)
        if not (err <= 1.0):
            h = I.next_step(h, err, NU.SAFETY, NU.FAC_MIN, 1.0) if err == err else NU.FAC_MIN * h
            if h < NU.H_MIN * tp:
                status = Rs.ST_UNDERFLOW
                break
            continue
        steps += 1
        I.dense_coeffs(I.METHOD_DOPRI5, K, h, y, y1, Q, N_STATE)
        ctx = (y, Q, p, iw, tmp, dy, aux)
        theta = 1.0
        if _released(ctx, 1.0):
            theta = I.bisect(_released, ctx, 0.0, 1.0, NU.EVENT_TOL * tp / h)[1]
        d = 1e-3 * theta
        if _force_at(ctx, d) > _force_at(ctx, 0.0) and _force_at(ctx, theta - d) > _force_at(ctx, theta):
            peak = max(peak, I.peak_max(_force_at, ctx, 0.0, theta, NU.PEAK_TOL)[1])
        peak = max(peak, _force_at(ctx, theta))
        I.dense_eval(y, Q, theta, y1, N_STATE)
        D1, Dd1 = penetration(y1, p, rigid)
        dmax = max(dmax, D1)
        if not math.isfinite(D1):
            status = Rs.ST_NONFINITE
            break
        if D1 > half_side:
            status = Rs.ST_PENETRATION
            break
        if theta < 1.0:
            out[Rs.RJ_PEAK_FORCE] = peak
            out[Rs.RJ_IMPULSE] = y1[4]
            out[Rs.RJ_CONTACT_TIME] = t + theta * h
            out[Rs.RJ_E_EFF] = -Dd1 / w
            status = Rs.ST_OK
            break
        t += h
        y[:] = y1
        K[0, :] = K[6, :]
        h = I.next_step(h, err, NU.SAFETY, NU.FAC_MIN, NU.FAC_MAX)
    out[Rs.RJ_MAX_PENETRATION] = dmax
    out[Rs.RJ_N_STEPS] = steps
    out[Rs.RJ_STATUS] = status
