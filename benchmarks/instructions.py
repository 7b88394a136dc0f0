"""The warm cycle kernel's instructions, a revision beside this tree: callgrind counts instructions,
not seconds, so the machine's noise (timed rounds of one revision vary by up to 2x on a shared
2-core machine) does not enter; asv (benchmarks/README.md) cannot hold such counts.

    python benchmarks/instructions.py REV [--passes 2] [--out FILE]   -> prints, writes --out (markdown)

Each tree (REV exported from git by `git archive` into a temporary folder, and this working tree) gets a
Numba cache of its own, warmed first. Then, under `valgrind --tool=callgrind` with collection
switched on only around the measured loop (callgrind_control), one process per tree runs the
main job's fixed sample of 60 scenes (the seed of benchmarks/asv_bench main_job_sample) through the
kernel's entry point, `run_cycles`, on parameter vectors its own `prepare` made: `passes`
passes, and once more with one pass less; the difference over 60 is one cycle's instructions
(the switching itself cancels). The trees run side by side, one per core.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from common import ROOT, export, sample_runs
#: one tree: the sample's parameter vectors, then `n` passes of run_cycles with collection on
WORKER = sample_runs() + r"""
import subprocess
n = int(sys.argv[1])
subprocess.run(["callgrind_control", "-i", "on", str(os.getpid())], capture_output=True)
for _ in range(n):
    for a in args:
        run_cycles(*a)
subprocess.run(["callgrind_control", "-i", "off", str(os.getpid())], capture_output=True)
"""


def _start(tree: Path, cache: Path, passes: int, out: Path) -> subprocess.Popen:
    env = {"NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(tree), "PYTHONHASHSEED": "0", "PATH": "/usr/bin:/bin"}
    cmd = ["valgrind", "--tool=callgrind", "--instr-atstart=no", f"--callgrind-out-file={out}", sys.executable,
           "-c", WORKER, str(passes)]
    return subprocess.Popen(cmd, env=env, cwd=tree, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _collected(proc: subprocess.Popen) -> int:
    _, err = proc.communicate()
    m = re.search(r"Collected : (\d+)", err)
    if proc.returncode or not m:
        raise SystemExit(f"callgrind failed:\n{err[-3000:]}")
    return int(m.group(1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev")
    ap.add_argument("--passes", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    counts = {}
    with tempfile.TemporaryDirectory() as tmp:
        trees = {a.rev: export(a.rev, Path(tmp) / "rev"), "this tree": ROOT}
        caches = {name: Path(tmp) / f"cache{k}" for k, name in enumerate(trees)}
        for name, tree in trees.items():  # warm each tree's cache
            subprocess.run([sys.executable, "-c", WORKER.replace("callgrind_control", "true"), "0"], check=True,
                           env={"NUMBA_CACHE_DIR": str(caches[name]), "PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"},
                           cwd=tree, capture_output=True)
        for passes in (a.passes - 1, a.passes):
            procs = {name: _start(tree, caches[name], passes, Path(tmp) / f"{k}.out")
                     for k, (name, tree) in enumerate(trees.items())}
            for name, proc in procs.items():
                counts[(name, passes)] = _collected(proc)
    lines = ["| tree | instructions, " + f"{a.passes - 1} and {a.passes} passes | one cycle | against {a.rev} |",
             "|---|---:|---:|---:|"]
    base = None
    for name in trees:
        per = (counts[(name, a.passes)] - counts[(name, a.passes - 1)]) / 60
        base = base or per
        lines.append(f"| {name} | {counts[(name, a.passes - 1)]:,}, {counts[(name, a.passes)]:,} | {per:,.0f} | "
                     f"{(per / base - 1) * 100:+.2f} % |")
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out is not None:
        a.out.write_text(text)


if __name__ == "__main__":
    main()
