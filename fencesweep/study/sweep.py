"""Sweeps: spec -> scenes -> distinct model runs -> parallel chunks -> one Parquet table.

1. plan: every scene of the spec is resolved (params.resolve) once, up front, so any bad
   combination is reported before work starts, and mapped to its model run by
   params.model_key: scenes that differ only in parameters their model does not use
   (B2, K2 under a rigid drive, ...) share one run (MODEL.md §8). The same pass
   writes the parameter columns of the table, block by block, into the work directory.
2. The distinct runs, numbered in order of first appearance, are cut into chunks of
   `chunk_size` runs: the spec's, or sized from a short timed sample to take about
   CHUNK_SECONDS each (dispatch and writing then cost well under 1 %), and recorded in
   the work directory so that a resumed sweep cuts the same chunks. A chunk's file name
   carries a digest of the spec hash, the package's source hash, its chunk size and the
   model keys of its runs, so a changed spec or engine never reuses a stale chunk.
3. Pending chunks run in parallel: locally in worker processes, or on a Dask cluster
   through joblib. A task carries only its chunk's scene numbers; the worker resolves
   them, runs them and writes the chunk atomically into the work directory `OUT.partial/`
   beside the output (with Dask the client writes it), so results never queue up in the
   parent. A killed sweep, rerun, computes only the chunks that are missing.
   On Linux the local workers are forked from this process once it has loaded the
   compiled kernels (which takes about as long as planning, so a forked helper plans
   meanwhile): they start at once and load nothing. Elsewhere they are loky processes.
4. The table is assembled block by block from the parameter blocks and the chunks (rows in
   scene order) into one Parquet file, atomically; then the work directory is removed.

Results depend only on each run's parameters, and the assembly only on the plan: the
table is the same, bit for bit, whatever --jobs or backend.
"""
from __future__ import annotations

import contextlib
import gc
import hashlib
import io
import itertools
import json
import math
import multiprocessing
import os
import pickle
import shutil
import signal
import sys
import threading
import time
from collections import OrderedDict
from concurrent.futures import FIRST_COMPLETED, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Iterator

import numpy as np

from fencesweep.model import params as P
from fencesweep.study import spec as S
from fencesweep.study import store
from fencesweep import resources
from fencesweep.errors import UsageError

#: chunk size rule: chunks of about CHUNK_SECONDS of work, at least MIN_CHUNKS of them.
#: A chunk costs ~0.6-2 ms of dispatch and ~2-15 ms to write (benchmarks/sweep_dispatch.py),
#: i.e. < 1.5 % of one second; MIN_CHUNKS keeps small sweeps balanced and resumable.
CHUNK_SECONDS, MIN_CHUNKS, CHUNK_MAX = 1.0, 16, 2_000  # CHUNK_MAX bounds the memory in flight
ASSEMBLY_BLOCK = 16_384  # rows per Parquet row group of the final table (and per parameter block)
CHUNK_CACHE = 8  # chunks held in memory while assembling
SERIAL_BELOW = 3.0  # seconds of estimated work under which a local sweep runs in-process
#: local workers: "fork" (inherit this process's loaded kernels; Linux) or "loky" (fresh processes)
START_METHOD = "fork" if sys.platform.startswith("linux") else "loky"
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


def plan_salt(spec: S.Spec) -> str:
    """Digest of the spec and the engine: names the work directory and salts the chunk names."""
    v = store.versions()
    return hashlib.sha256(f"{spec.hash}:{v['fencesweep']}:{v['source_hash']}".encode()).hexdigest()


def _key_digester() -> Callable[[tuple], bytes]:
    """model key -> 16-byte blake2b digest of its pickle (binary floats: 4x faster than repr).

    The pickler runs without a memo, so equal keys always give the same bytes."""
    buf = io.BytesIO()
    pickler = pickle.Pickler(buf, protocol=5)
    pickler.fast = True

    def digest(key: tuple) -> bytes:
        buf.seek(0)
        buf.truncate()
        pickler.dump(key)
        return hashlib.blake2b(buf.getvalue(), digest_size=16).digest()

    return digest


def _param_columns() -> dict:
    return {name: [] for name, _ in store.param_columns()}


