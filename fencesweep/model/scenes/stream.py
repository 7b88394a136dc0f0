"""Scene `stream` (docs/model.md §14): work cycles back to back, one load each, the fence's
(alpha, alpha') carried from one cycle into the next; and the one entry point of both `cycle`
and `stream` (a cycle is a stream of one: `run_cycles` with one load).

Cycle k runs in its own time tau = t - t_k, t_k = k T (T = `period`): the drive's
alpha_w(tau) of §2 (at rest for tau >= t_c) and the load's start of §1 are then exactly those
of a `cycle`, and every result time is measured from t_k, as §14 asks. Per cycle:

  begin_cycle  a new load at tau = 0 (cycle/books.start), the fence's state kept;
  cycle.run    the cycle's loop (scenes/cycle/run.py) over its window: to max(t_exit, t_c),
               or to min(t_max, T) for a load without outcome (its own t_max is lowered to T
               for every cycle but the last, whose window is a `cycle`'s);
  end_cycle    the outcome `jammed` for a load still on the belt at T, the results of §11
               (cycle/books.finish) and the start_* results;
  rest         the fence alone, drive at rest, from the window's end to T (not the last cycle).

The trajectory's t is t_k + tau (the rows of cycle k are shifted after it, `shift_times`);
its energy columns restart at 0 with every cycle (they are the cycle's integrals).
"""
from __future__ import annotations

import math

import numpy as np

from fencesweep.kernel import driver
from fencesweep.kernel import numerics as NU
from fencesweep.kernel import rk
from fencesweep.kernel.driver import N_COUNT
from fencesweep.kernel.jit import HEAP, bind, entry, kernel
from fencesweep.kernel.rk import N_STAGES
from fencesweep.kernel.trig import forget_angle
from fencesweep.model import layout as Lp
from fencesweep.model import results as Rs
from fencesweep.model.scenes.contacts import N_SLOTS
from fencesweep.model.scenes.cycle.books import (apply_contact_change, drop_load, finish, record, start,
                                                 swing_amplitude, sync_touch, time_out)
from fencesweep.model.scenes.cycle.layout import (A_EXITED, A_QMAX, A_STATUS, A_T_EXIT, AX_TRIG_AL, AX_TRIG_PHI, IW_EDGE, IW_MODE, IW_RIDE,
                                                  N_ACC, N_AUX_ALL, N_DENSE, N_IW, N_Q, N_QV, N_RISING, N_STATE, N_TRAJ,
                                                  Q_NF, QV_0, Work)
from fencesweep.model.scenes.cycle.peaks import quantities_from_aux
from fencesweep.model.scenes.cycle.rhs import deflection, fence_state, forget_drive, rhs, step
from fencesweep.model.scenes.cycle.run import run, set_tolerance
from fencesweep.model.scenes.cycle.slots import classify, in_contact


@kernel()
def cycle_params(p, load, period, last, pk):
    """pk: the parameters of one cycle of a stream, the scene's p with this cycle's load; every
    cycle but the last ends at the next one's start T at the latest: its window closes at
    min(t_max, T) (docs/model.md (14.2))."""
    for i in range(Lp.N_LOAD):
        pk[Lp.LOAD_SLOTS[i]] = load[i]
    pk[Lp.TMAX] = p[Lp.TMAX] if last else min(p[Lp.TMAX], period)


