"""Scene `impact` (paper §4.1, docs/model.md §8): a material point m1 hits the fence's point at
distance R from the pivot with normal speed w.

The fence is rigid (I2 = inf), flexible (Kelvin element B2, K2 to a drive at rest) or free
(B2 = K2 = 0). For a small rotation theta the contact point moves R theta along the impact
normal, so
  D = y_p - R theta,  m1 y_p'' = -N,  I2 theta'' = N R - B2 theta' - K2 theta.
The impact ends at the first return of N to 0 after the onset, located on the dense output.
State: [y_p, y_p', theta, theta', impulse] (theta unused when rigid). The scene `freefall`
(scenes/freefall.py) is this one on a rigid wall. It integrates with kernel/driver.py's loop,
as the cycle does: `accept` handles each step (the release, the peak, a failed state).
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from fencesweep.kernel import driver
from fencesweep.kernel import numerics as NU
from fencesweep.kernel import rk
from fencesweep.kernel.jit import entry, kernel
from fencesweep.kernel.search import bisector, peak_finder
from fencesweep.model import layout as Lp
from fencesweep.model import results as Rs
from fencesweep.model.contact import kelvin_force, pulse_time

N_STATE = 5
IW_RIGID, IW_FREE = 0, 1
# the run's scalars (Work.acc): the peak force so far, the largest penetration, the status, the
# impact's time scale (its undamped pulse time), and at the release its rebound rate D'
R_PEAK, R_DMAX, R_STATUS, R_TP, R_REBOUND, N_R = 0, 1, 2, 3, 4, 5

#: an impact's work arrays (allocated by impact_kernel)
Work = namedtuple("Work", ("y", "y1", "tmp", "dy", "K", "Q", "aux", "iw", "atol", "rtol", "count", "acc"))


@kernel(inline=True)
def penetration(y, p, rigid):
    """D and D' of the point against the fence point R theta (module docstring; docs/model.md
    (8.2))."""
    if rigid:
        return y[0], y[1]
    return y[0] - p[Lp.R] * y[2], y[1] - p[Lp.R] * y[3]


@kernel(inline=True)
def fence_rotation(N, theta, dtheta, p, free):
    """theta'' of the fence point (paper eq. (A1)_4 with the drive at rest): (N R - B2 theta' -
    K2 theta) / I2; B2 = K2 = 0 for the free fence."""
    b2 = 0.0 if free else p[Lp.B2]
    k2 = 0.0 if free else p[Lp.K2]
    return (N * p[Lp.R] - b2 * dtheta - k2 * theta) / p[Lp.I2]


@kernel()
def impact_rhs(t, y, p, iw, dy, aux):
    """Right-hand side while the point is in contact (docs/model.md (8.3)), with the impulse's
    integrand N; aux[0] = the Kelvin force N (docs/model.md §4; the run ends where it returns to
    0, so it is not clipped here)."""
    rigid = iw[IW_RIGID] != 0
    D, Dd = penetration(y, p, rigid)
    N = kelvin_force(max(D, 0.0), Dd, p[Lp.KC], p[Lp.CD], p[Lp.LAW])[0]
    dy[0] = y[1]
    dy[1] = -N / p[Lp.M1]
    dy[2] = 0.0
    dy[3] = 0.0
    if not rigid:
        dy[2] = y[3]
        dy[3] = fence_rotation(N, y[2], y[3], p, iw[IW_FREE] != 0)
    dy[4] = N
    aux[0] = N


@kernel()
def force_at(ctx, theta):
    """The Kelvin force on the dense output (search.peak_max, and bisect of its return to 0)."""
    y0, Q, p, iw, tmp, dy, aux = ctx
    rk.dense_eval(y0, Q, theta, tmp, N_STATE)
    impact_rhs(0.0, tmp, p, iw, dy, aux)
    return aux[0]


@kernel()
def released(ctx, theta):
    return force_at(ctx, theta) <= 0.0


#: the searches on the dense output (kernel/search.py) and the step (kernel/rk.py) of this scene
find_release = bisector(released, "impact_find_release")
peak_force = peak_finder(force_at, "impact_peak_force")
step = rk.stepper(impact_rhs, "impact_step")


@kernel()
def step_peak(ctx, theta, peak):
    """The largest force over [0, theta] of the step: an interior maximum (rising just after the
    start, falling just before theta) by Brent's search, and the value at theta."""
    d = 1e-3 * theta
    if force_at(ctx, d) > force_at(ctx, 0.0) and force_at(ctx, theta - d) > force_at(ctx, theta):
        peak = max(peak, peak_force(ctx, 0.0, theta, NU.PEAK_TOL)[1])
    return max(peak, force_at(ctx, theta))


