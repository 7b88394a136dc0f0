"""The cycle's book-keeping: its start (docs/model.md §1), the contact changes it counts (§10-§11),
the load's exit (§9), the results read at t_c and at the end (§11), the trajectory's rows."""
from __future__ import annotations

import math

from fencesweep.kernel import driver
from fencesweep.kernel import numerics as NU
from fencesweep.kernel.jit import kernel
from fencesweep.model import layout as Lp
from fencesweep.model import results as Rs
from fencesweep.model.drive import drive_angle
from fencesweep.model.scenes.contacts import APART, N_SLOTS
from fencesweep.model.scenes.cycle.layout import (A_DMAX, A_E_CONTACT, A_E_DAMPER, A_EXITED, A_N_IMPACTS,
                                                  A_OUTCOME, A_PHI_EXIT, A_QMAX, A_RESID, A_RESID_AMP, A_STAGE,
                                                  A_ONSET, A_STATUS, A_T_EXIT, A_T_FIRST, A_T_LOSS, A_TOUCH, A_X_EXIT,
                                                  AX_NF, AX_NR,
                                                  AX_TAU, FM_FREE, FM_KELVIN, FM_KINEMATIC, IW_CODE, IW_EDGE,
                                                  IW_LOAD, IW_MODE, IW_RIDE, N_ACC, N_CTRL, N_STATE, Q_ALPHA,
                                                  Q_DEFL, Q_NF, Q_NR)
from fencesweep.model.scenes.cycle.rhs import deflection, fence_state
from fencesweep.model.scenes.cycle.slots import fence_pushed, in_contact, stage_of, take_sides
from fencesweep.model.scenes.load import initial_state


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


@kernel(inline=True)
def release_free_fence(t, y, p, iw):
    """The free drive (docs/model.md (3.4)) at t_A, the first load-fence contact that carries
    force: the fence, kinematic until then, starts from the drive's alpha_w(t_A), alpha_w'(t_A)
    and moves without the element from then on (rhs.fence_rhs: I2 alpha'' = tau)."""
    if iw[IW_MODE] == FM_KINEMATIC and p[Lp.DRIVE] == Lp.DRIVE_FREE:
        aw, daw = drive_angle(t, p)
        iw[IW_MODE] = FM_FREE
        y[6] = aw
        y[7] = daw


@kernel(inline=True)
def touching(nf, p):
    """Does the load touch the fence: its load-fence force sum nf [N] (the fence's, (11.1))
    above numerics.TOUCH_FORCE x F_ff (docs/model.md (11.10))?"""
    return nf > NU.TOUCH_FORCE * p[Lp.FFORCE]


@kernel()
def note_touch(t, touch, acc):
    """The fence force passes the touch floor at t (docs/model.md (11.10)), upwards (touch) or
    downwards. Upwards: an impact (11.9); the first dates t_A (11.8) from where the fence's force
    first left 0 (acc[A_ONSET]). Downwards: the last loss, t_B."""
    if touch:
        acc[A_N_IMPACTS] += 1.0
        if math.isnan(acc[A_T_FIRST]):
            acc[A_T_FIRST] = acc[A_ONSET]
    else:
        acc[A_T_LOSS] = t
    acc[A_TOUCH] = 1.0 if touch else 0.0


@kernel(inline=True)
def sync_touch(t, nf, p, acc):
    """The touch at t from the fence force nf there: noted (note_touch) where it changed."""
    now = touching(nf, p)
    if now != (acc[A_TOUCH] != 0.0):
        note_touch(t, now, acc)


@kernel()
def apply_contact_change(t, y, p, iw, codes, edge, acc):
    """Enter the slots' new codes at an event; note where the fence's force first leaves 0 (t_A
    once a touch follows, docs/model.md (11.10)); release the free fence at the first load-fence
    contact that carries force (3.4). The touches (n_impacts, t_B) are counted on the force
    (note_touch)."""
    before = fence_pushed(iw)
    for k in range(N_SLOTS):
        iw[IW_CODE + k] = codes[k]
    iw[IW_EDGE] = edge
    iw[IW_RIDE] = 0
    if fence_pushed(iw) and not before:
        if math.isnan(acc[A_ONSET]):
            acc[A_ONSET] = t  # t_A, once the force passes the touch floor (note_touch)
        release_free_fence(t, y, p, iw)


@kernel()
def drop_load(t, y, iw, acc, outcome):
    """The load leaves the run at t (outcome event, or a timeout before t_c): its results."""
    acc[A_OUTCOME] = outcome
    acc[A_T_EXIT] = t
    acc[A_X_EXIT] = y[0]
    acc[A_PHI_EXIT] = y[2]
    acc[A_E_CONTACT] = y[9]
    if acc[A_TOUCH] != 0.0:
        note_touch(t, False, acc)  # still touching at exit: B = t_exit
    acc[A_EXITED] = 1.0
    iw[IW_LOAD] = 0
    iw[IW_RIDE] = 0
    for k in range(N_SLOTS):
        iw[IW_CODE + k] = APART