def _add_params(cols: dict, vals: dict) -> None:
    """Append one scene's row of the table's label and parameter columns (Psi derived)."""
    for name, col in cols.items():
        col.append(S.psi_of(vals) if name == "Psi" else vals[name])


def _params_path(work: Path, block: int) -> Path:
    return work / f"params-{ASSEMBLY_BLOCK}-{block:06d}.parquet"


#: memory per scene at the peak of make_plan (model-key digests, their np.unique, the map
#: scene -> run): 132 bytes measured with tracemalloc on 200 000 scenes, with a margin
PLAN_BYTES_PER_SCENE = 160


def _gib(n_bytes: float) -> str:
    return f"{n_bytes / 2**30:,.1f} GiB"


def plan_size_problem(spec: S.Spec) -> str | None:
    """Why `spec` is too large to plan in this machine's memory (its scene count, the limit and
    what to do), or None. Counts only: nothing proportional to the scenes is allocated."""
    n, avail = spec.n_scenes, resources.available_memory()
    if avail is None or n * PLAN_BYTES_PER_SCENE <= avail:
        return None
    most = avail // PLAN_BYTES_PER_SCENE
    pieces, names = 1, []  # split over the outermost dimensions until a piece fits
    for where, size in [("cases", len(spec.cases))] + [(a.where, len(a)) for a in spec.axes]:
        if n // pieces <= most:
            break
        pieces *= size
        names += [where] if size > 1 else []
    hint = (f" (one spec per value of {' x '.join(names)} gives {pieces} specs of {n // pieces} scenes)"
            if n // pieces <= most else "")
    return (f"{spec.path or 'the spec'} expands to {n} scenes ({spec.shape_text()}); planning them needs about "
            f"{_gib(n * PLAN_BYTES_PER_SCENE)} of memory ({PLAN_BYTES_PER_SCENE} bytes per scene), more than the "
            f"{_gib(avail)} available here, which hold at most {most} scenes. Split it into specs of at most "
            f"{most} scenes{hint}, or give its axes fewer values")


def make_plan(spec: S.Spec, progress: bool = False, params_dir: Path | None = None) -> Plan:
    """Resolve every scene (raising SpecError on the first bad one) and deduplicate the runs.

    With `params_dir`, the label and parameter columns of the table are written there too,
    one file per ASSEMBLY_BLOCK scenes, so that assembling the table resolves nothing again.

    Memory: PLAN_BYTES_PER_SCENE at the peak (16 bytes of model-key digest per scene while
    resolving, more at the np.unique), then 8 (its model number) plus 24 per distinct run;
    no Python object per scene is kept. A spec too large for the memory available raises
    UsageError (plan_size_problem) before anything is allocated.
    """
    problem = plan_size_problem(spec)
    if problem:
        raise UsageError(problem)
    n = spec.n_scenes
    keys = bytearray(16 * n)  # blake2b digest of each scene's model key
    valid = np.ones(n, dtype=bool)
    variants_row: dict = {}
    skipped, examples = 0, []
    digest = _key_digester()
    bar = _bar(n, "checking", progress and n > 20_000)
    try:
        for block, start in enumerate(range(0, n, ASSEMBLY_BLOCK)):
            stop = min(n, start + ASSEMBLY_BLOCK)
            cols = _param_columns() if params_dir is not None else None
            for i in range(start, stop):
                try:
                    vals = spec.resolve(i)
                except P.ParameterError as exc:
                    if spec.invalid == "skip":
                        valid[i] = False
                        skipped += 1
                        if len(examples) < 3:
                            examples.append(f"{spec.describe(i)}: {exc}")
                        continue
                    raise S.SpecError(f"{spec.describe(i)}: {exc}") from None
                keys[16 * i:16 * i + 16] = digest(P.model_key(vals))
                variants_row.setdefault((spec.scene,) + tuple(vals[c] for c in _CHOICES), i)
                if cols is not None:
                    _add_params(cols, vals)
            if cols is not None and cols["scene"]:
                store.write_table_atomic(store.param_table(cols), _params_path(params_dir, block), fsync=False)
            bar.update(stop - start)
    finally:
        bar.close()
    if skipped == n:
        raise S.SpecError(f"every one of the {n} scenes is invalid (invalid: skip); e.g. {examples[0]}")
    rows = np.nonzero(valid)[0]
    uniq, first, inverse = np.unique(np.frombuffer(keys, dtype="V16")[rows], return_index=True,
                                     return_inverse=True)
    del keys
    order = np.argsort(first, kind="stable")  # model runs numbered in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    row_model = np.full(n, -1, dtype=np.int64)
    row_model[rows] = rank[inverse.ravel()]
    first_row = rows[first[order]].astype(np.int64)
    digests = uniq[order].tobytes()
    variants = {k: int(row_model[i]) for k, i in variants_row.items()}
    return Plan(spec, row_model, first_row, digests, spec.chunk_size, variants, skipped, examples,
                plan_salt(spec))


def unused_axes(spec: S.Spec) -> list:
    """Axes over parameters that the scene's model never uses (every value gives the same run)."""
    uses = P.SCENE_USES[spec.scene] | {"step_factor", "Psi"}
    return [f"{a.where} ({n})" for a in spec.axes for n in a.names if n not in uses]


# ------------------------------------------------------------------------------ running
def _engine() -> Callable:
    from fencesweep.model import simulate as api

    return api.simulate_resolved


def run_models(scene: str, vals_list: list, simulate: Callable | None = None) -> list:
    """Run each parameter set; a run that raises becomes a row with outcome failed and the reason."""
    fn = simulate or _engine()
    rows = []
    for vals in vals_list:
        try:
            res, _ = fn(vals, trajectory=False)
            if scene == "stream":
                res = store.stream_row(res)
        except Exception as exc:  # recorded, never silent: status names the exception
            res = store.failed_result(scene, f"failed: exception {type(exc).__name__}: {exc}")
        rows.append(res)
    return rows


#: what every chunk of a sweep shares, (spec, simulate): set in each local worker by
#: _init_worker (inherited when forked), passed along with each task otherwise
_SHARED: tuple | None = None


def _run_chunk(c: int, ids: range, rows: np.ndarray, path: str | None, meta: dict,
               shared: tuple | None = None) -> tuple:
    """Run one chunk: resolve its scenes `rows` (one per model run `ids`), run them and, with
    `path` (local workers), write the chunk file and return no rows, so results never queue
    up in the parent; without (Dask), return the rows. Also returns (pid, start, ran, written)
    on the time.monotonic clock."""
    t0 = time.monotonic()
    spec, simulate = shared or _SHARED
    results = run_models(spec.scene, [spec.resolve(int(i)) for i in rows], simulate)
    t1 = time.monotonic()
    if path is None:
        return c, results, (os.getpid(), t0, t1, t1)
    store.write_chunk(path, spec.scene, list(ids), results, meta)
    return c, None, (os.getpid(), t0, t1, time.monotonic())


def _init_worker(shared: tuple | None, parent: int) -> None:
    """In each local worker process: the sweep's spec and engine; Ctrl-C is the parent's to
    handle (it stops the workers); exit when the parent is gone."""
    global _SHARED
    _SHARED = shared
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _watch_parent(parent)


_WATCHING = False


def _watch_parent(parent: int) -> None:
    """In a local worker process: exit when the sweep's process is gone (killed with SIGKILL),
    instead of lingering blocked on a result pipe that nobody reads."""
    global _WATCHING
    if _WATCHING or os.getpid() == parent or os.getppid() != parent:
        return  # in the sweep's own process, or not its child: nothing to watch
    _WATCHING = True

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="fencesweep-watch-parent", daemon=True).start()


