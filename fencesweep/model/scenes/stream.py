"""Scene `stream` (MODEL.md §14): work cycles back to back, one load each, the fence's
(alpha, alpha') carried from one cycle into the next; and the one kernel of both `cycle` and
`stream` (a cycle is a stream of one: `cycle_kernel`).

Cycle k runs in its own time tau = t - t_k, t_k = k T (T = `period`): the drive's
alpha_w(tau) of §2 (at rest for tau >= t_c) and the load's start of §1 are then exactly those
of a `cycle`, and every result time is measured from t_k, as §14 asks. Per cycle:

  begin_cycle  a new load at tau = 0 (cycle.start), the fence's state kept;
  cycle.run    the cycle's step loop (scenes/cycle.py) over its window: to max(t_exit, t_c),
               or to min(t_max, T) for a load without outcome (its own t_max is lowered to T
               for every cycle but the last, whose window is a `cycle`'s);
  end_cycle    the outcome `jammed` for a load still on the belt at T, the results of §11
               (cycle.finish) and the start_* results;
  rest         the fence alone, drive at rest, from the window's end to T (not the last cycle).

The trajectory's t is t_k + tau (the rows of cycle k are shifted after it, `shift_times`);
its energy columns restart at 0 with every cycle (they are the cycle's integrals).
"""
from __future__ import annotations

import math

import numpy as np
from fencesweep.kernel.jit import allocating, kernel

from fencesweep.kernel import integrate as I
from fencesweep.model import layout as Lp
from fencesweep.kernel import numerics as NU
from fencesweep.model import results as Rs
from fencesweep.model.scenes.contacts import N_SLOTS
from fencesweep.model.scenes.cycle import A_EXITED, A_QMAX, A_STATUS, A_T_EXIT, IW_EDGE, IW_MODE, IW_RIDE, N_ACC, N_AUX, N_IW, N_Q, N_STATE, apply_contact_change, classify, drop_load, fence_free_of_load, fence_state, finish, quantities_from_aux, record, rhs, run, start, swing_amplitude


@kernel(inline="always")
def load_row(p, row):
    """The entries of p that belong to the load (layout.LOAD_SLOTS) into one row of a loads table."""
    for i in range(Lp.N_LOAD):
        row[i] = p[Lp.LOAD_SLOTS[i]]


@kernel()
def cycle_params(p, load, period, last, pk):
    """pk: the parameters of one cycle of a stream, the scene's p with this cycle's load; every
    cycle but the last ends at the next one's start T at the latest (MODEL.md §14)."""
    for i in range(Lp.N_LOAD):
        pk[Lp.LOAD_SLOTS[i]] = load[i]
    pk[Lp.TMAX] = p[Lp.TMAX] if last else min(p[Lp.TMAX], period)


@kernel()
def begin_cycle(pk, y, iw, acc, atol, codes1, g0, r0, tags1, K, aux, qv, traj, row):
    """A new load at tau = 0 (MODEL.md §1) with the fence's (alpha, alpha') that y holds
    (0, 0 for the first cycle): the contacts it starts in, f(0, y), the tracked quantities'
    first values and the first trajectory row. Returns the row count."""
    al, dal = y[6], y[7]
    start(pk, y, iw, acc, atol)
    y[6] = al  # the fence carries over: nothing is reset (§14)
    y[7] = dal
    iw[IW_EDGE] = classify(0.0, y, pk, iw, codes1, g0, r0, tags1)
    apply_contact_change(0.0, y, pk, iw, codes1, iw[IW_EDGE], acc)
    iw[IW_RIDE] = 1 if fence_free_of_load(iw) else 0
    rhs(0.0, y, pk, iw, K[0], aux)
    quantities_from_aux(0.0, y, pk, iw, aux, qv[0])
    for k in range(N_Q):
        acc[A_QMAX + k] = qv[0, k]
    return record(traj, row, 0.0, y, pk, iw, aux)


@kernel()
def start_results(pk, y, iw, o):
    """MODEL.md §14: start_deflection dalpha(t_k), start_rate dalpha'(t_k), start_amplitude."""
    al, dal, aw, daw = fence_state(0.0, y, pk, iw[IW_MODE])
    o[Rs.RC_START_DEFLECTION] = al - aw
    o[Rs.RC_START_RATE] = dal - daw
    o[Rs.RC_START_AMPLITUDE] = swing_amplitude(al - aw, dal - daw, pk, iw[IW_MODE])


@kernel()
def end_cycle(pk, y, iw, acc, jam, o):
    """A load still on the belt when the window closed at T leaves as `jammed` (MODEL.md §14);
    then the results of §11 into o."""
    if jam and acc[A_EXITED] == 0.0 and acc[A_STATUS] == Rs.ST_OK:
        drop_load(pk[Lp.TMAX], y, pk, iw, acc, Rs.JAMMED)
    finish(pk, y, iw, acc, o)


