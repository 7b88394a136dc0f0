"""Sweeps: spec -> scenes -> distinct model runs -> parallel chunks -> one Parquet table.

run_sweep orchestrates the steps, each in its own module:

1. sweep/plan.py: every scene of the spec is resolved, up front, so any bad combination is
   reported before work starts, and mapped to its model run by params.model_key: scenes that
   differ only in parameters their model does not use (B2, K2 under a rigid drive, ...) share
   one run (docs/model.md §8). Both on whole columns (spec/scenes.py): params.resolve runs once
   per combination of the values it reads together (the envelope study: 64, not 419,904).
   A spec of more than pieces.PIECE_SCENES scenes is run in pieces (spec/pieces.py), one after
   the other, each a spec of its own written into one part of a Parquet dataset (_run_pieces).
2. sweep/runs.py: the distinct runs, numbered in order of first appearance, are cut into chunks of
   `chunk_size` runs: the spec's, or sized from a short timed sample to take about
   CHUNK_SECONDS each (dispatch and writing then cost well under 1 %), and recorded in
   the work directory (sweep/output.py) so that a resumed sweep cuts the same chunks. A chunk's
   file name carries a digest of the spec hash, the package's source hash, its chunk size
   and its runs' first scenes, so a changed spec or engine never reuses a stale chunk.
3. sweep/compute.py: pending chunks run in parallel, in their order but the lightest last
   (estimated from the timed sample: runs.dispatch_order): locally in worker processes, or on
   a Dask cluster (sweep/cluster.py: each worker warmed up before its first chunk). A task carries only its chunk's scene numbers; the worker
   resolves them, runs them and writes the chunk atomically into the work directory
   `OUT.partial/` beside the output (with Dask the client writes it), so results never queue
   up in the parent. A killed sweep, rerun, computes only the chunks that are missing. This
   process reads each chunk as it is written (sweep/chunks.py), for the steps below to take
   from memory, and writes the table's blocks that it completes (step 5). On Linux the local
   workers are forked from this process once it has loaded the compiled kernels: they start
   at once and load nothing. Elsewhere they are loky processes.
4. sweep/verify.py: a sample of the runs (the extremes first, then random) is run again at a 10x
   tighter tolerance and compared with the chunks' results, the table's values (verification).
   The re-runs go to the local workers, if any, while this process writes the table's last
   blocks (step 5).
5. sweep/assemble.py: the table is assembled block by block from the plan's columns and the
   chunks (rows in scene order) into one Parquet file, each block as soon as its chunks are
   in; the file is closed with the verification's record in its metadata and put in place
   atomically; then the work directory is removed.

The whole run holds the output's lock (store/lock.py: one writer per output), taken once the
output's directory is known to be writable and before anything is made or removed. A file that
cannot be written (a full disk) raises WriteError and keeps the chunks written so far.

Results depend only on each run's parameters, and the assembly only on the plan: the
table is the same, bit for bit, whatever --jobs or backend. sweep/estimate.py is the dry run of
the same steps; api.py the functions a Python user (and the CLI) calls.
"""
from __future__ import annotations

import contextlib
import logging
import os
import shutil
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from fencesweep.study.spec import pieces as SP
from fencesweep.study.spec import spec as S
from fencesweep.study.store import lock
from fencesweep.study.store import table as store
from fencesweep.study.sweep import cluster, compute, output, parts, runs
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import sample as VS
from fencesweep.study.sweep import verify as V
from fencesweep.study.sweep.assemble import Assembly
from fencesweep.study.sweep.chunks import ChunkTables
from fencesweep.study.sweep.estimate import describe_plan


@dataclass
class Outcome:
    """What run_sweep did: the table written, its counts, the chunks computed and reused, the time."""

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
    #: verify, assemble) and, summed over the chunks, of the workers' runs and chunk writes
    timings: dict = field(default_factory=dict)
    verify: dict | None = None  # the verification's record (sweep/verify.py; None: not verified)


@dataclass
class _Run:
    """One call of run_sweep: its settings, and the seconds of its phases so far."""

    spec: S.Spec
    out: Path
    work: Path
    jobs: int
    local: bool
    scheduler: str | None
    progress: bool
    simulate: Callable | None
    log: Callable[[str], None]
    serial_below: float | None
    timings: dict = field(default_factory=dict)
    per_run: float | None = None  # seconds per model run, when timed
    timed: dict = field(default_factory=dict)  # {model run: seconds} of the timed sample
    record: dict | None = None  # the verification's record, once made
    verify: bool | int | None = None  # run_sweep's `verify`
    ahead: V.Ahead | None = None  # what the verification began while the chunks ran
    gpu: dict | None = None  # backend "cuda": the GPU (sweep/gpu.py device_record); None: the CPU


