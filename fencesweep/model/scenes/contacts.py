"""The contacts of the load (docs/model.md §5): one small compiled function per kind for its
geometry (penetration D, its rate, the gap and the gap's rate when apart) and one for its
forces (on the load, the moment on the fence, N and the dissipated powers of §11).

Contact slots of the cycle: corner-fence j -> j (0-3), corner-rail j -> 4 + j; the fence's manifold
(docs/model.md §5.2) has two more: TIP (8), the under-tip point U on the fence's face or the tip
end of the fence's part below a load edge, and PIVOT (9), that part's pivot end.
A slot is APART (no penetration or out of its span), PUSH (penetrating, N > 0: it carries
force) or CLIPPED (penetrating with the Kelvin force <= 0: N = 0, docs/model.md §4).
"""
from __future__ import annotations


from fencesweep.kernel.jit import kernel

import math

from fencesweep.model.contact import coulomb, kelvin_force
from fencesweep.model.scenes.load import corner_motion, corner_offset

APART, PUSH, CLIPPED = 0, 1, 2
N_SLOTS = 10
RAIL0 = 4
TIP = 8
PIVOT = 9
#: the manifold's tag (docs/model.md (5.7)): 0-3 a load edge e; FACE + i + 4 b the fence's face, U on
#: the edge from corner i, b its branch (0: the tip end below that edge, 1: the corner beyond the tip)
FACE = 4


@kernel(inline=True)
def next_code(cur, D, Dd, in_span, kc, cd, law, d_gap, d_force):
    """The slot's code at penetration D and rate Dd, from its code `cur` (docs/model.md (4.9): PUSH
    while the Kelvin force is > 0, CLIPPED while it is <= 0 with D > 0). An apart slot enters
    at D > 0; a touching one leaves only at D < -d_gap, and switches between PUSH and CLIPPED
    only when the force is beyond +-d_force (numerics.CONTACT_HYSTERESIS): rounding noise
    at a contact resting at zero depth or zero force is not an event."""
    if not in_span:
        return APART
    if cur == APART:
        if D <= 0.0:
            return APART
        return PUSH if kelvin_force(D, Dd, kc, cd, law)[0] > 0.0 else CLIPPED
    if D < -d_gap:
        return APART
    n = kelvin_force(max(D, 0.0), Dd, kc, cd, law)[0]
    if cur == PUSH:
        return CLIPPED if n < -d_force else PUSH
    return PUSH if n > d_force else CLIPPED


@kernel(inline=True)
def code_margins(cur, D, Dd, kc, cd, law, d_gap, d_force):
    """How far a slot in its span is from leaving its code `cur` at penetration D and rate Dd, in
    two parts, both >= 0 while next_code keeps it and one < 0 once it changes (docs/model.md
    (4.9)): apart, (-D, inf); touching, (D + d_gap, the Kelvin force's distance from -d_force
    (PUSH) or d_force (CLIPPED)). The parts, not their minimum, as their units differ and the
    minimum is kinked where they cross: events.py brackets an event with the part that changes
    sign (search.root)."""
    if cur == APART:
        return -D, math.inf
    n = kelvin_force(max(D, 0.0), Dd, kc, cd, law)[0]
    return D + d_gap, (n + d_force if cur == PUSH else d_force - n)


@kernel(inline=True)
def damping_power(n, n_el, Dd):
    """The power one contact dissipates, (N - N_el) D' [W] (docs/model.md (11.7)): its damping
    while pushing; -N_el D' while CLIPPED (N = 0). add_contact sums it over the contacts, and
    the state's component 9 integrates it to contact_energy."""
    return (n - n_el) * Dd


@kernel(inline=True)
def friction_power(f, w):
    """The heat of one contact's friction, -f w [W], f its friction force, w its slip
    (docs/model.md (11.12), E_friction; summed by add_contact, integrated as the state's 12)."""
    return -f * w


# ---------------- corner-fence (docs/model.md §5.1) ----------------