def _start_pool(jobs: int, shared: tuple | None, method: str):
    """An executor of `jobs` local worker processes, each set up by _init_worker."""
    args = (shared, os.getpid())
    if method == "fork":
        from concurrent.futures import ProcessPoolExecutor

        return ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("fork"),
                                   initializer=_init_worker, initargs=args)
    from joblib.externals.loky import ProcessPoolExecutor

    return ProcessPoolExecutor(jobs, initializer=_init_worker, initargs=args)


def _stop_pool(pool, kill: bool) -> None:
    """Shut a pool down; with `kill` (an error or Ctrl-C) at once, stopping running tasks."""
    if not kill:
        pool.shutdown(wait=True)
    elif "kill_workers" in pool.shutdown.__code__.co_varnames:  # loky
        pool.shutdown(wait=False, kill_workers=True)
    else:
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in list((getattr(pool, "_processes", None) or {}).values()):
            with contextlib.suppress(Exception):
                proc.terminate()


@contextlib.contextmanager
def _pool(jobs: int, shared: tuple | None, method: str):
    """A pool of local workers for a with-block. Forked ones share this process's memory
    pages until one side writes to them, and a garbage collection writes to every object it
    scans: so the objects made so far are frozen out of collections (gc.freeze) while the
    pool lives. Measured on the main job with 2 jobs: the parent's kernel load beside the
    forked planning helper 0.37-0.41 s before, 0.345-0.348 s with the freeze."""
    if method == "fork":
        gc.freeze()
    pool = _start_pool(jobs, shared, method)
    try:
        yield pool
    except BaseException:
        _stop_pool(pool, kill=True)
        raise
    else:
        _stop_pool(pool, kill=False)
    finally:
        if method == "fork":
            gc.unfreeze()


