"""Convergence and cost of one cycle for the paper's named cases.

For small_far and long_near with the flexible, rigid and free drives: peak_force,
deflection_max and t_exit at the default step and 10x and 100x finer (step_factor 1, 0.1,
0.01), relative to the finest; steps taken; time per cycle cold (a fresh process that
compiles or loads the Numba cache) and warm (median of repeated calls, CPU time).

    python benchmarks/convergence.py            # prints and writes results/convergence.md
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import fencesweep  # noqa: E402

CASES = [(c, d) for c in ("small_far", "long_near") for d in ("flexible", "rigid", "free")]
FACTORS = (1.0, 0.1, 0.01)
KEYS = ("peak_force", "deflection_max", "t_exit")

COLD = """
import time, json, sys
t0 = time.perf_counter()
import fencesweep
t1 = time.perf_counter()
r = fencesweep.simulate(case=sys.argv[1], drive=sys.argv[2])
t2 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "first_call": t2 - t1}))
"""


def cold(case: str, drive: str) -> dict:
    out = subprocess.run([sys.executable, "-c", COLD, case, drive], capture_output=True, text=True,
                         cwd=ROOT, check=True)
    return json.loads(out.stdout)


def warm(case: str, drive: str, n: int = 30) -> float:
    fencesweep.simulate(case=case, drive=drive)
    ts = []
    for _ in range(n):
        t = time.process_time()
        fencesweep.simulate(case=case, drive=drive)
        ts.append(time.process_time() - t)
    return float(np.median(ts))


def rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b) if b != 0 else abs(a - b)


def main() -> None:
    lines = ["# Convergence and cost of one cycle", "",
             "Regenerate: `python benchmarks/convergence.py`. Relative differences to the finest step "
             "(step_factor 0.01); times are CPU seconds (warm: median of 30 calls; cold: a fresh "
             "process, first call, cache already on disk).", ""]
    lines += ["| case | drive | outcome | step_factor | steps | peak_force [N] | rel. | deflection_max [rad] | rel. | t_exit [s] | rel. |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    timing = []
    for case, drive in CASES:
        runs = {sf: fencesweep.simulate(case=case, drive=drive, step_factor=sf) for sf in FACTORS}
        ref = runs[FACTORS[-1]]
        for sf, r in runs.items():
            lines.append(f"| {case} | {drive} | {r['outcome']} | {sf:g} | {r['n_steps']} | "
                         + " | ".join(f"{r[k]:.6g} | {rel(r[k], ref[k]):.1e}" for k in KEYS) + " |")
        c = cold(case, drive)
        w = warm(case, drive)
        timing.append((case, drive, runs[1.0]["n_steps"], w, c["import"], c["first_call"]))
        print(lines[-3], lines[-2], lines[-1], sep="\n", flush=True)
    lines += ["", "| case | drive | steps | warm per cycle [ms] | cold: import [s] | cold: first call [s] |",
              "|---|---|---|---|---|---|"]
    for case, drive, steps, w, imp, first in timing:
        lines.append(f"| {case} | {drive} | {steps} | {w * 1e3:.3f} | {imp:.2f} | {first:.2f} |")
    text = "\n".join(lines) + "\n"
    print("\n".join(lines[-len(timing) - 2:]))
    (ROOT / "results").mkdir(exist_ok=True)
    (ROOT / "results" / "convergence.md").write_text(text)


if __name__ == "__main__":
    main()
