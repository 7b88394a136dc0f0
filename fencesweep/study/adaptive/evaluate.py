"""Adaptive maps: simulating a level's elements, chunk by chunk, and judging them.

A level's elements (adaptive.Refiner.ask) become tasks: an element, its scenes in the order its
loads run and their predictions (adaptive/loads.py). The tasks are cut into chunks of about
CHUNK_CYCLES planned cycles (at least MIN_CHUNKS per level when there are enough elements;
neither depends on --jobs), which run in this process, on local workers or on Dask
(compute.run_calls) and are written into the work directory as they finish, named by a digest
of the run's salt and their tasks. A run killed half-way keeps its chunks; the same run again
asks for the same elements in the same order (the refinement is deterministic in what it is
told), finds their chunks and runs only the rest. Each element is then judged over the loads it
ran by envelope.summarize, the full grid's judge.
"""
from __future__ import annotations

import contextlib
import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from fencesweep.study.adaptive import loads as AL
from fencesweep.study.adaptive.maps import Layout
from fencesweep.study.design import judge as J
from fencesweep.study.spec import design as DS
from fencesweep.study.store import table as store
from fencesweep.study.sweep import compute, runs

CHUNK_CYCLES = 512  # planned cycles per chunk, at most (about a second of work)
MIN_CHUNKS = 16  # chunks per level, at least, when it has that many elements
JUDGED = ("outcome", "overload", "deflection_max", "residual_amplitude")


@dataclass
class Task:
    """One element to simulate: its scenes in the order its loads run, their predictions and,
    per position, the smallest prediction of the loads after it (adaptive_loads.following)."""

    element: int
    scenes: np.ndarray
    predictions: np.ndarray
    following: np.ndarray


def run_tasks(c: int, tasks: list, path: str | None, meta: dict, limits: DS.Limits, rule: AL.LoadRule,
              shared: tuple | None = None, given: dict | None = None) -> tuple:
    """Run one chunk's elements, each load after load until it stops (adaptive_loads.stop), and
    write the chunk at `path` (local workers) or return its rows (Dask): (c, rows or None,
    scenes, elements). With `given` ({scene: results}, every load of the tasks run at once on a
    GPU) the loads' results are looked up instead of run: the same loads are kept."""
    spec, simulate = compute.shared(shared)
    rows, scenes = [], []
    for task in tasks:
        smallest = math.inf
        for i, scene in enumerate(task.scenes):
            vals = spec.resolve(int(scene))
            res = runs.run_one(spec.scene, vals, simulate) if given is None else given[int(scene)]
            rows.append(res)
            scenes.append(int(scene))
            dlim = vals["dalpha_perm"] if limits.deflection_max is None else limits.deflection_max
            margin = AL.load_margin(res, dlim, limits)
            smallest = min(smallest, margin)
            if AL.stop(margin, smallest, task.following[i], rule):
                break
    if path is None:
        return c, rows, scenes, len(tasks)
    store.write_chunk(path, spec.scene, scenes, rows, meta)
    return c, None, scenes, len(tasks)


def chunk_complete(path: Path) -> bool:
    """A chunk file that can be read (written atomically: present means whole)."""
    try:
        pq.read_metadata(path)
    except (OSError, pa.ArrowInvalid):
        return False
    return True