@kernel(inline=True)
def corner_fence_geometry(gx, gy, gvx, gvy, ca, sa, dal, sg):
    """s = G.d along the fence, D = -sigma h (h = G.n), D' = -sigma (v_G.n - alpha' s)
    (docs/model.md (1.1), (5.1), (5.3))."""
    s, h = fence_coords(gx, gy, ca, sa)
    return s, -sg * h, -sg * ((-gvx * sa + gvy * ca) - dal * s)


@kernel(inline=True)
def fence_coords(gx, gy, ca, sa):
    """A point G in the fence's frame (docs/model.md (1.1), (5.1)): s = G.d along the fence, h = G.n
    from its line."""
    return gx * ca + gy * sa, -gx * sa + gy * ca


@kernel(inline=True)
def corner_fence_force(rx, ry, gvx, gvy, s, D, Dd, sg, ca, sa, kc, cd, law, mu2, eps, push):
    """One corner on the fence (docs/model.md (5.4)): force sigma N n + friction along d on the load, its torque
    about the centroid, the moment -sigma N s on the fence, N, (N - N_el) D' and the friction
    power. Not pushing (CLIPPED): N = 0 and only -N_el D' is dissipated (§11)."""
    n, n_el = kelvin_force(max(D, 0.0), Dd, kc, cd, law)
    n = max(n, 0.0) if push else 0.0
    wsl = gvx * ca + gvy * sa  # slip along the fence
    f = coulomb(n, wsl, mu2, eps)
    cfx = -sg * n * sa + f * ca
    cfy = sg * n * ca + f * sa
    return cfx, cfy, rx * cfy - ry * cfx, -sg * n * s, n, damping_power(n, n_el, Dd), friction_power(f, wsl)


# ---------------- corner-rail (docs/model.md §5.3) ----------------

@kernel(inline=True)
def corner_rail_force(rx, ry, gvx, gvy, gy, kc, cd, law, mu2, eps, push):
    """One corner on the rail (x_G <= 0, y_G < 0): D = -y_G, D' = -y_G' (docs/model.md (5.11)); force (friction, N)
    on the load (5.12), its torque, N, (N - N_el) D' and the friction power."""
    D = max(-gy, 0.0)
    Dd = -gvy
    n, n_el = kelvin_force(D, Dd, kc, cd, law)
    n = max(n, 0.0) if push else 0.0
    f = coulomb(n, gvx, mu2, eps)
    return f, n, rx * n - ry * f, n, damping_power(n, n_el, Dd), friction_power(f, gvx)


# ---------------- tip-edge (docs/model.md §5.2) ----------------

@kernel(inline=True)
def tip_position(fl, ca, sa):
    """The fence tip T = l d [m] (docs/model.md (5.5)), d = (cos alpha, sin alpha) = (ca, sa)."""
    return fl * ca, fl * sa


@kernel(inline=True)
def tip_local(tx, ty, x, yy, cphi, sphi):
    """A fence point P = (tx, ty) (the tip T, or P(u) = u T) in the load's frame (docs/model.md
    (5.6)), and P - centroid in the world frame."""
    dx = tx - x
    dyy = ty - yy
    return cphi * dx + sphi * dyy, -sphi * dx + cphi * dyy, dx, dyy


@kernel(inline=True)
def edge_margin(e, plx, ply, hl, hw):
    """delta_e: depth of the point P' = (plx, ply) (the load's frame) below load edge e, > 0 on the
    load's side of its line (docs/model.md (5.8))."""
    if e == 0:
        return hl - plx
    if e == 1:
        return hl + plx
    if e == 2:
        return hw - ply
    return hw + ply


@kernel(inline=True)
def side_edge(i):
    """The load edge e of (5.8) from corner i to corner i + 1 mod 4 (load.corner_offset's order)."""
    if i == 0:
        return 2
    if i == 1:
        return 1
    if i == 2:
        return 3
    return 0


