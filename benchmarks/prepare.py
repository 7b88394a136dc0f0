"""The sweep's CPU side outside the kernel, an earlier revision against this tree: the GPU path's
(the card replaced by a stand-in), the main job's whole command, and a chunk's parameter vectors
prepared on whole columns (model/prepare.py prepare_columns) or one run at a time (prepare).
(results/prepare.md)

    python benchmarks/prepare.py [--before REV] [--rounds 3] [--spec sweeps/envelope.yaml] [--out FILE]

An earlier revision (REV) beside this tree, in rounds that alternate them, each measurement a
fresh process; the page gives each one's minimum over the rounds:
  stand-in   the GPU path with the card replaced (benchmarks/gpu.py --stand-in: its stand_in),
             the whole `run_grid` command's wall seconds and its phases: the plan, the compute
             phase (the vectors, the chunks written and read back, the table's blocks), the chunk
             writes on the workers (their seconds summed) and the stand-in card's answers; on all
             cores, unverified;
  main job   `fencesweep grid sweeps/b2k2.yaml --jobs N --out TMP --quiet`, the whole command's
             wall seconds (the interpreter's start included), on 1 and 2 jobs;
  worker     what a CPU worker does to a chunk before its runs, per run: the chunk's scenes
             resolved (compute._resolved) and each run's vector made (a tree without
             compute.prepared, c3a4204: prepare(vals); else compute.prepared, then vectors[k]),
             on every CHUNK_STEP-th chunk of CHUNK runs;
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


#: the main job, its whole command (benchmarks/README.md)
MAIN_JOB = ROOT / "sweeps" / "b2k2.yaml"


def _command(tree: Path, tmp: Path, jobs: int) -> float:
    """The wall seconds of `fencesweep grid MAIN_JOB --jobs N --quiet` in a fresh process of `tree`."""
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "fencesweep", "grid", str(MAIN_JOB), "--jobs", str(jobs), "--out",
                    str(tmp / "main.parquet"), "--quiet"], check=True, capture_output=True, cwd=tmp,
                   env={**os.environ, "PYTHONPATH": str(tree)})
    return time.perf_counter() - t


def measure(tree: Path, spec: Path, tmp: Path) -> dict:
    """One round of one tree: the stand-in sweep, the main job on 1 and 2 jobs, the worker's
    preparation."""
    s = _python(tree, tmp, bench.SWEEP, spec, tmp / "s.parquet", "cuda", os.cpu_count() or 1, 0, ROOT / "benchmarks")
    return {"command": s["wall"], "plan": s["timings"]["plan"], "compute": s["timings"]["compute"],
            "writes": s["timings"]["writes"], "card": s["timings"]["gpu"], "runs": s["runs"],
            "main_1": _command(tree, tmp, 1), "main_2": _command(tree, tmp, 2),
            **_python(tree, tmp, WORKER, spec, CHUNK, CHUNK_STEP)}


KEYS = ("command", "plan", "compute", "writes", "card", "main_1", "main_2", "card_us", "worker_us", "alone_us")
#: the line from which the page's earlier measurements are kept when it is written again
EARLIER = "## Earlier measurements"


def page(rows: dict, args, names: dict, earlier: str = "") -> str:
    """The page: the minima of each tree's rounds (the tables), every round, and `earlier`."""
    best = {t: {k: min(r[k] for r in rs) for k in KEYS} for t, rs in rows.items()}
    runs, cores = next(iter(rows.values()))[0], os.cpu_count() or 1

    def row(t: str, keys: tuple) -> str:
        return f"| {names[t]} | " + " | ".join(f"{best[t][k]:.2f}" for k in keys) + " |"

    out = ["# The sweep's CPU side outside the kernel (`benchmarks/prepare.py`)", "",
           f"Machine: {cores} cores, shared with other work while measured: the minima are what to compare, "
           f"single rounds vary by a factor of 2. {time.strftime('%Y-%m-%d')}. `python benchmarks/prepare.py "
           f"--before {args.before} --rounds {args.rounds} --spec {args.spec}`: {names['before']} against this "
           f"tree, alternating, each a fresh process, the minimum of {args.rounds} rounds.", "",
           f"The stand-in: the GPU path of {args.spec} ({runs['runs']:,} runs) with the card replaced "
           "(benchmarks/gpu.py --stand-in), on all cores, unverified: the whole command (`run_grid`, imports "
           "and the spec read included), its plan, its compute phase (the vectors, on the workers; the chunks "
           "written, on the workers; the stand-in card's answers; in the sweep's process each chunk taken in "
           "and the table's blocks written), the chunk writes (`writes`: the workers' seconds summed) and the "
           "card (`card`: launch to results, in the sweep's process). The main job: `fencesweep grid "
           "sweeps/b2k2.yaml --jobs N --out TMP --quiet`, the whole command (13,122 runs, verified).", "",
           "| tree | stand-in: command s | plan s | compute s | writes s | card s | main job, 1 job: s "
           "| main job, 2 jobs: s |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    out += [row(t, KEYS[:7]) for t in ("before", "this")]
    out += ["", f"Per run, on {runs['worker_runs']:,} runs (every {CHUNK_STEP}th chunk of {CHUNK}): the GPU path's "
            "preparation of a chunk (sweep/gpu.py _prepare); what a CPU worker does to a chunk before running it "
            "(its scenes resolved, each run's vector); prepare(vals) alone, as `simulate` does for one run.", "",
            "| tree | GPU chunk: µs a run | CPU worker: µs a run | one run: prepare µs |", "|---|---:|---:|---:|"]
    out += [row(t, KEYS[7:]) for t in ("before", "this")] + [""]
    out += ["Every round (" + ", ".join(KEYS) + "):", ""]
    for t in ("before", "this"):
        out.append(f"- {names[t]}: " + "; ".join(", ".join(f"{r[k]:.2f}" for k in KEYS) for r in rows[t]))
    return "\n".join(out) + "\n" + (f"\n{earlier.rstrip()}\n" if earlier else "")


def _earlier(path: Path) -> str:
    """What the page at `path` keeps from EARLIER on (empty: nothing)."""
    text = path.read_text() if path.exists() else ""
    return text[text.index(EARLIER):] if EARLIER in text else ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="c3a4204", help="an earlier revision (c3a4204: one run at a time; "
                    "bb7ffbe: chunks read back from Parquet, the table's blocks through NumPy)")
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
    text = page(rows, args, names, _earlier(args.out))
    print(text)
    args.out.write_text(text)


if __name__ == "__main__":
    main()
