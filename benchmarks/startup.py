"""What a fresh process pays before its first result: this tree against an earlier revision,
interleaved in one run.

    python benchmarks/startup.py [--before REV] [--repeat 7]   -> prints, writes results/startup.md

Every sweep worker, every test process and every `fencesweep run` starts by importing the
package and loading the compiled kernels from Numba's cache; every command builds the CLI's
parser. Measured, each in a fresh interpreter with a warm cache (one untimed run of each tree
first, which compiles into that tree's cache):
  * first cycle: `from fencesweep import api; api.simulate()` (the imports, the kernel load and
    one long_near cycle), wall time of the process;
  * --help: `python -m fencesweep --help`, wall time of the process;
  * python alone: `python -c pass`, the interpreter's own start, for scale.
REV is exported with git archive into a temporary folder; both trees run with PYTHONPATH set to
their folder, alternately (before, after, before, ...); medians are reported.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from main_job_v1_v2 import export  # a revision's package, exported from git

ROOT = Path(__file__).resolve().parents[1]
FIRST_CYCLE = "from fencesweep import api; api.simulate()"
PROBES = {"python alone": ["-c", "pass"], "first cycle": ["-c", FIRST_CYCLE],
          "--help": ["-m", "fencesweep", "--help"]}


def wall(tree: Path, args: list) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], cwd=tree, env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"},
                   check=True, capture_output=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="ecc777a", help="the earlier revision (default ecc777a)")
    ap.add_argument("--repeat", type=int, default=7)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {a.before: export(a.before, Path(tmp) / a.before), "this tree": ROOT}
        for tree in trees.values():
            wall(tree, ["-c", FIRST_CYCLE])  # compile into (or check) this tree's cache
        times = {(name, probe): [] for name in trees for probe in PROBES}
        for _ in range(a.repeat):
            for probe, args in PROBES.items():
                for name, tree in trees.items():
                    times[name, probe].append(wall(tree, args))
    lines = ["# Start-up of a process: before and after, in one run", "",
             f"Regenerate: `python benchmarks/startup.py --before {a.before}` (what is measured: its docstring). "
             f"Wall time of a fresh process with a warm Numba cache, median of {a.repeat} runs, the two trees "
             "alternating.", "",
             f"| probe | {a.before} [s] | this tree [s] | saved [s] |", "|---|---|---|---|"]
    for probe in PROBES:
        b = statistics.median(times[a.before, probe])
        n = statistics.median(times["this tree", probe])
        lines.append(f"| {probe} | {b:.3f} | {n:.3f} | {b - n:.3f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "results" / "startup.md").write_text(text)


if __name__ == "__main__":
    main()
