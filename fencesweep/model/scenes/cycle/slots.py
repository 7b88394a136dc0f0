"""The contact slots of the cycle at a state (docs/model.md §5): each slot's code (APART / PUSH /
CLIPPED, contacts.next_code), its tag (a corner's side sigma_j, §5.1; the fence's manifold, §5.2),
and its gap and the gap's rate (> 0 apart: what the graze check minimises); the stages (§10).

Slots: corner-fence j -> j (0-3), corner-rail j -> 4 + j, the manifold's TIP -> 8 and PIVOT -> 9
(contacts.py). The fence meets the load through one manifold (manifold): the corners and the
under-tip point on the fence's face, or the ends of the fence's part below one load edge."""
from __future__ import annotations

import math

from fencesweep.kernel import numerics as NU
from fencesweep.kernel.jit import kernel
from fencesweep.model import layout as Lp
from fencesweep.model import results as Rs
from fencesweep.model.drive import drive_angle
from fencesweep.model.scenes.contacts import (APART, CLIPPED, FACE, N_SLOTS, PIVOT, PUSH, RAIL0, TIP,
                                              code_margins, corner_fence_geometry, edge_margin, edge_point_rate, fence_coords, fence_part, next_code,
                                              tip_edge_normal, tip_gap, tip_local, tip_position,
                                              beyond_depth, side_edge, under_tip_edge)
from fencesweep.model.scenes.cycle.layout import (AX_CA, AX_CPHI, AX_DAL, AX_FRAME, AX_SA, AX_SPHI, IW_CODE, IW_EDGE,
                                                  IW_LOAD, IW_MODE)
from fencesweep.model.scenes.cycle.rhs import drive_once, fence_follows
from fencesweep.model.scenes.load import corner_motion

FENCE_BITS = 0b1100001111  # slots 0-3, TIP, PIVOT


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
def corner_geometry(j, y, p, iw, ca, sa, dal, cphi, sphi):
    """Corner j at state y (docs/model.md (1.4), (5.1), (5.3), (5.11)): (s along the fence, h from
    its line, D = -sigma h, D', x_G, y_G, y_G'); the slots' classification forms it once for all
    that read it (corner_geometries)."""
    rx, ry, gx, gy, gvx, gvy = corner_motion(j, y, 0.5 * p[Lp.LL], 0.5 * p[Lp.AA], cphi, sphi)
    s, D, Dd = corner_fence_geometry(gx, gy, gvx, gvy, ca, sa, dal, iw[j])
    return s, fence_coords(gx, gy, ca, sa)[1], D, Dd, gx, gy, gvy


@kernel(inline=True)
def corner_geometries(y, p, iw, ca, sa, dal, cphi, sphi):
    """corner_geometry of the four corners, a tuple of four."""
    return (corner_geometry(0, y, p, iw, ca, sa, dal, cphi, sphi), corner_geometry(1, y, p, iw, ca, sa, dal, cphi, sphi),
            corner_geometry(2, y, p, iw, ca, sa, dal, cphi, sphi), corner_geometry(3, y, p, iw, ca, sa, dal, cphi, sphi))


@kernel(inline=True)
def under_tip(geo, p, iw):
    """contacts.under_tip_edge from the corners' corner_geometry."""
    return under_tip_edge(geo[0][0], geo[0][1], geo[1][0], geo[1][1], geo[2][0], geo[2][1], geo[3][0], geo[3][1],
                          p[Lp.FL], iw)


@kernel(inline=True)
def side_of(j, geo, p, iw):
    """Corner j's side memory (5.2) at this state, from its corner_geometry."""
    return corner_side(geo[j][0], geo[j][2], iw[j], p[Lp.FL])


@kernel(inline=True)
def corner_code(j, geo, p, iw, d_gap, d_force):
    """Corner j on the fence (§5.1) on its own, from its corner_geometry: (code, D in the span or
    -inf, side memory at this state)."""
    s, D, Dd = geo[0], geo[2], geo[3]
    fl = p[Lp.FL]
    c = next_code(iw[IW_CODE + j], D, Dd, s >= 0.0 and s <= fl, p[Lp.KC], p[Lp.CD], p[Lp.LAW], d_gap, d_force)
    return c, D if (s >= 0.0 and s <= fl) else -math.inf, corner_side(s, D, iw[j], fl)


