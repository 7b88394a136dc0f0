"""The cycle's loop (docs/model.md §8-§9): kernel/driver.py's `integrate` with the cycle's right-hand
side and `accept`, the cycle's handling of each accepted step:

  the step's end classified -> the first event inside it located on its dense output (a contact
  slot changing its code, a graze, an outcome: events.py) and the step ended there -> the peaks
  located inside it (peaks.py) -> book-keeping (stages, the event's new contact codes, the side
  memory, the closed-form ride, the trajectory) -> the state moved on.

`run` drives the loop: to t_max while the load is on the belt (landing on t_c, where §11's
residuals are read), then, once the load has left (or timed out before t_c), the fence alone
to t_c.
"""
from __future__ import annotations

import math

from fencesweep.kernel import driver
from fencesweep.kernel import numerics as NU
from fencesweep.kernel import rk
from fencesweep.kernel.jit import kernel
from fencesweep.model import layout as Lp
from fencesweep.model import results as Rs
from fencesweep.model.contact import pulse_time
from fencesweep.model.scenes.contacts import APART, N_SLOTS, RAIL0, TIP
from fencesweep.model.scenes.cycle.books import after_step, at_t_c, count_stage_time, record, sync_touch, time_out
from fencesweep.model.scenes.cycle.events import event_state, find_event, long_step
from fencesweep.model.scenes.cycle.layout import (IW_CODE, IW_LOAD, A_DMAX, A_EXITED, A_QMAX, A_STATUS, AX_DMAX, N_Q, N_STATE, Q_NF,
                                                  QV_0, QV_1, QV_RATE, Q_DEFL)
from fencesweep.model.scenes.cycle.peaks import (quantities, quantities_from_aux, record_peaks, touch_in_step,
                                                 track_maxima)
from fencesweep.model.scenes.cycle.rhs import keep_drive, rhs, step
from fencesweep.model.scenes.cycle.slots import classify, classify_after_rhs, in_contact, new_push, releases


@kernel(inline=True)
def all_finite(y):
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    return True


@kernel(inline=True)
def onset_step(p, w, h_next):
    """The step after a contact onset: at most numerics.ONSET_STEP of the load's pulse time at the
    fastest closing speed (contact.pulse_time; docs/model.md (15.8))."""
    return min(h_next, NU.ONSET_STEP * pulse_time(p[Lp.LAW], p[Lp.M1], p[Lp.KC], w.atol0[3] / p[Lp.TOL]))


@kernel(inline=True)
def light_fence_contact(p, w):
    """Is the load letting go of the fence slowly: its deepest fence contact opening at the step's
    start, and less than numerics.LIGHT_DEPTH position tolerances (TOL l) deep or the fence's force
    below numerics.LIGHT_FORCE x F_ff (docs/model.md (15.14))?"""
    deepest = -1.0
    opening = True
    for k in range(N_SLOTS):
        if (k < RAIL0 or k == TIP) and w.iw[IW_CODE + k] != APART and -w.g0[k] > deepest:
            deepest = -w.g0[k]
            opening = w.r0[k] >= 0.0
    light = deepest < NU.LIGHT_DEPTH * w.atol0[0] or w.qv[QV_0, Q_NF] < NU.LIGHT_FORCE * p[Lp.FFORCE]
    return opening and deepest >= 0.0 and light


@kernel(inline=True)
def closing_time(g, r, a):
    """When a gap g > 0 with rate r and acceleration a closes (g + r tau + a tau^2 / 2 = 0), inf
    if it does not (docs/model.md §15, Events)."""
    if a < 0.0:
        return (r + math.sqrt(r * r - 2.0 * a * g)) / -a
    if r < 0.0:
        return g / -r
    return math.inf


