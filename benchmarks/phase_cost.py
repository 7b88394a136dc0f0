"""Cost per phase of one work cycle: approach, contact, after the exit.

For the named cases (small_far, long_near; default element B2 = 72, K2 = 570, and the rigid
drive) the cycle is split at the first load-fence contact A (t_first_contact) and at the
outcome event (t_exit):

  approach : [0, A]         the load rides the belt towards the fence
  contact  : [A, t_exit]    first contact to the exit (gaps in the contact included)
  after    : [t_exit, end]  only the fence, to t_c (empty when the exit comes after t_c)

A step belongs to the phase in which it starts. Per phase:

* steps (accepted) from the trajectory of the compiled kernel (one row per step);
* step attempts and right-hand-side evaluations from a replay of the same cycle with the JIT
  off (NUMBA_DISABLE_JIT=1, in a subprocess), in which the kernel's `rhs` and the step of the
  cycle's loop (kernel/driver.py `integrate`, cycle/run.py's `loop`) are wrapped by counters.
  The replay must take the same accepted steps per phase as the compiled kernel (checked; a
  difference is printed and marked);
* time, measured directly: while the compiled kernel runs (warm), a second thread, in
  compiled code without the GIL on the other core, watches the trajectory buffer and reads
  the CPU's time-stamp counter the moment the rows that end the phases are written (row 0:
  the loop starts; the step ending at A; the step ending at t_exit; the last row). The
  median of --rounds runs; beside it the kernel's time per cycle without a trajectory, and
  the time that each phase would get if the kernel time were apportioned by steps.

    python benchmarks/phase_cost.py [--rounds 101]    prints the table (Markdown)

benchmarks/throughput.py calls :func:`phase_table` for results/throughput.md. Time it alone
on the machine (it uses both cores: the kernel on one, the watcher on the other).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CASES = [("small_far", "flexible"), ("small_far", "rigid"), ("long_near", "flexible"), ("long_near", "rigid")]
PHASES = ("approach", "contact", "after")

# ---------------------------------------------------------------- the replay with counters

#: run as `python -c REPLAY case drive` with NUMBA_DISABLE_JIT=1: per phase the step attempts
#: (accepted, rejected) of the main loop and the right-hand-side evaluations, each evaluation
#: charged to the step attempt it belongs to (the peak search's extra step and the evaluations
#: after an event included); printed as JSON
REPLAY = r"""
import json, sys
from fencesweep.kernel.jit import JIT_DISABLED
from fencesweep.model import params
from fencesweep.model.simulate import simulate_resolved
from fencesweep.model.scenes import stream
from fencesweep.model.scenes.cycle import peaks, rhs as rhs_module, run as run_module

calls = []              # per rhs call: the start time of the current step attempt of the loop
attempts = []           # per step attempt of the loop: (t, err)
cur = [0.0]
real_rhs, real_step = rhs_module.rhs, rhs_module.step

def rhs(t, *a):
    calls.append(cur[0])
    return real_rhs(t, *a)

def loop_step(method, t, *a):   # the step of the cycle's loop, not an event's or a peak's re-step
    cur[0] = t
    err = real_step(method, t, *a)
    attempts.append((t, err))
    return err

# With the JIT off every kernel function is its plain Python function. rhs is called by name from
# these modules, and as RHS from the step's own globals (kernel/jit.py specialise gives a template's
# copy a globals dict of its own); the cycle's loop (kernel/driver.py integrate, specialised) calls
# the step as STEP from its own globals, while events.py and peaks.py call the same step by name.
assert JIT_DISABLED, "the replay needs NUMBA_DISABLE_JIT=1"
assert real_step.__globals__["RHS"] is real_rhs and run_module.loop.__globals__["STEP"] is real_step
for module in (run_module, peaks, stream):
    assert module.rhs is real_rhs
    module.rhs = rhs
real_step.__globals__["RHS"] = rhs
run_module.loop.__globals__["STEP"] = loop_step
vals = params.resolve("cycle", sys.argv[1], drive=sys.argv[2])
res, _ = simulate_resolved(vals)
print(json.dumps({"t_first_contact": res["t_first_contact"], "t_exit": res["t_exit"], "n_steps": res["n_steps"],
                  "n_rejected": res["n_rejected"], "calls": calls, "attempts": attempts}))
