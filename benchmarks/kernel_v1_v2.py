"""Kernel time per cycle, the first engine (v1, fixed-step RK4, commit fbbc326) against the
present one, side by side in one run on the same machine.

    python benchmarks/kernel_v1_v2.py      -> prints a table, writes results/kernel_v1_v2.md

v1 is exported from git into a temporary folder and run in a subprocess (its package has
the same name); both time the compiled kernel warm (CPU time, median of 5 repeats of 50 runs).
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
V1 = "fbbc326"
CODE = r"""
import json, sys, time, statistics
import numpy as np
import fencesweep
from fencesweep.params import resolve
from fencesweep.setup import prepare
from fencesweep.scenes.cycle import cycle_kernel, TRAJ_COLUMNS
from fencesweep.results import N_CYCLE_RESULTS, unpack
out = np.empty(N_CYCLE_RESULTS); traj = np.empty((0, len(TRAJ_COLUMNS)))
rows = []
for case in ("small_far", "long_near"):
    for drive in ("flexible", "rigid"):
        p = prepare(resolve("cycle", case, drive=drive))
        cycle_kernel(p, out, traj)
        ts = []
        for _ in range(5):
            t = time.process_time()
            for _ in range(50):
                cycle_kernel(p, out, traj)
            ts.append((time.process_time() - t) / 50)
        r = unpack("cycle", out)
        rows.append({"case": case, "drive": drive, "ms": statistics.median(ts) * 1e3,
                     "steps": r["n_steps"], "peak_force": r["peak_force"]})
print(json.dumps(rows))
"""


def run(where: Path) -> list[dict]:
    res = subprocess.run([sys.executable, "-c", CODE], cwd=where, capture_output=True, text=True,
                         env={"PYTHONPATH": str(where), "PATH": "/usr/bin:/bin"}, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        arch = subprocess.run(["git", "archive", V1, "fencesweep"], cwd=ROOT, capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", tmp], input=arch.stdout, check=True)
        old = run(Path(tmp))
    new = run(ROOT)
    lines = ["# Kernel time per cycle: v1 (RK4, " + V1 + ") against v2 (this tree)", "",
             "Regenerate: `python benchmarks/kernel_v1_v2.py`. CPU time of the compiled kernel, warm, "
             "median of 5 x 50 runs, both in one run on the same machine.", "",
             "| case | drive | v1 ms | v1 steps | v2 ms | v2 steps | v1 / v2 | peak_force v1 | peak_force v2 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for a, b in zip(old, new):
        lines.append(f"| {a['case']} | {a['drive']} | {a['ms']:.3f} | {a['steps']} | {b['ms']:.3f} | {b['steps']} | "
                     f"{a['ms'] / b['ms']:.2f} | {a['peak_force']:.2f} | {b['peak_force']:.2f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "results" / "kernel_v1_v2.md").write_text(text)


if __name__ == "__main__":
    main()
