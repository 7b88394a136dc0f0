"""No size limit from the sweep's own memory: planning's bytes per scene, a spec of 2 x 10^8 scenes
swept in pieces, and the envelope study ten times over.

    python benchmarks/scale_memory.py [--pieces 3] [--envelope10] [--jobs 2]
                                                     -> prints, writes results/scale_memory.md

1. Planning (sweep/plan.py make_plan) of B2 x K2 specs of 10^5 ... 5 x 10^6 scenes: its peak memory
   (tracemalloc) per scene and its time, in this process.
2. The spec of 2 x 10^8 scenes (B2 and K2 at 10,000 values each, two cases): its pieces
   (spec/pieces.py), its dry run (`fencesweep grid --dry-run`: the first piece planned and timed,
   the rest scaled), and its sweep run for --pieces pieces, each of up to PIECE_SCENES scenes,
   through the real pipeline (run_sweep: plan, chunks on --jobs workers, verification, assembly
   into the dataset's parts) with a stand-in engine that returns one real cycle's results at
   once (a real cycle takes ~0.4 ms: 5 million of them are ~17 core-minutes). The sweep is
   stopped when the next piece begins; its process's peak memory (ru_maxrss) after one and after
   all the pieces shows that it does not grow with the pieces.
3. With --envelope10: the envelope study with 640 loads instead of 64 (4.2 million cycles,
   benchmarks/specs/envelope_10x.yaml) run for real on --jobs workers: its peak memory, its time
   and its time outside compute (about 15 minutes on 2 cores).

Each part runs in a fresh process. Run it alone on the machine.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "scale_memory.md"
HUGE = """
description: 2 x 10^8 cycles, B2 and K2 at 10,000 values each over both named cases
params: {drive: flexible}
grid:
  B2: {linspace: [0, 400, 10000]}
  K2: {linspace: [100, 2100, 10000]}
cases: [small_far, long_near]
"""

PLANNING = r"""
import json, sys, time, tracemalloc, textwrap
from fencesweep.study.spec import file as specfile
from fencesweep.study.sweep import plan as PL
out = []
for n in (316, 1000, 2236):  # a B2 x K2 grid of n x n: 10^5, 10^6, 5 x 10^6 scenes
    text = f"params: {{drive: flexible}}\ngrid: {{B2: {{linspace: [0, 400, {n}]}}, K2: {{linspace: [100, 2100, {n}]}}}}\n"
    spec = specfile.loads(text)
    tracemalloc.start()
    t = time.perf_counter()
    plan = PL.make_plan(spec)
    seconds = time.perf_counter() - t
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    out.append({"scenes": spec.n_scenes, "seconds": seconds, "peak": peak, "runs": plan.n_models})
    del plan
print(json.dumps(out))
"""

PIECES = r"""
import json, resource, sys, time
from fencesweep import simulate_resolved
from fencesweep.study.spec import file as specfile, pieces as SP
from fencesweep.study.sweep import pipeline, estimate as EST
spec_path, out, jobs, n_pieces = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
spec = specfile.load(spec_path)
t = time.perf_counter()
est = EST.estimate(spec, __import__("pathlib").Path(out), jobs=jobs)
dry = {"seconds": time.perf_counter() - t, "lines": est.lines(), "estimate": est.seconds, "pieces": est.pieces}
ONE = simulate_resolved(spec.resolve(0))[0]  # one real cycle's results

def stand_in(vals, trajectory=False):
    return dict(ONE), None

marks = []
class Stop(Exception):
    pass

