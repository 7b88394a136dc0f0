"""Running a plan's pending chunks (step 3 of sweep/pipeline.py): in this process, on local worker
processes, or on a Dask cluster (sweep/cluster.py).

A task carries only its chunk's scene numbers; the worker resolves them, runs them and writes
the chunk atomically into the work directory (with Dask the client writes it), so results never
queue up in the parent. On Linux the local workers are forked from this process once it has
loaded the compiled kernels: they start at once and load nothing. Elsewhere they are loky
processes, which load the kernels from Numba's cache. A worker exits when the sweep's process
is gone, and Ctrl-C is the parent's to handle (it stops the workers). Dask's workers are warmed
up once, before their first chunk (sweep/cluster.py).
"""
from __future__ import annotations

import contextlib
import gc
import itertools
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, wait
from pathlib import Path
from typing import Callable, Iterable, Iterator

import numpy as np

from fencesweep.study.spec import spec as S
from fencesweep.study.spec.scenes import Scenes
from fencesweep.study.store import table as store
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import cluster, runs
from fencesweep.study.sweep.progress import bar as progress_bar

#: local workers: "fork" (inherit this process's loaded kernels; Linux) or "loky" (fresh processes)
START_METHOD = "fork" if sys.platform.startswith("linux") else "loky"


#: what every chunk of a sweep shares, (spec, simulate): set in each local worker by
#: _init_worker (inherited when forked), passed along with each task otherwise
_SHARED: tuple | None = None


def shared(given: tuple | None) -> tuple:
    """(spec, simulate) of a call: the one it was given, else the one its pool worker holds."""
    return given or _SHARED


def _run_chunk(c: int, ids: range, rows: np.ndarray, path: str | None, meta: dict,
               shared: tuple | None = None) -> tuple:
    """Run one chunk: resolve its scenes `rows` (one per model run `ids`), run them and, with
    `path` (local workers), write the chunk file and return no rows, so results never queue
    up in the parent; without (Dask), return the rows. Also returns (pid, start, ran, written)
    on the time.monotonic clock."""
    t0 = time.monotonic()
    spec, simulate = shared or _SHARED
    fn = simulate or runs.engine()
    vectors = prepared(spec, rows) if runs.takes_vectors(fn) else None
    results = runs.run_models(spec.scene, _resolved(spec, rows), fn, vectors)
    t1 = time.monotonic()
    if path is None:
        return c, results, (os.getpid(), t0, t1, t1)
    store.write_chunk(path, spec.scene, list(ids), results, meta)
    return c, None, (os.getpid(), t0, t1, time.monotonic())


#: (spec, its Scenes) of the last spec whose scenes this process resolved (_resolved)
_SCENES: tuple = (None, None)


def _scenes(spec: S.Spec) -> Scenes:
    """The Scenes of `spec` (spec/scenes.py), kept in this process for the sweep's next chunks:
    resolve runs once per combination of core values."""
    global _SCENES
    if _SCENES[0] is not spec:
        _SCENES = (spec, Scenes(spec))
    return _SCENES[1]


def _resolved(spec: S.Spec, rows) -> list:
    """spec.resolve of each scene of `rows`, on whole columns (_scenes)."""
    return _scenes(spec).resolved(rows)


def prepared(spec: S.Spec, rows, table: bool = True):
    """The parameter vectors of the scenes `rows` (prepare.Vectors), prepared on whole columns
    (prepare.prepare_columns on Scenes.value_columns); None where that raises: each run then
    prepares its own, and a run that cannot is a failed row naming the exception."""
    from fencesweep.model.prepare import COLUMNS, prepare_columns

    try:
        return prepare_columns(_scenes(spec).value_columns(rows, COLUMNS), len(rows), table)
    except Exception:  # found run by run, and recorded, by the caller
        return None


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


def start_pool(stack: contextlib.ExitStack, jobs: int, spec: S.Spec, simulate: Callable | None):
    """`jobs` local worker processes for the sweep of `spec`, entered on `stack` (they stop when it
    closes): the chunks run on them, and then the verification's re-runs (submit_reruns), which
    are too few to pay for starting workers of their own."""
    return stack.enter_context(_pool(jobs, (spec, simulate), START_METHOD))


def run_calls(stack: contextlib.ExitStack, make_calls: Callable, jobs: int, local: bool, scheduler: str | None,
              shared: tuple, pool=None, warm: list | None = None) -> Iterator:
    """The results of calls (fn, *args), as they finish: in this process (jobs 1), on `pool`
    (start_pool) or else on `jobs` local worker processes (entered on `stack`: they stop when it
    closes), or on Dask (sweep/cluster.py; with `warm`, scenes to warm every worker up with first).
    make_calls(where) yields the calls for where = "here", "pool" or "dask"; each fn takes the
    sweep's `shared` (spec, simulate) as its last argument, which a pool's workers already hold
    (_init_worker): calls for "pool" pass None."""
    if not local:
        client = stack.enter_context(cluster.connect(scheduler, None if warm is None else (shared[0], warm, shared[1])))
        return cluster.results(client, make_calls("dask"), shared)
    if pool is None and jobs == 1:
        return (fn(*args) for fn, *args in make_calls("here"))
    pool = pool or stack.enter_context(_pool(jobs, shared, START_METHOD))
    return _completed(pool, make_calls("pool"), ahead=2 * jobs)  # forks here, before a progress bar's thread