@kernel(inline=True)
def time_out(t, w):
    """The load still on the belt at t = t_max, neither scraped (9.1) nor escaped (9.2), leaves
    the run as a timeout at t (docs/model.md (9.3); run: t_max before t_c, the fence runs on
    alone; finish: at the end of the run)."""
    drop_load(t, w.y, w.iw, w.acc, Rs.TIMEOUT)


@kernel(inline=True)
def count_stage_time(iw, acc, t, t1):
    """Add the step [t, t1] to the time in its stage (docs/model.md (10.2)): the integral of
    [stage(t) = S] as a sum over the steps up to the exit (the stage is fixed within a step:
    its contacts change only at events, which end a step)."""
    acc[A_STAGE + stage_of(iw)] += t1 - t


@kernel()
def try_ride(y, p, iw):
    """A load with no contact whose slip is below numerics.SNAP_SLIP eps_v (docs/model.md (15.10))
    rides the belt in closed form from here on (8.1): velocity (v, 0), no spin. Returns whether it
    snapped."""
    if iw[IW_LOAD] == 0 or iw[IW_RIDE] != 0 or in_contact(iw):
        return False
    slip2 = (y[3] - p[Lp.V]) ** 2 + y[4] ** 2 + (p[Lp.RHO] * y[5]) ** 2
    if slip2 >= p[Lp.SNAP] ** 2:
        return False
    y[3] = p[Lp.V]
    y[4] = 0.0
    y[5] = 0.0
    iw[IW_RIDE] = 1
    return True


@kernel(inline=True)
def natural_frequency(k2, i2):
    """omega_n = sqrt(K2 / I2) [rad/s], the undamped natural frequency of the flexible element
    with the fence (docs/model.md (3.6))."""
    return math.sqrt(k2 / i2)


@kernel(inline=True)
def swing_amplitude(dev, rate, p, mode):
    """Undamped amplitude [rad] of the fence's swing about its drive from the deflection dev =
    alpha - alpha_w [rad] and its rate [rad/s] (docs/model.md (11.5) residual_amplitude, (14.4)
    start_amplitude): sqrt(dev^2 + (rate / omega_n)^2), omega_n = sqrt(K2 / I2); |dev| when
    K2 = 0 (or so small that omega_n underflows to 0) or the fence follows its drive."""
    wn = natural_frequency(p[Lp.K2], p[Lp.I2])
    if mode == FM_KELVIN and wn > 0.0:
        return math.sqrt(dev ** 2 + (rate / wn) ** 2)  # §11
    return abs(dev)


@kernel()
def at_t_c(t, y, p, iw, acc):
    """Results read at t_c: residual_deflection |alpha - alpha_w| (docs/model.md (11.4)), the
    residual amplitude (11.5), damper energy (11.6)."""
    al, dal, aw, daw = fence_state(t, y, p, iw[IW_MODE])
    dev, rate = deflection(al, dal, aw, daw)
    acc[A_RESID] = abs(dev)
    acc[A_RESID_AMP] = swing_amplitude(dev, rate, p, iw[IW_MODE])
    acc[A_E_DAMPER] = y[8]


@kernel()
def error_scales(p, atol):
    """atol: the absolute tolerance of each state component, TOL (p[TOL]) times its scale
    (docs/model.md (15.2)).
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
def start(p, w):
    """Initial state of the load (docs/model.md (1.5)), modes, accumulators, step counts and the
    error scales (error_scales) of a cycle; the fence's (alpha, alpha') in w.y are left as they
    are: a stream's fence carries over from one cycle into the next (14.3)."""
    al, dal = w.y[6], w.y[7]
    initial_state(p, w.y)
    w.y[6] = al
    w.y[7] = dal
    iw, acc = w.iw, w.acc
    for j in range(4):
        iw[j] = 1
    iw[IW_MODE] = FM_KELVIN if int(p[Lp.DRIVE]) == Lp.DRIVE_FLEXIBLE else FM_KINEMATIC
    iw[IW_LOAD] = 1
    iw[IW_RIDE] = 1  # at t = 0 the load moves with the belt (docs/model.md §1)
    for i in range(N_ACC):
        acc[i] = 0.0
    for i in (A_T_FIRST, A_T_LOSS, A_ONSET, A_T_EXIT, A_X_EXIT, A_PHI_EXIT, A_E_CONTACT, A_RESID, A_RESID_AMP,
              A_E_DAMPER):
        acc[i] = math.nan
    acc[A_OUTCOME] = Rs.TIMEOUT
    for i in range(driver.N_COUNT):
        w.count[i] = 0.0
    error_scales(p, w.atol0)
    for i in range(N_STATE):
        w.atol[i] = w.atol0[i]
    w.rtol[0] = p[Lp.TOL]


