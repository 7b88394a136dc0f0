"""Events inside a step of the cycle, located on its dense output (docs/model.md §9: "event times are
located inside the step, not rounded to it"): a contact slot changing its code, side or edge; a
graze (a gap that closes and opens again between two apart ends of the step); an outcome
(scraped, escaped). A release (a pushing contact whose force returns to 0) is located again on
the method's own flow (release_state; numerics.RELEASE_TOL says why).

The searches are kernel/search.py's, given a predicate or quantity of (ctx, theta) as data.
"""
from __future__ import annotations

import math

from fencesweep.kernel import numerics as NU
from fencesweep.kernel import rk
from fencesweep.kernel.jit import kernel
from fencesweep.kernel.search import bisector, checker, hermite_max, peak_finder, root_finder
from fencesweep.model import layout as Lp
from fencesweep.model.scenes.contacts import APART, N_SLOTS, RAIL0, TIP
from fencesweep.model.scenes.cycle.layout import IW_CODE, N_CTRL, N_STATE
from fencesweep.model.scenes.cycle.rhs import step
from fencesweep.model.scenes.cycle.slots import (FENCE_BITS, changed_at, changed_mask, classify, frame_at, margin_slot,
                                                 releases, slot_changed, slot_gap, slot_margins)
from fencesweep.model.scenes.load import outcome_margin


@kernel(inline=True)
def point_at(t0, h, y0, Q, p, iw, tmp, theta, fence):
    """The state at t0 + theta h on the step's dense output Q into tmp[:N_CTRL] (rk.dense_eval),
    and its frame there (slots.frame_at): what the searches' predicates and quantities read.
    Without `fence` (only the rail's slots or PIVOT's constant gap are read) the fence's part
    of the frame (the drive, cos and sin of alpha, alpha') is not formed, and is 0."""
    rk.dense_eval(y0, Q, theta, tmp, N_CTRL)
    if fence:
        return frame_at(t0 + theta * h, tmp, p, iw)
    return 0.0, 0.0, 0.0, math.cos(tmp[2]), math.sin(tmp[2])


@kernel(inline=True)
def reads_fence(k):
    """Does slot k's gap (slots.slot_gap) read the fence's frame: a corner on the fence, the tip?"""
    return k < RAIL0 or k == TIP


@kernel()
def mask_changed(ctx, theta):
    """Predicate for search.bisect: has any slot in ctx's mask changed at theta?"""
    t0, h, y0, Q, p, iw, tmp, mask = ctx
    ca, sa, dal, cphi, sphi = point_at(t0, h, y0, Q, p, iw, tmp, theta, (mask & FENCE_BITS) != 0)
    return changed_at(mask, tmp, p, iw, ca, sa, dal, cphi, sphi)


@kernel()
def neg_gap(ctx, theta):
    """-gap of one slot at theta (search.peak_max of it is the gap's minimum)."""
    t0, h, y0, Q, p, iw, tmp, k = ctx
    ca, sa, dal, cphi, sphi = point_at(t0, h, y0, Q, p, iw, tmp, theta, reads_fence(k))
    g, r = slot_gap(k, tmp, p, iw, ca, sa, dal, cphi, sphi)
    return -g


@kernel(inline=True)
def outcome_hit(kind, y, p):
    """Has outcome `kind` (0 scraped, 1 escaped) happened at state y (docs/model.md §9)? Not
    escaped while the centroid is at x_G <= l: opposite corners' offsets are exact negatives
    (load.corner_offset), so one corner is at x <= x_G and min_j x_Gj - l > 0 cannot hold (9.2);
    the corners' sines and cosines are then not needed."""
    if kind == 1 and y[0] <= p[Lp.FL]:
        return False
    m = outcome_margin(kind, y, p)
    return m >= 0.0 if kind == 0 else m > 0.0


@kernel()
def gap_crossed(ctx, theta):
    """Predicate for search.bisect: has the gap of one slot changed sign from its sign at the
    step's start (g0 > 0 or not) by theta?"""
    t0, h, y0, Q, p, iw, tmp, k, closed0 = ctx
    ca, sa, dal, cphi, sphi = point_at(t0, h, y0, Q, p, iw, tmp, theta, reads_fence(k))
    g, r = slot_gap(k, tmp, p, iw, ca, sa, dal, cphi, sphi)
    return (g <= 0.0) != closed0


