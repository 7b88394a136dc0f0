"""Scene `cycle`: one sorting work cycle (MODEL.md §1-§6, §9-§11).

State y (N_STATE = 13):
  0-5  load x, y, phi, x', y', omega                       (MODEL.md §1)
  6-7  fence alpha, alpha'                                  (§3; overwritten by alpha_w when kinematic)
  8    damper energy  int B2 (alpha_w' - alpha')^2 dt (the result is its value at t_c, §11)
  9    contact energy int sum (N - N_el) D' dt                              (§11)
  10   drive work     int T_lever alpha_w' dt (T_lever the element's torque; rigid: -tau alpha_w')
  11   belt work      int (F . v + M omega) dt  (work of belt friction on the load)
  12   contact friction dissipation int sum -f w dt
Integer work vector iw: 0-3 corner sides sigma_j (§5.1), 4 fence mode, 5 load present.

Phases (MODEL.md §8: model only what a phase needs):
  0  approach: no contact near; the load rides the belt in closed form, only the fence's
     ODE is stepped (coarse RK4);
  1  interaction: the full RHS, RK4 with a fine step near or in contact and a coarse
     step otherwise, bounded by the local stiffness; every change of the set of active
     contacts, the outcome events and the peaks are located inside the step on the
     step's cubic Hermite interpolant;
  2  after exit: the fence alone until t_c (residual deflection, damper energy).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import layout as Lp
from .. import results as Rs
from ..contact import belt_friction, coulomb, normal_force
from ..drive import drive_angle
from ..integrate import axpy, hermite, rk4_combine

N_STATE = 13
# fence modes
FM_KELVIN, FM_KINEMATIC, FM_FREE = 0, 1, 2
IW_MODE, IW_LOAD = 4, 5
# aux outputs of the RHS
AX_NF, AX_NR, AX_DMAX, AX_MASK, AX_TAU, AX_STIFF, AX_DDMAX, N_AUX = 0, 1, 2, 3, 4, 5, 6, 7
# contact mask bits: corner-fence j -> bit j, corner-rail j -> bit 4 + j, tip-edge -> bit 8
FENCE_BITS = 0x10F
RAIL_BITS = 0xF0
# trajectory columns
TRAJ_COLUMNS = ("t", "x", "y", "phi", "vx", "vy", "omega", "alpha", "alpha_w", "alpha_dot",
                "N_fence", "N_rail", "M_fence", "stage",
                "E_damper", "E_contact", "W_drive", "W_belt", "E_friction")
TRAJ_UNITS = ("s", "m", "m", "rad", "m/s", "m/s", "rad/s", "rad", "rad", "rad/s", "N", "N", "N m", "-",
              "J", "J", "J", "J", "J")
# quantities whose maxima are located inside the step
Q_NF, Q_NR, Q_DEFL, Q_ALPHA = 0, 1, 2, 3
GOLDEN = 0.6180339887498949
# step control in contact (numerics; chosen by the convergence measurements in benchmarks/)
C_STAB = 1.5  # h <= C_STAB / (largest local rate); RK4's real stability limit is 2.785
ETA_FORCE = 0.01  # sustained contact: relative change of the contact force per step
N_FLOOR = 0.01  # ... relative to the force plus this fraction of the free-fall force
C_ONSET = 0.25  # ... and at most C_ONSET / (local rate at the onset)
PULSE_WINDOW = 1.5  # fine steps for this many reference pulse times after an onset


@njit(cache=True, inline="always")
def corner_offset(j, hl, hw, cphi, sphi):
    """Offset of corner j from the centroid: local (+-L/2, +-A/2) rotated by phi (MODEL.md §1)."""
    lx = hl if (j == 0 or j == 3) else -hl
    ly = hw if j < 2 else -hw
    return cphi * lx - sphi * ly, sphi * lx + cphi * ly


@njit(cache=True, inline="always")
def fence_state(t, y, p, mode):
    """(alpha, alpha', alpha_w, alpha_w'): the fence follows alpha_w when kinematic (§3)."""
    aw, daw = drive_angle(t, p)
    if mode == FM_KINEMATIC:
        return aw, daw, aw, daw
    return y[6], y[7], aw, daw


@njit(cache=True)
def rhs(t, y, p, iw, dy, aux):
    """Right-hand side of the cycle (MODEL.md §3-§6); fills dy and aux (forces, contact mask)."""
    mode = iw[IW_MODE]
    al, dal, aw, daw = fence_state(t, y, p, mode)
    ca = math.cos(al)
    sa = math.sin(al)
    fl = p[Lp.FL]
    kc = p[Lp.KC]
    cd = p[Lp.CD]
    law = p[Lp.LAW]
    mu2 = p[Lp.MU2]
    eps = p[Lp.EPSV]
    inv_m1 = 1.0 / p[Lp.M1]
    inv_i1 = 1.0 / p[Lp.I1]
    inv_i2 = 1.0 / p[Lp.I2] if mode != FM_KINEMATIC else 0.0  # a kinematic fence: infinite mass
    nf = 0.0
    nr = 0.0
    dmax = 0.0
    mask = 0
    tau = 0.0  # moment of the load's contact forces on the fence about O
    p_diss = 0.0
    p_fric = 0.0
    p_belt = 0.0
    stiff = 0.0
    ddmax = 0.0  # largest closing rate D' of a force-carrying contact
    if iw[IW_LOAD] != 0:
        x = y[0]
        yy = y[1]
        vx = y[3]
        vy = y[4]
        om = y[5]
        cphi = math.cos(y[2])
        sphi = math.sin(y[2])
        # belt friction, Goyal-Ruina ellipse (A9), MODEL.md §6
        fx, fy, tq = belt_friction(vx - p[Lp.V], vy, om, p[Lp.FMAX], p[Lp.MMAX], p[Lp.RHO], eps)
        p_belt = fx * vx + fy * vy + tq * om
        s_belt = math.sqrt((vx - p[Lp.V]) ** 2 + vy * vy + (p[Lp.RHO] * om) ** 2 + eps * eps)
        stiff = max(p[Lp.FMAX] / p[Lp.M1], p[Lp.MMAX] * p[Lp.RHO] / p[Lp.I1]) / s_belt
        hl = 0.5 * p[Lp.LL]
        hw = 0.5 * p[Lp.AA]
        for j in range(4):
            rx, ry = corner_offset(j, hl, hw, cphi, sphi)
            gx = x + rx
            gy = yy + ry
            gvx = vx - om * ry
            gvy = vy + om * rx
            # corner-fence (MODEL.md §5.1): s along the fence, h from its line, side sigma_j
            s = gx * ca + gy * sa
            h = -gx * sa + gy * ca
            sg = iw[j]
            if s >= 0.0 and s <= fl and sg * h < 0.0:
                D = -sg * h
                Dd = -sg * ((-gvx * sa + gvy * ca) - dal * s)  # -sigma (v_G . n - alpha' s)
                n, n_el = normal_force(D, Dd, kc, cd, law)
                wsl = gvx * ca + gvy * sa  # slip along the fence
                f = coulomb(n, wsl, mu2, eps)
                cfx = -sg * n * sa + f * ca  # sigma N n + f d
                cfy = sg * n * ca + f * sa
                fx += cfx
                fy += cfy
                tq += rx * cfy - ry * cfx
                tau += -sg * n * s  # moment on the fence; friction along d has none
                nf += n
                p_diss += (n - n_el) * Dd
                p_fric -= f * wsl
                if n > 0.0:
                    mask |= 1 << j
                    ddmax = max(ddmax, Dd)
                    arm_n = rx * ca + ry * sa  # r x n
                    arm_t = rx * sa - ry * ca  # r x d
                    stiff += _contact_rate(D, n, wsl, kc, cd, law, mu2, eps,
                                           inv_m1 + arm_n * arm_n * inv_i1 + s * s * inv_i2,
                                           inv_m1 + arm_t * arm_t * inv_i1)
                if D > dmax:
                    dmax = D
            # corner-rail (MODEL.md §5.3)
            if gx <= 0.0 and gy < 0.0:
                D = -gy
                Dd = -gvy
                n, n_el = normal_force(D, Dd, kc, cd, law)
                f = coulomb(n, gvx, mu2, eps)
                fx += f
                fy += n
                tq += rx * n - ry * f
                nr += n
                p_diss += (n - n_el) * Dd
                p_fric -= f * gvx
                if n > 0.0:
                    mask |= 1 << (4 + j)
                    ddmax = max(ddmax, Dd)
                    stiff += _contact_rate(D, n, gvx, kc, cd, law, mu2, eps,
                                           inv_m1 + rx * rx * inv_i1, inv_m1 + ry * ry * inv_i1)
                if D > dmax:
                    dmax = D
        # tip-edge (MODEL.md §5.2): the tip T inside the load rectangle
        tx = fl * ca
        ty = fl * sa
        dx = tx - x
        dyy = ty - yy
        tlx = cphi * dx + sphi * dyy  # T in the load frame
        tly = -sphi * dx + cphi * dyy
        if abs(tlx) < hl and abs(tly) < hw:
            # separating-axis choice of the edge: overlap of segment O-T with the load per axis
            olx = -(cphi * x + sphi * yy)
            oly = sphi * x - cphi * yy
            ovx = min(hl, max(olx, tlx)) - max(-hl, min(olx, tlx))
            ovy = min(hw, max(oly, tly)) - max(-hw, min(oly, tly))
            if ovx < ovy:
                sgn = 1.0 if tlx >= 0.0 else -1.0
                D = hl - abs(tlx)
                nex = sgn * cphi  # outward normal of the edge x' = sgn L/2
                ney = sgn * sphi
            else:
                sgn = 1.0 if tly >= 0.0 else -1.0
                D = hw - abs(tly)
                nex = -sgn * sphi
                ney = sgn * cphi
            # velocity of the tip relative to the load's material point under it
            rvx = -dal * ty - (vx - om * dyy)
            rvy = dal * tx - (vy + om * dx)
            Dd = -(rvx * nex + rvy * ney)
            n, n_el = normal_force(D, Dd, kc, cd, law)
            tex = -ney
            tey = nex
            wl = -(rvx * tex + rvy * tey)  # slip of the load point along the edge
            f = coulomb(n, wl, mu2, eps)
            cfx = -n * nex + f * tex
            cfy = -n * ney + f * tey
            fx += cfx
            fy += cfy
            tq += dx * cfy - dyy * cfx
            tau += ty * cfx - tx * cfy  # reaction -F at T, friction included
            nf += n
            p_diss += (n - n_el) * Dd
            p_fric -= f * wl
            if n > 0.0:
                mask |= 1 << 8
                ddmax = max(ddmax, Dd)
                arm_n = dx * ney - dyy * nex
                arm_t = dx * tey - dyy * tex
                n_dot = -nex * sa + ney * ca  # share of the edge normal along the fence normal
                t_dot = -tex * sa + tey * ca
                stiff += _contact_rate(D, n, wl, kc, cd, law, mu2, eps,
                                       inv_m1 + arm_n * arm_n * inv_i1 + n_dot * n_dot * fl * fl * inv_i2,
                                       inv_m1 + arm_t * arm_t * inv_i1 + t_dot * t_dot * fl * fl * inv_i2)
            if D > dmax:
                dmax = D
        dy[0] = vx
        dy[1] = vy
        dy[2] = om
        dy[3] = fx / p[Lp.M1]
        dy[4] = fy / p[Lp.M1]
        dy[5] = tq / p[Lp.I1]
    else:
        for i in range(6):
            dy[i] = 0.0
    # fence (MODEL.md §3): I2 alpha'' = B2 (alpha_w' - alpha') + K2 (alpha_w - alpha) + tau
    p_damp = 0.0
    if mode == FM_KINEMATIC:
        dy[6] = 0.0
        dy[7] = 0.0
        p_drive = -tau * daw
    else:
        if mode == FM_KELVIN:
            torque = p[Lp.B2] * (daw - dal) + p[Lp.K2] * (aw - al)
            p_damp = p[Lp.B2] * (daw - dal) ** 2
        else:
            torque = 0.0
        dy[6] = dal
        dy[7] = (torque + tau) / p[Lp.I2]
        p_drive = torque * daw
    dy[8] = p_damp  # read at t_c, where a step always ends (MODEL.md §11: over [0, t_c])
    dy[9] = p_diss
    dy[10] = p_drive
    dy[11] = p_belt
    dy[12] = p_fric
    aux[AX_NF] = nf
    aux[AX_NR] = nr
    aux[AX_DMAX] = dmax
    aux[AX_MASK] = mask
    aux[AX_TAU] = tau
    aux[AX_STIFF] = stiff
    aux[AX_DDMAX] = ddmax


@njit(cache=True, inline="always")
def _contact_rate(D, n, w, kc, cd, law, mu, eps, inv_mn, inv_mt):
    """Largest local rate [1/s] of one active contact, for the step's stability bound:
    c/m + sqrt(k/m) of the normal law (k = dN/dD, c = dN/dD') with m the pair's effective
    mass along the normal (1/m = inv_mn), plus the slope of the regularised friction,
    mu N eps^2 / (w^2 + eps^2)^1.5, over the effective mass along the slip (1/m = inv_mt).
    The rates of all contacts are summed: the trace bounds the stiffest coupled mode."""
    if law == Lp.LAW_HERTZ:
        rd = math.sqrt(D)
        k = 1.5 * kc * rd
        c = cd * math.sqrt(rd)
    else:
        k = kc
        c = cd
    ww = w * w + eps * eps
    return c * inv_mn + math.sqrt(k * inv_mn) + mu * n * eps * eps / (ww * math.sqrt(ww)) * inv_mt


@njit(cache=True, inline="always")
def _pulse(w, p):
    """Undamped pulse time [s] and peak force [N] of an impact at closing speed w [m/s] for
    the smallest effective mass (MODEL.md §7 closed forms): Hertz 3.2181 (m^2/(k1^2 w))^0.2
    and k1 (5 m w^2 / (4 k1))^0.6; linear pi sqrt(m/k) and w sqrt(m k)."""
    m = p[Lp.M_RED]
    k = p[Lp.KC]
    w = max(w, 1e-9)
    if p[Lp.LAW] == Lp.LAW_HERTZ:
        return 3.2181 * (m * m / (k * k * w)) ** 0.2, k * (1.25 * m * w * w / k) ** 0.6
    return math.pi * math.sqrt(m / k), w * math.sqrt(m * k)


@njit(cache=True)
def rk4_step(t, y, f0, h, p, iw, y1, f1, aux, k2, k3, k4, tmp):
    """One classical RK4 step of size h from (t, y) with f0 = f(t, y); f1, aux at the end."""
    axpy(y, 0.5 * h, f0, tmp)
    rhs(t + 0.5 * h, tmp, p, iw, k2, aux)
    axpy(y, 0.5 * h, k2, tmp)
    rhs(t + 0.5 * h, tmp, p, iw, k3, aux)
    axpy(y, h, k3, tmp)
    rhs(t + h, tmp, p, iw, k4, aux)
    rk4_combine(y, h, f0, k2, k3, k4, y1)
    _pin_kinematic(t + h, y1, p, iw)
    rhs(t + h, y1, p, iw, f1, aux)


@njit(cache=True)
def _cut_at_contact_change(t, y, f0, h, y1, f1, mask0, p, iw, aux, k2, k3, k4, tmp, dyt, auxt):
    """The set of active contacts changed within the step [t, t + h]: locate the first
    change by bisection on the Hermite interpolant and end the step there -- just before
    an onset (so the next, graded, step starts the contact), just after a separation.
    The onset is checked against an RK4 re-step and bisected on re-steps if the
    interpolant placed it late. Returns (step taken, time of the change; > t + h when the
    change is an onset left to the next step)."""
    lo = 0.0
    hi = 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        hermite(y, f0, y1, f1, h, mid, tmp)
        rhs(t + mid * h, tmp, p, iw, dyt, auxt)
        if int(auxt[AX_MASK]) != mask0:
            hi = mid
        else:
            lo = mid
        if (hi - lo) * h < 1e-13:
            break
    hermite(y, f0, y1, f1, h, hi, tmp)
    rhs(t + hi * h, tmp, p, iw, dyt, auxt)
    onset = (int(auxt[AX_MASK]) & ~mask0) != 0
    s_cut = lo if onset else hi
    if s_cut * h <= 1e-12 or s_cut >= 1.0:
        return h, t + hi * h  # the change sits at the step's start (or end): keep the step
    hc = s_cut * h
    rk4_step(t, y, f0, hc, p, iw, y1, f1, aux, k2, k3, k4, tmp)
    if onset and (int(aux[AX_MASK]) & ~mask0) != 0:
        # the RK4 state is already past the onset: bisect on RK4 re-steps instead
        lo_h = 0.0
        hi_h = hc
        for _ in range(40):
            mid = 0.5 * (lo_h + hi_h)
            rk4_step(t, y, f0, mid, p, iw, y1, f1, aux, k2, k3, k4, tmp)
            if (int(aux[AX_MASK]) & ~mask0) != 0:
                hi_h = mid
            else:
                lo_h = mid
            if hi_h - lo_h < 1e-13:
                break
        if lo_h <= 1e-12:
            rk4_step(t, y, f0, hi_h, p, iw, y1, f1, aux, k2, k3, k4, tmp)
            return hi_h, t + lo_h
        hc = lo_h
        rk4_step(t, y, f0, hc, p, iw, y1, f1, aux, k2, k3, k4, tmp)
    if onset:
        return hc, math.inf
    return hc, t + hc


@njit(cache=True, inline="always")
def _pin_kinematic(t, y, p, iw):
    """A kinematic fence is alpha_w itself: write it into the state (for output only)."""
    if iw[IW_MODE] == FM_KINEMATIC:
        aw, daw = drive_angle(t, p)
        y[6] = aw
        y[7] = daw


@njit(cache=True)
def quantity(kind, t, y, p, iw, dy, aux):
    """A tracked quantity at (t, y): fence force, rail force, |alpha - alpha_w| or alpha."""
    if kind == Q_NF or kind == Q_NR:
        rhs(t, y, p, iw, dy, aux)
        return aux[AX_NF] if kind == Q_NF else aux[AX_NR]
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    if kind == Q_DEFL:
        return abs(al - aw)
    return al


@njit(cache=True)
def _interp(ta, ya, fa, tb, yb, fb, tc_, yc, fc, t, out):
    """Dense output over two consecutive steps [ta, tb], [tb, tc_]."""
    if t <= tb:
        h = tb - ta
        s = (t - ta) / h if h > 0.0 else 1.0
        hermite(ya, fa, yb, fb, h, s, out)
    else:
        h = tc_ - tb
        s = (t - tb) / h if h > 0.0 else 0.0
        hermite(yb, fb, yc, fc, h, s, out)


@njit(cache=True)
def refine_max(kind, ta, ya, fa, tb, yb, fb, tc_, yc, fc, qb, p, iw, tmp, dy, aux):
    """Maximum of a quantity that peaks near tb, by golden-section search on [ta, tc_]
    over the two steps' Hermite interpolants (the peak located inside the step)."""
    lo = ta
    hi = tc_
    best = qb
    x1 = hi - GOLDEN * (hi - lo)
    x2 = lo + GOLDEN * (hi - lo)
    _interp(ta, ya, fa, tb, yb, fb, tc_, yc, fc, x1, tmp)
    q1 = quantity(kind, x1, tmp, p, iw, dy, aux)
    _interp(ta, ya, fa, tb, yb, fb, tc_, yc, fc, x2, tmp)
    q2 = quantity(kind, x2, tmp, p, iw, dy, aux)
    for _ in range(40):
        if q1 > q2:
            hi = x2
            x2 = x1
            q2 = q1
            x1 = hi - GOLDEN * (hi - lo)
            _interp(ta, ya, fa, tb, yb, fb, tc_, yc, fc, x1, tmp)
            q1 = quantity(kind, x1, tmp, p, iw, dy, aux)
        else:
            lo = x1
            x1 = x2
            q1 = q2
            x2 = lo + GOLDEN * (hi - lo)
            _interp(ta, ya, fa, tb, yb, fb, tc_, yc, fc, x2, tmp)
            q2 = quantity(kind, x2, tmp, p, iw, dy, aux)
        if hi - lo < 1e-12 * (1.0 + abs(tc_)):
            break
    return max(best, q1, q2)


@njit(cache=True, inline="always")
def stage_of(mask):
    """Stage of MODEL.md §10 from the set of active contacts."""
    nfc = 0
    for b in (0, 1, 2, 3, 8):
        if mask & (1 << b):
            nfc += 1
    rail = (mask & RAIL_BITS) != 0
    if nfc == 0:
        return Rs.STAGE_RAIL if rail else Rs.STAGE_S2
    if rail:
        return Rs.STAGE_S4
    return Rs.STAGE_S1 if nfc == 1 else Rs.STAGE_S3


@njit(cache=True)
def min_corner_x(y, p):
    """Smallest x of the load's corners [m] (for the escape event)."""
    cphi = math.cos(y[2])
    sphi = math.sin(y[2])
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    xmin = math.inf
    for j in range(4):
        rx, ry = corner_offset(j, hl, hw, cphi, sphi)
        xmin = min(xmin, y[0] + rx)
    return xmin


@njit(cache=True)
def outcome_margin(kind, y, p):
    """Outcome event functions (MODEL.md §9), positive once the event has happened:
    0 scraped: y - P_max; 1 escaped: min_j x_Gj - l."""
    if kind == 0:
        return y[1] - p[Lp.PMAX]
    return min_corner_x(y, p) - p[Lp.FL]


@njit(cache=True)
def proximity(t, y, p, iw, margin, rail):
    """A lower bound on the distance [m] from the load to any contact (fence line near the
    fence's span, fence tip and, if `rail`, the rail). Negative when a contact is penetrated."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    ca = math.cos(al)
    sa = math.sin(al)
    fl = p[Lp.FL]
    cphi = math.cos(y[2])
    sphi = math.sin(y[2])
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    gap = math.inf
    for j in range(4):
        rx, ry = corner_offset(j, hl, hw, cphi, sphi)
        gx = y[0] + rx
        gy = y[1] + ry
        s = gx * ca + gy * sa
        if s >= -margin and s <= fl + margin:
            h = -gx * sa + gy * ca
            gap = min(gap, iw[j] * h)
        if rail and gx <= margin:
            gap = min(gap, gy)
    dx = fl * ca - y[0]
    dyy = fl * sa - y[1]
    tlx = abs(cphi * dx + sphi * dyy) - hl
    tly = abs(-sphi * dx + cphi * dyy) - hw
    gap = min(gap, math.sqrt(max(tlx, 0.0) ** 2 + max(tly, 0.0) ** 2))
    return gap


@njit(cache=True)
def update_sides(t, y, p, iw):
    """Side memory sigma_j (MODEL.md §5.1): beyond the tip sigma := sign(h) (0 -> +1);
    behind the pivot sigma := +1."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    ca = math.cos(al)
    sa = math.sin(al)
    cphi = math.cos(y[2])
    sphi = math.sin(y[2])
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    for j in range(4):
        rx, ry = corner_offset(j, hl, hw, cphi, sphi)
        gx = y[0] + rx
        gy = y[1] + ry
        s = gx * ca + gy * sa
        if s > p[Lp.FL]:
            iw[j] = -1 if (-gx * sa + gy * ca) < 0.0 else 1
        elif s < 0.0:
            iw[j] = 1


@njit(cache=True)
def _record(traj, row, t, y, p, iw, aux):
    if row >= traj.shape[0]:
        return row
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
    traj[row, 13] = stage_of(int(aux[AX_MASK])) if iw[IW_LOAD] != 0 else -1
    for i in range(5):
        traj[row, 14 + i] = y[8 + i]
    return row + 1


@njit(cache=True)
def initial_state(p, y):
    """MODEL.md §1: phi0; foremost corner at x = R_s, lowest at y = dP; belt velocity."""
    cphi = math.cos(p[Lp.PHI0])
    sphi = math.sin(p[Lp.PHI0])
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    xmax = -math.inf
    ymin = math.inf
    for j in range(4):
        rx, ry = corner_offset(j, hl, hw, cphi, sphi)
        xmax = max(xmax, rx)
        ymin = min(ymin, ry)
    for i in range(N_STATE):
        y[i] = 0.0
    y[0] = p[Lp.RS] - xmax
    y[1] = p[Lp.DP] - ymin
    y[2] = p[Lp.PHI0]
    y[3] = p[Lp.V]


@njit(cache=True)
def cycle_kernel(p, out, traj):
    """Simulate one work cycle; write CYCLE_RESULTS into out and the time series into traj
    (rows of TRAJ_COLUMNS, as many as fit). Returns the number of trajectory rows."""
    n = N_STATE
    y = np.empty(n)
    f0 = np.empty(n)
    y1 = np.empty(n)
    f1 = np.empty(n)
    ya = np.empty(n)  # the step before (for peaks located across two steps)
    fa = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    tmp = np.empty(n)
    dyt = np.empty(n)
    aux = np.zeros(N_AUX)
    auxt = np.zeros(N_AUX)
    iw = np.ones(6, dtype=np.int64)
    drive = int(p[Lp.DRIVE])
    iw[IW_MODE] = FM_KELVIN if drive == Lp.DRIVE_FLEXIBLE else FM_KINEMATIC
    iw[IW_LOAD] = 1
    tc = p[Lp.TC]
    tmax = p[Lp.TMAX]
    dt_c = p[Lp.DT_COARSE]
    dt_f = p[Lp.DT_FINE]
    half_side = 0.5 * min(p[Lp.LL], p[Lp.AA])
    r_load = 0.5 * math.sqrt(p[Lp.LL] ** 2 + p[Lp.AA] ** 2)
    for i in range(Rs.N_CYCLE_RESULTS):
        out[i] = 0.0
    initial_state(p, y)
    _pin_kinematic(0.0, y, p, iw)
    rhs(0.0, y, p, iw, f0, aux)
    row = _record(traj, 0, 0.0, y, p, iw, aux)
    t = 0.0
    ta = 0.0
    for i in range(n):
        ya[i] = y[i]
        fa[i] = f0[i]
    mask0 = int(aux[AX_MASK])
    # running maxima and their last two samples
    qmax = np.zeros(4)
    qprev = np.zeros(4)
    qcur = np.zeros(4)
    for k in range(4):
        qcur[k] = quantity(k, 0.0, y, p, iw, dyt, auxt)
        qprev[k] = qcur[k]
        qmax[k] = qcur[k]
    stage_time = np.zeros(5)
    t_first = math.nan
    t_last_loss = math.nan
    n_impacts = 0
    dmax_all = 0.0
    residual = math.nan
    e_damper = math.nan
    outcome = Rs.TIMEOUT
    status = Rs.ST_OK
    t_exit = tmax
    x_exit = math.nan
    phi_exit = math.nan
    e_contact = math.nan
    steps = 0
    max_steps = 50_000_000
    phase = 0
    exited = False
    v = p[Lp.V]
    h_grade = math.inf
    t_change = 0.0
    t_pulse_end = 0.0
    dt_pulse = dt_f
    h_prev = dt_f
    h_force = math.inf
    n_old = 0.0
    n_floor = N_FLOOR * p[Lp.FFORCE]
    eta = ETA_FORCE * p[Lp.STEPF]  # every step control scales with step_factor
    c_stab = min(C_STAB, C_STAB * p[Lp.STEPF])
    while True:
        t_end = tmax if not exited else tc
        if t >= t_end - 1e-12 * max(1.0, t_end) or steps >= max_steps:
            if steps >= max_steps:
                status = Rs.ST_MAXSTEPS
            elif not exited and t < tc:
                # a timeout before t_c (t_max < t_c): the cycle's results still run to t_c
                # (deflection over [0, max(t_exit, t_c)], residual at t_c, MODEL.md §11), so
                # the load is dropped here, as after an exit, and the fence goes on alone
                x_exit = y[0]
                phi_exit = y[2]
                e_contact = y[9]
                t_exit = t
                if (mask0 & FENCE_BITS) != 0:
                    t_last_loss = t
                exited = True
                iw[IW_LOAD] = 0
                mask0 = 0
                rhs(t, y, p, iw, f0, aux)
                continue
            break
        # ---- choose the step ----
        if phase == 0:
            margin = (v + p[Lp.FL] * p[Lp.DAW_MAX]) * dt_c * 2.0
            # the load rides the belt in closed form (y constant): only the fence can reach it
            if iw[IW_LOAD] != 0 and proximity(t, y, p, iw, margin, False) < margin:
                phase = 1
        if exited:
            h = dt_c
        elif phase == 0:
            h = dt_c
        else:
            speed = math.sqrt(y[3] ** 2 + y[4] ** 2) + abs(y[5]) * r_load \
                + p[Lp.FL] * (abs(y[7]) + p[Lp.DAW_MAX])
            margin = 2.0 * speed * dt_c
            gap = proximity(t, y, p, iw, margin, True) if mask0 == 0 else 0.0
            if mask0 == 0 and gap >= margin:
                h = dt_c  # no contact within reach of a coarse step
            elif mask0 == 0:
                # a contact is near: no contact can begin within gap / speed, so the steps
                # shrink geometrically with the gap down to the fine step (no tunnelling)
                # down to a quarter of the pulse time at that closing speed, so that a whole
                # contact cannot fall between two step ends
                h_floor = max(dt_f, 0.25 * p[Lp.STEPF] * _pulse(speed, p)[0])
                h = min(dt_c, max(h_floor, 0.5 * gap / speed))
            elif t < t_pulse_end:
                h = dt_pulse  # an impact pulse is under way
            else:
                # a sustained contact (sliding, S3/S4): the step follows the contact force,
                # at most ETA_FORCE of its size (plus a floor) per step, growing at most 2x
                h = min(dt_c, 2.0 * h_prev, h_force)
            if aux[AX_STIFF] > 0.0:
                h = min(h, c_stab / aux[AX_STIFF])  # RK4 stability on the stiffest local mode
            h = min(h, h_grade)
        if t < tc and t + h > tc:
            h = tc - t
        if t + h > t_end:
            h = t_end - t
        # ---- step ----
        if phase == 0 or exited:
            # the load rides the belt in closed form (or has left): step the fence alone
            iw[IW_LOAD] = 0
            rhs(t, y, p, iw, f0, aux)
            if not exited:
                f0[0] = v  # the closed-form ride, for the step's Hermite interpolant
            rk4_step(t, y, f0, h, p, iw, y1, f1, aux, k2, k3, k4, tmp)
            if not exited:
                iw[IW_LOAD] = 1
                y1[0] = y[0] + v * h
                for i in (1, 2, 4, 5):
                    y1[i] = y[i]
                y1[3] = v
                rhs(t + h, y1, p, iw, f1, aux)
        else:
            rk4_step(t, y, f0, h, p, iw, y1, f1, aux, k2, k3, k4, tmp)
            mask1 = int(aux[AX_MASK])
            if h_grade < math.inf:
                h_grade *= 2.0
                if h_grade > dt_f:
                    h_grade = math.inf
            if mask1 != mask0:
                h, t_change = _cut_at_contact_change(t, y, f0, h, y1, f1, mask0, p, iw, aux,
                                                     k2, k3, k4, tmp, dyt, auxt)
                if (int(aux[AX_MASK]) & ~mask0) != 0 or t_change > t + h:
                    # an onset in or right after this step: the damped law's force grows
                    # like (t - t_A)^(1/4), which costs RK4 its order on a step that starts
                    # there; grade the next steps from dt_fine/1024, doubling, so that each
                    # spans about [t, 2t] of the singular term
                    h_grade = dt_f / 1024.0
        steps += 1
        t1 = t + h
        h_prev = h
        if iw[IW_LOAD] != 0 and (int(aux[AX_MASK]) & ~mask0) != 0:
            # an onset: resolve its pulse with Lp.STEPS_PER_PULSE steps of the pulse time at
            # its own closing speed, unless its predicted peak is below the force floor (a
            # light touch, left to the force-following control). A contact can also begin at
            # a finite depth (a corner handed from the rail to the fence at the pivot): then
            # the local rate of the contact at the onset bounds the step too.
            t_pulse, f_pulse = _pulse(aux[AX_DDMAX], p)
            if f_pulse >= n_floor:
                t_pulse_end = max(t_pulse_end, t1 + PULSE_WINDOW * t_pulse)
                dt_pulse = p[Lp.STEPF] * t_pulse / Lp.STEPS_PER_PULSE
                if aux[AX_STIFF] > 0.0:
                    dt_pulse = min(dt_pulse, p[Lp.STEPF] * C_ONSET / aux[AX_STIFF])
                dt_pulse = max(dt_f / 16.0, min(dt_c, dt_pulse))
        if iw[IW_LOAD] != 0:
            n_new = aux[AX_NF] + aux[AX_NR]
            rate = abs(n_new - n_old) / h
            h_force = eta * (max(n_new, n_old) + n_floor) / rate if rate > 0.0 else math.inf
            n_old = n_new
        if t < tc and abs(t1 - tc) < 1e-12 * max(1.0, tc):
            t1 = tc  # steps end on t_c exactly (residual deflection, damper energy)
        mask1 = int(aux[AX_MASK]) if iw[IW_LOAD] != 0 else 0
        # ---- failure checks (MODEL.md §5) ----
        finite = True
        for i in range(n):
            if not math.isfinite(y1[i]):
                finite = False
        if not finite:
            status = Rs.ST_NONFINITE
            t_exit = t1
            break
        if aux[AX_DMAX] > dmax_all:
            dmax_all = aux[AX_DMAX]
        if dmax_all > half_side:
            status = Rs.ST_PENETRATION
            t_exit = t1
            break
        # ---- contact events and stage time ----
        fb0 = mask0 & FENCE_BITS
        fb1 = mask1 & FENCE_BITS
        if mask1 == mask0 or t_change > t1:
            t_change = t1
        if not exited:
            stage_time[stage_of(mask0)] += t_change - t
            stage_time[stage_of(mask1)] += t1 - t_change
            if fb0 == 0 and fb1 != 0:
                n_impacts += 1
                if math.isnan(t_first):
                    t_first = t_change
                if iw[IW_MODE] == FM_KINEMATIC and drive == Lp.DRIVE_FREE:
                    # the free fence's drive lets go at the first contact (MODEL.md §3)
                    iw[IW_MODE] = FM_FREE
                    aw, daw = drive_angle(t1, p)
                    y1[6] = aw
                    y1[7] = daw
                    rhs(t1, y1, p, iw, f1, aux)
            if fb0 != 0 and fb1 == 0:
                t_last_loss = t_change
        # ---- maxima located inside the step ----
        for k in range(4):
            if k <= Q_NR and (exited or phase == 0):
                continue
            if k == Q_NF:
                qk = aux[AX_NF]  # f1 was evaluated at (t1, y1): its forces are the samples
            elif k == Q_NR:
                qk = aux[AX_NR]
            else:
                qk = quantity(k, t1, y1, p, iw, dyt, auxt)
            if qcur[k] >= qprev[k] and qcur[k] >= qk and qcur[k] > 0.0 and qcur[k] >= qmax[k] * 0.999:
                qm = refine_max(k, ta, ya, fa, t, y, f0, t1, y1, f1, qcur[k], p, iw, tmp, dyt, auxt)
                if qm > qmax[k]:
                    qmax[k] = qm
            if qk > qmax[k]:
                qmax[k] = qk
            qprev[k] = qcur[k]
            qcur[k] = qk
        if t1 == tc:
            al, dal, aw, daw = fence_state(tc, y1, p, iw[IW_MODE])
            residual = abs(al - aw)
            e_damper = y1[8]
        # ---- outcome events (MODEL.md §9), located inside the step ----
        if not exited:
            kind = -1
            if outcome_margin(0, y1, p) >= 0.0:
                kind = 0
            elif outcome_margin(1, y1, p) > 0.0:
                kind = 1
            if kind >= 0:
                lo = 0.0
                hi = 1.0
                for _ in range(60):
                    mid = 0.5 * (lo + hi)
                    hermite(y, f0, y1, f1, h, mid, tmp)
                    if outcome_margin(kind, tmp, p) >= 0.0:
                        hi = mid
                    else:
                        lo = mid
                hermite(y, f0, y1, f1, h, hi, tmp)
                t_exit = t + hi * h
                outcome = Rs.SCRAPED if kind == 0 else Rs.ESCAPED
                x_exit = tmp[0]
                phi_exit = tmp[2]
                e_contact = tmp[9]
                # the stage time of the step is counted to t_exit only
                stage_time[stage_of(mask1)] -= t1 - t_exit
                if fb1 != 0:
                    t_last_loss = t_exit  # still touching at exit: B = t_exit
                exited = True
                iw[IW_LOAD] = 0
                for i in range(n):
                    y1[i] = tmp[i]
                t1 = t_exit
                _pin_kinematic(t1, y1, p, iw)
                rhs(t1, y1, p, iw, f1, aux)
                mask1 = 0
                row = _record(traj, row, t1, y1, p, iw, aux)
        if not exited:
            update_sides(t1, y1, p, iw)
            row = _record(traj, row, t1, y1, p, iw, aux)
        elif t1 > t_exit:
            row = _record(traj, row, t1, y1, p, iw, aux)
        # ---- advance ----
        ta = t
        for i in range(n):
            ya[i] = y[i]
            fa[i] = f0[i]
            y[i] = y1[i]
            f0[i] = f1[i]
        t = t1
        mask0 = mask1
        if exited and t >= tc:
            break
    if math.isnan(e_contact):
        e_contact = y[9]
    if status != Rs.ST_OK:
        outcome = Rs.FAILED
    if outcome == Rs.TIMEOUT and math.isnan(x_exit):
        x_exit = y[0]
        phi_exit = y[2]
        t_exit = min(t, tmax)
        if (mask0 & FENCE_BITS) != 0:
            t_last_loss = t_exit
    if math.isnan(residual) and t >= tc:
        al, dal, aw, daw = fence_state(tc, y, p, iw[IW_MODE])
        residual = abs(al - aw)
    out[Rs.RC_OUTCOME] = outcome
    out[Rs.RC_T_EXIT] = t_exit
    out[Rs.RC_PEAK_FORCE] = qmax[Q_NF]
    out[Rs.RC_PEAK_RAIL_FORCE] = qmax[Q_NR]
    out[Rs.RC_FREEFALL_FORCE] = p[Lp.FFORCE]
    out[Rs.RC_OVERLOAD] = qmax[Q_NF] / p[Lp.FFORCE]
    out[Rs.RC_SAFE] = 1.0 if qmax[Q_NF] <= p[Lp.FFORCE] else 0.0
    out[Rs.RC_DEFLECTION_OK] = 1.0 if qmax[Q_DEFL] <= p[Lp.DAPERM] else 0.0
    out[Rs.RC_DEFLECTION_MAX] = qmax[Q_DEFL]
    out[Rs.RC_RESIDUAL_DEFLECTION] = residual
    out[Rs.RC_ALPHA_MAX] = qmax[Q_ALPHA]
    out[Rs.RC_DAMPER_ENERGY] = e_damper if not math.isnan(e_damper) else y[8]
    out[Rs.RC_CONTACT_ENERGY] = e_contact
    out[Rs.RC_T_FIRST_CONTACT] = t_first
    if math.isnan(t_first):
        out[Rs.RC_CONTACT_TIME] = 0.0
    else:
        b = t_last_loss if not math.isnan(t_last_loss) else t_exit
        out[Rs.RC_CONTACT_TIME] = b - t_first
    out[Rs.RC_N_IMPACTS] = n_impacts
    out[Rs.RC_T_S1] = stage_time[Rs.STAGE_S1]
    out[Rs.RC_T_S2] = stage_time[Rs.STAGE_S2]
    out[Rs.RC_T_S3] = stage_time[Rs.STAGE_S3]
    out[Rs.RC_T_S4] = stage_time[Rs.STAGE_S4]
    out[Rs.RC_T_RAIL] = stage_time[Rs.STAGE_RAIL]
    out[Rs.RC_X_EXIT] = x_exit
    out[Rs.RC_PHI_EXIT] = phi_exit
    out[Rs.RC_MAX_PENETRATION] = dmax_all
    out[Rs.RC_N_STEPS] = steps
    out[Rs.RC_STATUS] = status
    return row