#: the default log: the "fencesweep" logger (api.py)
_quiet = logging.getLogger(__name__).info


def run_sweep(spec: S.Spec, out: str | Path | None = None, jobs: int | None = None,
              resume: bool = True, backend: str = "loky", scheduler: str | None = None,
              progress: bool = False, simulate: Callable | None = None, plan: PL.Plan | None = None,
              log: Callable[[str], None] | None = None, serial_below: float | None = None,
              overwrite: bool = False, verify: bool | int | None = None, wait: bool = False) -> Outcome:
    """Run a sweep and write its table. `simulate(vals, trajectory=False) -> (results, None)`
    defaults to fencesweep.model.simulate.simulate_resolved (tests pass a fake). A local sweep whose
    remaining work is estimated below `serial_below` seconds (default runs.SERIAL_BELOW) runs
    in this process: starting workers would cost more than it saves. `log` receives the
    notes a user should see (skipped scenes, unused axes, resuming, waiting). The output's
    directory must be writable (output.check_writable) and its lock free (lock.one_writer:
    another run writing `out` raises UsageError, or with `wait` is waited for). Without
    `overwrite`, another spec's table or unfinished run at `out` stops the sweep before it
    starts (output.check_output). `verify`: None or True, the default sample is re-run at
    tol / 10 (sweep/verify.py); N, N runs; False, none. A file that cannot be written (a full disk)
    raises WriteError; the chunks finished are kept for the next run."""
    t0 = time.perf_counter()
    if not isinstance(spec, S.Spec):
        raise TypeError(f"run_sweep takes a spec.Spec (specfile.load reads one from YAML), not {spec!r}")
    out = Path(out) if out is not None else output.default_output(spec)
    output.check_writable(out)
    output.check_can_start(spec, out, overwrite)  # refused at once: not even the lock file is made
    gpu = gpu_device(spec) if backend == "cuda" else None  # refused before anything is made
    if plan is None and spec.whole is None and SP.n_pieces(spec) > 1:  # (a piece is never cut again)
        return _run_pieces(spec, out, t0, wait, overwrite, log or _quiet, dict(
            jobs=jobs, resume=resume, backend=backend, scheduler=scheduler, progress=progress, simulate=simulate,
            serial_below=serial_below, verify=verify))
    with lock.one_writer(out, wait, log or _quiet):  # before anything is made or removed
        output.check_can_start(spec, out, overwrite)  # again: another run may have finished meanwhile
        if jobs is None:
            import joblib

            jobs = joblib.cpu_count()
        root = output.work_root(out)
        run = _Run(spec, out, root / (plan.salt if plan is not None else PL.plan_salt(spec))[:16], jobs,
                   backend != "dask", scheduler, progress, simulate, log or _quiet, serial_below, gpu=gpu)
        made = output.open_work(root, run.work, resume, run.log)
        if plan is None:
            plan = _plan(run, made)
        return _run(run, plan, root, verify, t0)


def gpu_device(spec: S.Spec) -> dict:
    """Backend "cuda": the GPU's record (sweep/gpu.py), or the reason it cannot run `spec` (a
    usage error: numba-cuda missing, no GPU, a scene other than cycle)."""
    from fencesweep.kernel import cuda
    from fencesweep.study.sweep import gpu

    gpu.check_scene(spec)
    return gpu.device_record(cuda.require_gpu())


