"""The contact slots of the cycle at a state (docs/model.md §5): each slot's code (APART / PUSH /
CLIPPED, contacts.next_code), its tag (a corner's side sigma_j, §5.1; the tip's edge, §5.2), and
its gap and the gap's rate (> 0 apart: what the graze check minimises); the stages (§10).

Slots: corner-fence j -> j (0-3), corner-rail j -> 4 + j, tip-edge -> 8 (contacts.py)."""
from __future__ import annotations

import math

from fencesweep.kernel import numerics as NU
from fencesweep.kernel.jit import kernel
from fencesweep.model import layout as Lp
from fencesweep.model import results as Rs
from fencesweep.model.scenes.contacts import (APART, CLIPPED, N_SLOTS, PUSH, RAIL0, TIP, corner_fence_geometry, next_code,
                                              tip_edge_choice, tip_edge_normal, tip_gap, tip_local, tip_position)
from fencesweep.model.scenes.cycle.layout import (AX_CA, AX_CPHI, AX_DAL, AX_FRAME, AX_SA, AX_SPHI, IW_CODE, IW_EDGE,
                                                  IW_LOAD, IW_MODE)
from fencesweep.model.scenes.cycle.rhs import fence_state
from fencesweep.model.scenes.load import corner_motion


@kernel(inline=True)
def corner_side(s, D, sg, fl):
    """The side memory sigma_j (docs/model.md (5.2)) at a corner's s (along the fence) and
    D = -sigma h: beyond the tip sign(h) (h = 0 counts as +1), behind the pivot +1, else
    unchanged (sigma_j(0) = +1: books.start; the change is an event: take_sides)."""
    if s > fl:
        return -1 if -D * sg < 0.0 else 1  # sign(h), h = -sigma D
    if s < 0.0:
        return 1
    return sg


@kernel(inline=True)
def corner_slot(k, y, p, iw, ca, sa, dal, cphi, sphi, d_gap, d_force):
    """(code, tag, gap, gap rate) of corner slot k (< TIP): on the fence (§5.1; tag the side) or
    on the rail (§5.3; tag 0)."""
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    kc, cd, law = p[Lp.KC], p[Lp.CD], p[Lp.LAW]
    fl = p[Lp.FL]
    cur = iw[IW_CODE + k]
    j = k % 4
    rx, ry, gx, gy, gvx, gvy = corner_motion(j, y, hl, hw, cphi, sphi)
    if k < RAIL0:
        s, D, Dd = corner_fence_geometry(gx, gy, gvx, gvy, ca, sa, dal, iw[j])
        side = corner_side(s, D, iw[j], fl)  # the side memory at this state; a change is an event
        return next_code(cur, D, Dd, s >= 0.0 and s <= fl, kc, cd, law, d_gap, d_force), side, -D, -Dd
    return next_code(cur, -gy, -gvy, gx <= 0.0, kc, cd, law, d_gap, d_force), 0, gy, gvy


@kernel(inline=True)
def tip_slot(y, p, iw, ca, sa, dal, cphi, sphi, d_gap, d_force):
    """(code, edge, gap, gap rate) of the tip's slot (§5.2): the box distance of the tip T from
    the load while apart, the depth below the edge it pushes (tip_edge_choice) inside."""
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    cur = iw[IW_CODE + TIP]
    tx, ty = tip_position(p[Lp.FL], ca, sa)
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
    return next_code(cur, D, Dd, True, p[Lp.KC], p[Lp.CD], p[Lp.LAW], d_gap, d_force), edge, gap, rate


@kernel(inline=True)
def slot_eval(k, y, p, iw, ca, sa, dal, cphi, sphi):
    """(code, tag, gap, gap rate) of contact slot k at state y, its code moved on from the one
    in iw (contacts.next_code, with numerics.CONTACT_HYSTERESIS)."""
    d_gap = NU.CONTACT_HYSTERESIS * p[Lp.FL]
    d_force = NU.CONTACT_HYSTERESIS * p[Lp.FFORCE]
    if k < TIP:
        return corner_slot(k, y, p, iw, ca, sa, dal, cphi, sphi, d_gap, d_force)
    return tip_slot(y, p, iw, ca, sa, dal, cphi, sphi, d_gap, d_force)


@kernel(inline=True)
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


@kernel(inline=True)
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


@kernel(inline=True)
def slot_changed(k, code, tag, iw):
    """Has slot k left the code it had at the step's start, or (tag) a corner its side, the
    tip the edge it pushes?"""
    if code != iw[IW_CODE + k]:
        return True
    if k < RAIL0:
        return tag != iw[k]
    return k == TIP and code != APART and tag != iw[IW_EDGE]


@kernel(inline=True)
def changed_mask(iw, codes, tags):
    """Bit k set when slot k changed its code, side or edge from iw (an event)."""
    mask = 0
    for k in range(N_SLOTS):
        if slot_changed(k, codes[k], tags[k], iw):
            mask |= 1 << k
    return mask


@kernel(inline=True)
def take_sides(iw, tags):
    """Side memory sigma_j (docs/model.md §5.1) from classify's tags at the step's end (corner_side
    applies the rule). Returns whether any side changed."""
    changed = False
    for j in range(RAIL0):
        if tags[j] != iw[j]:
            iw[j] = tags[j]
            changed = True
    return changed


@kernel(inline=True)
def releases(iw, codes):
    """Are codes releases only: some slots pushing in iw clipped in codes (docs/model.md §4: N
    returned to 0), every other slot's code as in iw?"""
    rel = False
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] == PUSH and codes[k] == CLIPPED:
            rel = True
        elif codes[k] != iw[IW_CODE + k]:
            return False
    return rel


@kernel(inline=True)
def new_push(iw, codes):
    """Does a slot apart in iw push in codes (a contact onset)?"""
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] == APART and codes[k] == PUSH:
            return True
    return False


@kernel(inline=True)
def fence_pushed(iw):
    """Does any load-fence slot (corners on the fence, the tip) carry force?"""
    for k in (0, 1, 2, 3, TIP):
        if iw[IW_CODE + k] == PUSH:
            return True
    return False


@kernel(inline=True)
def in_contact(iw):
    """Is any slot of the load in contact (not APART)?"""
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] != APART:
            return True
    return False


@kernel()
def stage_of(iw):
    """Stage from the slots that carry force (docs/model.md (10.1)): n_f pushing load-fence
    slots (corners on the fence, the tip), rail when a corner-rail slot pushes."""
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
