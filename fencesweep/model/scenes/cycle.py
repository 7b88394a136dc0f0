"""Scene `cycle`: one sorting work cycle (MODEL.md §1-§6, §9-§11).

State y (N_STATE = 13):
  0-5  load x, y, phi, x', y', omega                       (MODEL.md §1)
  6-7  fence alpha, alpha'                                  (§3; alpha_w itself when kinematic)
  8    damper energy  int B2 (alpha_w' - alpha')^2 dt       (§11, read at t_c)
  9    contact energy int sum (N - N_el) D' dt              (§11)
  10   drive work     int T_lever alpha_w' dt (rigid: -tau alpha_w')
  11   belt work      int (F . v + M omega) dt
  12   contact friction dissipation int sum -f w dt
The energies are quadratures of the first 8 components; all 13 are under error control (the
events and peaks read only the first 8 from the dense output).

Integer work vector iw: the corners' sides sigma_j (§5.1), the code of each contact slot
(contacts.py: APART / PUSH / CLIPPED), the tip's edge, the fence mode, whether the load is
on the belt and whether it rides the belt in closed form.

The kernel is scenes/stream.py's (a cycle is a stream of one): it calls `start`, then `run`,
the step loop of this file, then `finish`. The loop (`run`): choose the step -> take it (integrate.take_step; rejected when
its error estimate exceeds the tolerance) -> find the first event inside it on its dense
output (a contact slot changing its code, a graze between two apart samples, the outcome
of §9) and end the step there, its state from the dense output, or, at a release, from steps
of the method to it (release_state) -> book-keep (stages, peaks located inside the step, the
trajectory). Between events the right-hand side is smooth: it evaluates only the contacts
whose slot is not APART, in the mode fixed at the step's start.
"""
from __future__ import annotations

import math

from fencesweep.kernel.jit import kernel

from fencesweep.kernel import integrate as I
from fencesweep.model import layout as Lp
from fencesweep.kernel import numerics as NU
from fencesweep.model import results as Rs
from fencesweep.model.contact import belt_friction, pulse_time
from fencesweep.model.drive import drive_angle
from fencesweep.model.scenes.contacts import APART, CLIPPED, N_SLOTS, PUSH, RAIL0, TIP, next_code, corner_fence_force, corner_fence_geometry, corner_rail_force, tip_edge_choice, tip_edge_force, tip_edge_normal, tip_gap, tip_local
from fencesweep.model.scenes.load import corner_motion, initial_state, outcome_margin

N_STATE = 13
N_CTRL = 8  # components that events and peaks read from the dense output (the energies are not)
# integer work vector
IW_CODE = 4  # 4 .. 12: slot codes
IW_EDGE = 13
IW_MODE = 14
IW_LOAD = 15
IW_RIDE = 16
N_IW = 17
FM_KELVIN, FM_KINEMATIC, FM_FREE = 0, 1, 2
# aux outputs of the right-hand side
AX_NF, AX_NR, AX_TAU, AX_DMAX, AX_FX, AX_FY, AX_TQ, AX_PDISS, AX_PFRIC = 0, 1, 2, 3, 4, 5, 6, 7, 8
# ... and the frame the contacts were evaluated in (frame_at's values; AX_FRAME 1 when set),
# which classify reuses at the end of a step instead of computing it again
AX_CA, AX_SA, AX_DAL, AX_CPHI, AX_SPHI, AX_FRAME, N_AUX = 9, 10, 11, 12, 13, 14, 15
# tracked maxima (MODEL.md §11)
Q_NF, Q_NR, Q_DEFL, Q_ALPHA, N_Q = 0, 1, 2, 3, 4
# trajectory columns
TRAJ_COLUMNS = ("t", "x", "y", "phi", "vx", "vy", "omega", "alpha", "alpha_w", "alpha_dot",
                "N_fence", "N_rail", "M_fence", "stage",
                "E_damper", "E_contact", "W_drive", "W_belt", "E_friction")
TRAJ_UNITS = ("s", "m", "m", "rad", "m/s", "m/s", "rad/s", "rad", "rad", "rad/s", "N", "N", "N m", "-",
              "J", "J", "J", "J", "J")
# run accumulators (float vector `acc`)
(A_T_FIRST, A_T_LOSS, A_N_IMPACTS, A_DMAX, A_OUTCOME, A_STATUS, A_T_EXIT, A_X_EXIT, A_PHI_EXIT,
 A_E_CONTACT, A_RESID, A_RESID_AMP, A_E_DAMPER, A_STEPS, A_REJECTS, A_ERR, A_EXITED, A_QMAX,
 A_STAGE, N_ACC) = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 17 + N_Q, 17 + N_Q + 5)


@kernel(inline="always")
def fence_state(t, y, p, mode):
    """(alpha, alpha', alpha_w, alpha_w'): the fence follows alpha_w when kinematic (§3)."""
    aw, daw = drive_angle(t, p)
    if mode == FM_KINEMATIC:
        return aw, daw, aw, daw
    return y[6], y[7], aw, daw


# ---------------------------------------------------------------- right-hand side

@kernel(inline="always")
def add_contact(aux, ax_n, fx, fy, tq, tau, n, p_diss, p_fric, D):
    """Add one contact's forces (contacts.py) to the sums in aux: on the load, the moment on the
    fence, its normal force to the fence or rail sum, the dissipated powers, the penetration."""
    aux[AX_FX] += fx
    aux[AX_FY] += fy
    aux[AX_TQ] += tq
    aux[AX_TAU] += tau
    aux[ax_n] += n
    aux[AX_PDISS] += p_diss
    aux[AX_PFRIC] += p_fric
    aux[AX_DMAX] = max(aux[AX_DMAX], D)