def _run_pieces(spec: S.Spec, out: Path, t0: float, wait: bool, overwrite: bool, log: Callable[[str], None],
                kw: dict) -> Outcome:
    """Sweep a spec too large to plan at once piece by piece (spec/pieces.py) into the Parquet
    dataset OUT (sweep/parts.py), each piece a sweep of its own with the same settings (`kw`);
    the parts finished by an earlier run of it are kept (unless kw["resume"] is False)."""
    with lock.one_writer(out, wait, log):
        output.check_can_start(spec, out, overwrite)  # again: another run may have finished meanwhile
        parts.open_dataset(out, True)
        n, done = SP.n_pieces(spec), []
        for k, piece in enumerate(SP.pieces(spec)):
            path = out / parts.part_name(k)
            if kw["resume"] and parts.part_done(piece, path):
                continue
            log(f"piece {k + 1} of {n}: scenes {piece.offset:,} to {piece.offset + piece.n_scenes - 1:,}")
            res = run_sweep(piece, out / parts.WORK / path.name, log=log, overwrite=True, **kw)
            os.replace(res.out, path)
            done.append(res)
        parts.finish_dataset(out, n)
    metas = [store.read_metadata(out / parts.part_name(k)) for k in range(n)]
    timings: dict = {}
    for res in done:
        for key, value in res.timings.items():
            timings[key] = timings.get(key, 0) + value
    return Outcome(out, sum(m["counts"]["scenes"] for m in metas), sum(m["counts"]["model_runs"] for m in metas),
                   sum(r.n_chunks for r in done), sum(r.computed for r in done), sum(r.reused for r in done),
                   time.perf_counter() - t0, sum(r.failed_runs for r in done), done[-1].jobs if done else None,
                   timings, parts.verify_record([m.get("verify") for m in metas]))


def _run(run: _Run, plan: PL.Plan, root: Path, verify: bool | int | None, t0: float) -> Outcome:
    """Size the chunks, compute the missing ones, verify (on the same local workers, which stop
    after the table is written) while the table's first block is made, assemble the table,
    remove the work directory."""
    run.per_run, run.verify = _size_chunks(run, plan), verify
    output.write_state(run.work, plan)
    done = output.chunks_done(plan, run.work)
    pending = sorted(set(range(plan.n_chunks)) - set(done))
    if done:
        run.log(f"resuming: {len(done)} of {plan.n_chunks} chunks already in {run.work}")
    tables = ChunkTables(plan, run.work)  # each chunk read once: as it finishes, or when first needed
    table = Assembly(plan, run.work, run.out, tables)  # written as the chunks arrive
    with contextlib.ExitStack() as workers:
        workers.callback(table.abort)  # a sweep that stops leaves no partial table (its chunks stay)
        for c in done:
            table.feed(c)
        pool = _compute(run, plan, pending, done, workers, tables, table) if pending else None
        meta = _verification(run, plan, verify, pool, tables) if verify is not False else None
        if run.gpu is not None:  # the table names the GPU its chunks ran on
            meta = _with_device(meta, run.gpu)
        t, verifying = time.perf_counter(), run.timings.get("verify", 0.0)
        failed = table.finish(meta)
        run.timings["assemble"] = time.perf_counter() - t - (run.timings.get("verify", 0.0) - verifying)
    shutil.rmtree(root)
    return Outcome(run.out, plan.n_scenes - plan.skipped, plan.n_models, plan.n_chunks, len(pending), len(done),
                   time.perf_counter() - t0, failed, run.jobs if run.local else None, run.timings, run.record)


def _with_device(meta: Callable | None, device: dict) -> Callable:
    """The table's metadata to add (`meta`'s) with {"device": device}."""
    return lambda: {**(meta() if meta is not None else {}), "device": device}


def _verification(run: _Run, plan: PL.Plan, verify: bool | int | None, pool, tables: ChunkTables) -> Callable:
    """Begin the verification (verify.begin: its re-runs go to `pool`, the local workers, if any,
    those begun with the chunks, run.ahead, aside) and return the function that finishes it, for
    the assembly to call once it has written the table's blocks: {"verify": record}, also kept
    as run.record. Its seconds go to run.timings["verify"]."""
    t = time.perf_counter()
    finish = V.begin(plan, run.work, None if verify is None or verify is True else int(verify), run.jobs, run.local,
                     run.scheduler, run.simulate, run.serial_below, run.per_run, pool, tables, run.ahead)
    run.timings["verify"] = time.perf_counter() - t

    def meta() -> dict:
        t = time.perf_counter()
        run.record = finish()
        run.timings["verify"] += time.perf_counter() - t
        return {"verify": run.record}

    return meta


def _plan(run: _Run, made: bool) -> PL.Plan:
    """Plan the sweep (sweep/plan.py). A bad spec (or Ctrl-C) removes the work directory if this
    call made it. Logs skipped scenes and unused axes."""
    t = time.perf_counter()
    try:
        plan = PL.make_plan(run.spec)
    except BaseException:  # nothing of this planning is worth keeping
        if made:
            shutil.rmtree(run.work, ignore_errors=True)
            with contextlib.suppress(OSError):
                run.work.parent.rmdir()
        raise
    run.timings["plan"] = time.perf_counter() - t
    for line in describe_plan(plan, run.out)[1:]:
        if "note:" in line or "skipped" in line:
            run.log(line.strip())
    return plan


