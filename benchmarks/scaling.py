"""More cores, more cycles? A study's cycles per second at 1, 2, 4, ... jobs, and the time spent
outside the cycles.

    python benchmarks/scaling.py [--spec sweeps/envelope.yaml] [--jobs 1 2 4 ...] [--rounds 1]
                                                     -> prints, writes results/scaling.md

Each run is `fencesweep grid SPEC --jobs J` through the Python API (`run_grid`, the CLI's call),
in a fresh process with a warm Numba cache, writing to a temporary folder, with its verification
(as a user runs it). From the run's own record: wall seconds of the sweep, the compute phase
(`timings["compute"]`, the chunks on the workers), the rest ("outside": planning, loading the
kernels, the verification, the assembly, the tail), each phase, and the process's peak memory
(its own, not the workers'). Cycles per second: the spec's scenes / the sweep's seconds. The
speed-up is against the 2-job run (the bar: 16 jobs >= 6x of 2 jobs on a 16-core machine). Jobs
default to powers of two up to this machine's cores; rounds alternate the job counts. Run it
alone on the machine: every job count wants every core it asks for.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "scaling.md"

#: one run in a fresh process: the sweep's record (seconds, timings, scenes) and the peak memory
WORKER = r"""
import json, resource, sys
from fencesweep.study import api
spec, out, jobs = sys.argv[1], sys.argv[2], int(sys.argv[3])
run = api.run_grid(spec, out=out, jobs=jobs, overwrite=True, resume=False, progress=False)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # MiB (Linux: kB)
print(json.dumps({"seconds": run["seconds"], "timings": run["timings"], "scenes": run["scenes"],
                  "peak_mib": peak}))
"""


def default_jobs() -> list:
    cores = os.cpu_count() or 1
    jobs, j = [], 1
    while j <= cores:
        jobs.append(j)
        j *= 2
    return jobs if jobs[-1] == cores else jobs + [cores]


def one_run(spec: str, jobs: int, tmp: Path) -> dict:
    out = tmp / f"scaling_{jobs}.parquet"
    r = subprocess.run([sys.executable, "-c", WORKER, spec, str(out), str(jobs)], capture_output=True,
                       text=True, cwd=ROOT)
    if r.returncode != 0:
        raise SystemExit(f"jobs {jobs}: the run failed:\n{r.stderr[-2000:]}")
    rec = json.loads(r.stdout.strip().splitlines()[-1])
    rec["outside"] = rec["seconds"] - rec["timings"]["compute"]
    rec["cycles_per_s"] = rec["scenes"] / rec["seconds"]
    return rec


def page(spec: str, results: dict, rounds: int) -> str:
    base = results.get(2) or results[min(results)]
    base_cps = statistics.median(r["cycles_per_s"] for r in base)
    phases = ("load", "plan", "warm_up", "assemble", "tail")
    lines = [f"# More cores, more cycles: {Path(spec).name} at 1, 2, ... jobs", "",
             f"Regenerate: `python benchmarks/scaling.py --spec {spec} --jobs {' '.join(map(str, results))} "
             f"--rounds {rounds}` (what is measured: its docstring). This machine: {os.cpu_count()} cores. "
             f"{base[0]['scenes']:,} cycles a run; medians over the rounds; seconds of the sweep's own record.", "",
             "| jobs | seconds | compute | outside compute | cycles / s | vs 2 jobs | "
             + " | ".join(phases) + " | peak MiB (this process) |",
             "|---:|---:|---:|---:|---:|---:|" + "---:|" * len(phases) + "---:|"]
    for jobs, recs in results.items():
        def med(f, recs=recs):
            return statistics.median(f(r) for r in recs)

        cps = med(lambda r: r["cycles_per_s"])
        cells = [f"{med(lambda r, p=p: r['timings'].get(p, 0.0)):.2f}" for p in phases]
        lines.append(f"| {jobs} | {med(lambda r: r['seconds']):.1f} | {med(lambda r: r['timings']['compute']):.1f} | "
                     f"{med(lambda r: r['outside']):.1f} | {cps:,.0f} | {cps / base_cps:.2f} | "
                     + " | ".join(cells) + f" | {med(lambda r: r['peak_mib']):.0f} |")
    lines += ["", "Every run, in order: " + "; ".join(
        f"{j} jobs {r['seconds']:.1f} s ({r['outside']:.1f} s outside)" for j, recs in results.items() for r in recs)]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spec", default="sweeps/envelope.yaml")
    ap.add_argument("--jobs", type=int, nargs="+", default=None)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    jobs = args.jobs or default_jobs()
    results: dict = {j: [] for j in jobs}
    with tempfile.TemporaryDirectory(prefix="fencesweep-scaling-") as tmp:
        # the Numba cache warmed before timing: every run then loads the kernels, none compiles them
        subprocess.run([sys.executable, "-c", "import fencesweep; fencesweep.simulate(case='small_far')"],
                       check=True, cwd=ROOT, capture_output=True)
        for rnd in range(args.rounds):
            for j in jobs:
                rec = one_run(args.spec, j, Path(tmp))
                results[j].append(rec)
                print(f"round {rnd + 1}, {j} jobs: {rec['seconds']:.1f} s, {rec['outside']:.1f} s outside compute, "
                      f"{rec['cycles_per_s']:,.0f} cycles/s", flush=True)
    text = page(args.spec, results, args.rounds)
    args.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
