"""The cycle's right-hand side (docs/model.md §3, §5, §6): the fence's equation, the load's contacts
and its belt friction. Between events it is smooth: it evaluates only the contacts whose slot
is not APART, in the mode (iw) fixed at the step's start."""
from __future__ import annotations

import math

from fencesweep.kernel import numerics as NU
from fencesweep.kernel import rk
from fencesweep.kernel.jit import kernel
from fencesweep.kernel.trig import cos_sin_near
from fencesweep.model import layout as Lp
from fencesweep.model.contact import belt_friction
from fencesweep.model.drive import drive_angle
from fencesweep.model.scenes.contacts import (APART, FACE, N_SLOTS, PIVOT, PUSH, RAIL0, TIP, corner_fence_force,
                                              corner_fence_geometry, corner_rail_force, fence_part, tip_edge_force, tip_edge_normal, tip_local, tip_position,
                                              beyond_depth, side_edge)
from fencesweep.model.scenes.cycle.layout import (AX_CA, AX_CPHI, AX_DAL, AX_DMAX, AX_DRIVE, AX_FRAME, AX_FX, AX_FY, AX_KEPT, AX_NF,
                                                  AX_NR, AX_PDISS, AX_PFRIC, AX_SA, AX_SPHI, AX_TAU, AX_TQ, AX_TRIG_AL, AX_TRIG_PHI,
                                                  FM_KELVIN, FM_KINEMATIC, IW_CODE, IW_EDGE, IW_LOAD, IW_MODE,
                                                  IW_RIDE, N_AUX, N_CTRL)
from fencesweep.model.scenes.load import corner_motion


@kernel(inline=True)
def fence_state(t, y, p, mode):
    """(alpha, alpha', alpha_w, alpha_w') at (t, y): the drive at t and the fence following it
    when kinematic (docs/model.md (3.3), fence_follows)."""
    aw, daw = drive_angle(t, p)
    return fence_follows(y, mode, aw, daw)


@kernel(inline=True)
def fence_follows(y, mode, aw, daw):
    """(alpha, alpha', alpha_w, alpha_w'): the fence follows alpha_w when kinematic, alpha = alpha_w,
    alpha' = alpha_w' (docs/model.md (3.3): the rigid drive, and the free one until its release)."""
    if mode == FM_KINEMATIC:
        return aw, daw, aw, daw
    return y[6], y[7], aw, daw


@kernel(inline=True)
def fence_state_in(t, y, p, mode, aux):
    """fence_state with the drive from drive_once: evaluated once at each t where aux holds it."""
    aw, daw = drive_once(t, p, aux)
    return fence_follows(y, mode, aw, daw)


@kernel(inline=True)
def drive_once(t, p, aux):
    """drive_angle at t, from aux when the last right-hand side that wrote aux was at the same t
    (DOPRI5's sixth stage and its FSAL stage are both at t + h) or t is the step's start
    (keep_drive): the same values, once. A function of t alone: kept values are exact."""
    if aux[AX_DRIVE] == t:
        return aux[AX_DRIVE + 1], aux[AX_DRIVE + 2]
    if aux[AX_KEPT] == t:
        return aux[AX_KEPT + 1], aux[AX_KEPT + 2]
    aw, daw = drive_angle(t, p)
    aux[AX_DRIVE] = t
    aux[AX_DRIVE + 1] = aw
    aux[AX_DRIVE + 2] = daw
    return aw, daw


@kernel(inline=True)
def keep_drive(t, p, aux):
    """Keep the drive at t, the next step's start, in aux[AX_KEPT:]: the step's stages replace
    aux[AX_DRIVE:], and its peaks read the fence at both its ends (peaks.fence_values)."""
    aw, daw = drive_once(t, p, aux)
    aux[AX_KEPT] = t
    aux[AX_KEPT + 1] = aw
    aux[AX_KEPT + 2] = daw


@kernel(inline=True)
def forget_drive(aux):
    """No drive kept in aux: the next drive_once evaluates it (each cycle's drive is its own)."""
    aux[AX_DRIVE] = math.nan
    aux[AX_KEPT] = math.nan


@kernel(inline=True)
def add_contact(aux, ax_n, fx, fy, tq, tau, n, p_diss, p_fric, D):
    """Add one contact's forces (contacts.py) to the sums in aux (docs/model.md (5.14)): on the
    load, the moment on the fence, its normal force to the fence or rail sum, the dissipated
    powers, the penetration."""
    aux[AX_FX] += fx
    aux[AX_FY] += fy
    aux[AX_TQ] += tq
    aux[AX_TAU] += tau
    aux[ax_n] += n
    aux[AX_PDISS] += p_diss
    aux[AX_PFRIC] += p_fric
    aux[AX_DMAX] = max(aux[AX_DMAX], D)


@kernel(inline=True)
def save_frame(aux, ca, sa, dal, cphi, sphi):
    """Keep the frame the contacts were evaluated in (AX_CA..AX_SPHI) for slots.classify_after_rhs."""
    aux[AX_CA] = ca
    aux[AX_SA] = sa
    aux[AX_DAL] = dal
    aux[AX_CPHI] = cphi
    aux[AX_SPHI] = sphi
    aux[AX_FRAME] = 1.0