@kernel()
def accept(p, w, t, h, t1, err, h_next):
    """The impact's handling of an accepted step: the release (N back to 0) located on the dense
    output, the peak inside the step, a failed state; the driver's hook. At the release w.y1
    holds the state there."""
    rk.dense_coeffs(rk.METHOD_DOPRI5, w.K, h, w.y, w.y1, w.Q, N_STATE)
    ctx = (w.y, w.Q, p, w.iw, w.tmp, w.dy, w.aux)
    theta = 1.0
    if released(ctx, 1.0):
        theta = find_release(ctx, 0.0, 1.0, NU.EVENT_TOL * w.acc[R_TP] / h, 0.0, 1.0)[1]
    w.acc[R_PEAK] = step_peak(ctx, theta, w.acc[R_PEAK])
    rk.dense_eval(w.y, w.Q, theta, w.y1, N_STATE)
    D1, Dd1 = penetration(w.y1, p, w.iw[IW_RIGID] != 0)
    w.acc[R_DMAX] = max(w.acc[R_DMAX], D1)
    if not math.isfinite(D1):
        w.acc[R_STATUS] = Rs.ST_NONFINITE
        return t, h_next, True
    if D1 > 0.5 * min(p[Lp.LL], p[Lp.AA]):
        w.acc[R_STATUS] = Rs.ST_PENETRATION
        return t, h_next, True
    if theta < 1.0:
        w.acc[R_STATUS] = Rs.ST_OK
        w.acc[R_REBOUND] = Dd1
        return t + theta * h, h_next, True
    for i in range(N_STATE):
        w.y[i] = w.y1[i]
        w.K[0, i] = w.K[6, i]
    return t1, h_next, False


#: the driver's loop with this scene's step and accept (kernel/driver.py)
loop = driver.integrator(step, accept, "impact_loop")


@kernel()
def error_scales(p, w, speed, tp):
    """atol: the pulse's penetration w tp, the speed w, their angles about the pivot, the
    impulse m1 w, each times the tolerance p[TOL]."""
    rr = p[Lp.R] if p[Lp.R] > 0.0 else 1.0  # (a rigid wall has no R)
    tol = p[Lp.TOL]
    for i, sc in enumerate((speed * tp, speed, speed * tp / rr, speed / rr, p[Lp.M1] * speed)):
        w.atol[i] = tol * sc


@kernel()
def write_results(w, t, speed, out):
    """IMPACT_RESULTS into out (NaN where the run failed before the release): the peak force,
    the impulse J (the state's integral of N), e_eff = -D'(t_e) / w and contact_time = t_e
    (docs/model.md (8.4))."""
    for i in range(Rs.N_IMPACT_RESULTS):
        out[i] = math.nan
    if w.acc[R_STATUS] == Rs.ST_OK:
        out[Rs.RJ_PEAK_FORCE] = w.acc[R_PEAK]
        out[Rs.RJ_IMPULSE] = w.y1[4]
        out[Rs.RJ_CONTACT_TIME] = t
        out[Rs.RJ_E_EFF] = -w.acc[R_REBOUND] / speed
    out[Rs.RJ_MAX_PENETRATION] = w.acc[R_DMAX]
    out[Rs.RJ_N_STEPS] = w.count[driver.C_STEPS]
    out[Rs.RJ_STATUS] = w.acc[R_STATUS]


@kernel(inline=True)
def effective_mass(p, rigid):
    """The mass of the impact's time scale [kg] (docs/model.md (15.12)): m1 against a rigid
    fence, (1/m1 + R^2/I2)^-1 against a flexible or free one."""
    return p[Lp.M1] if rigid else 1.0 / (1.0 / p[Lp.M1] + p[Lp.R] ** 2 / p[Lp.I2])


@entry()
def impact_kernel(p, rigid, free, speed, out):
    """Integrate one impact from D = 0, D' = speed until N first returns to 0 (kernel/driver.py
    at the tolerance p[TOL]); writes IMPACT_RESULTS into out."""
    n = N_STATE
    w = Work(np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((rk.N_STAGES, n)), np.zeros((4, n)),
             np.zeros(1), np.array([1 if rigid else 0, 1 if free else 0]), np.empty(n), np.full(1, p[Lp.TOL]),
             np.zeros(driver.N_COUNT),
             np.zeros(N_R))
    tp = pulse_time(p[Lp.LAW], effective_mass(p, rigid), p[Lp.KC], speed)
    error_scales(p, w, speed, tp)
    w.acc[R_TP] = tp
    w.acc[R_STATUS] = Rs.ST_MAXSTEPS
    w.y[1] = speed
    impact_rhs(0.0, w.y, p, w.iw, w.K[0], w.aux)
    w.acc[R_PEAK] = w.aux[0]  # the linear law jumps to b w at contact
    ctl = (rk.METHOD_DOPRI5, math.inf, 0.0, NU.H_MIN * tp)
    t, h, why = loop(ctl, p, w, 0.0, math.inf, math.inf, 1e-3 * tp)
    if why == driver.STOP_UNDERFLOW:
        w.acc[R_STATUS] = Rs.ST_UNDERFLOW
    write_results(w, t, speed, out)
