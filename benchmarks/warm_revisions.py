"""The warm cost of a cycle along the history: revisions side by side in one run.

    python benchmarks/warm_revisions.py [REV ...] [--rounds 4]   -> prints, writes results/warm_revisions.md

Each revision (default: REVISIONS, the flat package and the commits that changed the kernel
since, then this working tree) is exported from git (benchmarks/revisions.py) and given a Numba
cache of its own in a temporary folder, warmed first. Then, for `rounds` rounds, every revision in turn
runs in a fresh process: the 60 scenes of the main job's fixed sample (sweeps/b2k2.yaml, the seed
of benchmarks/edges.py) through the public call `fencesweep.simulate` (the same code in every
revision), six passes, and the process reports its fastest pass as CPU ms a cycle (the fastest
pass is the one least disturbed by the machine). The table gives each revision's fastest round
(the machine's noise only ever adds time: on this 2-core machine rounds of one revision vary by
up to 2x) and its median, and every round.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from revisions import export  # benchmarks/revisions.py: a revision's tree, exported from git

ROOT = Path(__file__).resolve().parents[1]
REVISIONS = {
    "72ef80b": "the flat package, before the sub-packages",
    "d727f56": "the package in sub-packages",
    "b0b1218": "one step driver, the cycle split by concept, one signature per kernel function",
    "77620a2": "generic functions as templates compiled once per scene",
    "b70ff0b": "before the tolerance scale near grazes and for free fences",
    "fc50e29": "tolerance scaled near grazes and for free fences",
}
WORKER = r"""
import time, numpy as np, fencesweep
b2, k2 = np.linspace(0, 200, 81), np.linspace(100, 2100, 81)
idx = np.random.default_rng(20261123).choice(81 * 81 * 2, 60, replace=False)
sample = [(("small_far", "long_near")[i // 6561], float(b2[i % 6561 // 81]), float(k2[i % 81])) for i in idx]
for c, b, k in sample:
    fencesweep.simulate("cycle", case=c, B2=b, K2=k)
best = float("inf")
for _ in range(6):
    t = time.process_time()
    for c, b, k in sample:
        fencesweep.simulate("cycle", case=c, B2=b, K2=k)
    best = min(best, (time.process_time() - t) / len(sample) * 1e3)
print(best)
"""


def run(tree: Path, cache: Path) -> float:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH"))}
    env.update(NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(tree))
    r = subprocess.run([sys.executable, "-c", WORKER], env=env, capture_output=True, text=True, cwd=tree)
    if r.returncode:
        raise SystemExit(f"{tree} failed:\n{r.stderr[-3000:]}")
    return float(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("revisions", nargs="*", default=list(REVISIONS))
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--out", default=str(ROOT / "results" / "warm_revisions.md"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {rev: export(rev) for rev in a.revisions}
        trees["this tree"] = ROOT
        caches = {n: Path(tmp) / f"cache-{i}" for i, n in enumerate(trees)}
        for n, t in trees.items():  # warm every cache (cold compiles, one at a time)
            run(t, caches[n])
            print(f"{n}: warm", flush=True)
        times = {n: [] for n in trees}
        for r in range(a.rounds):
            for n, t in trees.items():
                times[n].append(run(t, caches[n]))
            print(f"round {r + 1}: " + ", ".join(f"{n} {times[n][-1]:.4f}" for n in trees), flush=True)
    names = list(trees)
    base = min(times[names[0]])
    lines = ["# The warm cost of a cycle along the history", "",
             f"Regenerate: `python benchmarks/warm_revisions.py --rounds {a.rounds}` (what is measured: its "
             "docstring). CPU ms a cycle of `fencesweep.simulate` on the main job's fixed sample of 60 scenes, "
             "the fastest of six passes in a fresh process; the revisions alternate round by round.", "",
             f"| revision | what it changed | ms a cycle (fastest of {a.rounds} rounds) | against {names[0]} | "
             "median | rounds |", "|---|---|---:|---:|---:|---|"]
    for n in names:
        best, med = min(times[n]), statistics.median(times[n])
        what = REVISIONS.get(n, "the working tree" if n == "this tree" else "")
        lines.append(f"| {n} | {what} | {best:.4f} | {best / base - 1:+.1%} | "
                     f"{med:.4f} | " + ", ".join(f"{x:.4f}" for x in times[n]) + " |")
    text = "\n".join(lines) + "\n"
    print(text)
    Path(a.out).write_text(text)


if __name__ == "__main__":
    main()