@kernel(inline=True)
def approach_step(p, w, dt, h_next):
    """The step after one of length dt: at most the time in which a slot apart at its end closes
    its gap at the gap's rate there and its acceleration over the step (closing_time), and not
    under numerics.APPROACH_FLOOR of the largest step: a step that spans a whole approach and
    separation, both ends apart and the gap opening at both, sees no contact in it."""
    if w.iw[IW_LOAD] == 0 or dt <= 0.0 or not long_step(p, h_next):  # (a step under the floor is not cut)
        return h_next
    floor = NU.APPROACH_FLOOR * p[Lp.H_MAX]
    per_dt = 1.0 / dt
    for k in range(N_SLOTS):
        g, r = w.g1[k], w.r1[k]
        a = (r - w.r0[k]) * per_dt
        # cannot close within h_next at its rate and acceleration: nothing to compute
        if w.codes1[k] != APART or not (g > 0.0 and g + h_next * (min(r, 0.0) + 0.5 * h_next * min(a, 0.0)) <= 0.0):
            continue
        h_next = min(h_next, max(closing_time(g, r, a), floor))
    return h_next


@kernel(inline=True)
def release_ahead(p, w, h):
    """Will the fence's or the rail's force, falling at the last step's rate, come within
    LIGHT_FORCE x F_ff of zero within the next step h (a release ahead, docs/model.md (15.14))?
    h = 0 at a cycle's start (stream.begin_cycle): no step yet, and the rates are the last
    cycle's."""
    if h <= 0.0:
        return False
    for k in range(Q_DEFL):
        q = w.qv[QV_0, k]
        r = w.qv[QV_RATE, k]
        if q > 0.0 and r < 0.0 and math.isfinite(r) and q + h * r <= NU.LIGHT_FORCE * p[Lp.FFORCE]:
            return True
    return False


@kernel(inline=True)
def set_tolerance(p, w, h_next):
    """The tolerances of the next step h_next (docs/model.md (15.14); numerics.APPROACH_TOL,
    FREE_TOL say why): the run's, times APPROACH_TOL while the load is on the belt and touches
    nothing, lets go of the fence slowly, or will let go of the fence or the rail within the
    step (release_ahead), times FREE_TOL for a free fence."""
    s = NU.APPROACH_TOL if w.iw[IW_LOAD] != 0 and (not in_contact(w.iw) or light_fence_contact(p, w)
                                                   or release_ahead(p, w, h_next)) else 1.0
    if int(p[Lp.DRIVE]) == Lp.DRIVE_FREE:
        s = min(s, NU.FREE_TOL)
    for i in range(N_STATE):
        w.atol[i] = s * w.atol0[i]
    w.rtol[0] = s * p[Lp.TOL]


@kernel(inline=True)
def move_on(p, w, t1, kind, edge1, h_next):
    """Apply the event that ended the step at t1 (books.after_step) and start the next step
    there: f(t1, y1) and the quantities anew when the mode changed, else the FSAL stage.
    Returns the next step."""
    onset = kind == 1 and new_push(w.iw, w.codes1)
    if after_step(t1, w.y1, p, w.iw, kind, w.codes1, w.tags1, edge1, w.acc):
        w.rising[N_Q] = 1.0
        if onset:
            h_next = onset_step(p, w, h_next)
        classify(t1, w.y1, p, w.iw, w.codes1, w.g1, w.r1, w.tags1)
        rhs(t1, w.y1, p, w.iw, w.K[0], w.aux)  # f(t1, y1) in the new mode
        quantities_from_aux(t1, w.y1, p, w.iw, w.aux, w.qv[QV_0])
    else:
        for i in range(N_STATE):
            w.K[0, i] = w.K[6, i]  # first same as last
        for k in range(N_Q):
            w.qv[QV_0, k] = w.qv[QV_1, k]  # the same point, the same right-hand side
    for k in range(N_Q):
        w.acc[A_QMAX + k] = max(w.acc[A_QMAX + k], w.qv[QV_0, k])
    w.acc[A_DMAX] = max(w.acc[A_DMAX], w.aux[AX_DMAX])
    for i in range(N_SLOTS):
        w.g0[i] = w.g1[i]
        w.r0[i] = w.r1[i]
    for i in range(N_STATE):
        w.y[i] = w.y1[i]
    keep_drive(t1, p, w.aux)
    set_tolerance(p, w, h_next)
    return h_next


