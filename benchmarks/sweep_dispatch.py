"""What a sweep chunk costs besides its model runs: dispatch to a worker and the chunk's file.

For chunk sizes of 1..4096 runs it times, on the sweep's own local pool (compute.START_METHOD:
forked workers on Linux, loky elsewhere) with --jobs workers:
  dispatch: the round trip of a task like the sweep's, which carries the chunk's scene
            numbers and returns a small tuple, but runs nothing (pickling, queueing);
  write:    store.write_chunk of the chunk's result rows (temporary file, rename);
and compares them with the chunk's compute time at the engine's measured ms per run.
The sweep's chunk rule (runs.auto_chunk_size: about CHUNK_SECONDS = 1 s of work a chunk,
sized from a timed sample) keeps that overhead well under a percent. Prints a table and
writes it to benchmarks/sweep_dispatch_SCENE.txt.

    python benchmarks/sweep_dispatch.py [--jobs 2] [--scene cycle|impact]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this tree's package

from fencesweep.model import params as P  # noqa: E402
from fencesweep.model import simulate as api  # noqa: E402
from fencesweep.study.sweep import compute as W  # noqa: E402
from fencesweep.study.sweep import runs  # noqa: E402
from fencesweep.study.store import table as store


def _noop(c, ids, rows, path, meta, shared=None):
    """The shape of compute._run_chunk's call and answer, without running or writing anything."""
    return c, None, (0, 0.0, 0.0, 0.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--tasks", type=int, default=200)
    ap.add_argument("--scene", default="cycle", choices=P.SCENES)
    args = ap.parse_args()

    vals = P.resolve(args.scene, "small_far")
    api.simulate_resolved(vals)  # compile / load the cache
    n = 30
    t0 = time.perf_counter()
    for _ in range(n):
        res, _ = api.simulate_resolved(vals)
    per_run = (time.perf_counter() - t0) / n

    lines = [f"engine: {per_run * 1e3:.3f} ms per {args.scene} run (small_far, defaults); "
             f"{W.START_METHOD} workers, {args.jobs} jobs",
             f"{'runs/chunk':>10} {'dispatch ms':>12} {'write ms':>9} {'compute ms':>11} {'overhead %':>11}"]
    with W._pool(args.jobs, None, W.START_METHOD) as pool, tempfile.TemporaryDirectory() as tmp:
        for _ in W._completed(pool, ((_noop, c, range(1), np.arange(1), None, {}) for c in range(20)),
                              ahead=2 * args.jobs):
            pass  # the workers are up
        for size in (1, 8, 32, 64, 128, 512, 1024, 4096):
            ids, rows = range(size), np.arange(size, dtype=np.int64)
            results = [res] * size
            tasks = max(20, args.tasks * 32 // max(size, 32))
            t0 = time.perf_counter()
            calls = ((_noop, c, ids, rows, f"{tmp}/c.parquet", {"chunk": c}) for c in range(tasks))
            for _ in W._completed(pool, calls, ahead=2 * args.jobs):
                pass
            dispatch = (time.perf_counter() - t0) / tasks * args.jobs  # per task, per worker
            t0 = time.perf_counter()
            k = 10
            for c in range(k):
                store.write_chunk(Path(tmp) / f"c{c}.parquet", args.scene, list(ids), results, {"chunk": c})
            write = (time.perf_counter() - t0) / k
            compute = per_run * size
            over = 100 * (dispatch + write) / compute
            lines.append(f"{size:>10} {dispatch * 1e3:>12.3f} {write * 1e3:>9.3f} {compute * 1e3:>11.1f} {over:>11.2f}")
    size = runs.auto_chunk_size(10**6, per_run)
    lines.append(f"chunk rule (runs.auto_chunk_size): ~{runs.CHUNK_SECONDS:g} s of work a chunk, "
                 f"i.e. {size} runs of this scene in a large sweep")
    text = "\n".join(lines)
    print(text)
    out = Path(__file__).with_name(f"sweep_dispatch_{args.scene}.txt")
    out.write_text(text + "\n")


if __name__ == "__main__":
    main()