def _completed(pool, calls: Iterable[tuple], ahead: int) -> Iterator:
    """Submit calls (fn, *args) to `pool`, at most `ahead` in flight; return an iterator of
    their results as they finish. The first ones are submitted here (for a forked pool:
    the workers are forked now)."""
    calls = iter(calls)
    running = {pool.submit(*call) for call in itertools.islice(calls, ahead)}

    def results():
        nonlocal running
        while running:
            done, running = wait(running, return_when=FIRST_COMPLETED)
            running |= {pool.submit(*call) for call in itertools.islice(calls, len(done))}
            for fut in done:
                yield fut.result()

    return results()


def work_root(out: Path) -> Path:
    """The work directory beside the output: OUT.partial/<salt[:16]>/chunk-*.parquet."""
    return out.with_name(out.name + ".partial")


def _bar(total: int, desc: str, enabled: bool, initial: int = 0):
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit="scene", disable=(None if enabled else True),
                file=sys.stderr, dynamic_ncols=True, smoothing=0.05)


@contextlib.contextmanager
def _dask(scheduler: str | None):
    """joblib's dask backend on a running scheduler."""
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


def _warm_rows(spec: S.Spec, rows: Iterable[int], fn: Callable) -> None:
    for i in rows:
        vals = spec.resolve(int(i))
        try:
            fn(vals, trajectory=False)
        except Exception as exc:
            raise RuntimeError(f"the engine failed on {spec.describe(int(i))}: "
                               f"{type(exc).__name__}: {exc}") from exc


def warm_up(plan: Plan, simulate: Callable | None = None) -> float:
    """Run one model of each variant (scene, drive, law, profile) in this process.

    This loads (or compiles, once, into Numba's on-disk cache) the kernels here; forked
    workers inherit them, loky workers load them from the cache. It also stops a sweep
    whose engine fails at once, before anything is dispatched. Returns the seconds it took.
    """
    t0 = time.perf_counter()
    _warm_rows(plan.spec, (plan.first_row[m] for m in plan.variants.values()), simulate or _engine())
    return time.perf_counter() - t0


def _plan_while_loading(spec: S.Spec, progress: bool, params_dir: Path, simulate: Callable | None) -> tuple:
    """make_plan in a forked helper process while this process loads the kernels on the
    first valid scene; returns (plan, seconds the kernels took to load)."""
    with _pool(1, None, "fork") as helper:
        planned = helper.submit(make_plan, spec, progress, params_dir)
        t0 = time.perf_counter()
        fn = simulate or _engine()
        for i in range(min(spec.n_scenes, 100)):
            try:
                vals = spec.resolve(i)
            except P.ParameterError:
                continue
            with contextlib.suppress(Exception):  # warm_up reports a failing engine
                fn(vals, trajectory=False)
            break
        loaded = time.perf_counter() - t0
        return planned.result(), loaded


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


