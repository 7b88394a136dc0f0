"""Kernel time per cycle, the first engine (v1, fixed-step RK4, commit fbbc326) against the
present one, side by side in one run on the same machine.

    python benchmarks/kernel_v1_v2.py      -> prints a table, writes results/kernel_v1_v2.md

v1 is exported from git (benchmarks/revisions.py) and run in a subprocess (its package has
the same name); both time the compiled kernel warm (CPU time, median of 5 repeats of 50 runs)
on the named cases (flexible and rigid drive), and on a fixed sample of the main job's scenes
(SAMPLE scenes of sweeps/b2k2.yaml drawn with a fixed seed; median of 5 repeats of 10 runs
each): the kernel time per cycle over a fixed sample of the main job's scenes. The machine's
noise (+-10% between runs) is larger than many effects, so v1 and v2 alternate for ROUNDS
rounds, each a fresh process; the table gives each run's median over the rounds and the
ratio of every round beside it.

    python benchmarks/kernel_v1_v2.py --rounds 1   -> one round (quicker, noisier)

In the same rounds the present kernel also runs the sample at LOOSER_TOLS, so that the page
shows how the kernel's time moves with the tolerance (and tolerance_scan.py what those
tolerances do to the validation set).
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # this tree's package, for numerics (step_factor, looser_table)

from revisions import export  # noqa: E402  (benchmarks/revisions.py: a revision's tree, exported from git)

V1 = "fbbc326"
CODE = r"""
import json, os, sys, time, statistics
import numpy as np
import fencesweep
# the layout is read from the package's own files, not from a failed import: an editable install
# of another checkout would otherwise supply the missing fencesweep.model to the flat package
if os.path.isdir(os.path.join(os.path.dirname(fencesweep.__file__), "model")):
    # the layered package: one compiled entry, run_cycles, for a cycle (a stream of one) and a stream
    from fencesweep.model.params import resolve
    from fencesweep.model.prepare import prepare
    from fencesweep.model import layout as Lp
    from fencesweep.model.scenes.cycle.layout import N_TRAJ
    from fencesweep.model.scenes.stream import run_cycles
    from fencesweep.model.results import N_CYCLE_RESULTS, N_STREAM_CYCLE_RESULTS, unpack
    out = np.empty((1, N_STREAM_CYCLE_RESULTS)); traj = np.empty((0, N_TRAJ)); starts = np.empty(2, np.int64)
    def kernel(p):
        loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :]); period = float(p[Lp.TC])
        return lambda: run_cycles(p, loads, period, out, traj, starts)
    def results():
        return unpack("cycle", out[0, :N_CYCLE_RESULTS])
else:  # the flat package of v1 (fbbc326): cycle_kernel(p, out, traj)
    from fencesweep.params import resolve
    from fencesweep.setup import prepare
    from fencesweep.scenes.cycle import TRAJ_COLUMNS, cycle_kernel
    from fencesweep.results import N_CYCLE_RESULTS, unpack
    out = np.empty(N_CYCLE_RESULTS); traj = np.empty((0, len(TRAJ_COLUMNS)))
    def kernel(p):
        return lambda: cycle_kernel(p, out, traj)
    def results():
        return unpack("cycle", out)
def timed(p, n):
    run = kernel(p)
    run()
    ts = []
    for _ in range(5):
        t = time.process_time()
        for _ in range(n):
            run()
        ts.append((time.process_time() - t) / n)
    return statistics.median(ts) * 1e3, results()
rows = []
for case in ("small_far", "long_near"):
    for drive in ("flexible", "rigid"):
        ms, r = timed(prepare(resolve("cycle", case, drive=drive)), 50)
        rows.append({"case": case, "drive": drive, "ms": ms, "steps": r["n_steps"], "peak_force": r["peak_force"]})
def sample_at(**kw):
    out_ = []
    for case, b2, k2 in json.loads(sys.argv[1]):
        ms, r = timed(prepare(resolve("cycle", case, B2=b2, K2=k2, **kw)), 10)
        out_.append({"ms": ms, "steps": r["n_steps"], "peak_force": r["peak_force"], "outcome": r["outcome"]})
    return out_