@kernel(inline="always")
def contact_sum(y, p, iw, ca, sa, dal, aux):
    """Sum into aux the forces of every slot that is not APART (MODEL.md §5): on the load
    (AX_FX, AX_FY, AX_TQ), the moment on the fence (AX_TAU), the normal-force sums and the
    dissipated powers."""
    kc, cd, law, mu2, eps = p[Lp.KC], p[Lp.CD], p[Lp.LAW], p[Lp.MU2], p[Lp.EPSV]
    cphi = math.cos(y[2])
    sphi = math.sin(y[2])
    aux[AX_CA] = ca
    aux[AX_SA] = sa
    aux[AX_DAL] = dal
    aux[AX_CPHI] = cphi
    aux[AX_SPHI] = sphi
    aux[AX_FRAME] = 1.0
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    for j in range(4):
        cf = iw[IW_CODE + j]
        cr = iw[IW_CODE + RAIL0 + j]
        if cf == APART and cr == APART:
            continue
        rx, ry, gx, gy, gvx, gvy = corner_motion(j, y, hl, hw, cphi, sphi)
        if cf != APART:
            s, D, Dd = corner_fence_geometry(gx, gy, gvx, gvy, ca, sa, dal, iw[j])
            a, b, c, d, n, pd, pf = corner_fence_force(rx, ry, gvx, gvy, s, D, Dd, iw[j], ca, sa,
                                                       kc, cd, law, mu2, eps, cf == PUSH)
            add_contact(aux, AX_NF, a, b, c, d, n, pd, pf, D)
        if cr != APART:
            a, b, c, n, pd, pf = corner_rail_force(rx, ry, gvx, gvy, gy, kc, cd, law, mu2, eps, cr == PUSH)
            add_contact(aux, AX_NR, a, b, c, 0.0, n, pd, pf, -gy)
    ct = iw[IW_CODE + TIP]
    if ct != APART:
        fl = p[Lp.FL]
        tx = fl * ca
        ty = fl * sa
        tlx, tly, dx, dyy = tip_local(tx, ty, y[0], y[1], cphi, sphi)
        D, nex, ney = tip_edge_normal(iw[IW_EDGE], tlx, tly, hl, hw, cphi, sphi)
        a, b, c, d, n, pd, pf, Dd = tip_edge_force(D, nex, ney, tx, ty, dx, dyy, y[3], y[4], y[5], dal,
                                                   kc, cd, law, mu2, eps, ct == PUSH)
        add_contact(aux, AX_NF, a, b, c, d, n, pd, pf, D)


@kernel(inline="always")
def load_rhs(y, p, iw, ca, sa, dal, dy, aux):
    """Load equations (MODEL.md §1, §5, §6): velocities, and accelerations from belt friction
    and the contacts; the closed-form belt ride when it rides. Returns the moment on the fence."""
    dy[0] = y[3]
    dy[1] = y[4]
    dy[2] = y[5]
    if iw[IW_RIDE] != 0:
        for i in (3, 4, 5, 9, 11, 12):
            dy[i] = 0.0
        return 0.0
    vx, vy, om = y[3], y[4], y[5]
    bx, by, bt = belt_friction(vx - p[Lp.V], vy, om, p[Lp.FMAX], p[Lp.MMAX], p[Lp.RHO], p[Lp.EPSV])
    contact_sum(y, p, iw, ca, sa, dal, aux)
    dy[3] = (aux[AX_FX] + bx) / p[Lp.M1]
    dy[4] = (aux[AX_FY] + by) / p[Lp.M1]
    dy[5] = (aux[AX_TQ] + bt) / p[Lp.I1]
    dy[9] = aux[AX_PDISS]
    dy[11] = bx * vx + by * vy + bt * om
    dy[12] = aux[AX_PFRIC]
    return aux[AX_TAU]


@kernel()
def rhs(t, y, p, iw, dy, aux):
    """Right-hand side of the cycle in the mode of iw; fills dy and aux (contact forces).
    Fence (MODEL.md §3): I2 alpha'' = B2 (alpha_w' - alpha') + K2 (alpha_w - alpha) + tau."""
    mode = iw[IW_MODE]
    al, dal, aw, daw = fence_state(t, y, p, mode)
    for i in range(N_AUX):
        aux[i] = 0.0
    tau = 0.0
    if iw[IW_LOAD] != 0:
        tau = load_rhs(y, p, iw, math.cos(al), math.sin(al), dal, dy, aux)
    else:
        for i in (0, 1, 2, 3, 4, 5, 9, 11, 12):
            dy[i] = 0.0
    dy[8] = 0.0
    if mode == FM_KINEMATIC:
        dy[6] = 0.0
        dy[7] = 0.0
        dy[10] = -tau * daw
        return
    torque = 0.0
    if mode == FM_KELVIN:
        torque = p[Lp.B2] * (daw - dal) + p[Lp.K2] * (aw - al)
        dy[8] = p[Lp.B2] * (daw - dal) ** 2
    dy[6] = dal
    dy[7] = (torque + tau) / p[Lp.I2]
    dy[10] = torque * daw


# ---------------------------------------------------------------- contact slots

@kernel(inline="always")
def slot_eval(k, y, p, iw, ca, sa, dal, cphi, sphi):
    """(code, tag, gap, gap rate) of contact slot k at state y, its code moved on from the one
    in iw (contacts.next_code); the tag is the tip's edge, or a corner's side sigma_j (§5.1);
    the gap is > 0 when apart and is what the graze check minimises."""
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    kc, cd, law = p[Lp.KC], p[Lp.CD], p[Lp.LAW]
    fl = p[Lp.FL]
    cur = iw[IW_CODE + k]
    d_gap = NU.CONTACT_HYSTERESIS * fl
    d_force = NU.CONTACT_HYSTERESIS * p[Lp.FFORCE]
    if k < TIP:
        j = k % 4
        rx, ry, gx, gy, gvx, gvy = corner_motion(j, y, hl, hw, cphi, sphi)
        if k < RAIL0:
            s, D, Dd = corner_fence_geometry(gx, gy, gvx, gvy, ca, sa, dal, iw[j])
            side = iw[j]  # the side memory of §5.1 at this state; a change is an event
            if s > fl:
                side = -1 if -D * iw[j] < 0.0 else 1  # sign(h), h = -sigma D
            elif s < 0.0:
                side = 1
            return next_code(cur, D, Dd, s >= 0.0 and s <= fl, kc, cd, law, d_gap, d_force), side, -D, -Dd
        return next_code(cur, -gy, -gvy, gx <= 0.0, kc, cd, law, d_gap, d_force), 0, gy, gvy
    tx = fl * ca
    ty = fl * sa
    tlx, tly, dx, dyy = tip_local(tx, ty, y[0], y[1], cphi, sphi)
    rvx = -dal * ty - y[3]  # d/dt (T - X)
    rvy = dal * tx - y[4]
    tlx_d = cphi * rvx + sphi * rvy + y[5] * tly
    tly_d = -sphi * rvx + cphi * rvy - y[5] * tlx
    gap, rate = tip_gap(tlx, tly, tlx_d, tly_d, hl, hw)
    edge = iw[IW_EDGE]
    if gap < 0.0 or cur != APART:
        edge = tip_edge_choice(y[0], y[1], cphi, sphi, tlx, tly, hl, hw)
    D, nex, ney = tip_edge_normal(edge, tlx, tly, hl, hw, cphi, sphi)
    Dd = -((-dal * ty - (y[3] - y[5] * dyy)) * nex + (dal * tx - (y[4] + y[5] * dx)) * ney)
    if gap >= 0.0:
        D = -gap  # outside the load: minus the gap
    return next_code(cur, D, Dd, True, kc, cd, law, d_gap, d_force), edge, gap, rate


