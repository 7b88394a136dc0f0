"""`fencesweep grid SPEC --adaptive`: a map's verdicts from a fraction of its cycles.

The steps, each in its own module:

1. adaptive/maps.py: the spec's maps (an envelope study, or a grid with cases) and the scenes
   of each element.
2. adaptive/refine.py: the Refiner asks for the coarse lattice, then level by level for the elements
   where the verdict or the binding constraint changes between neighbours or the margins say a
   boundary is near, and infers the rest.
3. adaptive/evaluate.py: each level's elements run in chunks (this process, local workers or Dask),
   load after load in the order most likely to break a constraint, stopping at the first that
   does (adaptive/loads.py); the chunks are written into OUT.partial/<id>/ as they finish.
4. The cycles run become the table T (one row per cycle, the full run's columns, in scene
   order) through the full run's machinery: a Plan whose runs are those cycles, the
   verification at tol / 10 (sweep/verify.py) and sweep/assemble.py; its metadata adds `fencesweep.adaptive`
   (the cycles run against the full grid's, the levels, the rules) and the counts.
5. The points table T_points (OUT_points.parquet): every element of the full grid, the full
   run's columns where it was simulated (judged over the loads it ran), its verdict, binding
   constraint and margins inferred elsewhere; `sampled` says which, `n_loads` how many loads
   ran and `n_predicted` how many were predicted safe instead.

Deterministic: the refinement depends only on what it was told, the chunks only on the
refinement, so the tables are the same, bit for bit, for any --jobs, backend or interruption (a
rerun finds the chunks it made and computes the rest). The salt of the work directory holds the
rules and VERSION: a changed rule never reuses a stale chunk. Orchestration only: no physics.
"""
from __future__ import annotations

import hashlib
import json
import logging
import math
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from fencesweep.study.adaptive import loads as AL
from fencesweep.study.adaptive import maps as AM
from fencesweep.study.adaptive import refine as A
from fencesweep.study.adaptive.evaluate import Evaluator
from fencesweep.study.spec import spec as S
from fencesweep.study.store import lock
from fencesweep.study.sweep import output, runs
from fencesweep.study.sweep import pipeline as SW
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import verify as V
from fencesweep.study.sweep.progress import bar as progress_bar

VERSION = 2  # of the refinement and its rules; in the work directory's salt
FINAL_CHUNK = 2_000  # cycles per chunk of the final Plan (what verify and assemble read)
PER_CYCLE = 2e-3  # seconds per cycle assumed before any is timed (whether to start workers)


@dataclass
class Outcome:
    """What run_adaptive did: the tables written, the cycles run, the time, the records."""

    out: Path
    points_path: Path
    points: dict  # summary of T_points
    record: dict  # fencesweep.adaptive
    seconds: float
    jobs: int | None
    chunks_computed: int
    chunks_reused: int
    failed_runs: int = 0
    verify: dict | None = None
    timings: dict = field(default_factory=dict)


def default_output(spec: S.Spec) -> Path:
    """The full run's output with _adaptive before .parquet: an adaptive map never replaces the full grid."""
    full = output.default_output(spec)
    return full.with_name(full.stem + "_adaptive.parquet")


def salt(spec: S.Spec, rule: A.Rule, load_rule: AL.LoadRule) -> str:
    """Digest of the spec, the engine, VERSION and the rules: names the work directory, salts the chunks."""
    text = json.dumps({"v": VERSION, "rule": rule.as_dict(), "loads": load_rule.as_dict()}, sort_keys=True)
    return hashlib.sha256(f"{PL.plan_salt(spec)}:adaptive:{text}".encode()).hexdigest()


def saved_chunks(spec: S.Spec, out: Path, rule: A.Rule | None = None, load_rule: AL.LoadRule | None = None) -> tuple:
    """(work directory, chunks saved in it, None) of an interrupted adaptive run."""
    work = output.work_root(Path(out)) / salt(spec, rule or A.Rule(), load_rule or AL.LoadRule())[:16]
    return work, len(list(work.glob("chunk-*.parquet"))) if work.exists() else 0, None


#: the default log: the "fencesweep" logger (api.py)
_quiet = logging.getLogger(__name__).info


def run_adaptive(spec: S.Spec, out: str | Path | None = None, jobs: int | None = None, resume: bool = True,
                 backend: str = "loky", scheduler: str | None = None, progress: bool = False,
                 simulate: Callable | None = None, log: Callable | None = None, serial_below: float | None = None,
                 overwrite: bool = False, verify: bool | int | None = None, wait: bool = False,
                 rule: A.Rule | None = None, load_rule: AL.LoadRule | None = None) -> Outcome:
    """The adaptive map of `spec` (module docstring) into `out` (default: default_output) and
    OUT_points.parquet; the arguments as sweep.run_sweep takes them. UsageError before anything
    is written when the spec makes no map (adaptive_maps.layout) or `out` is not to be replaced."""
    t0 = time.perf_counter()
    lay = AM.layout(spec)
    gpu = SW.gpu_device(spec) if backend == "cuda" else None  # the GPU's record, or why it cannot run
    rule, load_rule, log = rule or A.Rule(), load_rule or AL.LoadRule(), log or _quiet
    out = Path(out) if out is not None else default_output(spec)
    output.check_writable(out)
    if not overwrite:
        output.check_output(spec, out, adaptive=True)
    with lock.one_writer(out, wait, log):
        if not overwrite:
            output.check_output(spec, out, adaptive=True)
        if jobs is None:
            import joblib

            jobs = joblib.cpu_count()
        key = salt(spec, rule, load_rule)
        root = output.work_root(out)
        work = root / key[:16]
        output.open_work(root, work, resume, log)
        _write_state(work, spec, key)
        run = {"jobs": jobs, "local": backend != "dask", "scheduler": scheduler, "simulate": simulate,
               "serial_below": serial_below, "per_cycle": PER_CYCLE, "gpu": gpu}
        timings = {"warm_up": runs.warm_scenes(spec, lay.scenes(np.zeros(1, dtype=np.int64))[:1], simulate)}
        ev = Evaluator(lay, work, key, load_rule, run)
        refiner = A.Refiner(lay.grid, rule)
        t = time.perf_counter()
        _refine(lay, refiner, ev, progress)
        timings["refine"] = time.perf_counter() - t
        res = _finish(lay, refiner, ev, out, work, verify, run, timings)
        shutil.rmtree(root)
    return Outcome(out, res["points_path"], res["points"], res["record"], time.perf_counter() - t0,
                   jobs if run["local"] else None, ev.chunks_computed, ev.chunks_reused, res["failed"],
                   res["verify"], timings)