def saved_chunks(spec: S.Spec, out: Path) -> tuple:
    """(work directory, chunks saved in it, chunks in all or None) of an interrupted sweep."""
    work = work_root(Path(out)) / plan_salt(spec)[:16]
    saved = len(list(work.glob("chunk-*.parquet"))) if work.exists() else 0
    try:
        total = json.loads((work / PLAN_FILE).read_text()).get("n_chunks")
    except (OSError, ValueError):
        total = None
    return work, saved, total


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
    #: where the time went: seconds of this process's phases (plan, load, sample, compute,
    #: assemble) and, summed over the chunks, of the workers' runs and chunk writes
    timings: dict = field(default_factory=dict)


def _spec_label(path: str | None, spec_hash: str) -> str:
    """A spec as messages name it: its file (when known) and the start of its hash."""
    return f"{path} (spec hash {spec_hash[:12]})" if path else f"a spec with hash {spec_hash[:12]}"


def check_output(spec: S.Spec, out: Path) -> None:
    """Refuse (UsageError, naming both specs) to destroy another spec's results at `out`: the
    table there, or the saved chunks of its unfinished run in OUT.partial/. The same spec's
    table is replaced by a rerun and its chunks are resumed; chunks of the same spec from
    another engine can never be reused and are removed."""
    this = _spec_label(spec.path, spec.hash)
    if out.exists():
        try:
            meta = store.read_metadata(out)
        except (OSError, ValueError):  # not Parquet (pyarrow.ArrowInvalid is a ValueError)
            meta = {}
        if not isinstance(meta.get("spec_hash"), str):
            raise UsageError(f"{out} exists and is not a table written by fencesweep grid; not replacing it "
                             f"with the results of {this}: choose another --out, or add --overwrite to "
                             f"replace it")
        if meta["spec_hash"] != spec.hash:
            that = _spec_label(meta.get("spec_path"), meta["spec_hash"])
            raise UsageError(f"{out} holds the results of another spec, {that}; this is {this}. Not replacing "
                             f"it: choose another --out, or add --overwrite to replace it")
    root = work_root(out)
    for work in sorted(root.iterdir()) if root.is_dir() else ():
        try:
            state = json.loads((work / PLAN_FILE).read_text())
        except (OSError, ValueError):  # planning never finished there: no chunk was saved
            continue
        saved = len(list(work.glob("chunk-*.parquet")))
        other = state.get("spec_hash")
        if saved and isinstance(other, str) and other != spec.hash:
            that = _spec_label(state.get("spec_path"), other)
            raise UsageError(f"{root} holds the unfinished run of another spec, {that} ({saved} of "
                             f"{state.get('n_chunks', '?')} chunks saved); this is {this}. Not discarding it: "
                             f"finish that run first (the same command with its spec), choose another --out, "
                             f"or add --overwrite to discard it")


def check_can_start(spec: S.Spec, out: Path, overwrite: bool = False) -> None:
    """Raise UsageError if a sweep of `spec` into `out` must not start: too large to plan
    (plan_size_problem), or, without `overwrite`, another spec's results at `out` (check_output)."""
    problem = plan_size_problem(spec)
    if problem:
        raise UsageError(problem)
    if not overwrite:
        check_output(spec, out)


def _open_work(root: Path, work: Path, resume: bool, log: Callable[[str], None]) -> bool:
    """Make the sweep's work directory: remove other specs' (or, without resume, all) chunks
    and the temporary files of a worker killed while writing. Returns whether it was new."""
    if root.exists():
        for old in root.iterdir():
            if not resume or old.name != work.name:
                log(f"removing {old} ({'--no-resume' if not resume else 'chunks of another spec or engine'})")
                shutil.rmtree(old) if old.is_dir() else old.unlink()
    made = not work.exists()
    work.mkdir(parents=True, exist_ok=True)
    for tmp in work.glob(".fencesweep-tmp-*"):  # left by a worker killed while writing
        tmp.unlink(missing_ok=True)
    return made


