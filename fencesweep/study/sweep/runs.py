"""Model runs in this process: the engine, a list of runs with their failures recorded, and the
warm-up and the short timed sample that load the kernels and size a sweep's chunks (step 2 of
sweep/pipeline.py).

The engine is fencesweep.model.simulate.simulate_resolved, looked up when it is called (tests
pass a fake as `simulate`, or replace it there).
"""
from __future__ import annotations

import inspect
import math
import time
from typing import Callable, Iterable

import numpy as np

from fencesweep.study.spec import spec as S
from fencesweep.study.store import table as store
from fencesweep.study.sweep.plan import Plan

#: chunk size rule: chunks of about CHUNK_SECONDS of work, at least MIN_CHUNKS of them.
#: A chunk costs ~0.6-2 ms of dispatch and ~2-15 ms to write (benchmarks/sweep_dispatch_*.txt),
#: i.e. < 1.5 % of one second; MIN_CHUNKS keeps small sweeps balanced and resumable.
CHUNK_SECONDS, MIN_CHUNKS, CHUNK_MAX = 1.0, 16, 2_000  # CHUNK_MAX bounds the memory in flight
SERIAL_BELOW = 3.0  # seconds of estimated work under which a local sweep runs in-process


def auto_chunk_size(n_models: int, seconds_per_run: float) -> int:
    """Model runs per chunk: about CHUNK_SECONDS of work, but at least MIN_CHUNKS chunks."""
    by_time = math.ceil(CHUNK_SECONDS / max(seconds_per_run, 1e-7))
    return max(1, min(by_time, math.ceil(n_models / MIN_CHUNKS), CHUNK_MAX))


def local_jobs(jobs: int, work_left: float, serial_below: float | None = None) -> int:
    """Local processes to use: 1 (this process) when the work left is too small to pay for workers."""
    return 1 if work_left < (SERIAL_BELOW if serial_below is None else serial_below) else jobs


def engine() -> Callable:
    """The engine: simulate_resolved(vals, trajectory=False) -> (results, None)."""
    from fencesweep.model import simulate as api

    return api.simulate_resolved


def run_one(scene: str, vals: dict, simulate: Callable | None = None, p=None) -> dict:
    """Run one parameter set: its results (a stream's as one chunk row, store.stream_row); a run
    that raises becomes a row with outcome failed and the reason. `p`: its parameter vector,
    prepared with its chunk's (for an engine that takes it, takes_vectors)."""
    try:
        fn = simulate or engine()
        res, _ = fn(vals, trajectory=False) if p is None else fn(vals, trajectory=False, p=p)
        return store.stream_row(res) if scene == "stream" else res
    except Exception as exc:  # recorded, never silent: status names the exception
        return store.failed_result(scene, f"failed: exception {type(exc).__name__}: {exc}")


def takes_vectors(simulate: Callable) -> bool:
    """Whether the engine `simulate` takes a run's parameter vector prepared beforehand (its
    argument `p`, as simulate_resolved does; a test's stand-in does not)."""
    try:
        return "p" in inspect.signature(simulate).parameters
    except (TypeError, ValueError):
        return False


def run_models(scene: str, vals_list: list, simulate: Callable | None = None, vectors=None) -> list:
    """Run each parameter set (run_one), with its vector of `vectors` (prepare.Vectors of the same
    runs; None: each run prepares its own)."""
    fn = simulate or engine()
    if vectors is None:
        return [run_one(scene, vals, fn) for vals in vals_list]
    return [run_one(scene, vals, fn, vectors[k]) for k, vals in enumerate(vals_list)]


def _warm_rows(spec: S.Spec, rows: Iterable[int], fn: Callable) -> None:
    for i in rows:
        vals = spec.resolve(int(i))
        try:
            fn(vals, trajectory=False)
        except Exception as exc:
            raise RuntimeError(f"the engine failed on {spec.describe(int(i))}: "
                               f"{type(exc).__name__}: {exc}") from exc


def warm_scenes(spec: S.Spec, rows: Iterable[int], simulate: Callable | None = None) -> float:
    """Run the scenes `rows` in this process (loading the kernels, as warm_up does); the seconds."""
    t0 = time.perf_counter()
    _warm_rows(spec, rows, simulate or engine())
    return time.perf_counter() - t0


def warm_up(plan: Plan, simulate: Callable | None = None) -> float:
    """Run one model of each variant (scene, drive, law, profile) of a plan in this process.

    This loads (or compiles, once, into Numba's on-disk cache) the kernels here; forked
    workers inherit them, loky workers load them from the cache. It also stops a sweep
    whose engine fails at once, before anything is dispatched. Returns the seconds it took.
    """
    t0 = time.perf_counter()
    _warm_rows(plan.spec, (plan.first_row[m] for m in plan.variants.values()), simulate or engine())
    return time.perf_counter() - t0


def time_sample(plan: Plan, simulate: Callable | None = None, budget: float = 2.0, most: int = 64) -> tuple:
    """(seconds per model run, runs timed, {model run: its seconds}), timed on runs spread evenly
    over the sweep (after warm_up)."""
    fn = simulate or engine()
    ids = np.unique(np.linspace(0, plan.n_models - 1, min(most, plan.n_models)).round().astype(int))
    t0 = time.perf_counter()
    timed = {}
    for m in ids:
        t = time.perf_counter()
        try:
            fn(plan.model_vals(int(m)), trajectory=False)
        except Exception:  # timed all the same; the sweep records it as a failed row
            pass
        timed[int(m)] = time.perf_counter() - t
        if time.perf_counter() - t0 > budget:
            break
    return (time.perf_counter() - t0) / len(timed), len(timed), timed


#: chunks held back to the end of the dispatch, per job: the lightest (dispatch_order)
LIGHT_LAST = 2


def dispatch_order(plan: Plan, chunks: list, timed: dict, jobs: int) -> list:
    """The chunks `chunks` in the order to start them on `jobs` workers: in their own order, so
    that they finish about in the table's order and its blocks are written while the others run
    (sweep/assemble.py), but the LIGHT_LAST x jobs lightest last, the heaviest of them first.

    The workers then finish within about one light chunk of each other. In the chunks' own
    order alone a sweep whose costly runs come last leaves one worker running its last costly
    chunk alone: the main job's long_near chunks take ~0.39 s each against ~0.18 s for
    small_far's, which come first. A chunk's work is estimated as its number of runs times the
    seconds per run at its middle run, interpolated (np.interp) between the runs of `timed`
    ({model run: seconds}, time_sample); with fewer than two timed runs the chunks keep their
    own order."""
    if len(timed) < 2:
        return list(chunks)
    at = np.array(sorted(timed), dtype=float)
    seconds = np.array([timed[int(m)] for m in at])
    work = {}
    for c in chunks:
        r = plan.chunk_models(c)
        work[c] = len(r) * float(np.interp((r.start + r.stop - 1) / 2, at, seconds))
    light = set(sorted(chunks, key=lambda c: (work[c], c))[:LIGHT_LAST * jobs])
    return [c for c in chunks if c not in light] + sorted(light, key=lambda c: (-work[c], c))
