"""Sweeps: spec -> scenes -> distinct model runs -> parallel chunks -> one Parquet table.

1. plan: every scene of the spec is resolved (params.resolve) up front, so any bad
   combination is reported before work starts, and mapped to its model run by
   params.model_key: scenes that differ only in parameters their model does not use
   (B2, K2, m2 under a rigid drive, ...) share one run (MODEL.md §8).
2. The distinct runs, numbered in order of first appearance, are cut into chunks of
   `chunk_size` runs: the spec's, or sized from a short timed sample to take about
   CHUNK_SECONDS each (dispatch and writing then cost well under 1 %), and recorded in
   the work directory so that a resumed sweep cuts the same chunks. A chunk's file name
   carries a digest of the spec hash, the package's source hash, its chunk size and the
   model keys of its runs, so a changed spec or engine never reuses a stale chunk.
3. Pending chunks run in parallel through joblib (loky locally, or Dask); each finished
   chunk is written atomically into the work directory `OUT.partial/` beside the output
   (by the local worker that ran it, so results never queue up in the parent; with Dask by
   the client). A killed sweep, rerun, computes only the chunks that are missing.
4. The table is assembled block by block from the chunks (rows in scene order) into one
   Parquet file, atomically; then the work directory is removed.

Results depend only on each run's parameters, and the assembly only on the plan: the
table is the same, bit for bit, whatever --jobs or backend.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import shutil
import sys
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from . import params as P
from . import spec as S
from . import store
from .errors import UsageError

#: chunk size rule: chunks of about CHUNK_SECONDS of work, at least MIN_CHUNKS of them.
#: A chunk costs ~0.6-2 ms of dispatch and ~2-15 ms to write (benchmarks/sweep_dispatch.py),
#: i.e. < 1.5 % of one second; MIN_CHUNKS keeps small sweeps balanced and resumable.
CHUNK_SECONDS, MIN_CHUNKS, CHUNK_MAX = 1.0, 16, 2_000  # CHUNK_MAX bounds the memory in flight
ASSEMBLY_BLOCK = 16_384  # rows per Parquet row group of the final table
CHUNK_CACHE = 8  # chunks held in memory while assembling
SERIAL_BELOW = 3.0  # seconds of estimated work under which a local sweep runs in-process
_CHOICES = tuple(p.name for p in P.TABLE if p.kind == "choice")


def auto_chunk_size(n_models: int, seconds_per_run: float) -> int:
    """Model runs per chunk: about CHUNK_SECONDS of work, but at least MIN_CHUNKS chunks."""
    by_time = math.ceil(CHUNK_SECONDS / max(seconds_per_run, 1e-7))
    return max(1, min(by_time, math.ceil(n_models / MIN_CHUNKS), CHUNK_MAX))


def local_jobs(jobs: int, work_left: float, serial_below: float | None = None) -> int:
    """Local processes to use: 1 (this process) when the work left is too small to pay for workers."""
    return 1 if work_left < (SERIAL_BELOW if serial_below is None else serial_below) else jobs


# ------------------------------------------------------------------------------ plan
@dataclass
class Plan:
    """Scenes of a spec mapped to distinct model runs, cut into chunks."""

    spec: S.Spec
    row_model: np.ndarray  # model run of each scene; -1 for a skipped scene
    first_row: np.ndarray  # the first scene of each model run
    digests: bytes  # 16 bytes per model run: blake2b of its model key
    chunk_size: int | None  # None until measured (run_sweep) unless the spec gives it
    variants: dict  # (scene, drive, contact_law, profile) -> first model run with it
    skipped: int = 0
    skipped_examples: list = field(default_factory=list)
    salt: str = ""

    @property
    def n_scenes(self) -> int:
        return len(self.row_model)

    @property
    def n_models(self) -> int:
        return len(self.first_row)

    @property
    def n_chunks(self) -> int:
        return math.ceil(self.n_models / self.chunk_size)

    def chunk_models(self, c: int) -> range:
        return range(c * self.chunk_size, min(self.n_models, (c + 1) * self.chunk_size))

    def chunk_name(self, c: int) -> str:
        m = self.chunk_models(c)
        h = hashlib.sha256(f"{self.salt}:{self.chunk_size}:{c}:".encode())
        h.update(self.digests[16 * m.start:16 * m.stop])
        return f"chunk-{c:06d}-{h.hexdigest()[:16]}.parquet"

    def chunk_rows(self) -> np.ndarray:
        """Number of scenes each chunk fills."""
        valid = self.row_model[self.row_model >= 0]
        return np.bincount(valid // self.chunk_size, minlength=self.n_chunks)

    def model_vals(self, m: int) -> dict:
        return self.spec.resolve(int(self.first_row[m]))


def make_plan(spec: S.Spec, progress: bool = False) -> Plan:
    """Resolve every scene (raising SpecError on the first bad one) and deduplicate the runs.

    Memory: 16 bytes of model-key digest per scene while planning (about 60 at the
    np.unique), then 8 (its model number); no Python object per scene is kept.
    """
    n = spec.n_scenes
    keys = np.zeros(n, dtype="V16")  # blake2b digest of each scene's model key
    kbuf = keys.view(np.uint8)
    valid = np.ones(n, dtype=bool)
    variants_row: dict = {}
    skipped, examples = 0, []
    bar = _bar(n, "checking", progress and n > 20_000)
    for i in range(n):
        try:
            vals = spec.resolve(i)
        except P.ParameterError as exc:
            if spec.invalid == "skip":
                valid[i] = False
                skipped += 1
                if len(examples) < 3:
                    examples.append(f"{spec.describe(i)}: {exc}")
                continue
            bar.close()
            raise S.SpecError(f"{spec.describe(i)}: {exc}") from None
        d = hashlib.blake2b(repr(P.model_key(vals)).encode(), digest_size=16).digest()
        kbuf[16 * i:16 * i + 16] = np.frombuffer(d, dtype=np.uint8)
        variants_row.setdefault((spec.scene,) + tuple(vals[c] for c in _CHOICES), i)
        if (i & 4095) == 4095:
            bar.update(4096)
    bar.close()
    if skipped == n:
        raise S.SpecError(f"every one of the {n} scenes is invalid (invalid: skip); e.g. {examples[0]}")
    rows = np.nonzero(valid)[0]
    uniq, first, inverse = np.unique(keys[rows], return_index=True, return_inverse=True)
    del keys, kbuf
    order = np.argsort(first, kind="stable")  # model runs numbered in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    row_model = np.full(n, -1, dtype=np.int64)
    row_model[rows] = rank[inverse.ravel()]
    first_row = rows[first[order]].astype(np.int64)
    digests = uniq[order].tobytes()
    variants = {k: int(row_model[i]) for k, i in variants_row.items()}
    v = store.versions()
    salt = hashlib.sha256(f"{spec.hash}:{v['fencesweep']}:{v['source_hash']}".encode()).hexdigest()
    return Plan(spec, row_model, first_row, digests, spec.chunk_size, variants, skipped, examples, salt)


def unused_axes(spec: S.Spec) -> list:
    """Axes over parameters that the scene's model never uses (every value gives the same run)."""
    uses = P.SCENE_USES[spec.scene] | {"step_factor", "Psi"}
    return [f"{a.where} ({n})" for a in spec.axes for n in a.names if n not in uses]


