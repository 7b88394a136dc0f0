"""Throughput of the main job: cycles per second for sweeps/b2k2.yaml on 1 and 2 jobs.

Runs the whole command `fencesweep grid sweeps/b2k2.yaml --no-resume` in a fresh process on
1 and 2 jobs, side by side (1, 2, 1, 2, ... `--repeat` times; medians reported), with a warm
Numba cache, and once each cold (cache removed first, so the JIT compile is included). For
each run it records the wall time, cycles per second, the CPU seconds of the process tree,
its peak resident memory (sampled every 0.5 s), the CPU that *other* processes used on the
machine meanwhile (from /proc/stat; a run waits first until the machine is quiet), and
where the time went (`Outcome.timings` of fencesweep.study.sweep.pipeline.run_sweep: planning, kernel
load, compute with the workers' run and write seconds, assembly).

`--orchestration-of REV` also measures, in the same run and interleaved, the same package
with the orchestration files (ORCHESTRATION: study/, cli.py and errors.py of the layered
package) of git revision REV, a revision of the same layout: the same kernel, the sweep
machinery before and after. `--tree DIR` measures the package in DIR (a checkout or
an exported snapshot) instead of this checkout.

    python benchmarks/throughput.py [--spec sweeps/b2k2.yaml] [--repeat 3] [--orchestration-of REV] [--no-cold]
                                    [--phases-only | --no-phases]

writes results/throughput.md and results/throughput.csv. Run it alone on the machine.

The page ends with the cost per phase of a cycle (approach, contact, after the exit) of the
named cases, measured by benchmarks/phase_cost.py; `--phases-only` measures only that and
replaces that section of an existing results/throughput.md, `--no-phases` leaves it out.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import psutil
from revisions import export  # benchmarks/revisions.py: a revision's tree, exported from git

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_EVERY = 0.5  # seconds between memory samples
#: the orchestration files (the sweep machinery around the kernel) of each layout of the package; a
#: folder stands for every file in it
ORCHESTRATION = {"layered": ("fencesweep/study", "fencesweep/cli.py", "fencesweep/errors.py"),
                 "flat": ("fencesweep/sweep.py", "fencesweep/spec.py", "fencesweep/store.py", "fencesweep/cli.py",
                          "fencesweep/errors.py")}


def layout(files) -> str:
    """'layered' (sub-packages kernel/, model/, study/, ...) or 'flat' (fencesweep/sweep.py, ...), from the
    package's file paths relative to its checkout."""
    return "layered" if any(str(f).startswith("fencesweep/study/") for f in files) else "flat"

#: the CLI, run as `python -c DRIVER grid ...`: exactly `fencesweep grid ...`, plus the import
#: time and run_sweep's Outcome (seconds, timings) written as JSON to $FENCESWEEP_BENCH_OUT
DRIVER = """
import json, os, sys, time
t0 = time.perf_counter()
import fencesweep
if os.path.isdir(os.path.join(os.path.dirname(fencesweep.__file__), "study")):  # the layered package
    from fencesweep import cli
    from fencesweep.study.sweep import pipeline as sweep
else:  # the flat package of older revisions
    from fencesweep import cli, sweep
imports = time.perf_counter() - t0
real = sweep.run_sweep
def run_sweep(*a, **k):
    res = real(*a, **k)
    with open(os.environ["FENCESWEEP_BENCH_OUT"], "w") as f:
        json.dump({"imports": imports, "seconds": res.seconds, "timings": getattr(res, "timings", {})}, f)
    return res
sweep.run_sweep = run_sweep
sys.exit(cli.main(sys.argv[1:]))
"""


