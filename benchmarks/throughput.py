"""Throughput of the main job: cycles per second for sweeps/b2k2.yaml (issue 4).

Runs `fencesweep grid sweeps/b2k2.yaml --no-resume` in a fresh process on 1 and 2 jobs,
cold (Numba cache removed first, so the JIT compile is included) and warm (cache on disk),
and records wall time, cycles per second and the peak resident memory of the whole process
tree (sampled every 50 ms).

    python benchmarks/throughput.py [--spec sweeps/b2k2.yaml]

writes results/throughput.md and results/throughput.csv.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import psutil

ROOT = Path(__file__).resolve().parents[1]


def clear_cache() -> int:
    n = 0
    for pattern in ("*.nbi", "*.nbc"):
        for f in (ROOT / "fencesweep").rglob(pattern):
            f.unlink()
            n += 1
    return n


def run(spec: str, jobs: int, out: Path) -> dict:
    cmd = [sys.executable, "-m", "fencesweep.cli", "grid", spec, "--jobs", str(jobs), "--no-resume",
           "--out", str(out)]
    t0 = time.perf_counter()
    proc = psutil.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak = 0
    while proc.poll() is None:
        try:
            procs = [proc] + proc.children(recursive=True)
            peak = max(peak, sum(p.memory_info().rss for p in procs if p.is_running()))
        except psutil.Error:
            pass
        time.sleep(0.05)
    wall = time.perf_counter() - t0
    _, err = proc.communicate()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{err}")
    rows = len(pd.read_parquet(out, columns=["outcome"]))
    return {"jobs": jobs, "wall [s]": wall, "cycles": rows, "cycles/s": rows / wall, "peak RSS [MiB]": peak / 2**20}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", default="sweeps/b2k2.yaml")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for jobs in (1, 2):
            clear_cache()
            rows.append({"start": "cold", **run(args.spec, jobs, Path(tmp) / f"cold{jobs}.parquet")})
            print(rows[-1], flush=True)
            rows.append({"start": "warm", **run(args.spec, jobs, Path(tmp) / f"warm{jobs}.parquet")})
            print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    out = ROOT / "results"
    out.mkdir(exist_ok=True)
    df.to_csv(out / "throughput.csv", index=False)
    lines = ["# Throughput of the main job", "",
             f"Regenerate: `python benchmarks/throughput.py` (spec `{args.spec}`, the whole command "
             "`fencesweep grid` in a fresh process: start-up, planning, compile or cache load, the "
             "sweep, writing the table). Cold: the Numba cache removed first. Machine: "
             f"{psutil.cpu_count()} logical CPUs.", "",
             "| start | jobs | cycles | wall [s] | cycles/s | peak RSS [MiB] |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['start']} | {r['jobs']} | {r['cycles']} | {r['wall [s]']:.1f} | "
                     f"{r['cycles/s']:.0f} | {r['peak RSS [MiB]']:.0f} |")
    (out / "throughput.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