@kernel()
def begin_cycle(p, w):
    """A new load at tau = 0 (docs/model.md §1) with the fence's (alpha, alpha') that w.y holds
    (0, 0 for the first cycle; carried over, docs/model.md (14.3): books.start): the contacts it
    starts in, f(0, y), the tracked quantities' first values and the first trajectory row."""
    start(p, w)
    for a in (w.aux, w.auxs):  # each cycle's sines, cosines and drive its own (kernel/trig.py, rhs.drive_once)
        forget_angle(a, AX_TRIG_AL)
        forget_angle(a, AX_TRIG_PHI)
        forget_drive(a)
    w.iw[IW_EDGE] = classify(0.0, w.y, p, w.iw, w.codes1, w.g0, w.r0, w.tags1)
    apply_contact_change(0.0, w.y, p, w.iw, w.codes1, w.iw[IW_EDGE], w.acc)
    w.iw[IW_RIDE] = 0 if in_contact(w.iw) else 1
    rhs(0.0, w.y, p, w.iw, w.K[0], w.aux)
    quantities_from_aux(0.0, w.y, p, w.iw, w.aux, w.qv[QV_0])
    sync_touch(0.0, w.qv[QV_0, Q_NF], p, w.acc)
    for k in range(N_Q):
        w.acc[A_QMAX + k] = w.qv[QV_0, k]
    for i in range(N_Q + 1):
        w.rising[i] = 1.0
    set_tolerance(p, w, 0.0)
    w.row[0] = record(w.traj, w.row[0], 0.0, w.y, p, w.iw, w.aux)


@kernel()
def start_results(p, w, o):
    """docs/model.md (14.4): start_deflection dalpha(t_k), start_rate dalpha'(t_k), start_amplitude."""
    al, dal, aw, daw = fence_state(0.0, w.y, p, w.iw[IW_MODE])
    dev, rate = deflection(al, dal, aw, daw)
    o[Rs.RC_START_DEFLECTION] = dev
    o[Rs.RC_START_RATE] = rate
    o[Rs.RC_START_AMPLITUDE] = swing_amplitude(dev, rate, p, w.iw[IW_MODE])


@kernel()
def end_cycle(p, w, jam, o):
    """A load still on the belt when the window closed at T leaves as `jammed` (docs/model.md §14);
    then the results of §11 into o."""
    if jam and w.acc[A_EXITED] == 0.0 and w.acc[A_STATUS] == Rs.ST_OK:
        drop_load(p[Lp.TMAX], w.y, w.iw, w.acc, Rs.JAMMED)
    finish(p, w, o)


@kernel()
def rest_accept(p, w, t, h, t1, err, h_next):
    """The driver's hook while the fence is alone: the state moves on, FSAL, a trajectory row."""
    for i in range(N_STATE):
        w.y[i] = w.y1[i]
        w.K[0, i] = w.K[6, i]
    w.row[0] = record(w.traj, w.row[0], t1, w.y, p, w.iw, w.aux)
    return t1, h_next, False


#: the driver's loop with the cycle's step while the fence is alone (kernel/driver.py)
rest_loop = driver.integrator(step, rest_accept, "cycle_rest_loop")


@kernel()
def rest(p, w, t, t_end, o):
    """The fence alone (no load; the drive at rest after t_c) from t to t_end, stepped under
    the cycle's error control (docs/model.md §8: only the fence's linear ODE remains). Its steps are
    added to the cycle's n_steps and n_rejected; a rest that cannot be stepped fails the cycle."""
    method = int(p[Lp.METHOD])
    ctl = (method, p[Lp.H_MAX], p[Lp.DT], NU.H_MIN)
    h = p[Lp.DT] if method == rk.METHOD_RK4 else 0.1 * p[Lp.H_MAX]
    steps = w.count[driver.C_STEPS]
    rejects = w.count[driver.C_REJECTS]
    rhs(t, w.y, p, w.iw, w.K[0], w.aux)
    t, h, why = rest_loop(ctl, p, w, t, t_end, t_end, h)
    o[Rs.RC_N_STEPS] += w.count[driver.C_STEPS] - steps
    o[Rs.RC_N_REJECTED] += w.count[driver.C_REJECTS] - rejects
    if why == driver.STOP_MAX_STEPS or why == driver.STOP_UNDERFLOW:
        o[Rs.RC_OUTCOME] = Rs.FAILED
        o[Rs.RC_STATUS] = Rs.ST_MAXSTEPS if why == driver.STOP_MAX_STEPS else Rs.ST_UNDERFLOW
        return False
    return True