looser = {str(sf): sample_at(step_factor=sf) for sf in json.loads(sys.argv[2])}
print(json.dumps({"named": rows, "sample": sample_at(), "looser": looser}))
"""


#: scenes of the main job in the fixed sample, and the seed that draws them from its grid
SAMPLE, SEED = 60, 20261123
ROUNDS = 3
#: looser tolerances at which the present kernel also runs the sample (numerics.TOL x
#: step_factor^5), to show what the kernel bar would cost in accuracy; tolerance_scan.py
#: runs the validation set at the same tolerances
LOOSER_TOLS = (2e-6, 4e-6, 1e-5)


def b2k2_sample() -> list[tuple[str, float, float]]:
    """SAMPLE (case, B2, K2) of sweeps/b2k2.yaml's grid (81 x 81 x 2), drawn without replacement."""
    import numpy as np
    b2, k2 = np.linspace(0, 200, 81), np.linspace(100, 2100, 81)
    idx = np.random.default_rng(SEED).choice(81 * 81 * 2, SAMPLE, replace=False)
    return [(("small_far", "long_near")[i // 6561], float(b2[i % 6561 // 81]), float(k2[i % 81])) for i in idx]


def step_factor(tol: float) -> float:
    """The step_factor that gives tolerance tol (numerics.py: TOL x step_factor^TOL_EXPONENT)."""
    from fencesweep.kernel import numerics

    return (tol / numerics.TOL) ** (1.0 / numerics.TOL_EXPONENT)


def run(where: Path, step_factors: tuple = ()) -> dict:
    """One round in a fresh process of the package at `where`: the named cases, the sample, and
    the sample again at each of step_factors."""
    res = subprocess.run([sys.executable, "-c", CODE, json.dumps(b2k2_sample()), json.dumps(list(step_factors))],
                         cwd=where, capture_output=True, text=True,
                         env={"PYTHONPATH": str(where), "PATH": "/usr/bin:/bin"}, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def _median_run(runs: list[dict]) -> dict:
    """Per scene and named case, the run whose time is the median over the rounds."""
    import statistics

    def pick(rows):
        ms = statistics.median(r["ms"] for r in rows)
        return dict(min(rows, key=lambda r: abs(r["ms"] - ms)), ms=ms)
    out = {key: [pick(rows) for rows in zip(*(r[key] for r in runs))] for key in ("named", "sample")}
    out["looser"] = {sf: [pick(rows) for rows in zip(*(r["looser"][sf] for r in runs))] for sf in runs[0]["looser"]}
    return out


def looser_table(old: dict, new: dict, sfs: tuple) -> list[str]:
    """The sample at the default and the looser tolerances: mean time and steps, and v1's
    time over it (v1 at its own default, from the same rounds)."""
    from fencesweep.kernel import numerics

    t_old = sum(r["ms"] for r in old["sample"]) / len(old["sample"])
    lines = ["", "The present kernel on the same sample at looser tolerances (the same rounds; v1 at its default). "
             "What each tolerance does to the validation set: `results/tolerance_scan.md`.", "",
             "| tolerance | step_factor | mean ms per cycle | mean steps | v1 / this |", "|---|---|---|---|---|"]
    for tol, sf, rows in [(numerics.TOL, 1.0, new["sample"])] + [
            (tol, sf, new["looser"][str(sf)]) for tol, sf in zip(LOOSER_TOLS, sfs)]:
        ms = sum(r["ms"] for r in rows) / len(rows)
        steps = sum(r["steps"] for r in rows) / len(rows)
        lines.append(f"| {tol:g} | {sf:.3f} | {ms:.3f} | {steps:.1f} | {t_old / ms:.2f} |")
    return lines


def main() -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=ROUNDS, help=f"v1, v2 alternations (default {ROUNDS})")
    rounds = ap.parse_args().rounds
    olds, news = [], []
    sfs = tuple(round(step_factor(tol), 6) for tol in LOOSER_TOLS)
    v1 = export(V1)
    for _ in range(rounds):
        olds.append(run(v1))
        news.append(run(ROOT, sfs))
    ratios = [sum(r["ms"] for r in o["sample"]) / sum(r["ms"] for r in n["sample"]) for o, n in zip(olds, news)]
    old, new = _median_run(olds), _median_run(news)
    lines = ["# Kernel time per cycle: v1 (RK4, " + V1 + ") against v2 (this tree)", "",
             "Regenerate: `python benchmarks/kernel_v1_v2.py`. CPU time of the compiled kernel, warm, "
             f"median of 5 x 50 runs, both in one run on the same machine: {rounds} rounds of v1 then v2 "
             "(fresh processes), each time the median over the rounds.", "",
             "| case | drive | v1 ms | v1 steps | v2 ms | v2 steps | v1 / v2 | peak_force v1 | peak_force v2 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for a, b in zip(old["named"], new["named"]):
        lines.append(f"| {a['case']} | {a['drive']} | {a['ms']:.3f} | {a['steps']} | {b['ms']:.3f} | {b['steps']} | "
                     f"{a['ms'] / b['ms']:.2f} | {a['peak_force']:.2f} | {b['peak_force']:.2f} |")
    o, n = old["sample"], new["sample"]
    t_old, t_new = sum(r["ms"] for r in o), sum(r["ms"] for r in n)
    same = sum(a["outcome"] == b["outcome"] for a, b in zip(o, n))
    dpk = max(abs(a["peak_force"] - b["peak_force"]) / max(abs(a["peak_force"]), 1.0) for a, b in zip(o, n))
    lines += ["", f"Fixed sample of the main job: {SAMPLE} scenes of sweeps/b2k2.yaml (seed {SEED}).", "",
              "| kernel | mean ms per cycle | mean steps | |", "|---|---|---|---|",
              f"| v1 | {t_old / len(o):.3f} | {sum(r['steps'] for r in o) / len(o):.0f} | |",
              f"| v2 | {t_new / len(n):.3f} | {sum(r['steps'] for r in n) / len(n):.0f} | v1 / v2 = {t_old / t_new:.2f} |",
              "", "v1 / v2 on the sample, round by round: " + ", ".join(f"{r:.2f}" for r in ratios) + ".",
              "", f"Same outcome in {same} of {len(o)}; largest peak_force difference v1 - v2 {dpk:.1e} (relative)."]
    lines += looser_table(old, new, sfs)
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "results" / "kernel_v1_v2.md").write_text(text)


if __name__ == "__main__":
    main()