@kernel(inline=True)
def fence_in_load(olx, oly, tlx, tly, hl, hw, grow):
    """The fence's part inside the load, [u_a, u_b] of P(u) = u T (docs/model.md (5.7)), O' =
    (olx, oly), T' = (tlx, tly) in the load's frame: u cut by each edge's half-plane, the load
    grown by `grow` on every side (a contact's hysteresis). Returns (u_a, u_b, the edge that cuts
    u_a, the edge that cuts u_b; -1 for the fence's own ends); empty when u_a > u_b: then the
    fence misses the load and no point of the manifold pushes (5.7)."""
    lo, hi, e_lo, e_hi = 0.0, 1.0, -1, -1
    for e in range(4):
        c0 = edge_margin(e, olx, oly, hl, hw) + grow
        c1 = edge_margin(e, tlx, tly, hl, hw) + grow - c0  # delta_e(u) + grow = c0 + u c1
        if c1 > 0.0:
            if -c0 / c1 > lo:
                lo, e_lo = -c0 / c1, e
        elif c1 < 0.0:
            if -c0 / c1 < hi:
                hi, e_hi = -c0 / c1, e
        elif c0 < 0.0:
            return 1.0, 0.0, -1, -1
    return lo, hi, e_lo, e_hi


@kernel(inline=True)
def fence_part(fl, hl, hw, x, yy, ca, sa, cphi, sphi, grow):
    """The fence against the load at centroid (x, yy) (docs/model.md (5.5)-(5.7)): the tip T (the
    world frame), the pivot O' and the tip T' in the load's frame, and fence_in_load's part of the
    fence inside the load grown by `grow`: (tx, ty, olx, oly, tlx, tly, u_a, u_b, e_a, e_b)."""
    tx, ty = tip_position(fl, ca, sa)
    tlx, tly, _, _ = tip_local(tx, ty, x, yy, cphi, sphi)
    olx, oly = pivot_local(x, yy, cphi, sphi)
    lo, hi, e_lo, e_hi = fence_in_load(olx, oly, tlx, tly, hl, hw, grow)
    return tx, ty, olx, oly, tlx, tly, lo, hi, e_lo, e_hi


@kernel(inline=True)
def pivot_local(x, yy, cphi, sphi):
    """The pivot O in the load's frame (docs/model.md (5.6) with P = O)."""
    return -(cphi * x + sphi * yy), sphi * x - cphi * yy


@kernel(inline=True)
def edge_point_rate(px, py, dx, dyy, nex, ney, vx, vy, om, dal):
    """D' of the fence point P = (px, py) below the edge of outward normal n_e, dx, dyy = P - X
    (docs/model.md (5.9)): -(v_P - v_Q).n_e, v_P = alpha' k x P, v_Q the load's point under P."""
    return -((-dal * py - (vx - om * dyy)) * nex + (dal * px - (vy + om * dx)) * ney)


@kernel(inline=True)
def corner_s_h(j, y, hl, hw, ca, sa, cphi, sphi):
    """Corner j's position along the fence s and distance from its line h (docs/model.md (5.1))."""
    rx, ry = corner_offset(j, hl, hw, cphi, sphi)
    return fence_coords(y[0] + rx, y[1] + ry, ca, sa)


@kernel(inline=True)
def edge_depth_at_tip(si, hi, sj, hj, sgi, sgj, fl):
    """Depth at s = l of the load edge from a corner (si, hi) to one (sj, hj) that lies across the
    line s = l, with the in-span corner's side (docs/model.md (5.7)); -inf when the edge does not
    cross it."""
    if (si < fl) == (sj < fl):
        return -math.inf
    if si < fl:
        return -sgi * (hi + (fl - si) / (sj - si) * (hj - hi))
    return -sgj * (hj + (fl - sj) / (si - sj) * (hi - hj))


@kernel()
def under_tip_edge(s0, h0, s1, h1, s2, h2, s3, h3, fl, iw):
    """The load edge that carries the under-tip point U (docs/model.md (5.7)): of the edges i
    (corners i, i + 1 mod 4) with one corner in the span (s < l) and one beyond (s >= l), the
    one deeper at s = l (with the in-span corner's side); s_j, h_j: corner j's s along the fence
    and h from its line (corner_s_h). Returns (i, its depth there) or (-1, -inf)."""
    if max(max(s0, s1), max(s2, s3)) < fl:
        return -1, -math.inf  # the load within the span: no edge runs on past the tip
    best = -1
    deep = -math.inf
    for i, d in ((0, edge_depth_at_tip(s0, h0, s1, h1, iw[0], iw[1], fl)),
                 (1, edge_depth_at_tip(s1, h1, s2, h2, iw[1], iw[2], fl)),
                 (2, edge_depth_at_tip(s2, h2, s3, h3, iw[2], iw[3], fl)),
                 (3, edge_depth_at_tip(s3, h3, s0, h0, iw[3], iw[0], fl))):
        if d > deep:
            deep = d
            best = i
    return best, deep