def _size_chunks(run: _Run, plan: PL.Plan) -> float | None:
    """Set the plan's chunk size: the spec's, the one an interrupted run of it recorded, or (a
    first run) sized from a short timed sample, whose seconds per run are returned (else None)."""
    if plan.chunk_size is None:
        plan.chunk_size = output.recorded_chunk_size(run.work)
    if plan.chunk_size is not None:
        return None
    per_run, _, run.timed = _sample(run, plan, budget=0.5)
    plan.chunk_size = runs.auto_chunk_size(plan.n_models, per_run)
    return per_run


def _sample(run: _Run, plan: PL.Plan, budget: float) -> tuple:
    """Warm the engine up and time a short sample (runs.warm_up, runs.time_sample): in this
    process, or with Dask on the cluster (cluster.time_sample: every worker warms up, one of
    them times the sample; this process compiles nothing that only the workers run). The
    warm-up's seconds go to run.timings["warm_up"]; returns time_sample's (per run, n, timed)."""
    if run.local:
        run.timings["warm_up"] = runs.warm_up(plan, run.simulate)
        return runs.time_sample(plan, run.simulate, budget=budget, most=8)
    run.timings["warm_up"], sampled = cluster.time_sample(run.scheduler, plan, run.simulate, budget=budget, most=8)
    return sampled


def _compute(run: _Run, plan: PL.Plan, pending: list, done: list, workers: contextlib.ExitStack,
             tables: ChunkTables, table: Assembly):
    """Warm the engine up (unless sizing the chunks did), choose this process alone when the
    work left is too small to pay for workers, and run the pending chunks: on workers in their
    order but the lightest last (runs.dispatch_order: they then finish together), in this
    process in their order; each chunk, once written, is read here into `tables` and the
    table's blocks it completes are written (`table`). Returns the local workers, started on
    `workers` (they stop when it closes), or None (this process, or Dask)."""
    if run.per_run is None:
        run.per_run, _, run.timed = _sample(run, plan, budget=0.3)
    if run.local:
        work_left = run.per_run * sum(len(plan.chunk_models(c)) for c in pending)
        if run.jobs > 1 and runs.local_jobs(run.jobs, work_left, run.serial_below) == 1:
            run.log(f"about {work_left:.1f} s of work: running in this process (starting workers costs more)")
            run.jobs = 1
    if run.jobs > 1 or not run.local:  # in one process the order changes nothing
        pending = runs.dispatch_order(plan, pending, run.timed, run.jobs)
    run.ahead = V.Ahead(scored=VS.Scores(plan)) if run.verify is not False else None
    local_pool = run.local and run.jobs > 1
    early = V.early_rows(plan, None if run.verify is None or run.verify is True else int(run.verify)) \
        if local_pool and run.ahead is not None else []  # the sample's likely random rows, beside the chunks
    t = time.perf_counter()
    pool = compute.start_pool(workers, run.jobs, run.spec, run.simulate) if local_pool else None
    if pool is not None and run.ahead is not None:
        run.ahead.rows, run.ahead.results = set(early), compute.submit_reruns(pool, early, V.STEP_FACTOR_SCALE,
                                                                              run.jobs)
        threading.Thread(target=V.prepare, name="fencesweep-prepare", daemon=True).start()  # this process waits

    def finished(c: int) -> None:  # chunk c is written: read it, write the blocks it completes, score it
        tables.finished(c)
        table.feed(c)
        if run.ahead is not None:
            run.ahead.scored.add(c, tables)

    if run.gpu is not None:
        from fencesweep.study.sweep import gpu

        run.timings.update(gpu.compute_chunks(plan, run.spec, run.work, pending, done, gpu.runner(), run.progress,
                                              {"salt": plan.salt}, pool, finished))
        run.timings["compute"] = time.perf_counter() - t
        return pool
    stats = compute.compute_chunks(plan, run.spec, run.work, pending, done, run.jobs, run.local, run.scheduler,
                                   run.progress, run.simulate, {"salt": plan.salt}, pool, finished)
    run.timings["compute"] = time.perf_counter() - t
    run.timings.update(compute.worker_timings(stats))
    return pool
