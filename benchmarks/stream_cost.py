"""Does a stream of n cycles cost n cycles? A stream's cost per cycle against the cycle scene (docs/model.md §14).

    python benchmarks/stream_cost.py      -> prints a table, writes results/stream_cost.md

Both scenes run the one compiled kernel (scenes/stream.py run_cycles; a cycle is a stream of one). Warm
CPU time, the median of REPEATS repeats, a row's two measurements interleaved: the two named cases as
`cycle` runs (RUNS each), and a stream of N_CYCLES cycles of alternating small_far / long_near loads
(RUNS / N_CYCLES times) at T = t_c and at T = 2 t_c (the fence then rests alone for t_c after each cycle:
the stream's extra steps). Per cycle: the stream's time over N_CYCLES against the two cycles' mean; and
the steps (accepted + rejected) of each: a stream's later cycles start with the fence moving, which
changes their contacts' steps, and its rest adds steps.
"""
from __future__ import annotations

import statistics
import sys
import time

import numpy as np
from common import ROOT

sys.path.insert(0, str(ROOT))  # this tree's package
N_CYCLES = 20
RUNS = 200
REPEATS = 7
ELEMENTS = {"72/570 (paper)": dict(B2=72.0, K2=570.0), "15/2075 (maps' recommendation)": dict(B2=15.0, K2=2075.0),
            "rigid": dict(drive="rigid")}


def _kernels(params: dict, ratio: float):
    """The two named cases as `cycle` runs and the stream, each a call of the one compiled entry
    run_cycles (a cycle is a stream of one, as model/simulate.py runs it); and their result rows."""
    from fencesweep import resolve
    from fencesweep.model import layout as Lp
    from fencesweep.model.prepare import load_table, prepare
    from fencesweep.model.results import N_STREAM_CYCLE_RESULTS
    from fencesweep.model.scenes.cycle.layout import N_TRAJ
    from fencesweep.model.scenes.stream import run_cycles

    traj = np.empty((0, N_TRAJ))
    one_starts = np.empty(2, np.int64)
    cycles, outs = [], []
    for case in ("small_far", "long_near"):
        p = prepare(resolve("cycle", case, **params))
        one = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
        outs.append(np.empty((1, N_STREAM_CYCLE_RESULTS)))
        cycles.append(lambda p=p, one=one, tc=float(p[Lp.TC]), out=outs[-1]: run_cycles(p, one, tc, out, traj,
                                                                                         one_starts))
    vals = resolve("stream", loads=["small_far", "long_near"] * (N_CYCLES // 2), **params)
    period = ratio * vals["t_c"]
    vals = resolve("stream", loads=["small_far", "long_near"] * (N_CYCLES // 2), period=period, **params)
    p, loads = prepare(vals), load_table(vals)
    out = np.empty((N_CYCLES, N_STREAM_CYCLE_RESULTS))
    starts = np.empty(N_CYCLES + 1, np.int64)
    return cycles, (lambda: run_cycles(p, loads, period, out, traj, starts)), out, outs


def _time(fn, n: int) -> float:
    t = time.process_time()
    for _ in range(n):
        fn()
    return (time.process_time() - t) / n


def measure(params: dict, ratio: float) -> dict:
    from fencesweep.model.results import RI

    cycles, stream, out, outs = _kernels(params, ratio)
    for f in cycles + [stream]:
        f()  # compile / load
    c_ms, s_ms = [], []
    for _ in range(REPEATS):  # interleaved: a load on the machine hits both alike
        c_ms.append(0.5 * sum(_time(f, RUNS) for f in cycles) * 1e3)
        s_ms.append(_time(stream, RUNS // N_CYCLES) * 1e3)
    steps = out[:, RI["n_steps"]].sum() + out[:, RI["n_rejected"]].sum()
    c_steps = 0.5 * sum(o[0, RI["n_steps"]] + o[0, RI["n_rejected"]] for o in outs)
    return {"cycle_ms": statistics.median(c_ms), "stream_ms": statistics.median(s_ms), "steps_per_cycle": steps / N_CYCLES,
            "cycle_steps": c_steps}


def main() -> None:
    import fencesweep

    rows = []
    for name, params in ELEMENTS.items():
        for ratio in (1.0, 2.0):
            m = measure(params, ratio)
            per = m["stream_ms"] / N_CYCLES
            rows.append(f"| {name} | {ratio:g} t_c | {m['cycle_ms']:.3f} | {m['stream_ms']:.2f} | {per:.3f} | "
                        f"{per / m['cycle_ms']:.2f} | {m['cycle_steps']:.0f} | {m['steps_per_cycle']:.0f} |")
            print(rows[-1], flush=True)
    head = ["# Cost of a stream per cycle (benchmarks/stream_cost.py)", "",
            f"fencesweep {fencesweep.__version__}, {sys.platform}; warm CPU time, median of {REPEATS} interleaved "
            f"repeats; cycle: mean of small_far and long_near, {RUNS} runs each; stream: {N_CYCLES} cycles of "
            f"alternating small_far / long_near, {RUNS // N_CYCLES} runs; t_c = 1.36 s, v = 2 m/s. Steps per "
            f"cycle: accepted + rejected, the stream's rest to the next start included.", "",
            "| element | period T | cycle [ms] | stream of 20 [ms] | stream per cycle [ms] | per cycle / cycle | "
            "cycle: steps | stream: steps per cycle |",
            "|---|---|---|---|---|---|---|---|"]
    text = "\n".join(head + rows) + "\n"
    (ROOT / "results" / "stream_cost.md").write_text(text)
    print("wrote results/stream_cost.md")


if __name__ == "__main__":
    main()