@kernel(inline="always")
def frame_at(t, y, p, iw):
    """What slot_eval needs of the fence and the load at (t, y): cos and sin of alpha, alpha',
    cos and sin of phi."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    return math.cos(al), math.sin(al), dal, math.cos(y[2]), math.sin(y[2])


@kernel()
def classify(t, y, p, iw, codes, gaps, rates, tags):
    """Codes, gaps and gap rates of every slot at (t, y); returns the tip's edge. Without a
    load every slot is apart."""
    if iw[IW_LOAD] == 0:
        for k in range(N_SLOTS):
            codes[k] = APART
            gaps[k] = math.inf
            rates[k] = 0.0
            tags[k] = iw[k] if k < RAIL0 else 0
        return 0
    ca, sa, dal, cphi, sphi = frame_at(t, y, p, iw)
    return classify_in(y, p, iw, codes, gaps, rates, tags, ca, sa, dal, cphi, sphi)


@kernel()
def classify_after_rhs(t, y, p, iw, codes, gaps, rates, tags, aux):
    """classify at (t, y) where aux is from rhs at that point: its frame, when rhs evaluated
    the contacts there (AX_FRAME), saves drive_angle and four sines and cosines a step."""
    if iw[IW_LOAD] == 0 or aux[AX_FRAME] == 0.0:
        return classify(t, y, p, iw, codes, gaps, rates, tags)
    return classify_in(y, p, iw, codes, gaps, rates, tags, aux[AX_CA], aux[AX_SA], aux[AX_DAL], aux[AX_CPHI],
                       aux[AX_SPHI])


@kernel(inline="always")
def classify_in(y, p, iw, codes, gaps, rates, tags, ca, sa, dal, cphi, sphi):
    """classify's loop over the slots, in the frame (ca, sa, dal, cphi, sphi) of frame_at."""
    edge = 0
    for k in range(N_SLOTS):
        c, e, g, r = slot_eval(k, y, p, iw, ca, sa, dal, cphi, sphi)
        codes[k] = c
        gaps[k] = g
        rates[k] = r
        tags[k] = e
        if k == TIP:
            edge = e
    return edge


@kernel(inline="always")
def slot_changed(k, code, tag, iw):
    """Has slot k left the code it had at the step's start, or (tag) a corner its side, the
    tip the edge it pushes?"""
    if code != iw[IW_CODE + k]:
        return True
    if k < RAIL0:
        return tag != iw[k]
    return k == TIP and code != APART and tag != iw[IW_EDGE]


@kernel(inline="always")
def take_sides(iw, tags):
    """Side memory sigma_j (MODEL.md §5.1) from classify's tags at the step's end (slot_eval
    applies the rule: beyond the tip sigma := sign(h), 0 -> +1; behind the pivot sigma := +1).
    Returns whether any side changed."""
    changed = False
    for j in range(RAIL0):
        if tags[j] != iw[j]:
            iw[j] = tags[j]
            changed = True
    return changed


# ---------------------------------------------------------------- events on the dense output

@kernel()
def _mask_changed(ctx, theta):
    """Predicate for integrate.bisect: has any slot in ctx's mask changed at theta?"""
    t0, h, y0, Q, p, iw, tmp, mask = ctx
    I.dense_eval(y0, Q, theta, tmp, N_CTRL)
    ca, sa, dal, cphi, sphi = frame_at(t0 + theta * h, tmp, p, iw)
    for k in range(N_SLOTS):
        if mask & (1 << k):
            c, e, g, r = slot_eval(k, tmp, p, iw, ca, sa, dal, cphi, sphi)
            if slot_changed(k, c, e, iw):
                return True
    return False


@kernel()
def _neg_gap(ctx, theta):
    """-gap of one slot at theta (peak_max of it is the gap's minimum)."""
    t0, h, y0, Q, p, iw, tmp, k = ctx
    I.dense_eval(y0, Q, theta, tmp, N_CTRL)
    ca, sa, dal, cphi, sphi = frame_at(t0 + theta * h, tmp, p, iw)
    c, e, g, r = slot_eval(k, tmp, p, iw, ca, sa, dal, cphi, sphi)
    return -g


@kernel(inline="always")
def outcome_hit(kind, y, p):
    """Has outcome `kind` (0 scraped, 1 escaped) happened at state y (MODEL.md §9)?"""
    m = outcome_margin(kind, y, p)
    return m >= 0.0 if kind == 0 else m > 0.0


@kernel()
def _outcome_reached(ctx, theta):
    """Predicate for integrate.bisect: has outcome `kind` happened at theta?"""
    y0, Q, p, tmp, kind = ctx
    I.dense_eval(y0, Q, theta, tmp, N_CTRL)
    return outcome_hit(kind, tmp, p)


@kernel(inline="always")
def graze_candidate(k, iw, codes1, g0, r0, g1, r1):
    """Can slot k touch inside the step without changing its code at either end? Apart at both
    ends, with a gap that closes at the start and opens at the end (graze_theta)."""
    return (iw[IW_CODE + k] == APART and codes1[k] == APART and g0[k] > 0.0 and g1[k] > 0.0
            and r0[k] < 0.0 and r1[k] > 0.0)


@kernel(inline="always")
def ensure_dense(method, K, h, y0, y1, Q, qok):
    """The step's dense-output coefficients, formed the first time the step needs them (qok[0]
    is 0 after every step taken): most steps have no event and no peak, and never need them."""
    if qok[0] == 0:
        I.dense_coeffs(method, K, h, y0, y1, Q, N_STATE)
        qok[0] = 1


@kernel()
def graze_theta(t, h, y0, Q, p, iw, tmp, g0, r0, g1, r1, codes1):
    """Earliest theta at which a slot apart at both ends of the step touches in between: every
    gap whose rate changes sign from closing to opening is minimised on the dense output
    (no cheaper pre-test: a cubic through the end values missed a 10 us tip clip whose gap
    function changes branch, MODEL.md §5.2's box distance, inside the step).
    Returns (theta at the minimum, slot) or (2, -1)."""
    best = 2.0
    slot = -1
    for k in range(N_SLOTS):
        if not graze_candidate(k, iw, codes1, g0, r0, g1, r1):
            continue
        th, ng = I.peak_max(_neg_gap, (t, h, y0, Q, p, iw, tmp, k), 0.0, 1.0, NU.PEAK_TOL)
        if ng > 0.0 and th < best and _mask_changed((t, h, y0, Q, p, iw, tmp, 1 << k), th):
            best = th
            slot = k
    return best, slot