@kernel(inline=True)
def corner_sum(y, p, iw, ca, sa, dal, cphi, sphi, aux):
    """Add the forces of the corners' slots that are not APART: on the fence (§5.1), on the rail (§5.3)."""
    kc, cd, law, mu2, eps = p[Lp.KC], p[Lp.CD], p[Lp.LAW], p[Lp.MU2], p[Lp.EPSV]
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


@kernel(inline=True)
def edge_point_sum(e, u, code, y, p, ca, sa, dal, cphi, sphi, aux):
    """Add the force of the fence point P(u) = u T pushing load edge e (docs/model.md (5.9), (5.10))."""
    if code == APART:
        return
    tx, ty = tip_position(p[Lp.FL], ca, sa)
    px, py = u * tx, u * ty
    plx, ply, dx, dyy = tip_local(px, py, y[0], y[1], cphi, sphi)
    D, nex, ney = tip_edge_normal(e, plx, ply, 0.5 * p[Lp.LL], 0.5 * p[Lp.AA], cphi, sphi)
    a, b, c, d, n, pd, pf, Dd = tip_edge_force(D, nex, ney, px, py, dx, dyy, y[3], y[4], y[5], dal,
                                               p[Lp.KC], p[Lp.CD], p[Lp.LAW], p[Lp.MU2], p[Lp.EPSV], code == PUSH)
    add_contact(aux, AX_NF, a, b, c, d, n, pd, pf, D)


@kernel(inline=True)
def beyond_sum(i, y, p, iw, ca, sa, dal, cphi, sphi, aux):
    """Add the force of the under-tip point U on its branch 1 (docs/model.md (5.7)): the depth and
    rate of the corner C' beyond the tip on the edge from corner i, pushing at the tip as a corner
    does (5.4), with the in-span corner's side."""
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    c, D, Dd = beyond_depth(i, y, hl, hw, ca, sa, dal, cphi, sphi, iw)
    fl = p[Lp.FL]
    rx, ry = fl * ca - y[0], fl * sa - y[1]  # at the tip: the load's material point there
    a, b, cc, d, n, pd, pf = corner_fence_force(rx, ry, y[3] - y[5] * ry, y[4] + y[5] * rx, fl, D, Dd, iw[c], ca, sa,
                                                p[Lp.KC], p[Lp.CD], p[Lp.LAW], p[Lp.MU2], p[Lp.EPSV],
                                                iw[IW_CODE + TIP] == PUSH)
    add_contact(aux, AX_NF, a, b, cc, d, n, pd, pf, D)


@kernel(inline=True)
def tip_sum(y, p, iw, ca, sa, dal, cphi, sphi, aux):
    """Add the forces of the manifold's TIP and PIVOT slots (docs/model.md §5.2): the under-tip point
    on the fence's face, or the ends of the fence's part below load edge e (5.7)."""
    ct = iw[IW_CODE + TIP]
    cp = iw[IW_CODE + PIVOT]
    if ct == APART and cp == APART:
        return
    tag = iw[IW_EDGE]
    if tag >= FACE + 4:  # the face's U on its branch 1: the corner beyond the tip
        beyond_sum(tag - FACE - 4, y, p, iw, ca, sa, dal, cphi, sphi, aux)
        return
    e = side_edge(tag - FACE) if tag >= FACE else tag  # the face's U on branch 0: the tip end below its edge
    lo, hi, e_lo, e_hi = fence_part(p[Lp.FL], 0.5 * p[Lp.LL], 0.5 * p[Lp.AA], y[0], y[1], ca, sa, cphi, sphi,
                                    NU.CONTACT_HYSTERESIS * p[Lp.FL])[6:]
    if lo > hi:
        return
    edge_point_sum(e, hi, APART if e_hi == e else ct, y, p, ca, sa, dal, cphi, sphi, aux)
    if tag < FACE:
        edge_point_sum(e, lo, APART if e_lo == e else cp, y, p, ca, sa, dal, cphi, sphi, aux)


@kernel(inline=True)
def any_slot_on(iw):
    """Is any contact slot not APART in the step's mode (iw)? Only then do the contacts push."""
    for k in range(N_SLOTS):
        if iw[IW_CODE + k] != APART:
            return True
    return False


@kernel(inline=True)
def contact_sum(y, p, iw, al, dal, aux):
    """Sum into aux the forces of every slot that is not APART (docs/model.md §5): on the load
    (AX_FX, AX_FY, AX_TQ), the moment on the fence (AX_TAU), the normal-force sums and the
    dissipated powers. With every slot APART nothing pushes, and the frame (the sines and
    cosines of alpha and phi) is not formed: slots.classify_after_rhs then forms it itself.
    Otherwise they come from the last angles aux holds (kernel/trig.py cos_sin_near)."""
    if not any_slot_on(iw):
        return
    ca, sa = cos_sin_near(al, aux, AX_TRIG_AL)
    cphi, sphi = cos_sin_near(y[2], aux, AX_TRIG_PHI)
    save_frame(aux, ca, sa, dal, cphi, sphi)
    corner_sum(y, p, iw, ca, sa, dal, cphi, sphi, aux)
    tip_sum(y, p, iw, ca, sa, dal, cphi, sphi, aux)