@kernel()
def shift_times(traj, first, stop, k, period):
    """Trajectory rows first .. stop - 1 (those that fit) of cycle k from the cycle's time tau to
    the stream's t = t_k + tau, t_k = k T (docs/model.md (14.1)); every kernel of the cycle runs
    on tau."""
    t_k = k * period
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


@kernel()
def cycle_in_stream(p, w, loads, period, k, out, row_starts):
    """Cycle k of the stream (module docstring): its window, its results in out[k], the rest
    up to the next start. Returns whether the stream goes on."""
    n_cycles = loads.shape[0]
    last = k == n_cycles - 1
    pk = w.pk
    cycle_params(p, loads[k], period, last, pk)
    row_starts[k] = w.row[0]
    begin_cycle(pk, w)
    start_results(pk, w, out[k])
    run(pk, w)
    end_cycle(pk, w, not last and period <= p[Lp.TMAX], out[k])
    ok = w.acc[A_STATUS] == Rs.ST_OK
    if ok and not last:
        ok = rest(pk, w, max(pk[Lp.TC], w.acc[A_T_EXIT]), period, out[k])
    shift_times(w.traj, row_starts[k], w.row[0], k, period)
    return ok


@kernel(inline=True)
def fill_rows(a, value):
    """Every entry of the 2-D array a set to value."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            a[i, j] = value


@kernel()
def clear_work(p, w):
    """A run's work arrays at their start: counts, flags, state and tracked quantities 0, every
    quantity to be judged rising (peaks.track_maxima), pk a copy of p; the rest is written
    before it is read."""
    for a in (w.y, w.aux, w.auxs, w.count):
        for i in range(a.shape[0]):
            a[i] = 0.0
    for b in (w.qok, w.iw, w.codes1, w.tags1, w.row):
        for i in range(b.shape[0]):
            b[i] = 0
    fill_rows(w.Q, 0.0)
    fill_rows(w.qv, 0.0)
    for i in range(w.rising.shape[0]):
        w.rising[i] = 1.0
    for i in range(w.pk.shape[0]):
        w.pk[i] = p[i]


@kernel()
def cycles(p, w, loads, period, out, row_starts):
    """The cycles of run_cycles (its docstring) on the work arrays w (clear_work)."""
    n_cycles = loads.shape[0]
    for k in range(n_cycles):
        if not cycle_in_stream(p, w, loads, period, k, out, row_starts):
            not_run(out, k + 1)
            for j in range(k + 1, n_cycles):
                row_starts[j] = w.row[0]
            break
    row_starts[n_cycles] = w.row[0]
    return w.row[0]


#: where `cycles_with_work` allocates a run's work arrays, MEM.local.array(shape, dtype): jit.HEAP's
#: (np.empty) on the CPU (run_on_heap), numba.cuda's (the thread's local memory) in a GPU thread
#: (model/scenes/gpu.py); the shapes are compile-time constants, as cuda.local.array needs
MEM = None
F8, I8 = np.float64, np.int64


def cycles_with_work(p, loads, period, out, traj, row_starts, pk):
    """run_cycles (its docstring) with the work arrays (layout.Work) allocated here in MEM (a
    template: the one list of the work arrays' shapes, for both targets) and pk, the cycle's
    parameters, given (a copy of p's length)."""
    f, i = F8, I8
    w = Work(MEM.local.array(N_STATE, f), MEM.local.array(N_STATE, f), MEM.local.array(N_STATE, f),
             MEM.local.array(N_STATE, f), MEM.local.array((N_STAGES, N_STATE), f),
             MEM.local.array((N_DENSE, N_STATE), f), MEM.local.array(1, i), MEM.local.array(N_AUX_ALL, f),
             MEM.local.array(N_AUX_ALL, f), MEM.local.array(N_IW, i), MEM.local.array(N_SLOTS, i),
             MEM.local.array(N_SLOTS, i), MEM.local.array(N_SLOTS, f), MEM.local.array(N_SLOTS, f),
             MEM.local.array(N_SLOTS, f), MEM.local.array(N_SLOTS, f), MEM.local.array((N_QV, N_Q), f),
             MEM.local.array(N_ACC, f), MEM.local.array(N_STATE, f), MEM.local.array(N_STATE, f),
             MEM.local.array(1, f), MEM.local.array(N_RISING, f), MEM.local.array((N_STAGES, N_STATE), f),
             MEM.local.array(N_STATE, f), MEM.local.array(N_COUNT, f), traj, MEM.local.array(1, i), pk)
    clear_work(p, w)
    return cycles(p, w, loads, period, out, row_starts)


#: `cycles_with_work` on the CPU: its work arrays on the heap (kernel/jit.py: a kernel function that allocates)
run_on_heap = kernel(allocates=True)(bind(cycles_with_work, "run_on_heap", MEM=HEAP))


def compile_plan():
    """run_cycles' compile plan (kernel/share.py Plan: a first run compiles on two cores): the
    entry point and its large kernel functions, each with example arguments of the types
    run_cycles is called with and calls them with, the kernel functions split between the two
    processes from both ends (this process from the front: those the step loop calls; the
    helper from the back: the rest and the work arrays), and the preparation of a run's
    parameters (model/prepare.py), which the helper does after its kernel functions. A
    function renamed or an argument retyped here only costs time; tests/test_jit.py checks
    that each is what a run compiles."""
    from fencesweep.kernel.share import Plan
    from fencesweep.model.prepare import prepare
    from fencesweep.model.scenes.cycle import events, peaks
    from fencesweep.model.scenes.cycle import run as cycle

    p = np.zeros(Lp.N_P)
    traj = np.empty((0, N_TRAJ))
    t = 0.0
    loads, out = np.zeros((1, Lp.N_LOAD)), np.zeros((1, Rs.N_STREAM_CYCLE_RESULTS))
    starts = np.zeros(2, np.int64)
    # the work arrays as cycles_with_work allocates them: its own code, in Python, returning them
    w = bind(cycles_with_work, "work_arrays", MEM=HEAP, clear_work=lambda p, w: None,
             cycles=lambda p, w, *rest: w)(p, loads, t, out, traj, starts, p.copy())
    o = out[0]  # a cycle's row of results, as cycle_in_stream passes it
    entry = (run_cycles, (p, loads, t, out, traj, starts))
    kernels = [(rhs, (t, w.y, p, w.iw, w.K[0], w.aux)), (begin_cycle, (p, w)), (events.find_event, (p, w, t, t, False)),
               (events.event_state, (p, w, t, t, t, 0)), (peaks.track_maxima, (p, w, t, t, t)),
               (cycle.move_on, (p, w, t, 0, 0, t)), (cycle.check_state, (p, w)), (end_cycle, (p, w, False, o)),
               (rest, (p, w, t, t, o)), (start_results, (p, w, o)), (peaks.record_peaks, (p, w, t, t, t)),
               (time_out, (t, w)), (cycle_params, (p, loads[0], t, False, p)), (shift_times, (traj, 0, 0, 0, t)),
               (not_run, (out, 0))]
    return Plan(entry, kernels, prepare)


@entry()
def run_cycles(p, loads, period, out, traj, row_starts):
    """Simulate len(loads) work cycles starting every `period` [s] (docs/model.md §14; one cycle:
    the scene `cycle`), load k's parameters in loads[k] (layout.LOAD_SLOTS); write row k of out
    (STREAM_CYCLE_RESULTS) and the time series into traj (rows of TRAJ_COLUMNS, as many as
    fit), the first row of cycle k into row_starts[k] (row_starts[n]: the count). Returns the
    number of rows produced. Its work arrays are allocated once, by run_on_heap (pk uninitialised:
    clear_work copies p into it)."""
    return run_on_heap(p, loads, period, out, traj, row_starts, np.empty_like(p))