@kernel(inline=True)
def check_state(p, w):
    """A run that cannot be trusted ends (docs/model.md (5.15)): a non-finite state, or a
    penetration deeper than half the load's smaller side. Returns whether the run goes on."""
    if not all_finite(w.y):
        w.acc[A_STATUS] = Rs.ST_NONFINITE
    elif w.acc[A_DMAX] > 0.5 * min(p[Lp.LL], p[Lp.AA]):
        w.acc[A_STATUS] = Rs.ST_PENETRATION
    return w.acc[A_STATUS] == Rs.ST_OK


@kernel(inline=True)
def accept(p, w, t, h, t1, err, h_next):
    """The cycle's handling of an accepted step [t, t1] (module docstring); the driver's hook.
    Returns (the new t, the next step, stop): stop at an outcome or a failed state."""
    w.qok[0] = 0  # the step's dense output is formed when first needed (events.ensure_dense)
    exited = w.acc[A_EXITED] != 0.0
    edge1 = classify_after_rhs(t + h, w.y1, p, w.iw, w.codes1, w.g1, w.r1, w.tags1, w.aux)  # aux: of f(t + h, y1)
    theta, kind = find_event(p, w, t, h, exited)
    if kind == 0:
        quantities_from_aux(t1, w.y1, p, w.iw, w.aux, w.qv[QV_1])  # aux of the FSAL stage f(t1, y1)
    else:
        theta, edge1 = event_state(p, w, t, h, theta, kind)
        t1 = t + theta * h
        quantities(t1, w.y1, p, w.iw, w.aux, w.dy, w.qv[QV_1], True)
    track_maxima(p, w, t, h, theta)
    if w.traj.shape[0] > 0:
        record_peaks(p, w, t, h, theta)
    touch_in_step(p, w, t, h, theta, kind == 1 and releases(w.iw, w.codes1))
    if not exited:
        count_stage_time(w.iw, w.acc, t, t1)
    h_next = approach_step(p, w, t1 - t, h_next)
    h_next = move_on(p, w, t1, kind, edge1, h_next)
    sync_touch(t1, w.qv[QV_0, Q_NF], p, w.acc)  # a touch begun or ended by the event at t1
    if t1 == p[Lp.TC]:
        at_t_c(t1, w.y, p, w.iw, w.acc)
    w.row[0] = record(w.traj, w.row[0], t1, w.y, p, w.iw, w.aux)
    ok = check_state(p, w)
    return t1, h_next, kind >= 2 or not ok


#: the driver's loop with the cycle's step and accept (kernel/driver.py)
loop = driver.integrator(step, accept, "cycle_loop")


@kernel()
def run(p, w):
    """The cycle's loop (module docstring), from t = 0 with the state, codes and quantities that
    stream.begin_cycle set."""
    tc = p[Lp.TC]
    method = int(p[Lp.METHOD])
    ctl = (method, p[Lp.H_MAX], p[Lp.DT], NU.H_MIN)
    t = 0.0
    h = p[Lp.DT] if method == rk.METHOD_RK4 else 0.1 * p[Lp.H_MAX]
    while True:
        exited = w.acc[A_EXITED] != 0.0
        t_end = tc if exited else p[Lp.TMAX]
        if driver.reached(t, t_end):
            if exited or t >= tc:
                return
            # t_max before t_c (docs/model.md (9.3) timeout): the load leaves, the fence runs on alone
            # to t_c (its results are over [0, max(t_exit, t_c)])
            time_out(t, w)
            rhs(t, w.y, p, w.iw, w.K[0], w.aux)
            continue
        t, h, why = loop(ctl, p, w, t, t_end, tc, h)
        if why == driver.STOP_MAX_STEPS:
            w.acc[A_STATUS] = Rs.ST_MAXSTEPS
        elif why == driver.STOP_UNDERFLOW:
            w.acc[A_STATUS] = Rs.ST_UNDERFLOW
        if w.acc[A_STATUS] != Rs.ST_OK:
            return