def log(msg):
    if msg.startswith("piece "):
        marks.append({"at": time.perf_counter() - t0, "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      "msg": msg})
        if len(marks) > n_pieces:
            raise Stop

t0 = time.perf_counter()
try:
    pipeline.run_sweep(spec, out, jobs=jobs, simulate=stand_in, log=log, progress=False)
except Stop:
    pass
print(json.dumps({"dry": dry, "marks": marks, "piece_scenes": SP.piece_limit(), "n_pieces": SP.n_pieces(spec)}))
"""

ENVELOPE10 = r"""
import json, resource, sys
from fencesweep.study import api
run = api.run_grid(sys.argv[1], out=sys.argv[2], jobs=int(sys.argv[3]), overwrite=True, resume=False, progress=False)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
v = run["verify"]
print(json.dumps({"seconds": run["seconds"], "timings": run["timings"], "scenes": run["scenes"], "peak_mib": peak,
                  "verify_ok": v["ok"], "verify": {"n": v["n"], "outcome_mismatches": v["outcome_mismatches"],
                  "outcomes_differ": v["outcomes_differ"], "random": v["random"],
                  "over": {q: r for q, r in v["quantities"].items() if r["max_rel_diff"] > v["threshold"]
                           or r["undefined"]}}}))
"""


def _run(code: str, *args, cwd: Path = ROOT) -> dict:
    r = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, cwd=cwd)
    if r.returncode:
        raise SystemExit(r.stderr[-3000:])
    return json.loads(r.stdout.strip().splitlines()[-1])


def planning_lines() -> list:
    rows = _run(PLANNING)
    lines = ["## 1. Planning: memory and time per scene", "",
             "| scenes | model runs | plan s | peak (tracemalloc) MiB | bytes / scene |", "|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scenes']:,} | {r['runs']:,} | {r['seconds']:.3f} | {r['peak'] / 2**20:.0f} | "
                     f"{r['peak'] / r['scenes']:.0f} |")
    return lines + [""]


def pieces_lines(jobs: int, n_pieces: int, tmp: Path) -> list:
    spec = tmp / "huge.yaml"
    spec.write_text(textwrap.dedent(HUGE))
    t = time.perf_counter()
    rec = _run(PIECES, spec.name, "huge.parquet", jobs, n_pieces, cwd=tmp)  # names, not paths, in its text
    wall = time.perf_counter() - t
    parts = sorted((tmp / "huge.parquet").glob("part-*.parquet"))
    lines = ["## 2. 2 x 10^8 scenes in pieces", "",
             f"{rec['n_pieces']} pieces of up to {rec['piece_scenes']:,} scenes. The dry run took "
             f"{rec['dry']['seconds']:.1f} s (the first piece planned, the engine warmed up and timed) and says:", "",
             "```", *rec["dry"]["lines"], "```", "",
             f"The sweep with the stand-in engine on {jobs} jobs, stopped as piece {n_pieces + 1} began "
             f"({wall:.0f} s in all, {len(parts)} parts written):", "",
             "| piece begins | after s | peak memory of the sweep's process, MiB |", "|---|---:|---:|"]
    for m in rec["marks"]:
        lines.append(f"| {m['msg']} | {m['at']:.1f} | {m['peak_mib']:.0f} |")
    return lines + [""]


def envelope10_lines(jobs: int, tmp: Path) -> list:
    rec = _run(ENVELOPE10, ROOT / "benchmarks" / "specs" / "envelope_10x.yaml", tmp / "env10.parquet", jobs)
    tm = rec["timings"]
    outside = rec["seconds"] - tm["compute"]
    phases = ", ".join(f"{k} {tm[k]:.2f} s" for k in ("plan", "warm_up", "verify", "assemble", "tail") if k in tm)
    v = rec["verify"]
    return ["## 3. The envelope study ten times over (640 loads: 4.2 million cycles), for real", "",
            f"{rec['scenes']:,} cycles on {jobs} jobs: {rec['seconds']:.0f} s, of it {outside:.2f} s outside compute "
            f"({phases}); peak memory of the sweep's process {rec['peak_mib']:.0f} MiB; verification "
            f"{'ok' if rec['verify_ok'] else 'FAILED'} ({v['n']:,} runs re-run at tol/10).", "",
            "The verification's record, where it is over its bound:", "", "```",
            json.dumps({k: v[k] for k in ("outcome_mismatches", "outcomes_differ", "over", "random")}, indent=1),
            "```", ""]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--pieces", type=int, default=3)
    ap.add_argument("--envelope10", action="store_true")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    again = f"python benchmarks/scale_memory.py --jobs {args.jobs} --pieces {args.pieces}" + \
        (" --envelope10" if args.envelope10 else "")
    lines = ["# No size limit from the sweep's memory", "",
             f"Regenerate: `{again}` (what is measured: its docstring). This machine: {os.cpu_count()} cores.", ""]
    with tempfile.TemporaryDirectory(prefix="fencesweep-scale-") as tmp:
        lines += planning_lines()
        print("\n".join(lines), flush=True)
        lines += pieces_lines(args.jobs, args.pieces, Path(tmp))
        print("\n".join(lines[-12:]), flush=True)
        if args.envelope10:
            lines += envelope10_lines(args.jobs, Path(tmp))
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
