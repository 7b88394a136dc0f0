"""The main job, whole command, with the first engine (v1, commit V1) and with this tree,
side by side in one run: `fencesweep grid sweeps/b2k2.yaml` on 2 jobs, warm Numba cache,
interleaved v1, v2, v1, v2, ... (--repeat times; medians of the wall time).

    python benchmarks/main_job_v1_v2.py [--repeat 3] [--jobs 2]   -> results/main_job_v1_v2.md

v1 runs from its tree exported by revisions.export, each run in a fresh process (the package
names are the same); the table each writes goes to a temporary folder. Run it alone on the
machine (it uses every core it is given).
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
from revisions import export  # benchmarks/revisions.py: a revision's tree, exported from git

ROOT = Path(__file__).resolve().parents[1]
V1 = "fbbc326"
SPEC = ROOT / "sweeps" / "b2k2.yaml"


def run(tree: Path, out: Path, jobs: int) -> float:
    cmd = [sys.executable, "-c", "import sys; from fencesweep.cli import main; sys.exit(main(sys.argv[1:]))",
           "grid", str(SPEC), "--out", str(out), "--jobs", str(jobs), "--no-resume", "--quiet"]
    if out.exists():
        out.unlink()
    t = time.perf_counter()
    subprocess.run(cmd, cwd=tree, env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"}, check=True,
                   capture_output=True)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"v1": export(V1), "v2": ROOT}
        outs = {k: Path(tmp) / f"{k}.parquet" for k in trees}
        for k in trees:  # warm the Numba caches (and the OS's)
            run(trees[k], outs[k], a.jobs)
        times = {k: [] for k in trees}
        for _ in range(a.repeat):
            for k in trees:
                times[k].append(run(trees[k], outs[k], a.jobs))
        n = len(pd.read_parquet(outs["v2"]))
        t1, t2 = pd.read_parquet(outs["v1"]), pd.read_parquet(outs["v2"])
        same = int((t1["outcome"].to_numpy() == t2["outcome"].to_numpy()).sum())
    med = {k: statistics.median(v) for k, v in times.items()}
    lines = [f"# The main job with the first engine ({V1}) and with this tree", "",
             f"Regenerate: `python benchmarks/main_job_v1_v2.py --repeat {a.repeat} --jobs {a.jobs}`. Whole "
             f"command `fencesweep grid sweeps/b2k2.yaml --jobs {a.jobs}`, warm cache, {a.repeat} interleaved "
             "runs each, medians of the wall time.", "",
             "| engine | wall s (runs) | cycles / s |", "|---|---|---|"]
    for k in trees:
        lines.append(f"| {k} | {med[k]:.2f} ({', '.join(f'{x:.2f}' for x in times[k])}) | {n / med[k]:.0f} |")
    lines += ["", f"v2 / v1 cycles per second: {med['v1'] / med['v2']:.2f}. {n} cycles; same outcome in "
              f"{same} of {n}."]
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "results" / "main_job_v1_v2.md").write_text(text)


if __name__ == "__main__":
    main()