@kernel()
def rest(pk, t, t_end, y, y1, tmp, K, aux, iw, atol, traj, row, o):
    """The fence alone (no load; the drive at rest after t_c) from t to t_end, stepped under
    the cycle's error control (MODEL.md §8: only the fence's linear ODE remains). Its steps are
    added to the cycle's n_steps and n_rejected. Returns the trajectory row count."""
    method = int(pk[Lp.METHOD])
    tol = pk[Lp.TOL]
    h = pk[Lp.DT] if method == I.METHOD_RK4 else 0.1 * pk[Lp.H_MAX]
    rhs(t, y, pk, iw, K[0], aux)
    while t < t_end - 1e-12 * max(1.0, t_end):
        if method == I.METHOD_RK4:
            h = pk[Lp.DT]
        h = min(h, pk[Lp.H_MAX], t_end - t)
        err = I.take_step(method, rhs, t, y, h, pk, iw, K, tmp, y1, aux, atol, tol, N_STATE)
        if not (err <= 1.0):
            h = I.next_step(h, err, NU.SAFETY, NU.FAC_MIN, 1.0) if err == err else NU.FAC_MIN * h
            o[Rs.RC_N_REJECTED] += 1.0
            continue
        o[Rs.RC_N_STEPS] += 1.0
        t = t_end if t + h >= t_end else t + h
        for i in range(N_STATE):
            y[i] = y1[i]
            K[0, i] = K[6, i]
        h = I.next_step(h, err, NU.SAFETY, NU.FAC_MIN, NU.FAC_MAX)
        row = record(traj, row, t, y, pk, iw, aux)
    return row


@kernel()
def shift_times(traj, first, stop, t_k):
    """Trajectory rows first .. stop - 1 (those that fit) from the cycle's time to the stream's."""
    for r in range(first, min(stop, traj.shape[0])):
        traj[r, 0] += t_k


@kernel()
def not_run(out, k):
    """Cycles k.. of a stream stopped by a failed cycle: outcome failed, the status says why."""
    for j in range(k, out.shape[0]):
        for i in range(out.shape[1]):
            out[j, i] = math.nan
        out[j, Rs.RC_OUTCOME] = Rs.FAILED
        out[j, Rs.RC_STATUS] = Rs.ST_NOT_RUN


@allocating()
def stream_kernel(p, loads, period, out, traj, row_starts):
    """Simulate len(loads) work cycles starting every `period` [s] (MODEL.md §14), load k's
    parameters in loads[k] (layout.LOAD_SLOTS); write row k of out (STREAM_CYCLE_RESULTS) and
    the time series into traj (rows of TRAJ_COLUMNS, as many as fit), the first row of cycle
    k into row_starts[k] (row_starts[n]: the count). Returns the number of rows produced."""
    n = N_STATE
    y = np.zeros(n)  # the fence starts at rest
    y1 = np.empty(n)
    tmp = np.empty(n)
    dy = np.empty(n)
    K = np.empty((I.N_STAGES, n))
    Q = np.zeros((8, n))  # Q[:4]: the step's dense output; Q[4:]: a step to a release (cycle.release_state)
    qok = np.zeros(1, np.int64)  # Q[:4] holds the current step's dense output (cycle.ensure_dense)
    aux = np.zeros(N_AUX)
    auxs = np.zeros(N_AUX)  # the peak search's own: aux keeps f(t1, y1)'s forces
    iw = np.zeros(N_IW, np.int64)
    codes1 = np.zeros(N_SLOTS, np.int64)
    tags1 = np.zeros(N_SLOTS, np.int64)
    g0 = np.empty(N_SLOTS)
    r0 = np.empty(N_SLOTS)
    g1 = np.empty(N_SLOTS)
    r1 = np.empty(N_SLOTS)
    qv = np.zeros((6, N_Q))  # q0, q1, qa, qb, scratch, where the step's maxima lie (cycle.track_maxima)
    acc = np.empty(N_ACC)
    atol = np.empty(N_STATE)
    rising = np.ones(N_Q + 1)  # per quantity: rising at the step's start; last: judge it anew
    Ks = np.empty((I.N_STAGES, n))  # a step to a located peak
    ys = np.empty(n)
    pk = p.copy()
    n_cycles = loads.shape[0]
    row = 0
    for k in range(n_cycles):
        last = k == n_cycles - 1
        cycle_params(p, loads[k], period, last, pk)
        row_starts[k] = row
        row = begin_cycle(pk, y, iw, acc, atol, codes1, g0, r0, tags1, K, aux, qv, traj, row)
        start_results(pk, y, iw, out[k])
        for i in range(N_Q + 1):
            rising[i] = 1.0
        row = run(pk, y, y1, tmp, dy, K, Q, qok, aux, auxs, iw, codes1, tags1, g0, r0, g1, r1, qv, acc, atol, rising,
                  Ks, ys, traj, row)
        end_cycle(pk, y, iw, acc, not last and period <= p[Lp.TMAX], out[k])
        failed = acc[A_STATUS] != Rs.ST_OK
        if not (last or failed):
            row = rest(pk, max(pk[Lp.TC], acc[A_T_EXIT]), period, y, y1, tmp, K, aux, iw, atol, traj, row, out[k])
        shift_times(traj, row_starts[k], row, k * period)
        if failed:  # the state cannot be trusted: the stream stops here
            not_run(out, k + 1)
            for j in range(k + 1, n_cycles):
                row_starts[j] = row
            break
    row_starts[n_cycles] = row
    return row


@allocating()
def cycle_kernel(p, out, traj):
    """Simulate one work cycle (MODEL.md §8 `cycle`): a stream of one. Writes CYCLE_RESULTS
    into out and the time series into traj (rows of TRAJ_COLUMNS, as many as fit). Returns
    the number of rows the run produced."""
    loads = np.empty((1, Lp.N_LOAD))
    load_row(p, loads[0])
    res = np.empty((1, Rs.N_STREAM_CYCLE_RESULTS))
    row_starts = np.empty(2, np.int64)
    rows = stream_kernel(p, loads, p[Lp.TC], res, traj, row_starts)
    for i in range(Rs.N_CYCLE_RESULTS):
        out[i] = res[0, i]
    return rows
