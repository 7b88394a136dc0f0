"""The contacts of the load (docs/model.md §5): one small compiled function per kind for its
geometry (penetration D, its rate, the gap and the gap's rate when apart) and one for its
forces (on the load, the moment on the fence, N and the dissipated powers of §11).

Contact slots of the cycle: corner-fence j -> j (0-3), corner-rail j -> 4 + j, tip-edge -> 8.
A slot is APART (no penetration or out of its span), PUSH (penetrating, N > 0: it carries
force) or CLIPPED (penetrating with the Kelvin force <= 0: N = 0, docs/model.md §4).
"""
from __future__ import annotations


from fencesweep.kernel.jit import kernel

from fencesweep.model.contact import coulomb, kelvin_force

APART, PUSH, CLIPPED = 0, 1, 2
N_SLOTS = 9
RAIL0 = 4
TIP = 8


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
    s = gx * ca + gy * sa
    h = -gx * sa + gy * ca
    return s, -sg * h, -sg * ((-gvx * sa + gvy * ca) - dal * s)


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
    """The fence tip T = (tx, ty) in the load's frame (docs/model.md (5.6)), and T - centroid in the world
    frame."""
    dx = tx - x
    dyy = ty - yy
    return cphi * dx + sphi * dyy, -sphi * dx + cphi * dyy, dx, dyy


@kernel()
def tip_edge_choice(x, yy, cphi, sphi, tlx, tly, hl, hw):
    """Edge pushed by the tip, by a separating-axis test of the segment O-T against the load:
    the axis of smaller overlap, its edge nearest T (docs/model.md (5.7)). 0: x' = +L/2, 1: -L/2,
    2: y' = +A/2, 3: -A/2."""
    olx = -(cphi * x + sphi * yy)  # the pivot in the load frame
    oly = sphi * x - cphi * yy
    ovx = min(hl, max(olx, tlx)) - max(-hl, min(olx, tlx))
    ovy = min(hw, max(oly, tly)) - max(-hw, min(oly, tly))
    if ovx < ovy:
        return 0 if tlx >= 0.0 else 1
    return 2 if tly >= 0.0 else 3


@kernel(inline=True)
def tip_edge_normal(edge, tlx, tly, hl, hw, cphi, sphi):
    """Depth D of T below the edge and the edge's outward normal n_e in the world frame (docs/model.md (5.8))."""
    if edge == 0:
        return hl - tlx, cphi, sphi
    if edge == 1:
        return hl + tlx, -cphi, -sphi
    if edge == 2:
        return hw - tly, -sphi, cphi
    return hw + tly, sphi, -cphi


@kernel(inline=True)
def tip_edge_force(D, nex, ney, tx, ty, dx, dyy, vx, vy, om, dal, kc, cd, law, mu2, eps, push):
    """The tip pushing an edge: force -N n_e + friction along the edge on the load, its torque,
    the reaction's moment on the fence at T (friction included), N, (N - N_el) D', friction
    power. D' from the tip's velocity relative to the load's material point under it (docs/model.md (5.9),
    (5.10))."""
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
