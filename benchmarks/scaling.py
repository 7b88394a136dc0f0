"""More cores, more cycles? A study's cycles per second at 1, 2, 4, ... jobs, the time spent outside the
cycles and the whole command's time.

    python benchmarks/scaling.py [--spec sweeps/envelope.yaml] [--jobs 1 2 4 ...] [--rounds 1]
                                 [--out results/scaling.md]  -> prints, writes --out

Each run is `fencesweep grid SPEC --jobs J` through `run_grid` (the CLI's call), with its verification,
in a fresh process with a warm Numba cache, writing to a temporary folder. From the run's own record:
the sweep's wall seconds, its compute phase (the chunks on the workers), the rest ("outside": planning,
loading the kernels, the verification, the assembly, the tail), each phase (`runs`: the workers' seconds
in chunks, summed) and the process's peak memory (not the workers'); and the whole command's wall time,
imports included. Cycles per second: the scenes over the sweep's seconds, against the 2-job run (the
bar: 16 jobs >= 6x of 2 jobs on a 16-core machine); the command against its 1-job run. Jobs default to
powers of two up to this machine's cores; run it alone on the machine. Another revision's numbers:
`asv continuous REV HEAD` (benchmarks/README.md).
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import ROOT, run_json

OUT = ROOT / "results" / "scaling.md"

#: one run in a fresh process: the sweep's record (seconds, timings, scenes) and the peak memory
WORKER = r"""
import json, resource, sys
import fencesweep
from fencesweep.study import api
spec, out, jobs = sys.argv[1], sys.argv[2], int(sys.argv[3])
run = api.run_grid(spec, out=out, jobs=jobs, overwrite=True, resume=False, progress=False)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # MiB (Linux: kB)
print(json.dumps({"seconds": run["seconds"], "timings": run["timings"], "scenes": run["scenes"],
                  "peak_mib": peak}))
"""
WARM = "import fencesweep; fencesweep.simulate(case='small_far'); fencesweep.simulate(scene='impact')"
PHASES = ("load", "plan", "warm_up", "verify", "assemble", "tail", "runs")


def default_jobs() -> list:
    cores = os.cpu_count() or 1
    jobs, j = [], 1
    while j <= cores:
        jobs.append(j)
        j *= 2
    return jobs if jobs[-1] == cores else jobs + [cores]


def one_run(spec: str, jobs: int, tmp: Path) -> dict:
    t0 = time.perf_counter()
    rec = run_json(WORKER, ROOT / spec, tmp / f"scaling_{jobs}.parquet", jobs, cwd=tmp)
    rec["command"] = time.perf_counter() - t0
    rec["outside"] = rec["seconds"] - rec["timings"]["compute"]
    rec["cycles_per_s"] = rec["scenes"] / rec["seconds"]
    return rec


def _rows(results: dict) -> list:
    def med(recs, f):
        return statistics.median(f(r) for r in recs)

    base = results.get(2) or results[min(results)]
    base_cps = med(base, lambda r: r["cycles_per_s"])
    one = med(results[min(results)], lambda r: r["command"])
    lines = []
    for jobs, recs in results.items():
        cps = med(recs, lambda r: r["cycles_per_s"])
        cells = [f"{med(recs, lambda r, p=p: r['timings'].get(p, 0.0)):.2f}" for p in PHASES]
        lines.append(f"| {jobs} | {med(recs, lambda r: r['command']):.2f} | "
                     f"{one / med(recs, lambda r: r['command']):.2f} | {med(recs, lambda r: r['seconds']):.2f} | "
                     f"{med(recs, lambda r: r['timings']['compute']):.2f} | {med(recs, lambda r: r['outside']):.2f} | "
                     f"{cps:,.0f} | {cps / base_cps:.2f} | " + " | ".join(cells)
                     + f" | {med(recs, lambda r: r['peak_mib']):.0f} |")
    return lines


def page(spec: str, results: dict, jobs: list, rounds: int) -> str:
    scenes = next(iter(results.values()))[0]["scenes"]
    lines = [f"# More cores, more cycles: {Path(spec).name} at {', '.join(map(str, jobs))} jobs", "",
             f"Regenerate: `python benchmarks/scaling.py --spec {spec} --jobs {' '.join(map(str, jobs))} "
             f"--rounds {rounds}` (what is measured: its docstring). This machine: {os.cpu_count()} cores. "
             f"{scenes:,} cycles a run; medians over {rounds} round{'s' if rounds > 1 else ''}; seconds of the "
             "sweep's own record, and the command's wall time.", "",
             "| jobs | command s | command vs 1 job | sweep s | compute | outside compute | cycles / s | "
             "vs 2 jobs | " + " | ".join(PHASES) + " | peak MiB (this process) |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|" + "---:|" * len(PHASES) + "---:|"]
    lines += _rows(results)
    lines += ["", "Every run: " + "; ".join(f"{j} jobs {r['command']:.2f} s ({r['outside']:.2f} s outside compute)"
                                            for j, recs in results.items() for r in recs)]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="sweeps/envelope.yaml")
    ap.add_argument("--jobs", type=int, nargs="+", default=None)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    jobs = args.jobs or default_jobs()
    results = {j: [] for j in jobs}
    with tempfile.TemporaryDirectory(prefix="fencesweep-scaling-") as tmp:
        # the Numba cache warmed: every timed run loads, none compiles
        subprocess.run([sys.executable, "-c", WARM], check=True, cwd=tmp, capture_output=True)
        for rnd in range(args.rounds):
            for j in jobs:
                rec = one_run(args.spec, j, Path(tmp))
                results[j].append(rec)
                print(f"round {rnd + 1}, {j} jobs: command {rec['command']:.2f} s, sweep "
                      f"{rec['seconds']:.2f} s, {rec['outside']:.2f} s outside compute, "
                      f"{rec['cycles_per_s']:,.0f} cycles/s", flush=True)
    text = page(args.spec, results, jobs, args.rounds)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