def _write_state(work: Path, spec: S.Spec, key: str) -> None:
    """The work directory's record (output.PLAN_FILE), which output.check_output reads."""
    from fencesweep.study.store import table as store

    state = {"spec": spec.normalized(), "spec_hash": spec.hash, "spec_path": spec.path, "salt": key,
             "adaptive": True, "n_chunks": None}
    with store.atomic_path(work / output.PLAN_FILE) as tmp:
        tmp.write_text(json.dumps(state, indent=1))


def _refine(lay: AM.Layout, refiner: A.Refiner, ev: Evaluator, progress: bool) -> None:
    """Ask, simulate, tell, until every element is settled."""
    name = Path(lay.spec.path).stem if lay.spec.path else "sweep"
    bar = progress_bar(0, f"{name} (adaptive)", progress)
    bar.unit = "element"
    try:
        while True:
            ids, refs = refiner.ask()
            if not len(ids):
                break
            t, cycles = time.perf_counter(), ev.cycles
            refiner.tell(ids, *ev.evaluate(ids, refs, bar))
            if ev.cycles > cycles:
                used = ev.run["jobs"] if ev.run["local"] else 1
                ev.run["per_cycle"] = (time.perf_counter() - t) * used / (ev.cycles - cycles)
    finally:
        bar.close()


def _finish(lay: AM.Layout, refiner: A.Refiner, ev: Evaluator, out: Path, work: Path, verify, run: dict,
            timings: dict) -> dict:
    """The cycles run as a Plan: verified at tol / 10, assembled into T; T_points written."""
    from fencesweep.study.adaptive import points as APT
    from fencesweep.study.sweep.assemble import assemble
    from fencesweep.study.sweep.chunks import ChunkTables

    plan = _plan(lay, ev, work)
    tables = ChunkTables(plan, work)  # the verification and the assembly read each chunk once
    record = APT.record(lay, refiner, ev)
    vrec = None
    if verify is not False:
        vrec, timings["verify"] = V.run_verification(
            plan, work, None if verify is None or verify is True else int(verify), run["jobs"], run["local"],
            run["scheduler"], run["simulate"], run["serial_below"], run["per_cycle"], tables=tables)
    t = time.perf_counter()
    counts = {"scenes": plan.n_models, "skipped": 0, "model_runs": plan.n_models, "full_grid_scenes": lay.n_full}
    meta = {"adaptive": record, "counts": counts} | ({"verify": vrec} if vrec is not None else {}) \
        | ({"device": run["gpu"]} if run.get("gpu") else {})
    failed = assemble(plan, work, out, meta, tables)
    timings["assemble"] = time.perf_counter() - t
    path, summary = APT.write(lay, refiner, ev, out, record)
    return {"points_path": path, "points": summary, "record": record, "verify": vrec, "failed": failed}


def _plan(lay: AM.Layout, ev: Evaluator, work: Path) -> PL.Plan:
    """A Plan of the spec whose model runs are the cycles run, in scene order (the other scenes
    are left out, row_model -1), and its chunks written from the levels' chunks."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from fencesweep.study.store import table as store

    table = pa.concat_tables([pq.read_table(work / name).replace_schema_metadata(None) for name in ev.names])
    table = table.sort_by("_model")
    scenes = store.numpy_column(table.column("_model")).astype(np.int64)
    n = len(scenes)
    row_model = np.full(lay.spec.n_scenes, -1, dtype=np.int64)
    row_model[scenes] = np.arange(n)
    plan = PL.Plan(lay.spec, row_model, scenes, min(FINAL_CHUNK, max(n, 1)), {}, 0, [], ev.salt)
    table = table.set_column(table.schema.get_field_index("_model"), "_model", pa.array(np.arange(n)))
    for c in range(plan.n_chunks):
        m = plan.chunk_models(c)
        part = table.slice(m.start, len(m)).replace_schema_metadata(store._meta_bytes({"salt": ev.salt, "chunk": c}))
        store.write_table_atomic(part, work / plan.chunk_name(c), fsync=False)
    return plan


def per_cycle_note(record: dict) -> str:
    """The cycles run against the full grid's, for the summary line."""
    share = record["cycles"] / record["full_grid_cycles"] if record["full_grid_cycles"] else math.nan
    return f"{record['cycles']} cycles of the full grid's {record['full_grid_cycles']} ({share:.1%})"
