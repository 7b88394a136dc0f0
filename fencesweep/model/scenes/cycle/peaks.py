"""The tracked maxima of a cycle (docs/model.md §11: peak_force, peak_rail_force, deflection_max,
alpha_max), located inside each step (§9: "and so is the peak force"): a quantity that rises at
the step's start and falls at its end has an interior maximum, found by Brent's search on the
step's dense output (kernel/search.py) and valued at the state of a step of the method to it."""
from __future__ import annotations


import math

from fencesweep.kernel import numerics as NU
from fencesweep.kernel import rk
from fencesweep.kernel.jit import kernel
from fencesweep.kernel.search import bisector, hermite_max, peak_finder
from fencesweep.model import layout as Lp
from fencesweep.model.scenes.cycle.books import note_touch, record, touching
from fencesweep.model.scenes.cycle.events import ensure_dense
from fencesweep.model.scenes.cycle.layout import (A_QMAX, A_TOUCH, AX_NF, AX_NR, IW_LOAD, IW_MODE, IW_RIDE, N_CTRL, N_Q,
                                                  N_STATE, Q_ALPHA, Q_DEFL, Q_NF, Q_NR, QV_0, QV_1, QV_A, QV_B,
                                                  QV_RATE, QV_S, QV_THETA)
from fencesweep.model.scenes.cycle.rhs import deflection, fence_state_in, rhs, step

UNJUDGED = -1.0  # rising[k] when the step before did not judge quantity k at its end
SAMPLE = 1e-3  # judge_forces samples the forces this fraction of the step inside its ends


@kernel()
def quantities(t, y, p, iw, aux, dy, q, forces):
    """The tracked quantities at (t, y), whose maxima over t are peak_force, peak_rail_force
    (docs/model.md (11.1)), deflection_max and alpha_max (11.2): the fence and rail force sums,
    |alpha - alpha_w|, alpha. Their running maxima are kept at the steps' ends (run.move_on)
    and inside the steps (track_maxima). Without `forces` the force sums (which cost a
    right-hand side) are left as they are."""
    al, dal, aw, daw = fence_state_in(t, y, p, iw[IW_MODE], aux)
    if forces:
        q[Q_NF] = 0.0
        q[Q_NR] = 0.0
        if iw[IW_LOAD] != 0 and iw[IW_RIDE] == 0:
            rhs(t, y, p, iw, dy, aux)
            q[Q_NF] = aux[AX_NF]
            q[Q_NR] = aux[AX_NR]
    dev, rate = deflection(al, dal, aw, daw)
    q[Q_DEFL] = abs(dev)
    q[Q_ALPHA] = al


@kernel(inline=True)
def quantities_from_aux(t, y, p, iw, aux, q):
    """The tracked quantities at (t, y) with aux from rhs there."""
    al, dal, aw, daw = fence_state_in(t, y, p, iw[IW_MODE], aux)
    q[Q_NF] = aux[AX_NF]
    q[Q_NR] = aux[AX_NR]
    dev, rate = deflection(al, dal, aw, daw)
    q[Q_DEFL] = abs(dev)
    q[Q_ALPHA] = al


@kernel()
def quantity_at(ctx, theta):
    """One tracked quantity on the dense output (for search.peak_max)."""
    t0, h, y0, Q, p, iw, tmp, aux, dy, q, kind = ctx
    rk.dense_eval(y0, Q, theta, tmp, N_CTRL)
    quantities(t0 + theta * h, tmp, p, iw, aux, dy, q, kind < Q_DEFL)
    return q[kind]


#: Brent's search of a tracked quantity on the dense output (kernel/search.py)
peak_of = peak_finder(quantity_at, "cycle_peak_of")


@kernel(inline=True)
def near_maximum(q0, q1, rate, span, acc, k):
    """Can this step [t, t + span] hold a new maximum of force k? Only if the force can come within
    numerics.PEAK_CANDIDATE of the running maximum inside it (reach), and that maximum is not 0
    (a force before any contact: a contact's onset is an event, after which the step is judged
    anew)."""
    m = max(acc[A_QMAX + k], q0[k], q1[k])
    return reach(q0[k], q1[k], rate[k], span) >= NU.PEAK_CANDIDATE * m and m > 0.0