@kernel(inline=True)
def load_rhs(y, p, iw, al, dal, dy, aux):
    """Load equations (docs/model.md (6.5)): velocities, and accelerations from belt friction
    and the contacts; the closed-form belt ride (8.1) when it rides. Returns the moment on the
    fence."""
    dy[0] = y[3]
    dy[1] = y[4]
    dy[2] = y[5]
    if iw[IW_RIDE] != 0:
        for i in (3, 4, 5, 9, 11, 12):
            dy[i] = 0.0
        return 0.0
    vx, vy, om = y[3], y[4], y[5]
    bx, by, bt = belt_friction(vx - p[Lp.V], vy, om, p[Lp.FMAX], p[Lp.MMAX], p[Lp.RHO], p[Lp.EPSV])
    contact_sum(y, p, iw, al, dal, aux)
    dy[3] = (aux[AX_FX] + bx) / p[Lp.M1]
    dy[4] = (aux[AX_FY] + by) / p[Lp.M1]
    dy[5] = (aux[AX_TQ] + bt) / p[Lp.I1]
    dy[9] = aux[AX_PDISS]
    dy[11] = belt_power(bx, by, bt, vx, vy, om)
    dy[12] = aux[AX_PFRIC]
    return aux[AX_TAU]


@kernel(inline=True)
def belt_power(bx, by, bt, vx, vy, om):
    """The power of the belt on the load, F_b . X' + M_b omega [W] (docs/model.md (11.12), W_belt;
    integrated as the state's component 11; E_friction's power is contacts.friction_power)."""
    return bx * vx + by * vy + bt * om


@kernel(inline=True)
def deflection(al, dal, aw, daw):
    """The fence's deflection from its drive, alpha - alpha_w [rad] (docs/model.md (3.7)), and its
    rate alpha' - alpha_w' [rad/s]."""
    return al - aw, dal - daw


@kernel(inline=True)
def element_torque(aw, daw, al, dal, b2, k2):
    """Torque of the flexible element on the fence [N m] (docs/model.md §3): B2 (alpha_w' - alpha')
    + K2 (alpha_w - alpha)."""
    return b2 * (daw - dal) + k2 * (aw - al)


@kernel(inline=True)
def damper_power(b2, daw, dal):
    """The power the element's damper dissipates, B2 (alpha_w' - alpha')^2 [W] (docs/model.md
    (11.6); integrated as the state's component 8, damper_energy)."""
    return b2 * (daw - dal) ** 2


@kernel(inline=True)
def drive_power(torque, daw):
    """The power of the drive lever, its torque on the fence times alpha_w' [W] (docs/model.md
    (11.11); integrated as the state's component 10, W_drive): the element's torque, 0 for the
    free fence, -tau for the rigid drive (the lever then takes the load's moment itself)."""
    return torque * daw


@kernel(inline=True)
def fence_rhs(mode, al, dal, aw, daw, tau, p, dy):
    """The fence's rows of the right-hand side (alpha, alpha' and the energies of the fence) under
    the load's moment tau (docs/model.md (3.2)): I2 alpha'' = B2 (alpha_w' - alpha') + K2 (alpha_w -
    alpha) + tau, the element's torque from element_torque; the free fence after its release
    I2 alpha'' = tau (3.4); kinematic (3.3): alpha follows alpha_w, no rows of its own."""
    dy[8] = 0.0
    if mode == FM_KINEMATIC:
        dy[6] = 0.0
        dy[7] = 0.0
        dy[10] = drive_power(-tau, daw)
        return
    torque = 0.0
    if mode == FM_KELVIN:
        torque = element_torque(aw, daw, al, dal, p[Lp.B2], p[Lp.K2])
        dy[8] = damper_power(p[Lp.B2], daw, dal)
    dy[6] = dal
    dy[7] = (torque + tau) / p[Lp.I2]
    dy[10] = drive_power(torque, daw)


@kernel(inline=True)
def rhs(t, y, p, iw, dy, aux):
    """Right-hand side of the cycle in the mode of iw; fills dy and aux (contact forces): the
    load's (load_rhs, docs/model.md §6) and the fence's (fence_rhs, docs/model.md §3)."""
    mode = iw[IW_MODE]
    aw, daw = drive_once(t, p, aux)
    al, dal, aw, daw = fence_follows(y, mode, aw, daw)
    for i in range(N_AUX):
        aux[i] = 0.0
    tau = 0.0
    if iw[IW_LOAD] != 0:
        tau = load_rhs(y, p, iw, al, dal, dy, aux)
    else:
        for i in (0, 1, 2, 3, 4, 5, 9, 11, 12):
            dy[i] = 0.0
    fence_rhs(mode, al, dal, aw, daw, tau, p, dy)


#: one step of the integrator with this right-hand side (kernel/rk.py stepper), which reads the
#: first N_CTRL components of the state: the energies (the rest) are quadratures, in no stage
step = rk.stepper(rhs, "cycle_step", N_CTRL)