@kernel()
def gap_part(ctx, theta):
    """gap_crossed's gap as a quantity for search.root: the slot's gap, its sign turned so that it
    is >= 0 while gap_crossed is False (-g from a closed start)."""
    t0, h, y0, Q, p, iw, tmp, k, closed0 = ctx
    ca, sa, dal, cphi, sphi = point_at(t0, h, y0, Q, p, iw, tmp, theta, reads_fence(k))
    g = slot_gap(k, tmp, p, iw, ca, sa, dal, cphi, sphi)[0]
    return -g if closed0 else g


@kernel()
def outcome_reached(ctx, theta):
    """Predicate for search.bisect: has outcome `kind` happened at theta?"""
    y0, Q, p, tmp, kind = ctx
    rk.dense_eval(y0, Q, theta, tmp, N_CTRL)
    return outcome_hit(kind, tmp, p)


@kernel(inline=True)
def margins_at(t0, h, y0, Q, p, iw, tmp, k, theta):
    """slots.slot_margins of slot k at theta on the step's dense output Q."""
    ca, sa, dal, cphi, sphi = point_at(t0, h, y0, Q, p, iw, tmp, theta, True)
    return slot_margins(k, tmp, p, iw, ca, sa, dal, cphi, sphi)


@kernel()
def margin_at(ctx, theta):
    """Part j of slot k's margins at theta (for search.root)."""
    t0, h, y0, Q, p, iw, tmp, k, j = ctx
    return margins_at(t0, h, y0, Q, p, iw, tmp, k, theta)[j]


#: the searches on the dense output (kernel/search.py), bound to the predicates and the gap above
find_change = bisector(mask_changed, "cycle_find_change")
find_outcome = bisector(outcome_reached, "cycle_find_outcome")
find_crossing = bisector(gap_crossed, "cycle_find_crossing")
check_change = checker(mask_changed, "cycle_check_change")
find_gap = root_finder(gap_part, "cycle_find_gap")
check_crossing = checker(gap_crossed, "cycle_check_crossing")
min_gap = peak_finder(neg_gap, "cycle_min_gap")
find_margin = root_finder(margin_at, "cycle_find_margin")


@kernel()
def known_range(t, h, y0, Q, p, iw, tmp, lo, hi, mask, k, tol):
    """Where the change of a slot in mask inside [lo, hi] (fractions of the step [t, t + h] with
    dense output Q) is taken to lie before its bisection (search.bisect's (a, b)): the sign
    change of a part of slot k's margins (slots.slot_margins; k from slots.margin_slot, -1:
    none), the first part >= 0 at lo and < 0 at hi, bracketed by search.root to tol, then
    checked by the bisection's own predicate (search.checked): at its ends (a change the part
    does not make, the manifold's choice or another slot's, fails there, and the bracket is cut
    at the end that failed), and at the bisection's first numerics.MARGIN_CHECKS midpoints
    outside it. The bisection then ends where it would have without it, bit for bit, when
    the predicate changes once in [lo, hi], or changes back over one of the midpoints tested;
    where it changes and changes back between them, or flickers with rounding at the
    threshold, it may end at another change. Returns (lo, hi) when nothing is known."""
    if k < 0:
        return lo, hi
    q_lo = margins_at(t, h, y0, Q, p, iw, tmp, k, lo)
    q_hi = margins_at(t, h, y0, Q, p, iw, tmp, k, hi)
    j = -1
    for i in range(4):
        if j < 0 and q_lo[i] >= 0.0 and q_hi[i] < 0.0:
            j = i
    if j < 0:
        return lo, hi
    a, b = find_margin((t, h, y0, Q, p, iw, tmp, k, j), lo, hi, q_lo[j], q_hi[j], tol, NU.MARGIN_EVALS)
    return check_change((t, h, y0, Q, p, iw, tmp, mask), lo, hi, a, b, NU.MARGIN_CHECKS)


@kernel(inline=True)
def locate_change(t, h, y0, Q, p, iw, tmp, lo, hi, mask, k, tol):
    """The first change of a slot in mask in [lo, hi] on the dense output Q of the step [t, t + h]:
    the bisection's final bracket (search.bisect), from what known_range knows."""
    a, b = known_range(t, h, y0, Q, p, iw, tmp, lo, hi, mask, k, tol)
    return find_change((t, h, y0, Q, p, iw, tmp, mask), lo, hi, tol, a, b)


@kernel(inline=True)
def graze_candidate(k, iw, codes1, g0, r0, g1, r1):
    """Can slot k touch inside the step without changing its code at either end? Apart at both
    ends, with a gap that closes at the start and opens at the end (graze_theta)."""
    return (iw[IW_CODE + k] == APART and codes1[k] == APART and g0[k] > 0.0 and g1[k] > 0.0
            and r0[k] < 0.0 and r1[k] > 0.0)