# ------------------------------------------------------------------------------ running
def _engine() -> Callable:
    from . import api

    return api.simulate_resolved


def run_models(scene: str, vals_list: list, simulate: Callable | None = None) -> list:
    """Run each parameter set; a run that raises becomes a row with outcome failed and the reason."""
    fn = simulate or _engine()
    rows = []
    for vals in vals_list:
        try:
            res, _ = fn(vals, trajectory=False)
        except Exception as exc:  # recorded, never silent: status names the exception
            res = store.failed_result(scene, f"failed: exception {type(exc).__name__}: {exc}")
        rows.append(res)
    return rows


def _run_chunk(c: int, scene: str, model_ids: list, vals_list: list, simulate: Callable | None,
               parent: int | None = None, path: str | None = None, meta: dict | None = None):
    """Run one chunk. With `path` (local workers) the worker writes the chunk file itself and
    returns no rows, so results never queue up in the parent; without (Dask), the rows go back."""
    if parent is not None:
        _watch_parent(parent)
    rows = run_models(scene, vals_list, simulate)
    if path is None:
        return c, model_ids, rows
    store.write_chunk(path, scene, model_ids, rows, meta)
    return c, None, None


_WATCHING = False


def _watch_parent(parent: int) -> None:
    """In a local worker process: exit when the sweep's process is gone (killed with SIGKILL),
    instead of lingering blocked on a result pipe that nobody reads."""
    global _WATCHING
    if _WATCHING or os.getpid() == parent or os.getppid() != parent:
        return  # in the sweep's own process, or not its child (a Dask worker): nothing to watch
    _WATCHING = True

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="fencesweep-watch-parent", daemon=True).start()