def compute_chunks(plan: PL.Plan, spec: S.Spec, work: Path, pending: list, done: list, jobs: int,
                   local: bool, scheduler: str | None, progress: bool, simulate: Callable | None,
                   meta_chunk: dict, pool=None, finished: Callable[[int], None] | None = None) -> list:
    """Run the pending chunks (in this process, on `pool` or a local pool of their own, or on
    Dask) with a progress bar;
    every chunk is written as it completes (by the worker; with Dask by this process), then
    `finished(chunk)` is called here (chunks.ChunkTables.finished reads it). A
    chunk that cannot be written (a full disk) raises WriteError: the workers are stopped and
    the chunks written so far are kept. Returns the workers' timing records."""
    rows_of = plan.chunk_rows()
    shared = (spec, simulate)

    def calls(where: str):
        for c in pending:
            ids = plan.chunk_models(c)
            yield (_run_chunk, c, ids, plan.first_row[ids.start:ids.stop],
                   str(work / plan.chunk_name(c)) if where != "dask" else None, dict(meta_chunk, chunk=c),
                   shared if where != "pool" else None)

    stats = []
    with contextlib.ExitStack() as stack:
        warm = None if local else [int(plan.first_row[m]) for m in plan.variants.values()]  # as runs.warm_up
        results = run_calls(stack, calls, jobs, local, scheduler, shared, pool, warm)
        bar = stack.enter_context(contextlib.closing(progress_bar(
            plan.n_scenes - plan.skipped, Path(spec.path).stem if spec.path else "sweep", progress,
            initial=int(rows_of[done].sum()) if done else 0)))
        for c, rows, stat in results:
            if rows is not None:  # Dask: the client writes
                store.write_chunk(work / plan.chunk_name(c), spec.scene, list(plan.chunk_models(c)), rows,
                                  dict(meta_chunk, chunk=c))
            stats.append(stat)
            bar.update(int(rows_of[c]))
            if finished is not None:
                finished(c)
    return stats


def _rerun(rows: list, step_factor_scale: float, shared: tuple | None = None) -> list:
    """Run the scenes `rows` again with their step_factor times `step_factor_scale` (the rest of
    their parameters unchanged): [(row, results)], a stream's as one chunk row (store.stream_row)."""
    spec, simulate = shared or _SHARED
    out = []
    for i, vals in zip(rows, _resolved(spec, rows)):
        vals = dict(vals, step_factor=float(vals["step_factor"]) * step_factor_scale)
        out.append((int(i), runs.run_one(spec.scene, vals, simulate)))
    return out


def _rerun_groups(rows: list, jobs: int, local: bool) -> list:
    n_tasks = 1 if local and jobs == 1 else 4 * (jobs if local else 8)
    return [list(rows[k::n_tasks]) for k in range(min(n_tasks, len(rows)))]


def rerun_scenes(spec: S.Spec, rows: list, step_factor_scale: float, jobs: int, local: bool, scheduler: str | None,
                 simulate: Callable | None) -> dict:
    """Run the scenes `rows` again at step_factor x `step_factor_scale` (the verification,
    sweep/verify.py), on the same machinery as the chunks; {row: results}."""
    shared = (spec, simulate)

    def calls(where: str):
        for group in _rerun_groups(rows, jobs, local):
            yield (_rerun, group, step_factor_scale, shared if where != "pool" else None)

    out = {}
    with contextlib.ExitStack() as stack:
        for pairs in run_calls(stack, calls, jobs, local, scheduler, shared):
            out.update(pairs)
    return out


def submit_reruns(pool, rows: list, step_factor_scale: float, jobs: int) -> Callable[[], dict]:
    """rerun_scenes on the sweep's running workers (start_pool): submitted now, so that they run
    while this process makes the table's first block and reads the table's values (verify.begin);
    returns the function that waits for them and gives {row: results}."""
    futures = [pool.submit(_rerun, group, step_factor_scale, None) for group in _rerun_groups(rows, jobs, True)]

    def results() -> dict:
        out = {}
        for fut in futures:
            out.update(fut.result())
        return out

    return results


def worker_timings(stats: list) -> dict:
    """Sum over the chunks of the workers' run and write seconds, and how unevenly they ended."""
    if not stats:
        return {}
    ends: dict = {}
    for pid, _, _, written in stats:
        ends[pid] = max(ends.get(pid, written), written)
    return {"runs": sum(ran - start for _, start, ran, _ in stats),
            "writes": sum(written - ran for _, _, ran, written in stats),
            "workers": len(ends), "tail": max(ends.values()) - min(ends.values())}