@kernel(inline=True)
def reach(q0, q1, rate, span):
    """How high a force may climb inside a step of length span from its end values q0, q1 and
    its rate over the step before (numerics.PEAK_REACH): the larger end value plus PEAK_REACH
    times the larger of its rise over the step and its rise at the rate before (a force that
    falls into the step and over it has no maximum inside it above its start: a new rise is
    a contact's onset, an event). A concave force lies below its tangent at the start, whose
    slope the previous secant exceeds; the factor covers a force still convex there."""
    return max(q0, q1) + NU.PEAK_REACH * max(0.0, q1 - q0, rate * span)


@kernel(inline=True)
def fence_values(t, y, p, iw, aux):
    """The fence's tracked values at (t, y) and their rates: the deflection dalpha = alpha -
    alpha_w (docs/model.md §11; deflection_max is max |dalpha|), its rate, alpha and alpha'."""
    al, dal, aw, daw = fence_state_in(t, y, p, iw[IW_MODE], aux)
    dev, rate = deflection(al, dal, aw, daw)
    return dev, rate, al, dal


@kernel(inline=True)
def fence_peaks(p, w, t, h, theta_end):
    """Modelled interior maxima of the fence's tracked quantities over the step [t, t + theta_end
    h] into w.qv[QV_B] (-inf where the step has none): the cubic through their values and rates
    at the step's ends (hermite_max), |dalpha| as the larger of dalpha's and -dalpha's."""
    span = theta_end * h
    dv0, dr0, al0, da0 = fence_values(t, w.y, p, w.iw, w.aux)
    dv1, dr1, al1, da1 = fence_values(t + span, w.y1, p, w.iw, w.aux)
    qb = w.qv[QV_B]
    qb[Q_DEFL] = max(hermite_max(dv0, dr0 * span, dv1, dr1 * span),
                     hermite_max(-dv0, -dr0 * span, -dv1, -dr1 * span))
    qb[Q_ALPHA] = hermite_max(al0, da0 * span, al1, da1 * span)


@kernel()
def step_to(p, w, t, h, th):
    """w.ys: the state at t + th h from a step of the method from (t, w.y) to it, not from the
    dense output (whose error is not controlled); the value of a located peak is read there."""
    for i in range(N_STATE):
        w.tmp[i] = w.y[i]
    rhs(t, w.tmp, p, w.iw, w.Ks[0], w.auxs)
    step(int(p[Lp.METHOD]), t, w.tmp, th * h, p, w.iw, w.Ks, w.dy, w.ys, w.auxs, w.atol, p[Lp.TOL], N_CTRL)


@kernel()
def peak_value(p, w, t, h, th, k):
    """Quantity k at t + th h, from step_to: one extra step per located peak."""
    step_to(p, w, t, h, th)
    qs = w.qv[QV_S]
    quantities(t + th * h, w.ys, p, w.iw, w.auxs, w.dy, qs, k < Q_DEFL)
    return qs[k]


@kernel(inline=True)
def judge_forces(p, w, t, h, theta_end):
    """The force sums near their running maximum: whether they rose at the step's start (where
    not judged yet) and samples just before its end (QV_B), a thousandth of the step inside."""
    ensure_dense(p, w, h)
    q0, qa, qb, rising = w.qv[QV_0], w.qv[QV_A], w.qv[QV_B], w.rising
    d = SAMPLE * theta_end
    if rising[Q_NF] == UNJUDGED or rising[Q_NR] == UNJUDGED:
        rk.dense_eval(w.y, w.Q, d, w.tmp, N_CTRL)
        quantities(t + d * h, w.tmp, p, w.iw, w.auxs, w.dy, qa, True)
        for k in range(Q_DEFL):
            if rising[k] == UNJUDGED:
                rising[k] = 1.0 if qa[k] > q0[k] else 0.0
    rk.dense_eval(w.y, w.Q, theta_end - d, w.tmp, N_CTRL)
    quantities(t + (theta_end - d) * h, w.tmp, p, w.iw, w.auxs, w.dy, qb, True)