@kernel()
def after_step(t1, y1, p, iw, kind, codes1, tags1, edge1, acc):
    """Apply the event that ended a step at t1 (events.find_event's kind), the side memory and
    the closed-form ride. Returns True when the mode changed (the right-hand side must be
    evaluated anew at t1)."""
    changed = kind != 0
    if kind == 1:
        apply_contact_change(t1, y1, p, iw, codes1, edge1, acc)
    elif kind >= 2:
        drop_load(t1, y1, iw, acc, Rs.SCRAPED if kind == 2 else Rs.ESCAPED)
    if iw[IW_LOAD] != 0:
        changed |= take_sides(iw, tags1)
        changed |= try_ride(y1, p, iw)
    if iw[IW_MODE] == FM_KINEMATIC:
        y1[6], y1[7] = drive_angle(t1, p)
    return changed


@kernel(inline=True)
def error_estimate(sum_sq):
    """The run's error estimate (results.py error_estimate; docs/model.md (15.13)) from the sum of
    the squared error norms of its accepted steps, each the local error relative to its tolerance
    (rk.error_norm) times that tolerance (driver.integrate: a step may have a tighter one than
    the run's, run.set_tolerance): sqrt(sum (tol err)^2), the root-sum-square of the local
    errors relative to the error scales. Local errors of varying sign add up like a random
    walk, not like a plain sum, which overstates the error; results/error_estimate.md measures
    both against the reference on the validation scenes."""
    return math.sqrt(sum_sq)


@kernel(inline=True)
def contact_time(t_first, t_loss, t_exit):
    """contact_time = t_B - t_A (docs/model.md (11.8)) [s]: t_A the first load-fence contact
    (t_first_contact), t_B its last loss, t_exit if the load is still in contact then; 0 for a
    run without contact."""
    if math.isnan(t_first):
        return 0.0
    b = t_loss if not math.isnan(t_loss) else t_exit
    return b - t_first


@kernel(inline=True)
def overload_and_safe(peak_force, freefall_force):
    """overload = peak_force / F_ff and safe (1.0 when overload <= 1, tested as peak_force <=
    F_ff; else 0.0) (docs/model.md (7.3))."""
    return peak_force / freefall_force, 1.0 if peak_force <= freefall_force else 0.0


@kernel(inline=True)
def deflection_ok(deflection_max, dalpha_perm):
    """deflection_ok: 1.0 when deflection_max <= the permitted deflection, else 0.0 (docs/model.md
    (11.3))."""
    return 1.0 if deflection_max <= dalpha_perm else 0.0


@kernel(inline=True)
def contact_results(acc, out):
    """The contact results of docs/model.md §11 into out: first contact, contact time, impacts,
    stage times, largest penetration."""
    out[Rs.RC_T_FIRST_CONTACT] = acc[A_T_FIRST]
    out[Rs.RC_CONTACT_TIME] = contact_time(acc[A_T_FIRST], acc[A_T_LOSS], acc[A_T_EXIT])
    out[Rs.RC_N_IMPACTS] = acc[A_N_IMPACTS]
    for i, rc in enumerate((Rs.RC_T_S1, Rs.RC_T_S2, Rs.RC_T_S3, Rs.RC_T_S4, Rs.RC_T_RAIL)):
        out[rc] = acc[A_STAGE + i]
    out[Rs.RC_MAX_PENETRATION] = acc[A_DMAX]


@kernel()
def finish(p, w, out):
    """The results of docs/model.md §11 from the run's accumulators."""
    acc, y = w.acc, w.y
    if acc[A_STATUS] != Rs.ST_OK:
        acc[A_OUTCOME] = Rs.FAILED
    if acc[A_EXITED] == 0.0 and acc[A_STATUS] == Rs.ST_OK:
        time_out(p[Lp.TMAX], w)
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
    out[Rs.RC_OVERLOAD], out[Rs.RC_SAFE] = overload_and_safe(nf, p[Lp.FFORCE])
    out[Rs.RC_DEFLECTION_MAX] = acc[A_QMAX + Q_DEFL]
    out[Rs.RC_DEFLECTION_OK] = deflection_ok(acc[A_QMAX + Q_DEFL], p[Lp.DAPERM])
    out[Rs.RC_RESIDUAL_DEFLECTION] = acc[A_RESID]
    out[Rs.RC_RESIDUAL_AMPLITUDE] = acc[A_RESID_AMP]
    out[Rs.RC_ALPHA_MAX] = acc[A_QMAX + Q_ALPHA]
    out[Rs.RC_DAMPER_ENERGY] = acc[A_E_DAMPER] if not math.isnan(acc[A_E_DAMPER]) else y[8]
    out[Rs.RC_CONTACT_ENERGY] = acc[A_E_CONTACT]
    contact_results(acc, out)
    out[Rs.RC_X_EXIT] = acc[A_X_EXIT]
    out[Rs.RC_PHI_EXIT] = acc[A_PHI_EXIT]
    out[Rs.RC_N_STEPS] = w.count[driver.C_STEPS]
    out[Rs.RC_N_REJECTED] = w.count[driver.C_REJECTS]
    out[Rs.RC_ERROR_ESTIMATE] = error_estimate(w.count[driver.C_ERR2])
    out[Rs.RC_STATUS] = acc[A_STATUS]