"""


def phase_of(t: np.ndarray, t_a: float, t_e: float) -> np.ndarray:
    """0 approach, 1 contact, 2 after, for steps starting at t (no contact: no contact phase)."""
    t = np.asarray(t, float)
    out = np.where(t < t_e, 1, 2)
    if np.isfinite(t_a):
        out[t < t_a] = 0
    else:
        out[t < t_e] = 0
    return out


def replay_counts(case: str, drive: str) -> dict:
    env = dict(os.environ, NUMBA_DISABLE_JIT="1", PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", REPLAY, case, drive], env=env, cwd=ROOT, capture_output=True,
                       text=True, check=True)
    d = json.loads(r.stdout.strip().splitlines()[-1])
    t_a, t_e = d["t_first_contact"], d["t_exit"]
    t_a = float("nan") if t_a is None else t_a
    att = np.array(d["attempts"], float).reshape(-1, 2)
    ph_att = phase_of(att[:, 0], t_a, t_e)
    ok = att[:, 1] <= 1.0
    ph_calls = phase_of(np.array(d["calls"], float), t_a, t_e)
    return {"accepted": [int(np.sum(ok & (ph_att == k))) for k in range(3)],
            "rejected": [int(np.sum(~ok & (ph_att == k))) for k in range(3)],
            "rhs": [int(np.sum(ph_calls == k)) for k in range(3)],
            "n_steps": d["n_steps"], "n_rejected": d["n_rejected"]}


# ---------------------------------------------------------------- direct timing

#: a round counts only if the watcher ran throughout: no gap between two of its polls above this
MAX_POLL_GAP = 5e-6     # [s]


def _tsc_tools():
    """Compiled helpers: rdtsc(), and watch(...) run without the GIL by the watcher thread."""
    from llvmlite import ir
    from numba import njit, types
    from numba.core import cgutils
    from numba.extending import intrinsic

    @intrinsic
    def _rdtsc(typingctx):
        def codegen(context, builder, signature, args):
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.IntType(64), []),
                                                "llvm.readcyclecounter")
            return builder.call(fn, [])
        return types.int64(), codegen

    @intrinsic
    def _load_acquire(typingctx, arr, idx):
        """arr[idx] as an atomic acquire load: read anew from memory at every call (never hoisted)."""
        def codegen(context, builder, signature, args):
            ary = context.make_array(signature.args[0])(context, builder, value=args[0])
            ptr = cgutils.get_item_pointer(context, builder, signature.args[0], ary, [args[1]], wraparound=False)
            return builder.load_atomic(ptr, ordering="acquire", align=8)
        return arr.dtype(arr, types.intp), codegen

    @njit
    def rdtsc():
        return _rdtsc()

    @njit(nogil=True)
    def watch(col0, rows, stamps, ctl):
        """Spin on col0 (the kernel's trajectory column t): stamps[i] = TSC when col0[rows[i]]
        stops being NaN (the kernel wrote that row), in order. ctl[0] = 1 once watching;
        ctl[1] != 0: stop; on return ctl[2] = the longest gap between two polls [TSC ticks]."""
        ctl[0] = 1
        i = 0
        gap = 0
        last = _rdtsc()
        while i < rows.shape[0] and _load_acquire(ctl, 1) == 0:
            v = _load_acquire(col0, rows[i])
            now = _rdtsc()
            gap = max(gap, now - last)
            last = now
            if v == v:
                stamps[i] = now
                i += 1
        ctl[2] = gap

    return rdtsc, watch


def tsc_hz(rdtsc) -> float:
    """The time-stamp counter's rate, against perf_counter over 0.3 s."""
    rdtsc()
    c0, t0 = rdtsc(), time.perf_counter()
    time.sleep(0.3)
    c1, t1 = rdtsc(), time.perf_counter()
    return (c1 - c0) / (t1 - t0)


def phase_times(case: str, drive: str, rounds: int, tools, hz: float) -> dict:
    """Median seconds per phase (watched), the kernel without a trajectory, and the step split."""
    from fencesweep.model import layout as Lp
    from fencesweep.model import params
    from fencesweep.model.prepare import prepare
    from fencesweep.model.results import N_STREAM_CYCLE_RESULTS
    from fencesweep.model.scenes.cycle.layout import N_TRAJ
    from fencesweep.model.scenes.stream import run_cycles
    from fencesweep.model.simulate import simulate_resolved

    rdtsc, watch = tools
    vals = params.resolve("cycle", case, drive=drive)
    res, traj = simulate_resolved(vals, trajectory=True)
    t = traj["t"].to_numpy()
    t_a, t_e = res["t_first_contact"], res["t_exit"]
    # rows that end the phases: the row at A and the row at t_exit (steps start before them); the
    # trajectory has a row per step plus one at each maximum located inside a step
    k_e = int(np.searchsorted(t, t_e))
    k_a = int(np.searchsorted(t, t_a)) if np.isfinite(t_a) else k_e
    if len(t) - 1 < res["n_steps"] or abs(t[k_e] - t_e) > 1e-12 or abs(t[k_a] - min(t_a, t_e)) > 1e-12:
        raise RuntimeError(f"{case} {drive}: the trajectory has no row at A or t_exit, or fewer than one per step")
    rows = np.array([0, k_a, k_e, len(t) - 1], np.int64)
    p = prepare(vals)
    # the cycle as the kernel runs it: a stream of one (model/simulate.py _cycle)
    loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
    period = float(p[Lp.TC])
    out = np.empty((1, N_STREAM_CYCLE_RESULTS))
    starts = np.empty(2, np.int64)
    buf = np.empty((len(t) + 16, N_TRAJ))
    col0 = buf[:, 0]            # a view: the watcher reads the kernel's writes of column t
    none = np.empty((0, N_TRAJ))

    def cycle_kernel(traj):
        return run_cycles(p, loads, period, out, traj, starts)

    cycle_kernel(buf)
    cycle_kernel(none)   # warm
    watch(col0, rows[:0], np.zeros(1, np.int64), np.zeros(3, np.int64))   # compiled before the runs
    per_phase, total, bare = [], [], []
    tries = 0
    while len(per_phase) < rounds and tries < 20 * rounds:
        tries += 1
        buf[:, 0] = np.nan
        stamps = np.zeros(4, np.int64)
        ctl = np.zeros(3, np.int64)
        th = threading.Thread(target=watch, args=(col0, rows, stamps, ctl))
        th.start()
        while ctl[0] == 0:
            pass
        c0 = rdtsc()
        n = cycle_kernel(buf)
        c1 = rdtsc()
        ctl[1] = 1
        th.join()
        if n != len(t):
            raise RuntimeError(f"{case} {drive}: the watched run made {n} rows, the trajectory run {len(t)}")
        if (stamps == 0).any() or ctl[2] > MAX_POLL_GAP * hz:   # the watcher was descheduled: not counted
            continue
        per_phase.append(np.diff(stamps) / hz)
        total.append((c1 - c0) / hz)
        c0 = rdtsc()
        cycle_kernel(none)
        bare.append((rdtsc() - c0) / hz)
    if not per_phase:
        raise RuntimeError(f"{case} {drive}: the watcher never ran through a whole cycle (the other core busy?)")
    ph = np.median(np.array(per_phase), axis=0)
    return {"t_first_contact": t_a, "t_exit": t_e, "t_c": vals["t_c"],
            "phase_s": ph.tolist(), "traced_s": float(np.median(total)), "kernel_s": float(np.median(bare)),
            "outcome": res["outcome"], "n_steps": res["n_steps"], "n_rejected": res["n_rejected"],
            "rounds": len(per_phase), "tries": tries}


def measure(rounds: int = 101) -> list[dict]:
    tools = _tsc_tools()
    hz = tsc_hz(tools[0])
    out = []
    for case, drive in CASES:
        r = {"case": case, "drive": drive, **phase_times(case, drive, rounds, tools, hz),
             "counts": replay_counts(case, drive)}
        if sum(r["counts"]["accepted"]) != r["n_steps"]:
            raise RuntimeError(f"{case} {drive}: the replay took {sum(r['counts']['accepted'])} steps, "
                               f"the compiled kernel {r['n_steps']}")
        r["steps"] = r["counts"]["accepted"]
        out.append(r)
        print(f"phase cost: {case} {drive} done", flush=True)
    return out


def phase_table(rounds: int = 101) -> list[str]:
    """Markdown lines: the cost per phase of the named cases (see the module docstring)."""
    data = measure(rounds)
    lines = [
        "| case | drive | phase | interval [s] | steps | rejected | RHS evaluations | RHS per step | "
        "time [ms], watched | share of the cycle | µs per step | time [ms] if apportioned by steps |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    notes = []
    for r in data:
        c = r["counts"]
        bounds = [0.0, r["t_first_contact"], r["t_exit"], max(r["t_exit"], r["t_c"])]
        if not np.isfinite(bounds[1]):
            bounds[1] = bounds[2]
        watched = sum(r["phase_s"])
        n = sum(r["steps"])
        for k, name in enumerate(PHASES):
            acc = r["steps"][k]
            rhs = c["rhs"][k]
            per = f"{rhs / (acc + c['rejected'][k]):.1f}" if acc + c["rejected"][k] else "–"
            lines.append(
                f"| {r['case']} | {r['drive']} | {name} | {bounds[k]:.4g} – {bounds[k + 1]:.4g} | {acc} | "
                f"{c['rejected'][k]} | {rhs} | {per} | {r['phase_s'][k] * 1e3:.3f} | "
                f"{r['phase_s'][k] / watched:.0%} | {r['phase_s'][k] / acc * 1e6 if acc else float('nan'):.2f} | "
                f"{r['kernel_s'] * acc / n * 1e3:.3f} |")
        lines.append(
            f"| {r['case']} | {r['drive']} | **cycle** | outcome {r['outcome']} | {n} | {sum(c['rejected'])} | "
            f"{sum(c['rhs'])} | {sum(c['rhs']) / (n + sum(c['rejected'])):.1f} | {watched * 1e3:.3f} "
            f"(kernel alone {r['kernel_s'] * 1e3:.3f}) | 100% | {watched / n * 1e6:.2f} | {r['kernel_s'] * 1e3:.3f} |")
        if c["accepted"] != r["steps"]:
            notes.append(f"{r['case']} {r['drive']}: the plain-Python replay took {c['accepted']} accepted steps "
                         f"per phase, the compiled kernel {r['steps']}; its counts are those of the replay.")
    used = ", ".join(f"{r['case']} {r['drive']} {r['rounds']} of {r['tries']}" for r in data)
    text = [
        "Phases: *approach* from t = 0 to the first load–fence contact A (t_first_contact), *contact* from A to "
        "the outcome event (t_exit; losses of contact in between included), *after* from t_exit to the end of "
        "the cycle (max(t_exit, t_c): only the fence is stepped). A step belongs to the phase in which it starts. "
        "*steps*: accepted steps (their sum checked against the compiled kernel's n_steps), *rejected*, "
        "*RHS evaluations*: counted in a replay of the same cycle with the JIT off (NUMBA_DISABLE_JIT=1), the "
        "kernel's `rhs` and the step of the cycle's loop wrapped by counters; every evaluation is charged to the step "
        "attempt it belongs to (event handling and the peak search's extra step included; *RHS per step*: per "
        "attempt, rejected ones included). *time, watched*: measured directly, warm, the median over runs: a "
        "second thread, compiled and without the GIL on the other core, spins on the trajectory buffer and reads "
        "the time-stamp counter when the kernel writes the rows that end the phases (the loop's first row, the "
        "step ending at A, the one ending at t_exit, the last); a run counts only if that thread was never "
        f"descheduled (no gap over {MAX_POLL_GAP * 1e6:g} µs between two of its polls; runs counted of runs "
        f"made: {used}). The *cycle* row gives "
        "their sum and, beside it, the kernel's time per cycle without a trajectory (median of the same runs, "
        "interleaved: the watched phases leave out the set-up before the loop's first row and the results "
        "after its last, and the trajectory's writes and the watching add a little). *apportioned by steps*: the "
        "kernel's time shared out in proportion to the accepted steps, for comparison with the watched split. "
        "Regenerate alone: `python benchmarks/phase_cost.py`.", "", *lines]
    if notes:
        text += ["", *notes]
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=101, help="timed runs per case (median)")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT))
    print("\n".join(phase_table(args.rounds)))


if __name__ == "__main__":
    main()