def clear_cache(tree: Path) -> int:
    """Remove the compiled kernels of the package in `tree`, so that its next run compiles them: the
    kernel cache directory of the layered package (kernel/cache.py DIR, under NUMBA_CACHE_DIR when
    that is set, else in the package's __pycache__; with its compiled-* markers, which would
    otherwise say the kernels are warm) and every Numba cache file inside the package. Returns the
    number of files removed."""
    n = 0
    env = dict(os.environ, PYTHONPATH=str(tree))
    where = subprocess.run([sys.executable, "-c", "from fencesweep.kernel import cache; print(cache.DIR)"],
                           cwd=tree, env=env, capture_output=True, text=True)
    if where.returncode == 0 and where.stdout.strip():  # (a flat package, or an early layered one: no DIR)
        cache_dir = Path(where.stdout.strip())
        if cache_dir.is_dir():
            n += sum(1 for f in cache_dir.rglob("*") if f.is_file())
            shutil.rmtree(cache_dir)
    for pattern in ("*.nbi", "*.nbc"):
        for f in (tree / "fencesweep").rglob(pattern):
            f.unlink()
            n += 1
    return n


def busy_jiffies() -> int:
    """CPU time (clock ticks) spent by everything on the machine so far."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    return sum(fields) - fields[3] - fields[4]  # all but idle and iowait


def wait_quiet(most: float = 60.0, below: float = 0.15) -> float:
    """Wait (at most `most` s) until other processes use under `below` cores; return that load."""
    tick = os.sysconf("SC_CLK_TCK")
    t_end = time.monotonic() + most
    while True:
        b0, t0 = busy_jiffies(), time.monotonic()
        time.sleep(1.0)
        load = (busy_jiffies() - b0) / tick / (time.monotonic() - t0)
        if load < below or time.monotonic() > t_end:
            return load


def run(tree: Path, spec: str, jobs: int, out: Path) -> dict:
    bench_out = out.with_suffix(".json")
    bench_out.unlink(missing_ok=True)
    cmd = [sys.executable, "-c", DRIVER, "grid", spec, "--jobs", str(jobs), "--no-resume", "--quiet",
           "--out", str(out)]
    env = dict(os.environ, FENCESWEEP_BENCH_OUT=str(bench_out), PYTHONPATH=str(tree))
    tick = os.sysconf("SC_CLK_TCK")
    log = out.with_suffix(".log")
    with open(log, "w") as sink:
        ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        b0 = busy_jiffies()
        t0 = time.perf_counter()
        proc = psutil.Popen(cmd, cwd=tree, env=env, stdout=sink, stderr=subprocess.STDOUT)
        peak = 0
        while True:  # the memory of the process tree, sampled twice a second (a sample costs ~1 ms of CPU)
            try:
                proc.wait(timeout=SAMPLE_EVERY)
                break
            except psutil.TimeoutExpired:
                pass
            try:
                procs = [proc] + proc.children(recursive=True)
                peak = max(peak, sum(p.memory_info().rss for p in procs if p.is_running()))
            except psutil.Error:
                pass
        wall = time.perf_counter() - t0
        busy = (busy_jiffies() - b0) / tick
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{log.read_text()}")
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    rows = len(pd.read_parquet(out, columns=["outcome"]))
    inner = json.loads(bench_out.read_text())
    row = {"jobs": jobs, "wall [s]": wall, "cycles": rows, "cycles/s": rows / wall, "CPU [s]": cpu,
           "others [cores]": max(0.0, busy - cpu) / wall, "peak RSS [MiB]": peak / 2**20,
           "imports": inner["imports"], "run_sweep": inner["seconds"],
           "start+exit": wall - inner["imports"] - inner["seconds"]}
    row.update(inner["timings"])
    return row


def with_orchestration_of(rev: str, tree: Path, where: Path) -> Path:
    """A copy of `tree` (its package and the spec) whose ORCHESTRATION files are those of git revision `rev`
    (both of one layout: the files of the other do not fit the package)."""
    src = export(rev)
    rev_files = sorted(p.relative_to(src).as_posix() for p in (src / "fencesweep").rglob("*")
                       if p.is_file() and "__pycache__" not in p.parts)
    kind = layout(p.relative_to(tree).as_posix() for p in (tree / "fencesweep").rglob("*.py"))
    if layout(rev_files) != kind:
        raise SystemExit(f"--orchestration-of {rev}: that revision's package is {layout(rev_files)}, the one "
                         f"measured ({tree}) {kind}; its orchestration files do not fit it")
    copy = where / f"orchestration-{rev}"
    shutil.copytree(tree / "fencesweep", copy / "fencesweep", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(tree / "sweeps", copy / "sweeps")
    for entry in ORCHESTRATION[kind]:
        if (copy / entry).is_dir():  # a folder: exactly the revision's files in it
            shutil.rmtree(copy / entry)
        names = [f for f in rev_files if f == entry or f.startswith(entry + "/")]
        if not names:  # not in that revision
            (copy / entry).unlink(missing_ok=True)
        for name in names:
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src / name, copy / name)
    return copy


def parse_args() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", default="sweeps/b2k2.yaml")
    ap.add_argument("--repeat", type=int, default=3, help="warm runs per tree and job count (median)")
    ap.add_argument("--orchestration-of", metavar="REV",
                    help="also measure this package with the orchestration files of git revision REV")
    ap.add_argument("--tree", metavar="DIR", type=Path, default=ROOT, help="the package to measure")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-cache runs")
    ap.add_argument("--phases-only", action="store_true",
                    help="only the cost per phase: replace that section of results/throughput.md")
    ap.add_argument("--no-phases", action="store_true", help="leave out the cost per phase")
    ap.add_argument("--phase-rounds", type=int, default=101, help="timed runs per case for the cost per phase")
    return ap.parse_args()


def main() -> None:
    args = parse_args()
    md = ROOT / "results" / "throughput.md"
    if args.phases_only:
        old = md.read_text().split(PHASE_HEADING)[0].rstrip("\n").split("\n") if md.exists() else []
        md.write_text("\n".join(old + phase_section(args)) + "\n")
        print(f"wrote the cost per phase into {md.relative_to(ROOT)}")
        return
    df, head = measure_all(args)
    out = ROOT / "results"
    out.mkdir(exist_ok=True)
    df.to_csv(out / "throughput.csv", index=False, float_format="%.4g")
    lines = write_md(df, args, head)
    if not args.no_phases:
        lines += phase_section(args)
    md.write_text("\n".join(lines) + "\n")
    print(f"wrote {md.relative_to(ROOT)}, results/throughput.csv")


def measure_all(args) -> tuple[pd.DataFrame, str]:
    """Every run of the throughput table (cold, then warm interleaved); (rows, HEAD's short hash)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tree = args.tree.resolve()
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True).stdout.strip()
        trees = {"this package": tree}
        if args.orchestration_of:
            rev = subprocess.run(["git", "rev-parse", "--short", args.orchestration_of], cwd=ROOT, check=True,
                                 capture_output=True, text=True).stdout.strip()
            trees[f"orchestration of {rev}"] = with_orchestration_of(rev, tree, Path(tmp))

        def measure(label, tree, start, jobs):
            load = wait_quiet()
            r = {"code": label, "start": start, "quiet before": load,
                 **run(tree, args.spec, jobs, Path(tmp) / f"out{jobs}.parquet")}
            rows.append(r)
            print({k: round(v, 3) if isinstance(v, float) else v for k, v in r.items()}, flush=True)

        for label, tree in trees.items():
            if not args.no_cold:
                for jobs in (1, 2):
                    clear_cache(tree)
                    measure(label, tree, "cold", jobs)
            else:  # compile once, unmeasured
                run(tree, args.spec, 1, Path(tmp) / "compile.parquet")
        for _ in range(args.repeat):
            for label, tree in trees.items():
                for jobs in (1, 2):
                    measure(label, tree, "warm", jobs)
    return pd.DataFrame(rows), head