def work_root(out: Path) -> Path:
    """The work directory beside the output: OUT.partial/<salt[:16]>/chunk-*.parquet."""
    return out.with_name(out.name + ".partial")


def _bar(total: int, desc: str, enabled: bool, initial: int = 0):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit="scene", disable=(None if enabled else True),
                file=sys.stderr, dynamic_ncols=True, smoothing=0.05)


@contextlib.contextmanager
def _backend(backend: str, scheduler: str | None):
    """joblib's loky backend, or its dask backend on a running scheduler."""
    if backend == "loky":
        yield
        return
    try:
        import joblib
        from dask.distributed import Client
    except ImportError as exc:
        raise UsageError(f"--backend dask needs dask.distributed ({exc}); install it with "
                         f"pip install 'fencesweep[dask]'") from None
    try:
        client = Client(scheduler, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"--scheduler {scheduler!r}: cannot reach the Dask scheduler ({exc})") from None
    with client, joblib.parallel_config(backend="dask"):
        yield


def warm_up(plan: Plan, simulate: Callable | None = None) -> float:
    """Run one model of each variant (scene, drive, law, profile) in this process.

    This compiles the Numba kernels once here; with on-disk caching the workers then
    load them instead of compiling each. It also stops a sweep whose engine fails at
    once, before anything is dispatched. Returns the seconds it took.
    """
    fn = simulate or _engine()
    t0 = time.perf_counter()
    for m in plan.variants.values():
        vals = plan.model_vals(m)
        try:
            fn(vals, trajectory=False)
        except Exception as exc:
            raise RuntimeError(f"the engine failed on {plan.spec.describe(int(plan.first_row[m]))}: "
                               f"{type(exc).__name__}: {exc}") from exc
    return time.perf_counter() - t0


def time_sample(plan: Plan, simulate: Callable | None = None, budget: float = 2.0, most: int = 64) -> tuple:
    """Seconds per model run, timed on runs spread evenly over the sweep (after warm_up)."""
    fn = simulate or _engine()
    ids = np.unique(np.linspace(0, plan.n_models - 1, min(most, plan.n_models)).round().astype(int))
    t0 = time.perf_counter()
    k = 0
    for m in ids:
        try:
            fn(plan.model_vals(int(m)), trajectory=False)
        except Exception:  # timed all the same; the sweep records it as a failed row
            pass
        k += 1
        if time.perf_counter() - t0 > budget:
            break
    return (time.perf_counter() - t0) / k, k


PLAN_FILE = "plan.json"


def recorded_chunk_size(work: Path) -> int | None:
    """The chunk size an interrupted run of the same spec and engine used (None if none)."""
    try:
        size = json.loads((work / PLAN_FILE).read_text()).get("chunk_size")
    except (OSError, ValueError):
        return None
    return int(size) if isinstance(size, int) and size >= 1 else None


def chunks_done(plan: Plan, work: Path) -> list:
    """Chunks whose file is in `work` and complete (the others are computed)."""
    if not work.is_dir() or plan.chunk_size is None:
        return []
    return [c for c in range(plan.n_chunks)
            if store.chunk_complete(work / plan.chunk_name(c), len(plan.chunk_models(c)))]


def default_output(spec: S.Spec) -> Path:
    if spec.output:
        return Path(spec.output)
    stem = Path(spec.path).stem if spec.path else "sweep"
    return Path(f"{stem}.parquet")