@kernel(inline=True)
def beyond_corner(i, y, hl, hw, ca, sa, cphi, sphi):
    """Of the corners i and i + 1 mod 4 of the edge that carries U (docs/model.md (5.7)): (C, the one
    in the span, C', the one beyond the tip), by their s along the fence."""
    j = (i + 1) % 4
    si, _ = corner_s_h(i, y, hl, hw, ca, sa, cphi, sphi)
    sj, _ = corner_s_h(j, y, hl, hw, ca, sa, cphi, sphi)
    return (i, j) if si <= sj else (j, i)


@kernel(inline=True)
def beyond_depth(i, y, hl, hw, ca, sa, dal, cphi, sphi, iw):
    """U's branch 1 (docs/model.md (5.7)): the in-span corner C of the edge from corner i, and the
    depth and rate (5.3) of the corner C' beyond the tip, with C's side."""
    c, cb = beyond_corner(i, y, hl, hw, ca, sa, cphi, sphi)
    _, _, gx, gy, gvx, gvy = corner_motion(cb, y, hl, hw, cphi, sphi)
    _, D, Dd = corner_fence_geometry(gx, gy, gvx, gvy, ca, sa, dal, iw[c])
    return c, D, Dd


@kernel(inline=True)
def tip_edge_normal(edge, tlx, tly, hl, hw, cphi, sphi):
    """Depth D of a fence point P' = (tlx, tly) (the load's frame) below load edge `edge` and the
    edge's outward normal n_e in the world frame (docs/model.md (5.8))."""
    if edge == 0:
        return hl - tlx, cphi, sphi
    if edge == 1:
        return hl + tlx, -cphi, -sphi
    if edge == 2:
        return hw - tly, -sphi, cphi
    return hw + tly, sphi, -cphi


@kernel(inline=True)
def tip_edge_force(D, nex, ney, tx, ty, dx, dyy, vx, vy, om, dal, kc, cd, law, mu2, eps, push):
    """A fence point P = (tx, ty) pushing a load edge (the tip, or an end of the fence's part
    below the edge): force -N n_e + friction along the edge on the load, its torque, the
    reaction's moment on the fence at P (friction included), N, (N - N_el) D', friction power. D'
    from P's velocity relative to the load's material point under it (docs/model.md (5.9), (5.10))."""
    rvx = -dal * ty - (vx - om * dyy)
    rvy = dal * tx - (vy + om * dx)
    Dd = -(rvx * nex + rvy * ney)
    n, n_el = kelvin_force(max(D, 0.0), Dd, kc, cd, law)
    n = max(n, 0.0) if push else 0.0
    tex = -ney
    tey = nex
    wl = -(rvx * tex + rvy * tey)  # slip of the load point along the edge
    f = coulomb(n, wl, mu2, eps)
    cfx = -n * nex + f * tex
    cfy = -n * ney + f * tey
    return (cfx, cfy, dx * cfy - dyy * cfx, ty * cfx - tx * cfy, n, damping_power(n, n_el, Dd), friction_power(f, wl),
            Dd)


@kernel(inline=True)
def tip_gap(tlx, tly, tlx_d, tly_d, hl, hw):
    """Signed box distance of T from the load (< 0 inside) and its rate, for the graze check
    (docs/model.md (15.7))."""
    gx = abs(tlx) - hl
    gy = abs(tly) - hw
    if gx >= gy:
        return gx, (tlx_d if tlx >= 0.0 else -tlx_d)
    return gy, (tly_d if tly >= 0.0 else -tly_d)