@kernel(inline=True)
def long_step(p, h):
    """Is a step of length h over numerics.APPROACH_FLOOR of the largest step: long enough to hold
    a gap's dip between two opening ends (dip_candidate), and to be cut by run.approach_step?"""
    return h > NU.APPROACH_FLOOR * p[Lp.H_MAX]


@kernel(inline=True)
def dip_candidate(k, iw, codes1, g0, r0, g1, r1, h):
    """Can slot k dip to contact inside the step although its gap is not closing at the start
    and opening at the end (graze_candidate)? Apart at both ends, its gap could close within the
    step at its end rates, and the cubic through the gap's values and rates at the ends
    (search.hermite_max, docs/model.md (15.9)) has an interior minimum below numerics.DIP_MARGIN
    of the smaller end gap: a tip that skims along an edge of the load, the gap opening at
    both ends of a long step, passed in and out of the load inside one. (The caller asks only
    of steps over APPROACH_FLOOR of the largest step: a shorter one holds no such dip.)"""
    near = min(g0[k], g1[k])
    if not (near > 0.0 and near < (abs(r0[k]) + abs(r1[k])) * h):
        return False
    if iw[IW_CODE + k] != APART or codes1[k] != APART or graze_candidate(k, iw, codes1, g0, r0, g1, r1):
        return False
    return -hermite_max(-g0[k], -r0[k] * h, -g1[k], -r1[k] * h) < NU.DIP_MARGIN * near


@kernel(inline=True)
def crossing_candidate(k, iw, codes1, g0, g1):
    """Can slot k have touched inside the step while its gap changed sign? Apart at both ends
    (out of its span at one of them: docs/model.md §15, Events), its gap of one sign at the start and
    of the other at the end: a rail corner that dips below y = 0 at x < 0 and passes the pivot
    (x > 0) within one step, a fence corner that meets the fence and slides past its tip."""
    return iw[IW_CODE + k] == APART and codes1[k] == APART and (g0[k] > 0.0) != (g1[k] > 0.0)


@kernel(inline=True)
def known_crossing(ctx, tol):
    """The bracket of a slot's gap sign change (gap_crossed's ctx) that search.bisect takes as
    known, as known_range's: the gap (gap_part) bracketed by search.root to tol, then checked by
    gap_crossed (search.checked); (0, 1) when the gap's ends do not bracket a sign change."""
    q0 = gap_part(ctx, 0.0)
    q1 = gap_part(ctx, 1.0)
    if not (q0 >= 0.0 and q1 < 0.0):
        return 0.0, 1.0
    a, b = find_gap(ctx, 0.0, 1.0, q0, q1, tol, NU.MARGIN_EVALS)
    return check_crossing(ctx, 0.0, 1.0, a, b, NU.MARGIN_CHECKS)


@kernel()
def crossing_theta(p, w, t, h, k, tol):
    """theta inside the step at which slot k (crossing_candidate) touches, or 2: its gap's sign
    change located on the dense output (search.bisect, from what known_crossing knows), and the
    slot's code read on the side of it where the gap is closed."""
    closed0 = not (w.g0[k] > 0.0)
    ctx = (t, h, w.y, w.Q, p, w.iw, w.tmp, k, closed0)
    a, b = known_crossing(ctx, tol)
    lo, hi = find_crossing(ctx, 0.0, 1.0, tol, a, b)
    th = lo if closed0 else hi
    if mask_changed((t, h, w.y, w.Q, p, w.iw, w.tmp, 1 << k), th):
        return th
    return 2.0


@kernel(inline=True)
def ensure_dense(p, w, h):
    """The step's dense-output coefficients w.Q[:4] of the first N_CTRL components (what events
    and peaks read), formed the first time the step needs them (w.qok[0] is 0 after every step
    taken, 1 with these, 2 with every component): most steps have no event and no peak, and
    never need them."""
    if w.qok[0] == 0:
        rk.dense_coeffs_of(int(p[Lp.METHOD]), w.K, h, w.y, w.y1, w.Q, 0, N_CTRL)
        w.qok[0] = 1


@kernel(inline=True)
def ensure_dense_all(p, w, h):
    """ensure_dense and the other components' coefficients too (the energies): only the state
    at an event reads them."""
    ensure_dense(p, w, h)
    if w.qok[0] == 1:
        rk.dense_coeffs_of(int(p[Lp.METHOD]), w.K, h, w.y, w.y1, w.Q, N_CTRL, N_STATE)
        w.qok[0] = 2