@dataclass
class Outcome:
    out: Path
    n_scenes: int
    n_models: int
    n_chunks: int
    computed: int  # chunks computed by this call
    reused: int  # chunks found in the work directory
    seconds: float
    failed_runs: int = 0
    jobs: int | None = None  # local processes used (None: Dask)


def run_sweep(spec: S.Spec | str | Path, out: str | Path | None = None, jobs: int | None = None,
              resume: bool = True, backend: str = "loky", scheduler: str | None = None,
              progress: bool = False, simulate: Callable | None = None, plan: Plan | None = None,
              log: Callable[[str], None] | None = None, serial_below: float | None = None) -> Outcome:
    """Run a sweep and write its table. `simulate(vals, trajectory=False) -> (results, None)`
    defaults to fencesweep.api.simulate_resolved (tests pass a fake). A local sweep whose
    remaining work is estimated below `serial_below` seconds (default SERIAL_BELOW) runs
    in this process: starting workers would cost more than it saves."""
    import joblib

    t0 = time.perf_counter()
    log = log or (lambda msg: None)
    if not isinstance(spec, S.Spec):
        spec = S.load(spec)
    plan = plan or make_plan(spec, progress=progress)
    out = Path(out) if out is not None else default_output(spec)
    if jobs is None:
        jobs = joblib.cpu_count()
    root = work_root(out)
    work = root / plan.salt[:16]
    if root.exists():
        for old in root.iterdir():
            if not resume or old.name != work.name:
                log(f"removing {old} ({'--no-resume' if not resume else 'chunks of another spec or engine'})")
                shutil.rmtree(old) if old.is_dir() else old.unlink()
    work.mkdir(parents=True, exist_ok=True)
    per_run = None
    if plan.chunk_size is None:
        plan.chunk_size = recorded_chunk_size(work)
    if plan.chunk_size is None:  # first run: size the chunks from a short timed sample
        warm_up(plan, simulate)
        per_run, _ = time_sample(plan, simulate, budget=0.5, most=8)
        plan.chunk_size = auto_chunk_size(plan.n_models, per_run)
    state = {"spec": spec.normalized(), "spec_hash": spec.hash, "salt": plan.salt, "chunk_size": plan.chunk_size}
    with store.atomic_path(work / PLAN_FILE) as tmp:
        tmp.write_text(json.dumps(state, indent=1))
    rows_of = plan.chunk_rows()
    done = chunks_done(plan, work)
    pending = sorted(set(range(plan.n_chunks)) - set(done))
    if done:
        log(f"resuming: {len(done)} of {plan.n_chunks} chunks already in {work}")
    meta_chunk = {"salt": plan.salt}
    if pending:
        if per_run is None:
            warm_up(plan, simulate)
            per_run, _ = time_sample(plan, simulate, budget=0.3, most=8)
        work_left = per_run * sum(len(plan.chunk_models(c)) for c in pending)
        if backend == "loky" and jobs > 1 and local_jobs(jobs, work_left, serial_below) == 1:
            log(f"about {work_left:.1f} s of work: running in this process (starting workers costs more)")
            jobs = 1
        bar = _bar(plan.n_scenes - plan.skipped, Path(spec.path).stem if spec.path else "sweep", progress,
                   initial=int(rows_of[done].sum()) if done else 0)

        def tasks():
            for c in pending:
                ids = list(plan.chunk_models(c))
                local = backend == "loky"
                yield joblib.delayed(_run_chunk)(c, spec.scene, ids, [plan.model_vals(m) for m in ids], simulate,
                                                 os.getpid() if local else None,
                                                 str(work / plan.chunk_name(c)) if local else None,
                                                 dict(meta_chunk, chunk=c))

        try:
            with _backend(backend, scheduler):
                n_jobs = jobs if backend == "loky" else -1
                par = joblib.Parallel(n_jobs=n_jobs, return_as="generator_unordered", batch_size=1,
                                      pre_dispatch="2*n_jobs")
                for c, ids, rows in par(tasks()):
                    if rows is not None:  # Dask: the client writes
                        store.write_chunk(work / plan.chunk_name(c), spec.scene, ids, rows,
                                          dict(meta_chunk, chunk=c))
                    bar.update(int(rows_of[c]))
        finally:
            bar.close()
    failed = assemble(plan, work, out)
    shutil.rmtree(root)
    return Outcome(out, plan.n_scenes - plan.skipped, plan.n_models, plan.n_chunks, len(pending), len(done),
                   time.perf_counter() - t0, failed, jobs if backend == "loky" else None)


