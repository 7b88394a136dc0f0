"""Scenes `impact` (paper §4.1) and `freefall` (MODEL.md §7): a material point m1 hits an
obstacle with normal speed w.

impact: the obstacle is the fence's point at distance R from the pivot; rigid (I2 = inf),
flexible (Kelvin element B2, K2 to a drive at rest) or free (B2 = K2 = 0). For a small
rotation theta the contact point moves R theta along the impact normal, so
  D = y_p - R theta,  m1 y_p'' = -N,  I2 theta'' = N R - B2 theta' - K2 theta.
freefall: the same point on a rigid wall with w = v_H = sqrt(2 g H), no gravity during contact.
Both end at the first return of N to 0 after the onset.
State: [y_p, y_p', theta, theta', impulse] (theta unused when rigid).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import layout as Lp
from ..contact import normal_force
from ..integrate import axpy, hermite, parabola_peak, rk4_combine
from .. import results as Rs
from ..results import N_IMPACT_RESULTS, ST_OK, ST_PENETRATION, ST_NONFINITE, ST_MAXSTEPS

N_STATE = 5


@njit(cache=True)
def impact_rhs(y, p, rigid, free, dy):
    """Right-hand side of the point-on-fence impact; returns the normal force N [N]."""
    R = p[Lp.R]
    if rigid:
        D = y[0]
        Dd = y[1]
    else:
        D = y[0] - R * y[2]
        Dd = y[1] - R * y[3]
    N = 0.0
    if D > 0.0 or (D == 0.0 and Dd > 0.0):  # the contact starts at D = 0 with D' = w > 0
        N = normal_force(D, Dd, p[Lp.KC], p[Lp.CD], p[Lp.LAW])[0]
    dy[0] = y[1]
    dy[1] = -N / p[Lp.M1]
    if rigid:
        dy[2] = 0.0
        dy[3] = 0.0
    else:
        b2 = 0.0 if free else p[Lp.B2]
        k2 = 0.0 if free else p[Lp.K2]
        dy[2] = y[3]
        dy[3] = (N * R - b2 * y[3] - k2 * y[2]) / p[Lp.I2]  # (A1)_4 with the drive at rest
    dy[4] = N
    return N


@njit(cache=True)
def impact_kernel(p, rigid, free, w, dt, out):
    """Integrate one impact from D = 0, D' = w until N first returns to 0.

    dt [s] is the RK4 step; the first steps are graded from dt/1024, doubling, because the
    force is singular at the onset (D^0.25 for the modified law, a jump for the linear
    one) and a full step starting there loses RK4's order. The separation is located inside the last step by
    bisection on the Hermite interpolant; the peak by a parabola through the three samples
    around the largest one. Writes the IMPACT_RESULTS vector into out.
    """
    for i in range(N_IMPACT_RESULTS):
        out[i] = math.nan
    y = np.zeros(N_STATE)
    y1 = np.zeros(N_STATE)
    f0 = np.zeros(N_STATE)
    f1 = np.zeros(N_STATE)
    k2 = np.zeros(N_STATE)
    k3 = np.zeros(N_STATE)
    k4 = np.zeros(N_STATE)
    tmp = np.zeros(N_STATE)
    y[1] = w
    half_side = 0.5 * min(p[Lp.LL], p[Lp.AA])
    N0 = impact_rhs(y, p, rigid, free, f0)  # the linear law jumps to b w at contact
    t = 0.0
    q_prev2 = N0
    t_prev2 = 0.0
    q_prev = N0
    t_prev = 0.0
    peak = N0
    dmax = 0.0
    status = ST_MAXSTEPS
    n = 0
    max_steps = 10_000_000
    h = dt / 1024.0
    while n < max_steps:
        # RK4 on a step of size h
        axpy(y, 0.5 * h, f0, tmp)
        impact_rhs(tmp, p, rigid, free, k2)
        axpy(y, 0.5 * h, k2, tmp)
        impact_rhs(tmp, p, rigid, free, k3)
        axpy(y, h, k3, tmp)
        impact_rhs(tmp, p, rigid, free, k4)
        rk4_combine(y, h, f0, k2, k3, k4, y1)
        N1 = impact_rhs(y1, p, rigid, free, f1)
        n += 1
        D1 = y1[0] if rigid else y1[0] - p[Lp.R] * y1[2]
        if not math.isfinite(D1):
            status = ST_NONFINITE
            break
        if D1 > dmax:
            dmax = D1
        if D1 > half_side:
            status = ST_PENETRATION
            break
        # peak: the largest sample, refined by a parabola where the previous sample is an
        # interior local maximum (not at a jump: the first sample is the force at contact)
        peak = max(peak, N1)
        if n >= 2 and q_prev >= q_prev2 and q_prev >= N1 and q_prev > 0.0:
            tp, qp = parabola_peak(t_prev2, q_prev2, t_prev, q_prev, t + h, N1)
            if qp > peak:
                peak = qp
        if N1 <= 0.0:
            # separation inside (t, t + dt]: bisect on N > 0 along the Hermite interpolant
            lo = 0.0
            hi = 1.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                hermite(y, f0, y1, f1, h, mid, tmp)
                if impact_rhs(tmp, p, rigid, free, k2) > 0.0:
                    lo = mid
                else:
                    hi = mid
            hermite(y, f0, y1, f1, h, hi, tmp)
            t_sep = t + hi * h
            Dd = tmp[1] if rigid else tmp[1] - p[Lp.R] * tmp[3]
            out[Rs.RJ_PEAK_FORCE] = max(peak, q_prev)
            out[Rs.RJ_IMPULSE] = tmp[4]
            out[Rs.RJ_CONTACT_TIME] = t_sep
            out[Rs.RJ_E_EFF] = -Dd / w
            status = ST_OK
            break
        q_prev2 = q_prev
        t_prev2 = t_prev
        q_prev = N1
        t_prev = t + h
        t += h
        h = min(2.0 * h, dt)
        for i in range(N_STATE):
            y[i] = y1[i]
            f0[i] = f1[i]
    out[Rs.RJ_MAX_PENETRATION] = dmax
    out[Rs.RJ_N_STEPS] = n
    out[Rs.RJ_STATUS] = status