@kernel()
def find_event(t, h, y0, y1, K, Q, qok, p, iw, tmp, g0, r0, g1, r1, codes1, tags1, exited):
    """First event inside the step [t, t + h] on its dense output: (theta just past it, kind)
    with kind 0 none (theta = 1), 1 a contact change or graze, 2 scraped, 3 escaped. The ends
    of the step tell which events can lie inside it; only then is its dense output formed."""
    method = int(p[Lp.METHOD])
    mask = 0
    grazing = False
    for k in range(N_SLOTS):
        if slot_changed(k, codes1[k], tags1[k], iw):
            mask |= 1 << k
        grazing |= graze_candidate(k, iw, codes1, g0, r0, g1, r1)
    hi = 1.0 if mask != 0 else 2.0
    if grazing:
        ensure_dense(method, K, h, y0, y1, Q, qok)
        th_g, slot = graze_theta(t, h, y0, Q, p, iw, tmp, g0, r0, g1, r1, codes1)
        if slot >= 0 and th_g < hi:
            hi = th_g
            mask |= 1 << slot
    tol = NU.EVENT_TOL * max(1.0, t) / h
    theta = 1.0
    kind = 0
    if mask != 0:
        ensure_dense(method, K, h, y0, y1, Q, qok)
        theta = I.bisect(_mask_changed, (t, h, y0, Q, p, iw, tmp, mask), 0.0, hi, tol)[1]
        kind = 1
    if not exited:
        for oc in range(2):
            if outcome_hit(oc, y1, p):
                ensure_dense(method, K, h, y0, y1, Q, qok)
                th = I.bisect(_outcome_reached, (y0, Q, p, tmp, oc), 0.0, 1.0, tol)[1]
                if th <= theta:
                    theta = th
                    kind = 2 + oc
    return theta, kind


# ---------------------------------------------------------------- releases on the method's flow

@kernel(inline="always")
def releases(iw, codes):
    """Are codes releases only: some slots pushing in iw clipped in codes (MODEL.md §4: N
    returned to 0), every other slot's code as in iw?"""
    rel = False
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] == PUSH and codes[k] == CLIPPED:
            rel = True
        elif codes[k] != iw[IW_CODE + k]:
            return False
    return rel


@kernel(inline="always")
def changed_mask(iw, codes, tags):
    """Bit k set when slot k changed its code, side or edge from iw (an event, find_event's mask)."""
    mask = 0
    for k in range(N_SLOTS):
        if slot_changed(k, codes[k], tags[k], iw):
            mask |= 1 << k
    return mask


@kernel()
def step_part(t, h, s, y0, K, p, iw, tmp, aux, Ks, ys, atol, codes, gaps, rates, tags):
    """ys: the state at t + s h from one step of the method from (t, y0), K[0] = f(t, y0);
    classified into codes..tags. Returns the slots changed there (changed_mask)."""
    for i in range(N_STATE):
        Ks[0, i] = K[0, i]
    I.take_step(int(p[Lp.METHOD]), rhs, t, y0, s * h, p, iw, Ks, tmp, ys, aux, atol, p[Lp.TOL], N_CTRL)
    classify(t + s * h, ys, p, iw, codes, gaps, rates, tags)
    return changed_mask(iw, codes, tags)


@kernel()
def release_state(t, h, th, y0, K, Q, p, iw, tmp, dy, aux, Ks, ys, atol, codes, gaps, rates, tags):
    """A release located at th on the dense output Q[:4] of the step [t, t + h], located anew
    on the method's flow (numerics.RELEASE_TOL says why): [lo, hi] (fractions of h) brackets
    it on that flow (a step of the method to lo has not released yet, one to hi has; hi = 1 at
    first, the step's end). Each try steps to s = g + m (hi - g) past the latest located
    release g; one that reaches it becomes hi, and the release is located again on its dense
    output Q[4:]; one that falls short becomes lo and g, and the margin m grows. Returns the
    release, once the step to hi passed it by at most RELEASE_TOL (or, when the tries run
    out, as located in [lo, hi] on the dense output of the step to hi), the state there in ys."""
    lo = 0.0
    hi = 1.0
    g = th
    m = 0.0
    mask = (1 << N_SLOTS) - 1  # the slots changed at hi (all: until a step shorter than h reached it)
    tol = NU.RELEASE_TOL * max(1.0, t) / h
    for _ in range(NU.RELEASE_TRIES):
        s = g + m * (hi - g)
        changed = step_part(t, h, s, y0, K, p, iw, dy, aux, Ks, ys, atol, codes, gaps, rates, tags)
        if changed != 0:
            hi = s
            mask = changed
            I.dense_coeffs(int(p[Lp.METHOD]), Ks, s * h, y0, ys, Q[4:], N_STATE)
            g = located(t, h, lo, hi, y0, Q[4:], p, iw, tmp, mask)
            if hi - g <= tol:
                break
            m = NU.RELEASE_MARGIN
        else:
            lo = s
            g = s
            m = min(0.5, 4.0 * m) if m > 0.0 else NU.RELEASE_MARGIN
    Qh = Q[:4] if hi == 1.0 else Q[4:]  # the dense output of the step to hi
    if g <= lo:
        g = located(t, h, lo, hi, y0, Qh, p, iw, tmp, mask)
    I.dense_eval(y0, Qh, g / hi, ys, N_STATE)
    return g


@kernel(inline="always")
def located(t, h, lo, hi, y0, Q2, p, iw, tmp, mask):
    """The first change of a slot in mask in [lo, hi] (fractions of h) on the dense output Q2
    of the step [t, t + hi h], just past it (integrate.bisect)."""
    sh = hi * h
    return hi * I.bisect(_mask_changed, (t, sh, y0, Q2, p, iw, tmp, mask), lo / hi, 1.0,
                         NU.EVENT_TOL * max(1.0, t) / sh)[1]


@kernel()
def event_state(t, h, theta, kind, y0, y1, K, Q, p, iw, tmp, dy, aux, Ks, ys, atol, codes1, g1, r1, tags1):
    """The state y1 at the event that ends the step [t, t + h] (find_event's theta and kind;
    codes1.. hold the step's end on entry and the event's on return): on the dense output, or,
    for releases only (at the event and at the step's end), from release_state. Returns
    (theta, the tip's edge)."""
    released = kind == 1 and releases(iw, codes1)
    I.dense_eval(y0, Q, theta, y1, N_STATE)
    edge1 = classify(t + theta * h, y1, p, iw, codes1, g1, r1, tags1)
    if released and releases(iw, codes1):
        theta = release_state(t, h, theta, y0, K, Q, p, iw, tmp, dy, aux, Ks, ys, atol, codes1, g1, r1, tags1)
        for i in range(N_STATE):
            y1[i] = ys[i]
        edge1 = classify(t + theta * h, y1, p, iw, codes1, g1, r1, tags1)
    return theta, edge1