@kernel(inline=True)
def fence_in_use(iw):
    """Is the fence's manifold in use: a corner on the fence, TIP or PIVOT not APART?"""
    for k in (0, 1, 2, 3, TIP, PIVOT):
        if iw[IW_CODE + k] != APART:
            return True
    return False


@kernel(inline=True)
def edge_end_depth(e, u, tx, ty, y, p, dal, cphi, sphi):
    """Depth D and rate D' of the fence point P(u) = u T below load edge e (docs/model.md (5.8),
    (5.9))."""
    px, py = u * tx, u * ty
    plx, ply, pdx, pdy = tip_local(px, py, y[0], y[1], cphi, sphi)
    D, nex, ney = tip_edge_normal(e, plx, ply, 0.5 * p[Lp.LL], 0.5 * p[Lp.AA], cphi, sphi)
    return D, edge_point_rate(px, py, pdx, pdy, nex, ney, y[3], y[4], y[5], dal)


@kernel(inline=True)
def edge_end_code(e, u, tx, ty, y, p, iw, slot, cur, dal, cphi, sphi, d_gap, d_force):
    """Code of the fence point P(u) = u T pushing load edge e (docs/model.md (5.8), (5.9)); its
    code in iw counts only while it is the point in use (cur)."""
    D, Dd = edge_end_depth(e, u, tx, ty, y, p, dal, cphi, sphi)
    return next_code(iw[IW_CODE + slot] if cur else APART, D, Dd, True, p[Lp.KC], p[Lp.CD], p[Lp.LAW], d_gap, d_force)


@kernel(inline=True)
def end_depths(e, e_lo, e_hi, ma, mb):
    """The depths below edge e of the ends of the fence's part inside the load (docs/model.md
    (5.7)): ma, mb their margins (edge_margin); an end on e's own line is none (-inf)."""
    return -math.inf if e_lo == e else ma, -math.inf if e_hi == e else mb


@kernel(inline=True)
def edge_measure(e, e_lo, e_hi, ma, mb, d_gap):
    """Axis E_e (docs/model.md (5.7)): (its measure, whether it pushes with the pivot end): the
    deeper end below e, the tip end unless the pivot end is deeper by CONTACT_HYSTERESIS l (a
    bias, not a memory: the choice is the state's alone); the fence along e's own line
    penetrates 0."""
    Da, Db = end_depths(e, e_lo, e_hi, ma, mb)
    if Da == -math.inf and Db == -math.inf:
        return 0.0, False
    return (Da, True) if Da > Db + d_gap else (Db, False)


@kernel(inline=True)
def face_point(ui, u, tx, ty, e_hi, y, p, iw, held, ca, sa, dal, cphi, sphi, d_gap, d_force):
    """The face's TIP slot (docs/model.md (5.7)): the code of the under-tip point U on the edge from
    corner ui and the manifold's tag, FACE + ui + 4 b. U is the shallower of the fence's tip end
    P(u) below that edge (b = 0) and the corner C' beyond the tip behind the fence's line (b = 1);
    none where the tip end lies on that edge or there is no such edge (APART, FACE). Its code in
    iw counts only while the face with U on that edge is in use (held)."""
    if ui < 0 or e_hi == side_edge(ui):
        return APART, FACE + max(ui, 0)
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    _, D, Dd = beyond_depth(ui, y, hl, hw, ca, sa, dal, cphi, sphi, iw)
    plx, ply, _, _ = tip_local(u * tx, u * ty, y[0], y[1], cphi, sphi)
    if D < edge_margin(side_edge(ui), plx, ply, hl, hw):
        return next_code(iw[IW_CODE + TIP] if held else APART, D, Dd, True, p[Lp.KC], p[Lp.CD], p[Lp.LAW], d_gap,
                         d_force), FACE + ui + 4
    return edge_end_code(side_edge(ui), u, tx, ty, y, p, iw, TIP, held, dal, cphi, sphi, d_gap, d_force), FACE + ui