def _compute(plan: Plan, spec: S.Spec, work: Path, pending: list, done: list, jobs: int, local: bool,
             scheduler: str | None, progress: bool, simulate: Callable | None, meta_chunk: dict) -> list:
    """Run the pending chunks (in this process, a local pool, or Dask) with a progress bar;
    every chunk is written as it completes. Returns the workers' timing records."""
    rows_of = plan.chunk_rows()
    shared = (spec, simulate)

    def calls(write: bool, with_shared: bool):
        for c in pending:
            ids = plan.chunk_models(c)
            yield (_run_chunk, c, ids, plan.first_row[ids.start:ids.stop],
                   str(work / plan.chunk_name(c)) if write else None, dict(meta_chunk, chunk=c),
                   shared if with_shared else None)

    stats = []
    with contextlib.ExitStack() as stack:
        if not local:
            import joblib

            stack.enter_context(_dask(scheduler))
            results = joblib.Parallel(n_jobs=-1, return_as="generator_unordered", batch_size=1,
                                      pre_dispatch="2*n_jobs")(
                joblib.delayed(fn)(*args) for fn, *args in calls(False, True))
        elif jobs == 1:
            results = (fn(*args) for fn, *args in calls(True, True))
        else:
            pool = stack.enter_context(_pool(jobs, shared, START_METHOD))
            results = _completed(pool, calls(True, False), ahead=2 * jobs)  # forks before the bar's thread
        bar = stack.enter_context(contextlib.closing(_bar(
            plan.n_scenes - plan.skipped, Path(spec.path).stem if spec.path else "sweep", progress,
            initial=int(rows_of[done].sum()) if done else 0)))
        for c, rows, stat in results:
            if rows is not None:  # Dask: the client writes
                store.write_chunk(work / plan.chunk_name(c), spec.scene, list(plan.chunk_models(c)), rows,
                                  dict(meta_chunk, chunk=c))
            stats.append(stat)
            bar.update(int(rows_of[c]))
    return stats


def run_sweep(spec: S.Spec, out: str | Path | None = None, jobs: int | None = None,  # noqa: C901 (16)
              resume: bool = True, backend: str = "loky", scheduler: str | None = None,
              progress: bool = False, simulate: Callable | None = None, plan: Plan | None = None,
              log: Callable[[str], None] | None = None, serial_below: float | None = None,
              overwrite: bool = False) -> Outcome:
    """Run a sweep and write its table. `simulate(vals, trajectory=False) -> (results, None)`
    defaults to fencesweep.model.simulate.simulate_resolved (tests pass a fake). A local sweep whose
    remaining work is estimated below `serial_below` seconds (default SERIAL_BELOW) runs
    in this process: starting workers would cost more than it saves. `log` receives the
    notes a user should see (skipped scenes, unused axes, resuming). Without `overwrite`,
    another spec's table or unfinished run at `out` stops the sweep before it starts
    (check_output)."""
    t0 = time.perf_counter()
    log = log or (lambda msg: None)
    if not isinstance(spec, S.Spec):
        raise TypeError(f"run_sweep takes a spec.Spec (specfile.load reads one from YAML), not {spec!r}")
    out = Path(out) if out is not None else default_output(spec)
    check_can_start(spec, out, overwrite)  # before anything is made or removed
    if jobs is None:
        import joblib

        jobs = joblib.cpu_count()
    local = backend == "loky"
    root = work_root(out)
    work = root / (plan.salt if plan is not None else plan_salt(spec))[:16]
    made = _open_work(root, work, resume, log)
    timings = {}
    forking = local and jobs > 1 and START_METHOD == "fork"
    if plan is None:
        t = time.perf_counter()
        try:
            if forking:
                plan, timings["load"] = _plan_while_loading(spec, progress, work, simulate)
            else:
                plan = make_plan(spec, progress=progress, params_dir=work)
        except BaseException:  # a bad spec (or Ctrl-C): nothing of this planning is worth keeping
            if made:
                shutil.rmtree(work, ignore_errors=True)
                with contextlib.suppress(OSError):
                    root.rmdir()
            raise
        timings["plan"] = time.perf_counter() - t
        for line in describe_plan(plan, out)[1:]:
            if "note:" in line or "skipped" in line:
                log(line.strip())
    per_run = None
    if plan.chunk_size is None:
        plan.chunk_size = recorded_chunk_size(work)
    if plan.chunk_size is None:  # first run: size the chunks from a short timed sample
        timings["warm_up"] = warm_up(plan, simulate)
        per_run, _ = time_sample(plan, simulate, budget=0.5, most=8)
        plan.chunk_size = auto_chunk_size(plan.n_models, per_run)
    state = {"spec": spec.normalized(), "spec_hash": spec.hash, "spec_path": spec.path, "salt": plan.salt,
             "chunk_size": plan.chunk_size, "n_chunks": plan.n_chunks}
    with store.atomic_path(work / PLAN_FILE) as tmp:
        tmp.write_text(json.dumps(state, indent=1))
    done = chunks_done(plan, work)
    pending = sorted(set(range(plan.n_chunks)) - set(done))
    if done:
        log(f"resuming: {len(done)} of {plan.n_chunks} chunks already in {work}")
    meta_chunk = {"salt": plan.salt}
    if pending:
        if per_run is None:
            timings["warm_up"] = warm_up(plan, simulate)
            per_run, _ = time_sample(plan, simulate, budget=0.3, most=8)
        if local:
            work_left = per_run * sum(len(plan.chunk_models(c)) for c in pending)
            if jobs > 1 and local_jobs(jobs, work_left, serial_below) == 1:
                log(f"about {work_left:.1f} s of work: running in this process (starting workers costs more)")
                jobs = 1
        t = time.perf_counter()
        stats = _compute(plan, spec, work, pending, done, jobs, local, scheduler, progress, simulate, meta_chunk)
        timings["compute"] = time.perf_counter() - t
        timings.update(_worker_timings(stats))
    t = time.perf_counter()
    failed = assemble(plan, work, out)
    timings["assemble"] = time.perf_counter() - t
    shutil.rmtree(root)
    return Outcome(out, plan.n_scenes - plan.skipped, plan.n_models, plan.n_chunks, len(pending), len(done),
                   time.perf_counter() - t0, failed, jobs if local else None, timings)