@kernel(inline=True)
def peak_inside(q0, qa, qb, q1, rate, span, fresh, at_event):
    """Has a force that rose at the step's start (judge_forces) a maximum inside the step? It
    falls at the end (qb above q1), or, rising at both ends of a step cut short by an event
    (`at_event`), the cubic through its values and rates at the ends (search.hermite_max,
    docs/model.md (15.9)) has an interior maximum above both: a sum of two contacts' forces that
    peaks and dips again before one of them lets go. The rate at the start is qa's (`fresh`:
    sampled in this step) or the step before's."""
    if qb > q1:
        return True
    if not at_event:
        return False
    d0 = (qa - q0) / SAMPLE if fresh else rate * span
    if not math.isfinite(d0):
        return False
    return hermite_max(q0, d0, q1, (q1 - qb) / SAMPLE) > max(q0, q1)


@kernel(inline=True)
def track_maxima(p, w, t, h, theta_end):
    """Running maxima of the tracked quantities over the step [t, t + theta_end h]: the end
    samples, and an interior maximum, located by Brent's search on the dense output
    (search.peak_max, docs/model.md §9) and valued at a step of the method to it (peak_value):
      * the force sums, which have no cheap derivative, when they rise at the step's start and
        fall at its end, judged by samples on the dense output (judge_forces, each a right-hand
        side), and only in steps near their running maximum. w.rising[k] says whether force k
        rose at the start (1, 0; UNJUDGED when the step before was far from its maximum, or
        after an event: rising[N_Q] = 1); on return it says so for the step's end;
      * the fence's deflection |dalpha| and alpha, when the cubic through their values and rates
        at the step's ends has an interior maximum within numerics.PEAK_CANDIDATE of the running
        maximum (fence_peaks): a long step can hold a maximum well above its ends, and two
        extrema where the rates at the ends have one sign.
    w.qv[QV_THETA][k]: the fraction of the step at which quantity k's interior maximum was
    located, -1 where none was."""
    q0, q1, qb, ths, acc, rising = w.qv[QV_0], w.qv[QV_1], w.qv[QV_B], w.qv[QV_THETA], w.acc, w.rising
    rate = w.qv[QV_RATE]
    span = theta_end * h
    for k in range(N_Q):
        ths[k] = -1.0
    if rising[N_Q] != 0.0:  # after an event: the force's rate before it says nothing of its course
        for k in range(Q_DEFL):
            rising[k] = UNJUDGED
            rate[k] = math.inf
    forces = near_maximum(q0, q1, rate, span, acc, Q_NF) or near_maximum(q0, q1, rate, span, acc, Q_NR)
    fresh_nf, fresh_nr = rising[Q_NF] == UNJUDGED, rising[Q_NR] == UNJUDGED  # qa sampled: the rate at the start
    if forces:
        judge_forces(p, w, t, h, theta_end)
    fence_peaks(p, w, t, h, theta_end)
    for k in range(N_Q):
        m = max(acc[A_QMAX + k], q0[k], q1[k])
        if k < Q_DEFL and not forces:
            acc[A_QMAX + k] = m
            rising[k] = UNJUDGED
            continue
        if k < Q_DEFL:
            inside = (rising[k] == 1.0 and reach(q0[k], q1[k], rate[k], span) >= NU.PEAK_CANDIDATE * m
                      and peak_inside(q0[k], w.qv[QV_A, k], qb[k], q1[k], rate[k], span,
                                      fresh_nf if k == Q_NF else fresh_nr, theta_end < 1.0))
            rising[k] = 1.0 if q1[k] > qb[k] else 0.0
        else:
            inside = qb[k] >= NU.PEAK_CANDIDATE * m
        if inside:
            ensure_dense(p, w, h)
            th, qm = peak_of((t, h, w.y, w.Q, p, w.iw, w.tmp, w.auxs, w.dy, w.qv[QV_S], k), 0.0, theta_end,
                             NU.PEAK_TOL)
            m = max(m, peak_value(p, w, t, h, th, k))
            ths[k] = th
        acc[A_QMAX + k] = m
    for k in range(Q_DEFL):
        rate[k] = (q1[k] - q0[k]) / span if span > 0.0 else 0.0
    rising[N_Q] = 0.0