# ---------------------------------------------------------------- tracked maxima

@kernel()
def quantities(t, y, p, iw, aux, dy, q, forces=True):
    """The tracked quantities at (t, y): fence and rail force sums, |alpha - alpha_w|, alpha.
    Without `forces` the force sums (which cost a right-hand side) are left as they are."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    if forces:
        q[Q_NF] = 0.0
        q[Q_NR] = 0.0
        if iw[IW_LOAD] != 0 and iw[IW_RIDE] == 0:
            rhs(t, y, p, iw, dy, aux)
            q[Q_NF] = aux[AX_NF]
            q[Q_NR] = aux[AX_NR]
    q[Q_DEFL] = abs(al - aw)
    q[Q_ALPHA] = al


@kernel(inline="always")
def quantities_from_aux(t, y, p, iw, aux, q):
    """The tracked quantities at (t, y) with aux from rhs there."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    q[Q_NF] = aux[AX_NF]
    q[Q_NR] = aux[AX_NR]
    q[Q_DEFL] = abs(al - aw)
    q[Q_ALPHA] = al


@kernel(inline="always")
def all_finite(y):
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    return True


@kernel()
def _quantity_at(ctx, theta):
    """One tracked quantity on the dense output (for peak_max)."""
    t0, h, y0, Q, p, iw, tmp, aux, dy, q, kind = ctx
    I.dense_eval(y0, Q, theta, tmp, N_CTRL)
    quantities(t0 + theta * h, tmp, p, iw, aux, dy, q, kind < Q_DEFL)
    return q[kind]


@kernel(inline="always")
def near_maximum(q0, q1, acc, k):
    """Can this step hold a new maximum of tracked quantity k? Only if one of its end samples
    is within numerics.PEAK_CANDIDATE of the running maximum (the samples around an interior
    peak are, at steps that resolve it), and that maximum is not 0 (a force before any contact:
    a contact's onset is an event, after which the step is judged anew)."""
    m = max(acc[A_QMAX + k], q0[k], q1[k])
    return max(q0[k], q1[k]) >= NU.PEAK_CANDIDATE * m and m > 0.0


UNJUDGED = -1.0  # rising[k] when the step before did not judge quantity k at its end


@kernel(inline="always")
def fence_slopes(t, y, p, iw):
    """Time derivatives of the tracked fence quantities at (t, y): of the deflection
    |alpha - alpha_w| (MODEL.md §11) and of alpha."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    rate = dal - daw
    if al - aw < 0.0:
        rate = -rate
    elif al == aw:
        rate = abs(rate)
    return rate, dal


@kernel()
def step_to(t, h, th, y0, p, iw, tmp, aux, dy, Ks, ys, atol):
    """ys: the state at t + th h from a step of the method from (t, y0) to it, not from the
    dense output (whose error is not controlled); the value of a located peak is read there."""
    for i in range(N_STATE):
        tmp[i] = y0[i]
    rhs(t, tmp, p, iw, Ks[0], aux)
    I.take_step(int(p[Lp.METHOD]), rhs, t, tmp, th * h, p, iw, Ks, dy, ys, aux, atol, p[Lp.TOL], N_CTRL)


@kernel()
def peak_value(t, h, th, y0, p, iw, tmp, aux, dy, qs, Ks, ys, atol, k):
    """Quantity k at t + th h, from step_to: one extra step per located peak."""
    step_to(t, h, th, y0, p, iw, tmp, aux, dy, Ks, ys, atol)
    quantities(t + th * h, ys, p, iw, aux, dy, qs, k < Q_DEFL)
    return qs[k]


@kernel()
def track_maxima(t, h, theta_end, y0, y1, K, Q, qok, p, iw, tmp, aux, dy, q0, q1, qa, qb, qs, ths, acc, rising,
                 Ks, ys, atol):
    """Running maxima of the tracked quantities over the step [t, t + theta_end h]: the end
    samples, and an interior maximum (the quantity rising at the start and falling at the
    end, judged on the dense output) located by Brent's search (integrate.peak_max, MODEL.md §9).
    rising[k] says whether quantity k rose at the start (1, 0; UNJUDGED when the step before
    was far from its maximum, or after an event: rising[N_Q] = 1); on return it says so for
    the step's end. The fence's quantities are judged by their derivatives at the ends
    (fence_slopes); the force sums, which have no cheap derivative, by samples on the dense
    output, each costing a right-hand side, and only in steps near their running maximum. ths[k]: the fraction of the step at which quantity
    k's interior maximum was located, -1 where none was."""
    for k in range(N_Q):
        ths[k] = -1.0
    forces = near_maximum(q0, q1, acc, Q_NF) or near_maximum(q0, q1, acc, Q_NR)
    method = int(p[Lp.METHOD])
    if rising[N_Q] != 0.0:
        for k in range(N_Q):
            rising[k] = UNJUDGED
    if forces:  # sampled a thousandth of the step inside its ends
        ensure_dense(method, K, h, y0, y1, Q, qok)
        d = 1e-3 * theta_end
        if rising[Q_NF] == UNJUDGED or rising[Q_NR] == UNJUDGED:
            I.dense_eval(y0, Q, d, tmp, N_CTRL)
            quantities(t + d * h, tmp, p, iw, aux, dy, qa, True)
            for k in range(Q_DEFL):
                if rising[k] == UNJUDGED:
                    rising[k] = 1.0 if qa[k] > q0[k] else 0.0
        I.dense_eval(y0, Q, theta_end - d, tmp, N_CTRL)
        quantities(t + (theta_end - d) * h, tmp, p, iw, aux, dy, qb, True)
    if rising[Q_DEFL] == UNJUDGED or rising[Q_ALPHA] == UNJUDGED:  # the fence's quantities: by
        sd, sa = fence_slopes(t, y0, p, iw)  # their derivatives
        if rising[Q_DEFL] == UNJUDGED:
            rising[Q_DEFL] = 1.0 if sd > 0.0 else 0.0
        if rising[Q_ALPHA] == UNJUDGED:
            rising[Q_ALPHA] = 1.0 if sa > 0.0 else 0.0
    sd, sa = fence_slopes(t + theta_end * h, y1, p, iw)
    qb[Q_DEFL] = q1[Q_DEFL] - sd  # stand-ins for samples just before the end: only the sign of
    qb[Q_ALPHA] = q1[Q_ALPHA] - sa  # their difference from q1 is read
    for k in range(N_Q):
        m = max(acc[A_QMAX + k], q0[k], q1[k])
        if k < Q_DEFL and not forces:
            acc[A_QMAX + k] = m
            rising[k] = UNJUDGED
            continue
        if rising[k] == 1.0 and qb[k] > q1[k] and max(q1[k], q0[k]) >= NU.PEAK_CANDIDATE * m:
            ensure_dense(method, K, h, y0, y1, Q, qok)
            th, qm = I.peak_max(_quantity_at, (t, h, y0, Q, p, iw, tmp, aux, dy, qs, k),
                                  0.0, theta_end, NU.PEAK_TOL)
            m = max(m, peak_value(t, h, th, y0, p, iw, tmp, aux, dy, qs, Ks, ys, atol, k))
            ths[k] = th
        acc[A_QMAX + k] = m
        rising[k] = 1.0 if q1[k] > qb[k] else 0.0
    rising[N_Q] = 0.0