@kernel(inline=True)
def under_tip_measure(ui, d_own, e_hi, bx, by, hl, hw):
    """The face's measure of the under-tip point U on load edge ui, U's own depth d_own (docs/model.md
    (5.7)): the depth below that edge of the fence's tip end (bx, by), as the edge measures it,
    while the edge lies within acos(1 - FACE_TOL) of the fence; beyond, d_own (1 - FACE_TOL)."""
    if ui < 0 or e_hi == side_edge(ui):
        return d_own
    return max(edge_margin(side_edge(ui), bx, by, hl, hw), (1.0 - NU.FACE_TOL) * d_own)


@kernel(inline=True)
def least_edge(e_lo, e_hi, ax, ay, bx, by, hl, hw, m_face, d_gap):
    """Of the load's edges, the first shallower than the face's (biased) measure m_face (docs/model.md
    (5.7)), the ends of the fence's part inside the load at (ax, ay), (bx, by) (fence_in_load, cut
    by edges e_lo, e_hi): (its edge or FACE, its measure, whether it pushes with the pivot end)."""
    best, m_best, piv = FACE, m_face, False
    for e in range(4):
        m, pe = edge_measure(e, e_lo, e_hi, edge_margin(e, ax, ay, hl, hw), edge_margin(e, bx, by, hl, hw), d_gap)
        if m < m_best:
            best, m_best, piv = e, m, pe
    return best, m_best, piv


@kernel()
def manifold(y, p, iw, ca, sa, dal, cphi, sphi, d_gap, d_force, geo):
    """The fence's contact manifold with the load (docs/model.md (5.7)). The bodies touch where the
    fence's segment enters the load (fence_in_load, the load grown by the hysteresis). The axis is
    the one of least penetration among the fence's face (the deepest of the load's corners in the
    span and the edge's point under the tip) and the load's four edges (least_edge), chosen from
    the state alone: the face's measure is biased by CONTACT_HYSTERESIS l, in its favour while one
    of its corners is in contact, against it when U is its only point. Its points push: the face's
    corners and U, or one end on the edge. Returns the codes of corners 0-3 on the fence, TIP,
    PIVOT, the tag (an edge e, or FACE + U's edge + 4 x its depth's branch) and the corners' sides (5.2).
    geo: the corners' corner_geometries at this state."""
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    cur_tag = iw[IW_EDGE]
    cur = (FACE if cur_tag >= FACE else cur_tag) if fence_in_use(iw) else -1
    tx, ty, olx, oly, tlx, tly, lo, hi, e_lo, e_hi = fence_part(p[Lp.FL], hl, hw, y[0], y[1], ca, sa, cphi, sphi, d_gap)
    ax, ay = olx + lo * (tlx - olx), oly + lo * (tly - oly)  # the ends of the fence's part inside the load
    bx, by = olx + hi * (tlx - olx), oly + hi * (tly - oly)
    if not (lo <= hi and inside_all(e_lo, e_hi, ax, ay, bx, by, hl, hw, -d_gap)):
        return (APART, APART, APART, APART, APART, APART, cur_tag, side_of(0, geo, p, iw), side_of(1, geo, p, iw),
                side_of(2, geo, p, iw), side_of(3, geo, p, iw))  # the fence misses the load
    c0, D0, s0 = corner_code(0, geo[0], p, iw, d_gap, d_force)
    c1, D1, s1 = corner_code(1, geo[1], p, iw, d_gap, d_force)
    c2, D2, s2 = corner_code(2, geo[2], p, iw, d_gap, d_force)
    c3, D3, s3 = corner_code(3, geo[3], p, iw, d_gap, d_force)
    ui, d_own = under_tip(geo, p, iw)
    bias = NU.CONTACT_HYSTERESIS * p[Lp.FL] * (-1.0 if (c0 != APART or c1 != APART or c2 != APART or c3 != APART) else 1.0)
    m_face = max(max(D0, D1), max(max(D2, D3), under_tip_measure(ui, d_own, e_hi, bx, by, hl, hw))) + bias
    axis, _, piv = least_edge(e_lo, e_hi, ax, ay, bx, by, hl, hw, m_face, d_gap)
    if axis == FACE:
        cu, tag = face_point(ui, hi, tx, ty, e_hi, y, p, iw, cur == FACE and (cur_tag - FACE) % 4 == ui, ca, sa, dal,
                             cphi, sphi, d_gap, d_force)
        return c0, c1, c2, c3, cu, APART, tag, s0, s1, s2, s3
    code = edge_end_code(axis, lo if piv else hi, tx, ty, y, p, iw, PIVOT if piv else TIP, cur == axis, dal, cphi,
                         sphi, d_gap, d_force)
    if piv:
        return APART, APART, APART, APART, APART, code, axis, s0, s1, s2, s3
    return APART, APART, APART, APART, code, APART, axis, s0, s1, s2, s3


