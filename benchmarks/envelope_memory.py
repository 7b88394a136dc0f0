"""Peak memory and time of an envelope study against its size.

Runs `fencesweep grid` on sweeps/envelope.yaml with its B2 x K2 grid cut to n x n elements
(n = 11, 21, 41, 81; always the same 64 loads), each in a fresh process, and samples the
memory of the whole process tree (the sweep and its workers) with psutil every 0.2 s:
the peak of the summed RSS (shared pages of the forked workers counted in each: an upper
bound) and of the summed USS (pages private to each process). The largest run is the
canonical study itself and writes results/envelope.parquet and results/envelope_points.parquet.
Writes results/envelope_memory.csv and .md. Run from the repository root, alone on the machine:

    python benchmarks/envelope_memory.py [--jobs N] [--sizes 11 21 41 81]
"""
from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parent.parent
SPEC = ROOT / "sweeps" / "envelope.yaml"


def tree_memory(proc: psutil.Process) -> tuple[int, int]:
    procs = [proc] + proc.children(recursive=True)
    rss = uss = 0
    for p in procs:
        try:
            info = p.memory_full_info()
        except psutil.Error:
            continue
        rss += info.rss
        uss += info.uss
    return rss, uss


def run(spec: Path, out: Path, jobs: int) -> dict:
    cmd = [sys.executable, "-m", "fencesweep", "grid", str(spec), "--out", str(out), "--jobs", str(jobs),
           "--quiet", "--no-resume", "--overwrite"]
    t0 = time.perf_counter()
    proc = psutil.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    peak_rss = peak_uss = 0
    while True:
        try:
            proc.wait(timeout=0.2)
            break
        except psutil.TimeoutExpired:
            rss, uss = tree_memory(proc)
            peak_rss, peak_uss = max(peak_rss, rss), max(peak_uss, uss)
    err = proc.stderr.read().decode()
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err}")
    return {"seconds": time.perf_counter() - t0, "peak_rss": peak_rss, "peak_uss": peak_uss}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=os.cpu_count())
    ap.add_argument("--sizes", type=int, nargs="+", default=[11, 21, 41, 81])
    ap.add_argument("--render", action="store_true", help="only rewrite the page from results/envelope_memory.csv")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT))
    from fencesweep.study.spec import file as specfile

    text = SPEC.read_text()
    n_loads = len(specfile.load(SPEC).envelope.loads)
    if args.render:
        render(n_loads, args.jobs)
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            t = re.sub(r"B2: \{linspace: \[0, 400, 81\]\}", f"B2: {{linspace: [0, 400, {n}]}}", text)
            t = re.sub(r"K2: \{linspace: \[100, 2100, 81\]\}", f"K2: {{linspace: [100, 2100, {n}]}}", t)
            canonical = t == text
            spec = SPEC.relative_to(ROOT) if canonical else Path(tmp) / f"envelope_{n}.yaml"  # run in ROOT
            if not canonical:
                spec.write_text(t)
            out = Path("results", "envelope.parquet") if canonical else Path(tmp) / f"envelope_{n}.parquet"
            r = run(spec, out, args.jobs)
            r.update(n=n, cycles=n * n * n_loads)
            rows.append(r)
            print(f"{n} x {n} x {n_loads} = {r['cycles']} cycles: {r['seconds']:.1f} s, "
                  f"peak RSS {r['peak_rss'] / 2**20:.0f} MiB, peak USS {r['peak_uss'] / 2**20:.0f} MiB", flush=True)
    import pandas as pd

    pd.DataFrame([{"n": r["n"], "cycles": r["cycles"], "seconds": round(r["seconds"], 1),
                   "peak_rss_mib": round(r["peak_rss"] / 2**20), "peak_uss_mib": round(r["peak_uss"] / 2**20)}
                  for r in rows]).to_csv(CSV, index=False)
    render(n_loads, args.jobs)


CSV = ROOT / "results" / "envelope_memory.csv"


def render(n_loads: int, jobs: int) -> None:
    """results/envelope_memory.md from the measurements in results/envelope_memory.csv."""
    import pandas as pd

    rows = pd.read_csv(CSV).to_dict("records")
    for r in rows:
        r["peak_rss"], r["peak_uss"] = r["peak_rss_mib"] * 2**20, r["peak_uss_mib"] * 2**20
    mib = 2 ** 20
    lines = ["# Envelope study: peak memory and time against size", "",
             "`python benchmarks/envelope_memory.py`: `fencesweep grid sweeps/envelope.yaml` with "
             f"its B2 x K2 grid cut to n x n elements, {n_loads} loads each, `--jobs {jobs}`, each run a fresh "
             "process (numba's cache warm); memory of the process tree sampled every 0.2 s with psutil. "
             "RSS sums each process's resident pages (the pages a forked worker shares with its parent counted in "
             "each: an upper bound); USS sums the pages private to each process. The sweep, the table's assembly and "
             "the per-design-point judgement (envelope.write_points, in batches of rows) each hold a bounded amount.",
             "", f"Machine: {platform.machine()}, {psutil.cpu_count()} logical CPUs, Python {platform.python_version()}.",
             "", "| elements | cycles | time [s] | cycles/s | peak RSS, tree [MiB] | peak USS, tree [MiB] |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['n']} x {r['n']} | {r['cycles']} | {r['seconds']:.1f} | {r['cycles'] / r['seconds']:.0f} | "
                     f"{r['peak_rss'] / mib:.0f} | {r['peak_uss'] / mib:.0f} |")
    small, prev, big = rows[0], rows[-2], rows[-1]
    lines += ["", f"From {small['cycles']} to {big['cycles']} cycles ({big['cycles'] / small['cycles']:.0f} x) the peak "
              f"RSS grows by {(big['peak_rss'] - small['peak_rss']) / mib:.0f} MiB ({big['peak_rss'] / small['peak_rss']:.2f} x) "
              f"and the peak USS by {(big['peak_uss'] - small['peak_uss']) / mib:.0f} MiB "
              f"({big['peak_uss'] / small['peak_uss']:.2f} x); over the last step, {prev['cycles']} to {big['cycles']} "
              f"cycles ({big['cycles'] / prev['cycles']:.1f} x), by {(big['peak_rss'] - prev['peak_rss']) / mib:.0f} MiB "
              f"(RSS) and {(big['peak_uss'] - prev['peak_uss']) / mib:.0f} MiB (USS): about "
              f"{(big['peak_uss'] - prev['peak_uss']) / (big['cycles'] - prev['cycles']):.0f} bytes per cycle, against the "
              f"{70e6 / 419904:.0f} bytes per cycle of the per-load table on disk. The small runs end before the "
              "workers have run long enough to reach their steady private memory, so the first step is larger."]
    (ROOT / "results" / "envelope_memory.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