@kernel()
def graze_theta(p, w, t, h):
    """Earliest theta at which a slot apart at both ends of the step touches in between: every
    gap whose rate changes sign from closing to opening is minimised on the dense output
    (no cheaper pre-test: a cubic through the end values missed a 10 us tip clip whose gap
    function changes branch, docs/model.md §5.2's box distance, inside the step).
    Returns (theta at the minimum, slot) or (2, -1)."""
    best = 2.0
    slot = -1
    for k in range(N_SLOTS):
        if not (graze_candidate(k, w.iw, w.codes1, w.g0, w.r0, w.g1, w.r1)
                or (long_step(p, h) and dip_candidate(k, w.iw, w.codes1, w.g0, w.r0, w.g1, w.r1, h))):
            continue
        th, ng = min_gap((t, h, w.y, w.Q, p, w.iw, w.tmp, k), 0.0, 1.0, NU.PEAK_TOL)
        if ng > 0.0 and th < best and mask_changed((t, h, w.y, w.Q, p, w.iw, w.tmp, 1 << k), th):
            best = th
            slot = k
    return best, slot


@kernel(inline=True)
def touched_between(p, w, t, h, hi, mask, grazing, tol):
    """Slots apart at both ends of the step that touch in between (graze_theta, crossing_theta),
    on its dense output: the earliest such touch before hi becomes the end of the bracket that
    find_event bisects, its slot added to the mask. Returns (hi, mask)."""
    ensure_dense(p, w, h)
    if grazing:
        th_g, slot = graze_theta(p, w, t, h)
        if slot >= 0 and th_g < hi:
            hi = th_g
            mask |= 1 << slot
    for k in range(N_SLOTS):
        if crossing_candidate(k, w.iw, w.codes1, w.g0, w.g1):
            th_c = crossing_theta(p, w, t, h, k, tol)
            if th_c < hi:
                hi = th_c
                mask |= 1 << k
    return hi, mask


@kernel(inline=True)
def step_ends(p, w, h):
    """What the ends of the step tell: (the slots changed, as a mask; may a slot apart at both
    ends touch in between, its gap of one sign at both (graze_candidate, dip_candidate), or of
    the other at the end (crossing_candidate))."""
    mask = 0
    grazing = False
    crossing = False
    long = long_step(p, h)
    for k in range(N_SLOTS):
        if slot_changed(k, w.codes1[k], w.tags1[k], w.iw):
            mask |= 1 << k
        if w.codes1[k] != APART or w.iw[IW_CODE + k] != APART:
            continue  # the candidates below are apart at both ends
        if crossing_candidate(k, w.iw, w.codes1, w.g0, w.g1):
            crossing = True  # (a graze's or a dip's gap has one sign at both ends)
        elif graze_candidate(k, w.iw, w.codes1, w.g0, w.r0, w.g1, w.r1) or (
                long and dip_candidate(k, w.iw, w.codes1, w.g0, w.r0, w.g1, w.r1, h)):
            grazing = True
    return mask, grazing, crossing


@kernel(inline=True)
def find_event(p, w, t, h, exited):
    """First event inside the step [t, t + h] on its dense output: (theta just past it, kind)
    with kind 0 none (theta = 1), 1 a contact change or graze, 2 scraped, 3 escaped. The ends
    of the step tell which events can lie inside it; only then is its dense output formed. A
    change of one of the fence's slots is searched over all of them: one may change and change
    back inside the step before the change seen at its end (a pivot end that pushes while a
    corner leaves the rail)."""
    mask, grazing, crossing = step_ends(p, w, h)
    hi = 1.0 if mask != 0 else 2.0
    tol = NU.EVENT_TOL * max(1.0, t) / h
    if grazing or crossing:
        hi, mask = touched_between(p, w, t, h, hi, mask, grazing, tol)
    if mask & FENCE_BITS:  # one manifold (docs/model.md §15, Events): a change of any of its slots
        mask |= FENCE_BITS
    theta = 1.0
    kind = 0
    if mask != 0:
        ensure_dense(p, w, h)
        theta = locate_change(t, h, w.y, w.Q, p, w.iw, w.tmp, 0.0, hi, mask, margin_slot(w.iw, w.codes1, w.tags1, mask), tol)[1]
        kind = 1
    if not exited:
        for oc in range(2):
            if outcome_hit(oc, w.y1, p):
                ensure_dense(p, w, h)
                th = find_outcome((w.y, w.Q, p, w.tmp, oc), 0.0, 1.0, tol, 0.0, 1.0)[1]
                if th <= theta:
                    theta = th
                    kind = 2 + oc
    return theta, kind


