"""A sweep's chunks on a GPU (backend "cuda"; step 3 of sweep/pipeline.py): one GPU thread per
model run (model/scenes/gpu.py), the chunks in batches; orchestration only.

Per batch (consecutive pending chunks, at most `batch_size` runs):
  1. the runs' parameter vectors (header only) are made chunk by chunk, each chunk's on whole
     columns (prepare.prepare_columns), on the local workers (or in this process with one job),
     while the GPU runs the batch before;
  2. the batch is launched, asynchronously;
  3. the batch's chunks are written (on the workers: unpacked and written as the CPU's chunks
     are), and each written chunk is handed on (`finished`, as compute.compute_chunks does) with
     its table (no file read back) once the next batch's results are back: the table's blocks and
     the verification's scores go on as with the CPU, while the workers write the next chunks.
A run whose parameters cannot be prepared is a failed row naming the exception, as on the CPU.
Only the scene `cycle` runs here (check_scene); the verification re-runs on the CPU.
"""
from __future__ import annotations

import contextlib
import functools
import os
import time
from pathlib import Path
from typing import Callable

import numpy as np

from fencesweep.errors import UsageError
from fencesweep.study.spec import spec as S
from fencesweep.study.store import table as store
from fencesweep.study.sweep import chunks, compute
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep.progress import bar as progress_bar

#: most runs in a batch: enough to fill a card many times over (an H200 holds ~2,000 blocks of
#: 128 threads at once), few enough that preparing the next batch on the CPU overlaps the GPU's
#: work on this one; and never more than a quarter of the card's free memory (batch_size)
BATCH_RUNS = 131_072


@functools.cache
def runner():
    """This process's cycle kernel on the GPU (model/scenes/gpu.py Cycles), made once: its compile
    (or its load from the cache) is paid at its first launch."""
    from fencesweep.model.scenes.gpu import Cycles

    return Cycles()


def run_scenes(spec: S.Spec, scenes: np.ndarray, runner) -> list:
    """The results of the cycle scenes `scenes` (scene numbers of `spec`) on the GPU, in batches
    (batch_size), as result dicts (as runs.run_one gives them; a run that cannot be prepared is
    a failed row), in this process: an adaptive map's level (adaptive/evaluate.py)."""
    from fencesweep.model.results import N_CYCLE_RESULTS, unpack

    size, out = batch_size(runner.free_memory()), []
    for at in range(0, len(scenes), size):
        _, P, failed = _prepare(0, scenes[at:at + size], (spec, None))
        res = runner.launch(P).result()
        out += [store.failed_result("cycle", failed[k]) if k in failed else unpack("cycle", res[k, :N_CYCLE_RESULTS])
                for k in range(P.shape[0])]
    return out


def check_scene(spec: S.Spec) -> None:
    """Backend "cuda" runs `cycle` scenes only: another scene is a usage error naming it."""
    if spec.scene != "cycle":
        raise UsageError(f"backend 'cuda' runs the scene 'cycle' only, not {spec.scene!r}: 'stream', 'impact' and "
                         f"'freefall' run on the CPU (backend 'loky')")


def device_record(device: dict) -> dict:
    """What the table's metadata says of the GPU that ran it."""
    from fencesweep.kernel.cuda import version

    return {"backend": "cuda", "name": device["name"], "compute_capability": list(device["cc"]),
            "memory": int(device["memory"]), "numba_cuda": version()}