# ---------------------------------------------------------------- book-keeping

@kernel()
def stage_of(iw):
    """Stage of MODEL.md §10 from the slots that carry force."""
    nfc = 0
    rail = False
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] == PUSH:
            if k >= RAIL0 and k < TIP:
                rail = True
            else:
                nfc += 1
    if nfc == 0:
        return Rs.STAGE_RAIL if rail else Rs.STAGE_S2
    if rail:
        return Rs.STAGE_S4
    return Rs.STAGE_S1 if nfc == 1 else Rs.STAGE_S3


@kernel(inline="always")
def fence_pushed(iw):
    """Does any load-fence slot (corners on the fence, the tip) carry force?"""
    for k in (0, 1, 2, 3, TIP):
        if iw[IW_CODE + k] == PUSH:
            return True
    return False


@kernel()
def record(traj, row, t, y, p, iw, aux):
    """One trajectory row (TRAJ_COLUMNS) at (t, y), aux from rhs there; returns the row count,
    which goes on counting past the buffer's capacity (the caller grows it and reruns)."""
    if row < traj.shape[0]:
        al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
        traj[row, 0] = t
        for i in range(6):
            traj[row, 1 + i] = y[i]
        traj[row, 7] = al
        traj[row, 8] = aw
        traj[row, 9] = dal
        traj[row, 10] = aux[AX_NF]
        traj[row, 11] = aux[AX_NR]
        traj[row, 12] = -aux[AX_TAU]  # moment of the load on the fence, paper's sign (N R > 0)
        traj[row, 13] = stage_of(iw) if iw[IW_LOAD] != 0 else -1
        for i in range(5):
            traj[row, 14 + i] = y[8 + i]
    return row + 1


@kernel()
def record_peaks(traj, row, t, h, theta_end, y0, p, iw, ths, tmp, dy, aux, Ks, ys, atol):
    """Trajectory rows at the maxima located inside the step (track_maxima's ths), in time
    order, each at the state of a step of the method to it: so that the trajectory's peaks are
    the results' (peak_force, deflection_max, alpha_max), not the samples around them."""
    prev = 0.0
    while True:
        th = 2.0
        for k in range(N_Q):
            if ths[k] > prev and ths[k] < th:
                th = ths[k]
        if th >= theta_end * (1.0 - 1e-9):
            return row
        step_to(t, h, th, y0, p, iw, tmp, aux, dy, Ks, ys, atol)
        rhs(t + th * h, ys, p, iw, dy, aux)
        row = record(traj, row, t + th * h, ys, p, iw, aux)
        prev = th


@kernel(inline="always")
def new_push(iw, codes):
    """Does a slot apart in iw push in codes (a contact onset)?"""
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] == APART and codes[k] == PUSH:
            return True
    return False


@kernel()
def apply_contact_change(t, y, p, iw, codes, edge, acc):
    """Enter the slots' new codes at an event; count onsets and losses of load-fence contact
    (MODEL.md §10-§11); release the free fence at the first contact (§3)."""
    before = fence_pushed(iw)
    for k in range(N_SLOTS):
        iw[IW_CODE + k] = codes[k]
    iw[IW_EDGE] = edge
    iw[IW_RIDE] = 0
    after = fence_pushed(iw)
    if after and not before:
        acc[A_N_IMPACTS] += 1.0
        if math.isnan(acc[A_T_FIRST]):
            acc[A_T_FIRST] = t
        if iw[IW_MODE] == FM_KINEMATIC and p[Lp.DRIVE] == Lp.DRIVE_FREE:
            aw, daw = drive_angle(t, p)
            iw[IW_MODE] = FM_FREE
            y[6] = aw
            y[7] = daw
    if before and not after:
        acc[A_T_LOSS] = t


@kernel()
def drop_load(t, y, p, iw, acc, outcome):
    """The load leaves the run at t (outcome event, or a timeout before t_c): its results."""
    acc[A_OUTCOME] = outcome
    acc[A_T_EXIT] = t
    acc[A_X_EXIT] = y[0]
    acc[A_PHI_EXIT] = y[2]
    acc[A_E_CONTACT] = y[9]
    if fence_pushed(iw):
        acc[A_T_LOSS] = t  # still touching at exit: B = t_exit
    acc[A_EXITED] = 1.0
    iw[IW_LOAD] = 0
    iw[IW_RIDE] = 0
    for k in range(N_SLOTS):
        iw[IW_CODE + k] = APART


@kernel()
def try_ride(y, p, iw):
    """A load with no contact whose slip is below numerics.SNAP_SLIP eps_v rides the belt in
    closed form from here on (MODEL.md §8): velocity (v, 0), no spin. Returns whether it snapped."""
    if iw[IW_LOAD] == 0 or iw[IW_RIDE] != 0:
        return False
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] != APART:
            return False
    slip2 = (y[3] - p[Lp.V]) ** 2 + y[4] ** 2 + (p[Lp.RHO] * y[5]) ** 2
    if slip2 >= p[Lp.SNAP] ** 2:
        return False
    y[3] = p[Lp.V]
    y[4] = 0.0
    y[5] = 0.0
    iw[IW_RIDE] = 1
    return True


@kernel(inline="always")
def swing_amplitude(dev, rate, p, mode):
    """Undamped amplitude [rad] of the fence's swing about its drive from the deflection dev =
    alpha - alpha_w [rad] and its rate [rad/s] (MODEL.md §11 residual_amplitude, §14
    start_amplitude): sqrt(dev^2 + (rate / omega_n)^2), omega_n = sqrt(K2 / I2); |dev| when
    K2 = 0 (or so small that omega_n underflows to 0) or the fence follows its drive."""
    wn = math.sqrt(p[Lp.K2] / p[Lp.I2])
    if mode == FM_KELVIN and wn > 0.0:
        return math.sqrt(dev ** 2 + (rate / wn) ** 2)  # §11
    return abs(dev)