@kernel(inline=True)
def record_peaks(p, w, t, h, theta_end):
    """Trajectory rows at the maxima located inside the step (track_maxima's QV_THETA), in time
    order, each at the state of a step of the method to it: so that the trajectory's peaks are
    the results' (peak_force, deflection_max, alpha_max), not the samples around them."""
    ths = w.qv[QV_THETA]
    prev = 0.0
    while True:
        th = 2.0
        for k in range(N_Q):
            if ths[k] > prev and ths[k] < th:
                th = ths[k]
        if th >= theta_end * (1.0 - 1e-9):
            return
        step_to(p, w, t, h, th)
        rhs(t + th * h, w.ys, p, w.iw, w.dy, w.auxs)
        w.row[0] = record(w.traj, w.row[0], t + th * h, w.ys, p, w.iw, w.auxs)
        prev = th


@kernel()
def touch_changed(ctx, theta):
    """Predicate for search.bisect: does the touch (books.touching) at theta differ from `was`,
    the touch at the step's start?"""
    t0, h, y0, Q, p, iw, tmp, aux, dy, q, was = ctx
    rk.dense_eval(y0, Q, theta, tmp, N_CTRL)
    quantities(t0 + theta * h, tmp, p, iw, aux, dy, q, True)
    return touching(q[Q_NF], p) != was


#: the bisection of a touch's change on the dense output (kernel/search.py)
find_touch = bisector(touch_changed, "cycle_find_touch")


@kernel(inline=True)
def touch_in_step(p, w, t, h, theta_end, release):
    """touch_changes, called only for the steps that need it: most steps neither end at a release
    nor carry the fence force across the touch floor (such a call, with the work arrays, in every
    step cost ~5 % of a cycle: +13.2 % against +7.8 % for the whole change, results/warm_revisions.md)."""
    was = w.acc[A_TOUCH] != 0.0
    if (release and not was) or touching(w.qv[QV_1, Q_NF], p) != was:
        touch_changes(p, w, t, h, theta_end, release)


@kernel()
def touch_changes(p, w, t, h, theta_end, release):
    """The fence force passing the touch floor inside the step [t, t + theta_end h] (docs/model.md
    (11.10): its value at the step's end, w.qv[QV_1], on the other side of the floor than the
    touch at its start), noted by books.note_touch: upwards at once (t_A is dated from the force's
    first onset, an event); downwards at the step's end when the step ends at a `release` (the
    force falls from the floor to 0 within a rounding of it, and the step's dense output is
    least accurate just there: events.release_state), else where it is located on the dense
    output by bisection (events are located inside the step, §9). A release that ends a step
    begun without a touch may have had one inside it (a light re-contact of ~0.2 N, pushing and
    letting go within a step): the force's maximum in the step is searched (peak_of), and a
    touch there is noted, begun and ended, judged by the force there from a step of the method
    (peak_value), the value peak_force reads: the dense output's own, less accurate, could put a
    touch above the floor that peak_force puts below it."""
    was = w.acc[A_TOUCH] != 0.0
    if release and not was:
        ensure_dense(p, w, h)
        th, _ = peak_of((t, h, w.y, w.Q, p, w.iw, w.tmp, w.auxs, w.dy, w.qv[QV_S], Q_NF), 0.0, theta_end,
                        NU.PEAK_TOL)
        if touching(peak_value(p, w, t, h, th, Q_NF), p):
            note_touch(t + th * h, True, w.acc)
            note_touch(t + theta_end * h, False, w.acc)
        return
    if touching(w.qv[QV_1, Q_NF], p) == was:
        return
    if not was or release:
        note_touch(t + theta_end * h, not was, w.acc)
        return
    ensure_dense(p, w, h)
    tol = NU.EVENT_TOL * max(1.0, t) / h
    th = find_touch((t, h, w.y, w.Q, p, w.iw, w.tmp, w.auxs, w.dy, w.qv[QV_S], was), 0.0, theta_end, tol, 0.0, theta_end)[1]
    note_touch(t + th * h, not was, w.acc)