def batch_size(free_bytes: int | None) -> int:
    """Runs per batch: BATCH_RUNS, or fewer where a quarter of the card's free memory holds fewer
    rows of parameters and results (model/scenes/gpu.py ROW_BYTES)."""
    from fencesweep.model.scenes.gpu import ROW_BYTES

    if not free_bytes:
        return BATCH_RUNS
    return int(max(1, min(BATCH_RUNS, free_bytes // 4 // ROW_BYTES)))


def _prepare(c: int, rows: np.ndarray, shared: tuple | None = None) -> tuple:
    """Chunk c's parameter vectors (n, N_P), prepared on whole columns (compute.prepared), and
    {position: reason} of the runs that could not be prepared (found run by run where the
    columns' preparation raises): their thread runs the default cycle (docs/model.md §12), whose
    result is discarded (a vector of zeros would step with h = 0 to the step budget)."""
    from fencesweep.model import params
    from fencesweep.model.layout import N_P
    from fencesweep.model.prepare import prepare

    spec, _ = compute.shared(shared)
    vectors = compute.prepared(spec, rows, table=False)
    if vectors is not None:
        return c, vectors.header, {}
    P = np.zeros((len(rows), N_P))
    failed = {}
    for k, vals in enumerate(compute._resolved(spec, rows)):
        try:
            P[k] = prepare(vals, table=False)
        except Exception as exc:  # recorded, never silent, as runs.run_one does
            failed[k] = f"failed: exception {type(exc).__name__}: {exc}"
    if failed:
        P[list(failed)] = prepare(params.resolve("cycle"), table=False)
    return c, P, failed


def _write(path: str, ids: list, out: np.ndarray, failed: dict, meta: dict, shared: tuple | None = None) -> tuple:
    """Chunk `path`'s file from its runs' result rows, decoded as whole columns, the runs that
    could not be prepared as failed rows. Returns the seconds it took and the chunk's table as
    Arrow IPC bytes (chunks.ipc_bytes), which the sweep's process takes instead of reading the
    file back (`shared`: unused, as every call on the workers takes it)."""
    from fencesweep.model.results import CYCLE_RESULTS, N_CYCLE_RESULTS, unpack_columns

    t = time.monotonic()
    cols = unpack_columns(CYCLE_RESULTS, out[:, :N_CYCLE_RESULTS])
    for k, reason in failed.items():
        for name, value in store.failed_result("cycle", reason).items():
            cols[name][k] = value
    table = store.write_chunk_columns(path, "cycle", ids, cols, meta)
    return time.monotonic() - t, chunks.ipc_bytes(table)


class _Now:
    """A finished future of a call made in this process (one job: no workers)."""

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


def _batches(plan: PL.Plan, pending: list, size: int) -> list:
    """The pending chunks in consecutive groups of at most `size` runs (a chunk is never split)."""
    out, cur, n = [], [], 0
    for c in pending:
        k = len(plan.chunk_models(c))
        if cur and n + k > size:
            out.append(cur)
            cur, n = [], 0
        cur.append(c)
        n += k
    return out + ([cur] if cur else [])


def compute_chunks(plan: PL.Plan, spec: S.Spec, work: Path, pending: list, done: list, runner, progress: bool,
                   meta_chunk: dict, pool=None, finished: Callable[[int], None] | None = None) -> dict:
    """Run the pending chunks on the GPU (module docstring) with `runner` (model/scenes/gpu.py
    Cycles), the CPU side on `pool` (the local workers; None: this process). A batch's chunks are
    handed on (_drain) after the next batch's results are back and its writes submitted: this
    process reads them and writes the table's blocks while the workers write and prepare the next
    ones. Returns the seconds of the GPU's batches ("gpu": launch to results back) and of the
    chunk writes."""
    shared = (spec, None)
    submit = (lambda fn, *a: pool.submit(fn, *a)) if pool is not None else (lambda fn, *a: _Now(fn(*a, shared)))

    def prepare(batch):
        return [submit(_prepare, c, plan.first_row[plan.chunk_models(c).start:plan.chunk_models(c).stop])
                for c in batch]

    def write(parts: list, out: np.ndarray) -> list:
        written, at = [], 0
        for c, P, failed in parts:
            n = P.shape[0]
            written.append((c, submit(_write, str(work / plan.chunk_name(c)), list(plan.chunk_models(c)),
                                      out[at:at + n], failed, dict(meta_chunk, chunk=c))))
            at += n
        return written

    batches = _batches(plan, pending, batch_size(runner.free_memory()))
    timing = {"gpu": 0.0, "writes": 0.0, "batches": len(batches)}
    rows_of = plan.chunk_rows()
    with contextlib.closing(progress_bar(plan.n_scenes - plan.skipped, Path(spec.path).stem if spec.path else "sweep",
                                         progress, initial=int(rows_of[done].sum()) if done else 0)) as bar:
        def drain(written: list) -> None:  # the chunks written: counted, handed on
            _drain(written, timing, lambda c: bar.update(int(rows_of[c])), finished, work, plan)

        ready, written = (prepare(batches[0]) if batches else []), []
        for k in range(len(batches)):
            parts = [f.result() for f in ready]
            t = time.monotonic()
            launched = runner.launch(np.concatenate([P for _, P, _ in parts]))
            ready = prepare(batches[k + 1]) if k + 1 < len(batches) else []  # while the GPU runs
            out = launched.result()
            timing["gpu"] += time.monotonic() - t
            written, before = write(parts, out), written
            drain(before)  # the batch before's chunks, while the workers write this one's
        drain(written)
    timing["pid"] = os.getpid()
    return timing


def _drain(written: list, timing: dict, count: Callable[[int], None], finished: Callable[[int], None] | None,
           work: Path, plan: PL.Plan) -> None:
    """Wait for the chunk writes `written` ([(chunk, future)]), in order: their seconds go to
    timing["writes"], each chunk is counted and handed on to `finished` with its table
    (chunks.handed: the sweep's ChunkTables takes it instead of reading the file)."""
    for c, future in written:
        seconds, data = future.result()
        timing["writes"] += seconds
        count(c)
        if finished is not None:
            with chunks.handed(work / plan.chunk_name(c), data):
                finished(c)