@kernel()
def at_t_c(t, y, p, iw, acc):
    """Results read at t_c (MODEL.md §11): residual deflection and amplitude, damper energy."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    acc[A_RESID] = abs(al - aw)
    acc[A_RESID_AMP] = swing_amplitude(al - aw, dal - daw, p, iw[IW_MODE])
    acc[A_E_DAMPER] = y[8]


@kernel()
def start(p, y, iw, acc, atol):
    """Initial state, modes, accumulators and the error scales (error_scales) of the run."""
    initial_state(p, y)
    for j in range(4):
        iw[j] = 1
    drive = int(p[Lp.DRIVE])
    iw[IW_MODE] = FM_KELVIN if drive == Lp.DRIVE_FLEXIBLE else FM_KINEMATIC
    iw[IW_LOAD] = 1
    iw[IW_RIDE] = 1  # at t = 0 the load moves with the belt (MODEL.md §1)
    for i in range(N_ACC):
        acc[i] = 0.0
    for i in (A_T_FIRST, A_T_LOSS, A_T_EXIT, A_X_EXIT, A_PHI_EXIT, A_E_CONTACT, A_RESID, A_RESID_AMP,
              A_E_DAMPER):
        acc[i] = math.nan
    acc[A_OUTCOME] = Rs.TIMEOUT
    error_scales(p, atol)


@kernel()
def error_scales(p, atol):
    """atol: the absolute tolerance of each state component, TOL (p[TOL]) times its scale.
    The scales are chosen so that every component's allowed error moves a point of the scene by
    about the same distance, TOL l (l the fence length) or TOL x the fastest speed:
      x, y: l;  phi: l / r;  x', y': speed;  omega: speed / r;  alpha: 1 rad (l at the tip);
      alpha': speed / l;
    with speed the fastest belt-or-fence speed v + l max|alpha_w'| and r the load's half-diagonal
    (its corners move by r dphi: an angle error of TOL l / r moves them by TOL l, as the fence's
    TOL moves its tip by TOL l). The energies (components N_CTRL..) are on the scale of the
    fence's kinetic energy at that speed. (phi and omega were on 1 rad and speed / l before:
    l / r times tighter than the corners need, 3.4 and 10.7 for the named loads; on the b2k2
    sample that cost 4% more steps, 332.7 against 318.5 a cycle.)"""
    tol = p[Lp.TOL]
    speed = p[Lp.V] + p[Lp.FL] * p[Lp.DAW_MAX]
    r = 0.5 * math.sqrt(p[Lp.LL] ** 2 + p[Lp.AA] ** 2)
    fl = p[Lp.FL]
    for i, sc in enumerate((fl, fl, fl / r, speed, speed, speed / r, 1.0, speed / fl)):
        atol[i] = tol * sc
    e_scale = p[Lp.I2] * (speed / fl) ** 2
    for i in range(N_CTRL, N_STATE):
        atol[i] = tol * e_scale


@kernel()
def after_step(t1, y1, p, iw, kind, codes1, tags1, edge1, acc):
    """Apply the event that ended a step at t1 (find_event's kind), the side memory and the
    closed-form ride. Returns True when the mode changed (the right-hand side must be
    evaluated anew at t1)."""
    changed = kind != 0
    if kind == 1:
        apply_contact_change(t1, y1, p, iw, codes1, edge1, acc)
    elif kind >= 2:
        drop_load(t1, y1, p, iw, acc, Rs.SCRAPED if kind == 2 else Rs.ESCAPED)
    if iw[IW_LOAD] != 0:
        changed |= take_sides(iw, tags1)
        changed |= try_ride(y1, p, iw)
    if iw[IW_MODE] == FM_KINEMATIC:
        y1[6], y1[7] = drive_angle(t1, p)
    return changed


@kernel(inline="always")
def fence_free_of_load(iw):
    """No slot of the load is in contact."""
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] != APART:
            return False
    return True


@kernel()
def run(p, y, y1, tmp, dy, K, Q, qok, aux, auxs, iw, codes1, tags1, g0, r0, g1, r1, qv, acc, atol, rising, Ks, ys,
        traj, row):
    """The step loop of the cycle (module docstring). Returns the trajectory row count."""
    method = int(p[Lp.METHOD])
    tol = p[Lp.TOL]
    tc = p[Lp.TC]
    half_side = 0.5 * min(p[Lp.LL], p[Lp.AA])
    t = 0.0
    h = p[Lp.DT] if method == I.METHOD_RK4 else 0.1 * p[Lp.H_MAX]
    while True:
        t_end = tc if acc[A_EXITED] != 0.0 else p[Lp.TMAX]
        if t >= t_end - 1e-12 * max(1.0, t_end):
            if acc[A_EXITED] == 0.0 and t < tc:
                # t_max before t_c (MODEL.md §9 timeout): the load leaves, the fence runs on
                # alone to t_c (its results are over [0, max(t_exit, t_c)])
                drop_load(t, y, p, iw, acc, Rs.TIMEOUT)
                rhs(t, y, p, iw, K[0], aux)
                continue
            break
        if acc[A_STEPS] + acc[A_REJECTS] >= NU.MAX_STEPS:
            acc[A_STATUS] = Rs.ST_MAXSTEPS
            break
        if method == I.METHOD_RK4:
            h = p[Lp.DT]
        h = min(h, p[Lp.H_MAX], t_end - t)
        hits_tc = t < tc and t + h >= tc
        if hits_tc:
            h = tc - t
        err = I.take_step(method, rhs, t, y, h, p, iw, K, tmp, y1, aux, atol, tol, N_STATE)
        if not (err <= 1.0):  # rejected (a NaN error too)
            h = I.next_step(h, err, NU.SAFETY, NU.FAC_MIN, 1.0) if err == err else NU.FAC_MIN * h
            acc[A_REJECTS] += 1.0
            if h < NU.H_MIN * max(1.0, t):
                acc[A_STATUS] = Rs.ST_UNDERFLOW
                break
            continue
        acc[A_STEPS] += 1.0
        acc[A_ERR] += err * err  # finish: error_estimate
        qok[0] = 0  # the step's dense output is formed when first needed (ensure_dense)
        edge1 = classify_after_rhs(t + h, y1, p, iw, codes1, g1, r1, tags1, aux)  # aux: of f(t + h, y1)
        theta, kind = find_event(t, h, y, y1, K, Q, qok, p, iw, tmp, g0, r0, g1, r1, codes1, tags1,
                                 acc[A_EXITED] != 0.0)
        if kind == 0:
            t1 = tc if hits_tc else t + h
        else:
            theta, edge1 = event_state(t, h, theta, kind, y, y1, K, Q, p, iw, tmp, dy, auxs, Ks, ys, atol,
                                       codes1, g1, r1, tags1)
            t1 = t + theta * h
        if kind == 0:
            quantities_from_aux(t1, y1, p, iw, aux, qv[1])  # aux of the FSAL stage f(t1, y1)
        else:
            quantities(t1, y1, p, iw, aux, dy, qv[1])
        track_maxima(t, h, theta, y, y1, K, Q, qok, p, iw, tmp, auxs, dy, qv[0], qv[1], qv[2], qv[3], qv[4], qv[5],
                     acc, rising, Ks, ys, atol)
        if traj.shape[0] > 0:
            row = record_peaks(traj, row, t, h, theta, y, p, iw, qv[5], tmp, dy, auxs, Ks, ys, atol)
        if acc[A_EXITED] == 0.0:
            acc[A_STAGE + stage_of(iw)] += t1 - t
        h_next = I.next_step(h, err, NU.SAFETY, NU.FAC_MIN, NU.FAC_MAX)
        onset = kind == 1 and new_push(iw, codes1)
        if after_step(t1, y1, p, iw, kind, codes1, tags1, edge1, acc):
            rising[N_Q] = 1.0
            if onset:
                h_next = min(h_next, NU.ONSET_STEP * pulse_time(p[Lp.LAW], p[Lp.M1], p[Lp.KC], atol[3] / tol))
            classify(t1, y1, p, iw, codes1, g1, r1, tags1)
            rhs(t1, y1, p, iw, K[0], aux)  # f(t1, y1) in the new mode
            quantities_from_aux(t1, y1, p, iw, aux, qv[0])
        else:
            for i in range(N_STATE):
                K[0, i] = K[6, i]  # first same as last
            for k in range(N_Q):
                qv[0, k] = qv[1, k]  # the same point, the same right-hand side
        for k in range(N_Q):
            acc[A_QMAX + k] = max(acc[A_QMAX + k], qv[0, k])
        acc[A_DMAX] = max(acc[A_DMAX], aux[AX_DMAX])
        for i in range(N_SLOTS):
            g0[i] = g1[i]
            r0[i] = r1[i]
        for i in range(N_STATE):
            y[i] = y1[i]
        t = t1
        if t == tc:
            at_t_c(t, y, p, iw, acc)
        row = record(traj, row, t, y, p, iw, aux)
        if not all_finite(y):
            acc[A_STATUS] = Rs.ST_NONFINITE
            break
        if acc[A_DMAX] > half_side:
            acc[A_STATUS] = Rs.ST_PENETRATION
            break
        h = h_next
    return row


@kernel(inline="always")
def error_estimate(sum_sq, tol):
    """The run's error estimate (results.py error_estimate) from the sum of the squared error
    norms of its accepted steps, each the local error relative to its tolerance
    (integrate.error_norm): tol sqrt(sum err^2), the root-sum-square of the local errors
    relative to the error scales. Local errors of varying sign add up like a random walk,
    not like a plain sum, which overstates the error; results/error_estimate.md measures
    both against the reference on the validation scenes."""
    return tol * math.sqrt(sum_sq)


@kernel()
def finish(p, y, iw, acc, out):
    """The results of MODEL.md §11 from the run's accumulators."""
    if acc[A_STATUS] != Rs.ST_OK:
        acc[A_OUTCOME] = Rs.FAILED
    if acc[A_EXITED] == 0.0 and acc[A_STATUS] == Rs.ST_OK:
        drop_load(p[Lp.TMAX], y, p, iw, acc, Rs.TIMEOUT)
    if math.isnan(acc[A_E_CONTACT]):
        acc[A_E_CONTACT] = y[9]
    for k in range(Rs.N_CYCLE_RESULTS):
        out[k] = 0.0
    nf = acc[A_QMAX + Q_NF]
    out[Rs.RC_OUTCOME] = acc[A_OUTCOME]
    out[Rs.RC_T_EXIT] = acc[A_T_EXIT]
    out[Rs.RC_PEAK_FORCE] = nf
    out[Rs.RC_PEAK_RAIL_FORCE] = acc[A_QMAX + Q_NR]
    out[Rs.RC_FREEFALL_FORCE] = p[Lp.FFORCE]
    out[Rs.RC_OVERLOAD] = nf / p[Lp.FFORCE]
    out[Rs.RC_SAFE] = 1.0 if nf <= p[Lp.FFORCE] else 0.0
    out[Rs.RC_DEFLECTION_MAX] = acc[A_QMAX + Q_DEFL]
    out[Rs.RC_DEFLECTION_OK] = 1.0 if acc[A_QMAX + Q_DEFL] <= p[Lp.DAPERM] else 0.0
    out[Rs.RC_RESIDUAL_DEFLECTION] = acc[A_RESID]
    out[Rs.RC_RESIDUAL_AMPLITUDE] = acc[A_RESID_AMP]
    out[Rs.RC_ALPHA_MAX] = acc[A_QMAX + Q_ALPHA]
    out[Rs.RC_DAMPER_ENERGY] = acc[A_E_DAMPER] if not math.isnan(acc[A_E_DAMPER]) else y[8]
    out[Rs.RC_CONTACT_ENERGY] = acc[A_E_CONTACT]
    out[Rs.RC_T_FIRST_CONTACT] = acc[A_T_FIRST]
    if math.isnan(acc[A_T_FIRST]):
        out[Rs.RC_CONTACT_TIME] = 0.0
    else:
        b = acc[A_T_LOSS] if not math.isnan(acc[A_T_LOSS]) else acc[A_T_EXIT]
        out[Rs.RC_CONTACT_TIME] = b - acc[A_T_FIRST]
    out[Rs.RC_N_IMPACTS] = acc[A_N_IMPACTS]
    for i, rc in enumerate((Rs.RC_T_S1, Rs.RC_T_S2, Rs.RC_T_S3, Rs.RC_T_S4, Rs.RC_T_RAIL)):
        out[rc] = acc[A_STAGE + i]
    out[Rs.RC_X_EXIT] = acc[A_X_EXIT]
    out[Rs.RC_PHI_EXIT] = acc[A_PHI_EXIT]
    out[Rs.RC_MAX_PENETRATION] = acc[A_DMAX]
    out[Rs.RC_N_STEPS] = acc[A_STEPS]
    out[Rs.RC_N_REJECTED] = acc[A_REJECTS]
    out[Rs.RC_ERROR_ESTIMATE] = error_estimate(acc[A_ERR], p[Lp.TOL])
    out[Rs.RC_STATUS] = acc[A_STATUS]
