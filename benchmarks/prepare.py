"""What does preparing a chunk's parameter vectors on whole columns (model/prepare.py
prepare_columns) save against preparing them one run at a time (prepare), on the GPU path's CPU
side and on the CPU's workers? (results/prepare.md)

    python benchmarks/prepare.py [--before REV] [--rounds 3] [--spec sweeps/envelope.yaml] [--out FILE]

An earlier revision (REV, one run at a time) beside this tree, in rounds that alternate them, each
measurement a fresh process; the page gives each one's minimum over the rounds:
  stand-in   the GPU path with the card replaced (benchmarks/gpu.py --stand-in: its stand_in),
             the whole `run_grid` command's wall seconds and its compute phase (the vectors, the
             chunks written and read back, the table's blocks), on all cores, unverified;
  worker     what a CPU worker does to a chunk before its runs, per run: the chunk's scenes
             resolved (compute._resolved) and each run's vector made (REV: prepare(vals); this
             tree: compute.prepared, then vectors[k]), on every CHUNK_STEP-th chunk of CHUNK runs;
  card       the GPU path's preparation of the same chunks (sweep/gpu.py _prepare), per run;
  one run    prepare(vals) alone (what `simulate` does for a single run), on the same runs.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gpu as bench  # benchmarks/gpu.py: the stand-in sweep
from revisions import export  # benchmarks/revisions.py: a revision's tree, exported from git

ROOT = Path(__file__).resolve().parents[1]

CHUNK, CHUNK_STEP = 2000, 10

#: a worker's preparation of chunks and prepare alone, in a fresh process of one tree
WORKER = r"""
import json, sys, time
from fencesweep.model.prepare import prepare
from fencesweep.study.spec import file as F
from fencesweep.study.sweep import compute, gpu, plan as PL
spec, size, step = F.load(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
plan = PL.make_plan(spec)
chunks = [plan.first_row[at:at + size] for at in range(0, plan.n_models, size * step)]
columns = hasattr(compute, "prepared")
def worker(rows):
    vals = compute._resolved(spec, rows)
    if columns:
        vectors = compute.prepared(spec, rows)
        for k in range(len(vals)):
            vectors[k]
    else:
        for v in vals:
            prepare(v)
def card(rows):
    gpu._prepare(0, rows, (spec, None))
def alone(vals):
    for v in vals:
        prepare(v)
worker(chunks[0]); card(chunks[0]); alone(compute._resolved(spec, chunks[0]))  # caches and imports warm
out = {"worker_runs": sum(len(r) for r in chunks)}
for name, fn, args in (("worker_us", worker, chunks), ("card_us", card, chunks),
                       ("alone_us", alone, [compute._resolved(spec, rows) for rows in chunks])):
    t = time.perf_counter()
    for a in args:
        fn(a)
    out[name] = (time.perf_counter() - t) / out["worker_runs"] * 1e6
print(json.dumps(out))
"""


#: a first run in a tree: its kernels compiled into its own cache, not in a measured run
WARM = "import fencesweep; fencesweep.simulate(); print('{}')"


def _python(tree: Path, tmp: Path, code: str, *args) -> dict:
    """`code` in a fresh process that imports the package of `tree` (run from `tmp`: the working
    directory comes first on sys.path, before PYTHONPATH and the editable install's folder)."""
    r = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, cwd=tmp,
                       env={**os.environ, "PYTHONPATH": str(tree)})
    if r.returncode != 0:
        raise RuntimeError(f"a benchmark run failed:\n{r.stderr[-4000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def measure(tree: Path, spec: Path, tmp: Path) -> dict:
    """One round of one tree: the stand-in sweep, then the worker's preparation."""
    s = _python(tree, tmp, bench.SWEEP, spec, tmp / "s.parquet", "cuda", os.cpu_count() or 1, 0, ROOT / "benchmarks")
    return {"command": s["wall"], "compute": s["timings"]["compute"], "writes": s["timings"]["writes"],
            "card": s["timings"]["gpu"], "runs": s["runs"], **_python(tree, tmp, WORKER, spec, CHUNK, CHUNK_STEP)}


def page(rows: dict, args, names: dict) -> str:
    keys = ("command", "compute", "writes", "card", "card_us", "worker_us", "alone_us")
    best = {t: {k: min(r[k] for r in rs) for k in keys} for t, rs in rows.items()}
    runs = next(iter(rows.values()))[0]
    out = ["# Parameter vectors on whole columns (`benchmarks/prepare.py`)", "",
           f"Machine: {os.cpu_count()} cores, shared with other work while measured. {time.strftime('%Y-%m-%d')}. "
           f"`python benchmarks/prepare.py --before {args.before} --rounds {args.rounds} --spec {args.spec}`: "
           f"{names['before']} (one run at a time) against this tree (prepare_columns), alternating, each "
           f"a fresh process, the minimum of {args.rounds} rounds.", "",
           f"The stand-in: the GPU path of {args.spec} ({runs['runs']:,} runs) with the card replaced "
           "(benchmarks/gpu.py --stand-in), on all cores; `compute` is its compute phase: the vectors (on "
           "the workers), the chunks written (on the workers, `writes`: their seconds summed), the stand-in "
           "card's answers (`card`: launch to results, in the sweep's process) and, in the sweep's process, "
           "each chunk read back and the table's blocks written. Per run, on "
           f"{runs['worker_runs']:,} runs "
           f"(every {CHUNK_STEP}th chunk of {CHUNK}): the GPU path's preparation of a chunk (sweep/gpu.py "
           "_prepare); what a CPU worker does to a chunk before running it (its scenes resolved, each "
           "run's vector); prepare(vals) alone, as `simulate` does for one run.", "",
           "| tree | stand-in: command s | compute s | writes s | card s | GPU chunk: µs a run "
           "| CPU worker: µs a run | one run: prepare µs |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for t in ("before", "this"):
        out.append(f"| {names[t]} | " + " | ".join(f"{best[t][k]:.2f}" for k in keys) + " |")
    cores, n = os.cpu_count() or 1, runs["runs"]
    out += ["", "Of the stand-in's compute phase, the vectors are about GPU chunk µs x runs / cores: "
            + ", ".join(f"{names[t]} {best[t]['card_us'] * n / 1e6 / cores:.2f} s" for t in ("before", "this"))
            + "; the chunks' writes about writes / cores: "
            + ", ".join(f"{names[t]} {best[t]['writes'] / cores:.2f} s" for t in ("before", "this"))
            + ". The rest is the sweep's process: the card's answers, each chunk read back and the table's "
            "blocks written (and the workers' results awaited).",
            "", "Every round (" + ", ".join(keys) + "):", ""]
    for t in ("before", "this"):
        out.append(f"- {names[t]}: " + "; ".join(", ".join(f"{r[k]:.2f}" for k in keys) for r in rows[t]))
    return "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="c3a4204", help="a revision that prepares one run at a time")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--spec", default="sweeps/envelope.yaml")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "prepare.md")
    args = ap.parse_args()
    trees = {"before": export(args.before), "this": ROOT}
    names = {"before": args.before, "this": "this tree"}
    rows: dict = {"before": [], "this": []}
    spec = (ROOT / args.spec).resolve()
    with tempfile.TemporaryDirectory() as tmp:
        for tree in trees.values():
            _python(tree, Path(tmp), WARM)
        for k in range(args.rounds):
            for t in (("before", "this") if k % 2 == 0 else ("this", "before")):
                rows[t].append(measure(trees[t], spec, Path(tmp)))
                print(t, json.dumps(rows[t][-1]), flush=True)
    text = page(rows, args, names)
    print(text)
    args.out.write_text(text)


if __name__ == "__main__":
    main()