def table_meta(plan: Plan) -> dict:
    spec = plan.spec
    return {"spec": spec.normalized(), "spec_hash": spec.hash, "spec_source": spec.source,
            "versions": store.versions(), "scene": spec.scene,
            "counts": {"scenes": plan.n_scenes - plan.skipped, "skipped": plan.skipped,
                       "model_runs": plan.n_models}}


def assemble(plan: Plan, work: Path, out: Path) -> int:
    """Write the table: rows in scene order, parameters re-resolved, results from the chunks.

    Memory holds one block of rows and at most CHUNK_CACHE chunks. Returns the number of
    rows whose run raised (status 'failed: exception ...').
    """
    spec, size = plan.spec, plan.chunk_size
    schema = store.table_schema(spec.scene, table_meta(plan))
    pcols = store.param_columns()
    rcols = [(f.name, f.type) for f in store.result_schema(spec.scene)]
    np_type = {"double": np.float64, "int64": np.int64, "bool": np.bool_}
    cache: OrderedDict = OrderedDict()
    failed = 0

    def chunk(c: int) -> dict:
        if c in cache:
            cache.move_to_end(c)
            return cache[c]
        data = store.read_chunk(work / plan.chunk_name(c))
        cache[c] = data
        if len(cache) > CHUNK_CACHE:
            cache.popitem(last=False)
        return data

    with store.TableWriter(out, schema) as writer:
        for start in range(0, plan.n_scenes, ASSEMBLY_BLOCK):
            stop = min(plan.n_scenes, start + ASSEMBLY_BLOCK)
            rows = np.nonzero(plan.row_model[start:stop] >= 0)[0] + start
            if len(rows) == 0:
                continue
            cols = {name: [] for name, _ in pcols}
            for i in rows:
                vals = spec.resolve(int(i))
                vals["Psi"] = S.psi_of(vals)
                for name, _ in pcols:
                    cols[name].append(vals[name])
            models = plan.row_model[rows]
            which = models // size
            for name, typ in rcols:
                cols[name] = np.empty(len(rows), dtype=np_type.get(str(typ), object))
            for c in np.unique(which):
                sel = which == c
                local = models[sel] - c * size
                data = chunk(int(c))
                if not np.array_equal(data["_model"][local], models[sel]):
                    raise RuntimeError(f"chunk {c} in {work} does not hold the runs it should; "
                                       f"rerun with --no-resume")
                for name, _ in rcols:
                    cols[name][sel] = data[name][local]
            failed += int(sum(1 for s in cols["status"] if str(s).startswith("failed: exception")))
            writer.write(cols)
    return failed


# ------------------------------------------------------------------------------ dry run
def describe_plan(plan: Plan, out: Path) -> list:
    spec = plan.spec
    lines = [f"{spec.path or 'spec'}: scene {spec.scene}, {plan.n_scenes - plan.skipped} scenes "
             f"({spec.shape_text()}) -> {out}"]
    if plan.skipped:
        lines.append(f"  skipped (invalid: skip): {plan.skipped} scenes, e.g. {plan.skipped_examples[0]}")
    saved = plan.n_scenes - plan.skipped - plan.n_models
    lines.append(f"  distinct model runs: {plan.n_models}" + (f" ({saved} scenes share a run)" if saved else ""))
    if plan.chunk_size:
        lines.append(f"  chunks: {plan.n_chunks} of up to {plan.chunk_size} runs")
    for axis in unused_axes(spec):
        lines.append(f"  note: {axis} is not used by scene {spec.scene}; its values all give the same run")
    return lines


def __getattr__(name: str):
    """The grid command's parser and handler moved to fencesweep.cli (kept importable from here)."""
    if name in ("add_grid_parser", "cmd_grid"):
        from . import cli

        return getattr(cli, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