def _worker_timings(stats: list) -> dict:
    """Sum over the chunks of the workers' run and write seconds, and how unevenly they ended."""
    if not stats:
        return {}
    ends: dict = {}
    for pid, _, _, written in stats:
        ends[pid] = max(ends.get(pid, written), written)
    return {"runs": sum(ran - start for _, start, ran, _ in stats),
            "writes": sum(written - ran for _, _, ran, written in stats),
            "workers": len(ends), "tail": max(ends.values()) - min(ends.values())}


def table_meta(plan: Plan) -> dict:
    spec = plan.spec
    return {"spec": spec.normalized(), "spec_hash": spec.hash, "spec_source": spec.source, "spec_path": spec.path,
            "versions": store.versions(), "scene": spec.scene,
            "counts": {"scenes": plan.n_scenes - plan.skipped, "skipped": plan.skipped,
                       "model_runs": plan.n_models}}


def _block_params(plan: Plan, work: Path, block: int, rows: np.ndarray):
    """The label and parameter columns of the scenes `rows` of one block: from the file that
    make_plan wrote, or resolved here if there is none."""
    table = store.read_param_table(_params_path(work, block))
    if table is not None and table.num_rows == len(rows):
        return table
    cols = _param_columns()
    for i in rows:
        _add_params(cols, plan.spec.resolve(int(i)))
    return store.param_table(cols)


def _table_rows(scene: str, cols: dict, n_params: int) -> dict:
    """A block's columns, one entry per scene, as the table's rows: for `stream` one per cycle
    (MODEL.md §14, store.explode_streams), for the other scenes the same."""
    return store.explode_streams(cols, n_params) if scene == "stream" else cols


def assemble(plan: Plan, work: Path, out: Path) -> int:
    """Write the table: rows in scene order, parameters from the planning pass, results from the chunks.

    Memory holds one block of rows and at most CHUNK_CACHE chunks. Returns the number of
    rows whose run raised (status 'failed: exception ...').
    """
    spec, size = plan.spec, plan.chunk_size
    schema = store.table_schema(spec.scene, table_meta(plan))
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
        for block, start in enumerate(range(0, plan.n_scenes, ASSEMBLY_BLOCK)):
            stop = min(plan.n_scenes, start + ASSEMBLY_BLOCK)
            rows = np.nonzero(plan.row_model[start:stop] >= 0)[0] + start
            if len(rows) == 0:
                continue
            params = _block_params(plan, work, block, rows)
            cols = {name: params.column(name) for name in params.column_names}
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
            cols = _table_rows(spec.scene, cols, len(params.column_names))
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