# ---------------------------------------------------------------- releases on the method's flow

@kernel()
def step_part(p, w, t, h, s):
    """w.ys: the state at t + s h from one step of the method from (t, w.y), K[0] = f(t, y);
    classified into w.codes1 ... w.tags1. Returns the slots changed there (changed_mask)."""
    for i in range(N_STATE):
        w.Ks[0, i] = w.K[0, i]
    step(int(p[Lp.METHOD]), t, w.y, s * h, p, w.iw, w.Ks, w.dy, w.ys, w.auxs, w.atol, p[Lp.TOL], N_CTRL)
    classify(t + s * h, w.ys, p, w.iw, w.codes1, w.g1, w.r1, w.tags1)
    return changed_mask(w.iw, w.codes1, w.tags1)


@kernel(inline=True)
def located(p, w, t, h, lo, hi, Q2, mask):
    """The first change of a slot in mask in [lo, hi] (fractions of h) on the dense output Q2
    of the step [t, t + hi h], just past it (search.bisect)."""
    sh = hi * h
    return hi * locate_change(t, sh, w.y, Q2, p, w.iw, w.tmp, lo / hi, 1.0, mask, margin_slot(w.iw, w.codes1, w.tags1, mask),
                              NU.EVENT_TOL * max(1.0, t) / sh)[1]


@kernel()
def release_state(p, w, t, h, th):
    """A release located at th on the dense output Q[:4] of the step [t, t + h], located anew
    on the method's flow (numerics.RELEASE_TOL says why): [lo, hi] (fractions of h) brackets
    it on that flow (a step of the method to lo has not released yet, one to hi has; hi = 1 at
    first, the step's end). Each try steps to s = g + m (hi - g) past the latest located
    release g; one that reaches it becomes hi, and the release is located again on its dense
    output Q[4:]; one that falls short becomes lo and g, and the margin m grows. Returns the
    release, once the step to hi passed it by at most RELEASE_TOL (or, when the tries run
    out, as located in [lo, hi] on the dense output of the step to hi), the state there in w.ys."""
    lo = 0.0
    hi = 1.0
    g = th
    m = 0.0
    mask = (1 << N_SLOTS) - 1  # the slots changed at hi (all: until a step shorter than h reached it)
    tol = NU.RELEASE_TOL * max(1.0, t) / h
    for _ in range(NU.RELEASE_TRIES):
        s = g + m * (hi - g)
        changed = step_part(p, w, t, h, s)
        if changed != 0:
            hi = s
            mask = changed
            rk.dense_coeffs(int(p[Lp.METHOD]), w.Ks, s * h, w.y, w.ys, w.Q[4:], N_STATE)
            g = located(p, w, t, h, lo, hi, w.Q[4:], mask)
            if hi - g <= tol:
                break
            m = NU.RELEASE_MARGIN
        else:
            lo = s
            g = s
            m = min(0.5, 4.0 * m) if m > 0.0 else NU.RELEASE_MARGIN
    Qh = w.Q[:4] if hi == 1.0 else w.Q[4:]  # the dense output of the step to hi
    if g <= lo:
        g = located(p, w, t, h, lo, hi, Qh, mask)
    rk.dense_eval(w.y, Qh, g / hi, w.ys, N_STATE)
    return g


@kernel()
def event_state(p, w, t, h, theta, kind):
    """The state w.y1 at the event that ends the step [t, t + h] (find_event's theta and kind;
    w.codes1 .. hold the step's end on entry and the event's on return): on the dense output,
    or, for releases only (at the event and at the step's end), from release_state. Returns
    (theta, the tip's edge)."""
    released = kind == 1 and releases(w.iw, w.codes1)
    ensure_dense_all(p, w, h)
    rk.dense_eval(w.y, w.Q, theta, w.y1, N_STATE)
    edge1 = classify(t + theta * h, w.y1, p, w.iw, w.codes1, w.g1, w.r1, w.tags1)
    if released and releases(w.iw, w.codes1):
        theta = release_state(p, w, t, h, theta)
        for i in range(N_STATE):
            w.y1[i] = w.ys[i]
        edge1 = classify(t + theta * h, w.y1, p, w.iw, w.codes1, w.g1, w.r1, w.tags1)
    return theta, edge1