PHASE_HEADING = "## Cost per phase of a cycle"


def phase_section(args) -> list[str]:
    """The cost per phase of the named cases (benchmarks/phase_cost.py), as Markdown lines."""
    sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]
    import phase_cost

    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "--", "fencesweep"], cwd=ROOT, capture_output=True,
                           text=True).stdout.strip()
    head += " with uncommitted changes to fencesweep/" if dirty else ""
    lines = ["", PHASE_HEADING, "",
             f"Measured at commit {head} (this checkout's package, in this process; "
             "`python benchmarks/throughput.py --phases-only` redoes this section alone).", ""]
    lines += phase_cost.phase_table(args.phase_rounds)
    print("\n".join(lines), flush=True)
    return lines


def write_md(df: pd.DataFrame, args, head: str) -> list[str]:
    def med(g, col):
        return statistics.median(g[col]) if col in g and g[col].notna().any() else float("nan")

    lines = ["# Throughput of the main job", "",
             f"Regenerate: `python benchmarks/throughput.py"
             f"{f' --orchestration-of {args.orchestration_of}' if args.orchestration_of else ''}` "
             f"(measured at commit {head}: *this package* is its `fencesweep`; spec `{args.spec}`; the whole "
             "command `fencesweep grid` in a fresh process: start-up, "
             "planning, kernel load, the sweep, writing the table). Cold: the Numba cache removed first "
             f"(one run). Warm: median of {args.repeat} runs, 1 and 2 jobs interleaved. Machine: "
             f"{psutil.cpu_count()} logical CPUs; *others*: cores used by other processes during the run "
             "(measured; each run waits for a quiet machine first).", "",
             "| code | start | jobs | cycles | wall [s] | cycles/s | 2 jobs / 1 job | CPU [s] | others [cores] "
             "| peak RSS [MiB] |", "|---|---|---|---|---|---|---|---|---|---|"]
    for (code, start), g in df.groupby(["code", "start"], sort=False):
        base = None
        for jobs, h in g.groupby("jobs"):
            wall = med(h, "wall [s]")
            base = wall if jobs == 1 else base
            speedup = f"{base / wall:.2f}x" if jobs != 1 and base else ""
            lines.append(f"| {code} | {start} | {jobs} | {int(h['cycles'].iloc[0])} | {wall:.2f} | "
                         f"{h['cycles'].iloc[0] / wall:.0f} | {speedup} | {med(h, 'CPU [s]'):.1f} | "
                         f"{med(h, 'others [cores]'):.2f} | {med(h, 'peak RSS [MiB]'):.0f} |")
    phases = [("start+exit", "interpreter start and exit"), ("imports", "imports of the CLI"),
              ("plan", "planning: every scene resolved and checked once (wall; forked: the kernel load beside it)"),
              ("load", "  kernel load (Numba cache), forked runs: beside the planning"),
              ("warm_up", "warm-up: one run of each variant (1 job: the kernel load)"),
              ("compute", "chunks on the workers, wall"), ("runs", "  workers: scenes resolved and run (sum)"),
              ("writes", "  workers: chunk files written (sum)"), ("tail", "  last worker done after the first"),
              ("assemble", "assembly of the table")]
    warm = df[df.start == "warm"]
    lines += ["", "Where the time goes, warm (median seconds; the phases of `run_sweep` in `Outcome.timings`):",
              "", "| phase | " + " | ".join(f"{c}, {j} job{'s' if j > 1 else ''}"
                                             for (c, j), _ in warm.groupby(["code", "jobs"], sort=False)) + " |",
              "|---|" + "---|" * warm.groupby(["code", "jobs"]).ngroups]
    for col, what in phases:
        cells = [f"{med(g, col):.3f}" if col in g and g[col].notna().any() else "-"
                 for _, g in warm.groupby(["code", "jobs"], sort=False)]
        lines.append(f"| {what} | " + " | ".join(cells) + " |")
    print("\n".join(lines))
    return lines


if __name__ == "__main__":
    main()