@kernel(inline=True)
def inside_all(e_lo, e_hi, ax, ay, bx, by, hl, hw, floor):
    """Does the fence's part inside the load (fence_in_load: its ends (ax, ay), (bx, by) in the
    load's frame, cut by edges e_lo, e_hi) lie deeper than floor below every edge: is the fence
    inside the load, not on its boundary (docs/model.md (5.7): an edge along which it penetrates
    no deeper separates the bodies)?"""
    for e in range(4):
        da = -1.0 if e_lo == e else edge_margin(e, ax, ay, hl, hw)
        db = -1.0 if e_hi == e else edge_margin(e, bx, by, hl, hw)
        if max(da, db) <= floor:
            return False
    return True


@kernel(inline=True)
def slot_gap(k, y, p, iw, ca, sa, dal, cphi, sphi):
    """Gap and gap rate of slot k on its own (> 0 apart; the graze and crossing checks'
    quantity): a corner's -D on the fence (5.3) or y_G on the rail (5.11), the tip's box distance
    from the load (15.7); PIVOT has none (1, 0): it touches only within a manifold."""
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    if k < TIP:
        rx, ry, gx, gy, gvx, gvy = corner_motion(k % 4, y, hl, hw, cphi, sphi)
        if k < RAIL0:
            s, D, Dd = corner_fence_geometry(gx, gy, gvx, gvy, ca, sa, dal, iw[k])
            return -D, -Dd
        return gy, gvy
    if k == PIVOT:
        return 1.0, 0.0
    tx, ty = tip_position(p[Lp.FL], ca, sa)
    tlx, tly, dx, dyy = tip_local(tx, ty, y[0], y[1], cphi, sphi)
    rvx = -dal * ty - y[3]  # d/dt (T - X)
    rvy = dal * tx - y[4]
    tlx_d = cphi * rvx + sphi * rvy + y[5] * tly
    tly_d = -sphi * rvx + cphi * rvy - y[5] * tlx
    return tip_gap(tlx, tly, tlx_d, tly_d, hl, hw)


@kernel(inline=True)
def rail_code(k, y, p, iw, cphi, sphi, d_gap, d_force):
    """Code of rail slot k (§5.3): corner k - 4 below y = 0 at x <= 0."""
    rx, ry, gx, gy, gvx, gvy = corner_motion(k % 4, y, 0.5 * p[Lp.LL], 0.5 * p[Lp.AA], cphi, sphi)
    return next_code(iw[IW_CODE + k], -gy, -gvy, gx <= 0.0, p[Lp.KC], p[Lp.CD], p[Lp.LAW], d_gap, d_force)


@kernel(inline=True)
def slot_code_margins(cur, D, Dd, p):
    """contacts.code_margins of a slot with code cur at D, D', with p's contact law and the
    hysteresis next_code is given (numerics.CONTACT_HYSTERESIS x l, x F_ff)."""
    return code_margins(cur, D, Dd, p[Lp.KC], p[Lp.CD], p[Lp.LAW], NU.CONTACT_HYSTERESIS * p[Lp.FL],
                        NU.CONTACT_HYSTERESIS * p[Lp.FFORCE])