class Evaluator:
    """Runs the elements the refinement asks for and judges them; keeps, per simulated element,
    its per-load margins (measured, or predicted for the loads it skipped; NaN: not known)."""

    def __init__(self, lay: Layout, work: Path, salt: str, rule: AL.LoadRule, run: dict):
        self.lay, self.work, self.salt, self.rule, self.run = lay, work, salt, rule, run
        self.values: dict = {}  # element -> per-load margins [n_loads]
        self.broke = np.zeros(lay.n_loads, dtype=np.int64)  # elements whose cycle broke a constraint, per load
        self.frames: list = []  # per level: the judged columns of its cycles
        self.names: list = []  # the chunk files of every level, in order
        self.predicted: dict = {}  # element -> loads predicted safe instead of run
        self.level = 0
        self.cycles = 0
        self.chunks_reused = self.chunks_computed = 0
        self.stats = {"stopped": 0, "predicted": 0, "loads_predicted": 0}

    # ---- planning ------------------------------------------------------------------------
    def tasks(self, ids: np.ndarray, refs: np.ndarray) -> list:
        """The elements' tasks: their loads in order, with predictions, from their references."""
        out, n = [], self.lay.n_loads
        for e, r in zip(ids, refs):
            ref_values = np.array([self.values[int(x)] for x in r if x >= 0]).reshape(-1, n)
            pred, low, key = AL.predictions(ref_values, self.rule.kappa)
            loads = AL.order(key, low, self.broke)
            scenes = self.lay.scenes(np.full(n, e), loads) if self.lay.mode == "envelope" else self.lay.scenes([e])
            out.append(Task(int(e), scenes, pred[loads], AL.following(pred[loads])))
        return out

    def chunks(self, tasks: list) -> list:
        """(file name, tasks) of each chunk of a level."""
        per = max(1, min(CHUNK_CYCLES // self.lay.n_loads, math.ceil(len(tasks) / MIN_CHUNKS)))
        out = []
        for k, start in enumerate(range(0, len(tasks), per)):
            part = tasks[start:start + per]
            h = hashlib.sha256(f"{self.salt}:{self.level}:{k}:".encode())
            for t in part:
                h.update(np.int64(t.element).tobytes() + t.scenes.tobytes() + t.predictions.tobytes())
            out.append((f"chunk-L{self.level:02d}-{k:05d}-{h.hexdigest()[:16]}.parquet", part))
        return out

    # ---- running ---------------------------------------------------------------------------
    def evaluate(self, ids: np.ndarray, refs: np.ndarray, bar) -> tuple:
        """Simulate the elements `ids` (references `refs`); (feasible, binding code, margins [N, 4])."""
        tasks = self.tasks(ids, refs)
        chunks = self.chunks(tasks)
        self.names += [name for name, _ in chunks]
        pending = [k for k, (name, _) in enumerate(chunks) if not chunk_complete(self.work / name)]
        self.chunks_reused += len(chunks) - len(pending)
        self.chunks_computed += len(pending)
        bar.total = (bar.total or 0) + len(tasks)
        todo = set(pending)
        bar.update(sum(len(part) for k, (_, part) in enumerate(chunks) if k not in todo))
        if pending:
            self._run(chunks, pending, bar)
        frame = self._read(chunks, tasks)
        self.level += 1
        return self._judge(frame, ids)

    def _run(self, chunks: list, pending: list, bar) -> None:
        r = self.run
        if r.get("gpu"):
            return self._run_gpu(chunks, pending, bar)
        planned = sum(len(t.scenes) for k in pending for t in chunks[k][1])
        jobs = runs.local_jobs(r["jobs"], planned * r["per_cycle"], r["serial_below"]) if r["local"] else r["jobs"]
        meta = {"salt": self.salt, "adaptive_level": self.level}
        shared = (self.lay.spec, r["simulate"])

        def calls(where: str):
            for k in pending:
                name, part = chunks[k]
                yield (run_tasks, k, part, str(self.work / name) if where != "dask" else None,
                       dict(meta, chunk=k), self.lay.limits, self.rule, shared if where != "pool" else None)

        with contextlib.ExitStack() as stack:
            for k, rows, scenes, n in compute.run_calls(stack, calls, jobs, r["local"], r["scheduler"], shared):
                if rows is not None:  # Dask: this process writes
                    store.write_chunk(self.work / chunks[k][0], self.lay.spec.scene, scenes, rows,
                                      dict(meta, chunk=k))
                bar.update(n)

    def _run_gpu(self, chunks: list, pending: list, bar) -> None:
        """The level's pending chunks with every load of their elements run at once on the GPU
        (sweep/gpu.py run_scenes), then each element's loads walked to its stop as on the CPU
        (run_tasks): more cycles than the CPU runs, the same rows kept."""
        from fencesweep.study.sweep import gpu

        meta = {"salt": self.salt, "adaptive_level": self.level}
        tasks = [t for k in pending for t in chunks[k][1]]
        scenes = np.unique(np.concatenate([t.scenes for t in tasks])) if tasks else np.empty(0, np.int64)
        given = dict(zip(scenes.tolist(), gpu.run_scenes(self.lay.spec, scenes, gpu.runner())))
        for k in pending:
            name, part = chunks[k]
            bar.update(run_tasks(k, part, str(self.work / name), dict(meta, chunk=k), self.lay.limits, self.rule,
                                 (self.lay.spec, None), given)[3])

    def _read(self, chunks: list, tasks: list):
        """The level's cycles from its chunks: element, load, the judged columns, dalpha_perm;
        records the per-load margins, the predictions of the loads skipped and the counts."""
        import pandas as pd

        parts = [pq.read_table(self.work / name, columns=["_model", *JUDGED]) for name, _ in chunks]
        table = pa.concat_tables(parts)
        scenes = store.numpy_column(table.column("_model"))
        frame = pd.DataFrame({c: store.numpy_column(table.column(c)) for c in JUDGED})
        spec, limits = self.lay.spec, self.lay.limits
        frame["dalpha_perm"] = [spec.resolve(int(s))["dalpha_perm"] for s in scenes]
        frame["_element"], frame["load"] = self.lay.element_of(scenes)
        frame["_scene"] = scenes
        self._record(frame, tasks, limits)
        self.cycles += len(frame)
        self.frames.append(frame)
        return frame

    def _record(self, frame, tasks: list, limits: DS.Limits) -> None:
        dlim = frame["dalpha_perm"].to_numpy() if limits.deflection_max is None else \
            np.full(len(frame), limits.deflection_max)
        margins = np.array([AL.load_margin(row, d, limits) for row, d in
                            zip(frame[list(JUDGED)].to_dict("records"), dlim)])
        ran: dict = {}
        for e, k, m in zip(frame["_element"].to_numpy(), frame["load"].to_numpy(), margins):
            ran.setdefault(int(e), {})[int(k)] = m
        for t in tasks:
            vals = np.full(self.lay.n_loads, np.nan)
            mine = ran.get(t.element, {})
            loads = [int(x) for x in self.lay.element_of(t.scenes)[1]]
            skipped = len(loads) - len(mine)
            broken = any(m < 0 for m in mine.values())
            for k, p in zip(loads, t.predictions):
                # a load not run: its prediction (safe) when the element stopped feasible; unknown
                # (NaN) when it stopped at a broken constraint
                vals[k] = mine.get(k, np.nan if broken else p)
            self.values[t.element] = vals
            self.stats["stopped"] += int(broken and skipped > 0)
            self.stats["predicted"] += int(not broken and skipped > 0)
            self.stats["loads_predicted"] += 0 if broken else skipped
            self.predicted[t.element] = 0 if broken else skipped
            self.broke[[k for k, m in mine.items() if m < 0]] += 1

    def _judge(self, frame, ids: np.ndarray) -> tuple:
        pts = J.summarize(frame, ["_element"], self.lay.limits).set_index("_element").loc[ids]
        binding = np.array([J.MARGINS.index("margin_" + b) for b in pts["binding"]], dtype=np.int64)
        return pts["feasible"].to_numpy(bool), binding, pts[J.MARGINS].to_numpy(float)