@kernel(inline=True)
def corner_margins(k, y, p, iw, ca, sa, dal, cphi, sphi):
    """How far corner k on the fence (slot 0-3) is at y from leaving its code and side in iw, in
    four parts, all >= 0 while corner_code keeps both (the manifold's choice of its axis aside)
    and one < 0 once one changes (docs/model.md (4.9), (5.2)). Touching: its span, s and l - s,
    then contacts.code_margins. Apart: its entry, max(-D, -s, s - l) (D > 0 inside the span); its
    side, turned beyond the tip by D > 0, max(l - s, -D), and behind the pivot from -1 to +1, s."""
    s, _, D, Dd, _, _, _ = corner_geometry(k, y, p, iw, ca, sa, dal, cphi, sphi)
    fl = p[Lp.FL]
    cur = iw[IW_CODE + k]
    if cur == APART:
        return max(-D, max(-s, s - fl)), max(fl - s, -D), s if iw[k] < 0 else math.inf, math.inf
    dg, df = slot_code_margins(cur, D, Dd, p)
    return s, fl - s, dg, df


@kernel(inline=True)
def tip_margins(y, p, iw, ca, sa, dal, cphi, sphi):
    """How far the TIP slot, touching, is at y from leaving its code in iw (docs/model.md (4.9),
    (5.7)-(5.9)), in corner_margins' four parts: contacts.code_margins of its point under iw's tag
    (an edge e: the tip end on e; FACE + i + 4 b: U on the edge from corner i, by its branch b),
    the length of the fence's part inside the load (< 0: the fence misses it), inf. The manifold's
    choice of the point (a change of tag) is not in it."""
    fl = p[Lp.FL]
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    tag = iw[IW_EDGE]
    tx, ty, _, _, _, _, lo, hi, _, _ = fence_part(fl, hl, hw, y[0], y[1], ca, sa, cphi, sphi, NU.CONTACT_HYSTERESIS * fl)
    if tag >= FACE + 4:
        _, D, Dd = beyond_depth((tag - FACE) % 4, y, hl, hw, ca, sa, dal, cphi, sphi, iw)
    else:
        D, Dd = edge_end_depth(tag if tag < FACE else side_edge(tag - FACE), hi, tx, ty, y, p, dal, cphi, sphi)
    dg, df = slot_code_margins(iw[IW_CODE + TIP], D, Dd, p)
    return dg, df, hi - lo, math.inf


@kernel(inline=True)
def slot_margins(k, y, p, iw, ca, sa, dal, cphi, sphi):
    """corner_margins of slot k = 0-3, tip_margins of TIP (margin_slot's slots)."""
    if k == TIP:
        return tip_margins(y, p, iw, ca, sa, dal, cphi, sphi)
    return corner_margins(k, y, p, iw, ca, sa, dal, cphi, sphi)


@kernel(inline=True)
def margin_slot(iw, codes, tags, mask):
    """The slot in mask whose slot_margins bracket its change (events.known_range): the first
    corner on the fence (slot 0-3) whose code or side in codes, tags differs from iw's, else TIP
    touching with another code; -1 if none. Not the rail's corners: on the main job's sample a
    rail corner's code changed, changed back and changed again inside one step, and its margin
    bracketed the last change where the bisection over the step finds the first."""
    for k in range(RAIL0):
        if mask & (1 << k) and slot_changed(k, codes[k], tags[k], iw):
            return k
    if mask & (1 << TIP) and iw[IW_CODE + TIP] != APART and codes[TIP] != iw[IW_CODE + TIP]:
        return TIP
    return -1


@kernel(inline=True)
def frame_at(t, y, p, iw):
    """What the manifold and the slots need of the fence and the load at (t, y): cos and sin of alpha, alpha',
    cos and sin of phi."""
    aw, daw = drive_angle(t, p)
    return frame_of(y, iw, aw, daw)


@kernel(inline=True)
def frame_of(y, iw, aw, daw):
    """frame_at with the drive's alpha_w, alpha_w' at that time given."""
    al, dal, aw, daw = fence_follows(y, iw[IW_MODE], aw, daw)
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
    the contacts there (AX_FRAME), saves drive_angle and four sines and cosines a step; else
    its drive (rhs.drive_once) saves drive_angle."""
    if iw[IW_LOAD] == 0:
        return classify(t, y, p, iw, codes, gaps, rates, tags)
    if aux[AX_FRAME] == 0.0:
        aw, daw = drive_once(t, p, aux)
        ca, sa, dal, cphi, sphi = frame_of(y, iw, aw, daw)
        return classify_in(y, p, iw, codes, gaps, rates, tags, ca, sa, dal, cphi, sphi)
    return classify_in(y, p, iw, codes, gaps, rates, tags, aux[AX_CA], aux[AX_SA], aux[AX_DAL], aux[AX_CPHI],
                       aux[AX_SPHI])


@kernel(inline=True)
def classify_in(y, p, iw, codes, gaps, rates, tags, ca, sa, dal, cphi, sphi):
    """classify in the frame (ca, sa, dal, cphi, sphi) of frame_at: the manifold's codes and tag,
    the rails' codes, every slot's gap; returns the manifold's tag."""
    d_gap = NU.CONTACT_HYSTERESIS * p[Lp.FL]
    d_force = NU.CONTACT_HYSTERESIS * p[Lp.FFORCE]
    geo = corner_geometries(y, p, iw, ca, sa, dal, cphi, sphi)  # each corner's once: the manifold, gaps, rails
    (codes[0], codes[1], codes[2], codes[3], codes[TIP], codes[PIVOT], tag,
     tags[0], tags[1], tags[2], tags[3]) = manifold(y, p, iw, ca, sa, dal, cphi, sphi, d_gap, d_force, geo)
    tags[TIP] = tag
    tags[PIVOT] = tag
    for j in range(4):  # its gap on the fence, its rail slot
        _, _, D, Dd, gx, gy, gvy = geo[j]
        gaps[j] = -D
        rates[j] = -Dd
        k = RAIL0 + j
        codes[k] = next_code(iw[IW_CODE + k], -gy, -gvy, gx <= 0.0, p[Lp.KC], p[Lp.CD], p[Lp.LAW], d_gap, d_force)
        gaps[k] = gy
        rates[k] = gvy
        tags[k] = 0
    gaps[TIP], rates[TIP] = slot_gap(TIP, y, p, iw, ca, sa, dal, cphi, sphi)
    gaps[PIVOT], rates[PIVOT] = 1.0, 0.0
    return tag


@kernel()
def changed_at(mask, y, p, iw, ca, sa, dal, cphi, sphi):
    """Has any slot in mask (bit k: slot k) left its code, side or tag of iw at state y (the
    manifold evaluated once for all the fence's slots)?"""
    d_gap = NU.CONTACT_HYSTERESIS * p[Lp.FL]
    d_force = NU.CONTACT_HYSTERESIS * p[Lp.FFORCE]
    if mask & FENCE_BITS:
        c0, c1, c2, c3, ct, cp, tag, s0, s1, s2, s3 = manifold(y, p, iw, ca, sa, dal, cphi, sphi, d_gap, d_force,
                                                               corner_geometries(y, p, iw, ca, sa, dal, cphi, sphi))
        if ((mask & 1 and slot_changed(0, c0, s0, iw)) or (mask & 2 and slot_changed(1, c1, s1, iw))
                or (mask & 4 and slot_changed(2, c2, s2, iw)) or (mask & 8 and slot_changed(3, c3, s3, iw))
                or (mask & (1 << TIP) and slot_changed(TIP, ct, tag, iw))
                or (mask & (1 << PIVOT) and slot_changed(PIVOT, cp, tag, iw))):
            return True
    for k in range(RAIL0, TIP):
        if mask & (1 << k) and rail_code(k, y, p, iw, cphi, sphi, d_gap, d_force) != iw[IW_CODE + k]:
            return True
    return False


@kernel(inline=True)
def slot_changed(k, code, tag, iw):
    """Has slot k left the code it had at the step's start, or (tag) a corner its side, the
    tip the edge it pushes?"""
    if code != iw[IW_CODE + k]:
        return True
    if k < RAIL0:
        return tag != iw[k]
    return k >= TIP and code != APART and tag != iw[IW_EDGE]


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
    """Does any load-fence slot (the manifold's: corners on the fence, TIP, PIVOT) carry force?"""
    for k in (0, 1, 2, 3, TIP, PIVOT):
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
