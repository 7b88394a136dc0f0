"""The table of a sweep (step 5 of sweep/pipeline.py), assembled block by block from the spec's scenes
as columns (spec/scenes.py, as planned) and the chunks of results: rows in scene order, ASSEMBLY_BLOCK rows per
Parquet row group, one file written atomically with the spec, its hash and the versions in its
schema metadata (table_meta).

Memory holds one block of rows and at most CHUNK_CACHE chunks. The assembly depends only on the
plan, so the table is the same, bit for bit, whatever the jobs, backend or chunking.
"""
from __future__ import annotations

from collections import OrderedDict
from pathlib import Path
from typing import Callable

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from fencesweep.study.store import table as store
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep.chunks import ChunkTables, tables_of

CHUNK_CACHE = 8  # chunks held in memory while assembling


def table_meta(plan: PL.Plan) -> dict:
    """The table's provenance (its schema metadata, store.read_metadata): the resolved spec, its
    hash, source and file, the versions used and the counts of scenes, skipped scenes and runs.
    A piece of a larger spec (spec/pieces.py) records that spec, and itself under "piece"."""
    spec = plan.spec
    whole = spec.whole if spec.whole is not None else spec
    meta = {"spec": whole.normalized(), "spec_hash": whole.hash, "spec_source": whole.source,
            "spec_path": whole.path, "versions": store.versions(), "scene": spec.scene,
            "counts": {"scenes": plan.n_scenes - plan.skipped, "skipped": plan.skipped,
                       "model_runs": plan.n_models}}
    if spec.whole is not None:
        meta["piece"] = {"hash": spec.hash, "first_scene": spec.offset, "scenes": spec.n_scenes,
                         "of_scenes": whole.n_scenes}
    return meta


def _table_rows(scene: str, cols: dict, n_params: int) -> dict:
    """A block's columns, one entry per scene, as the table's rows: for `stream` one per cycle
    (docs/model.md §14, store.explode_streams), for the other scenes the same."""
    return store.explode_streams(cols, n_params) if scene == "stream" else cols


def assemble(plan: PL.Plan, work: Path, out: Path, meta: dict | Callable[[], dict] | None = None,
             tables: ChunkTables | None = None) -> int:
    """Write the table of a plan whose chunks are all in `work` at once (Assembly: fed every
    chunk, then finished with `meta`). Returns the number of rows whose run raised."""
    table = Assembly(plan, work, out, tables_of(plan, work, tables))
    return table.finish(meta)


class Assembly:
    """The table of `plan` into `out`, written block by block as the chunks it needs arrive
    (feed), while the workers run the others; finish writes the rest and closes the file with
    the metadata known only then (the verification's record). Rows in scene order, parameters
    from the plan's columns, results from the chunks (`tables`: as the sweep reads them,
    sweep/chunks.py). Memory holds one block of rows and at most CHUNK_CACHE chunks."""

    def __init__(self, plan: PL.Plan, work: Path, out: Path, tables: ChunkTables):
        self.plan, self.work, self.out, self.tables = plan, Path(work), Path(out), tables
        self.fields = store.table_schema(plan.spec.scene)
        self.result_schema = store.result_schema(plan.spec.scene)  # the chunks' columns, `_model` aside
        self.starts = list(range(0, plan.n_scenes, PL.ASSEMBLY_BLOCK))
        self._arrived: set = set()
        self._next = 0  # the next block to write
        self._waiting: set | None = None  # the chunks it needs (None: not found yet)
        self._writer = None
        self._cache: OrderedDict = OrderedDict()
        self.failed = 0  # rows whose run raised (status 'failed: exception ...'), in the blocks written

    def _needs(self, k: int) -> np.ndarray:
        """The chunks that block `k` takes results from."""
        m = self.plan.row_model[self.starts[k]:self.starts[k] + PL.ASSEMBLY_BLOCK]
        return np.unique(m[m >= 0] // self.plan.chunk_size)

    def feed(self, c: int | None = None) -> None:
        """Chunk `c` is written (None: nothing new): write the blocks now complete, in order."""
        if c is not None:
            self._arrived.add(int(c))
        while self._next < len(self.starts):
            if self._waiting is None:  # the chunks the next block needs, found once per block
                self._waiting = set(self._needs(self._next).tolist())
            if not self._arrived.issuperset(self._waiting):
                return
            self._write(self._next)
            self._next, self._waiting = self._next + 1, None

    def finish(self, meta: dict | Callable[[], dict] | None = None) -> int:
        """Write the blocks left (every chunk is in the work directory by now), add `meta` to the
        schema metadata (e.g. {"verify": record}; a function that gives it is called after the
        blocks are written: a sweep's verification finishes then, its re-runs on the workers
        meanwhile) and put the file in place. Returns the rows whose run raised."""
        try:
            self._arrived.update(range(self.plan.n_chunks))
            self.feed()
            meta = meta() if callable(meta) else meta
            self._open().close(meta or None)
            self._writer = None
        except BaseException:
            if self._writer is not None:
                self._writer.abort()
            raise
        return self.failed

    def abort(self) -> None:
        """Remove the partly written table (the chunks stay: a rerun resumes from them)."""
        if self._writer is not None:
            self._writer.abort()
            self._writer = None

    def _open(self) -> store.TableWriter:
        if self._writer is None:
            self._writer = store.TableWriter(self.out, store.table_schema(self.plan.spec.scene, table_meta(self.plan)))
        return self._writer

    def _chunk(self, c: int) -> tuple:
        """Chunk `c`'s table (as the sweep read it) and its runs' numbers (`_model`, as NumPy)."""
        if c in self._cache:
            self._cache.move_to_end(c)
            return self._cache[c]
        table = self.tables.read(c)
        data = self._cache[c] = (table, store.numpy_column(table.column("_model")))
        if len(self._cache) > CHUNK_CACHE:
            self._cache.popitem(last=False)
        return data

    def _write(self, k: int) -> None:
        """Write block `k`: ({column: Arrow array}) of its scenes that have a run."""
        plan, start = self.plan, self.starts[k]
        rows = np.nonzero(plan.row_model[start:start + PL.ASSEMBLY_BLOCK] >= 0)[0] + start
        if len(rows) == 0:
            return
        cols = plan.columns().columns(rows)
        n_params = len(cols)
        results = self._results(plan.row_model[rows])
        if plan.spec.scene == "stream":  # its lists laid out per cycle from NumPy (store.explode_streams)
            results = {f.name: _numpy(results[f.name], f.type) for f in store.result_schema("stream")}
        cols.update(results)
        cols = _table_rows(plan.spec.scene, cols, n_params)
        arrays = {f.name: store.arrow_array(cols[f.name], f.type) for f in self.fields}
        self.failed += int(pc.sum(pc.starts_with(arrays["status"], "failed: exception")).as_py() or 0)
        self._open().write(arrays)

    def _results(self, models: np.ndarray) -> dict:
        """The result columns of the runs `models`, taken from their chunks' tables as Arrow
        arrays (no conversion: the chunks hold the table's types)."""
        size = self.plan.chunk_size
        which = models // size
        parts, position, at = [], np.empty(len(models), np.int64), 0
        for c in np.unique(which).tolist():
            sel = which == c
            local = models[sel] - c * size
            table, ids = self._chunk(c)
            if not np.array_equal(ids[local], models[sel]):
                raise RuntimeError(f"chunk {c} in {self.work} does not hold the runs it should; "
                                   f"rerun with --no-resume")
            position[sel] = at + local
            parts.append(table)
            at += table.num_rows
        return _taken(parts, self.result_schema, position)


def _taken(tables: list, schema: pa.Schema, position: np.ndarray) -> dict:
    """The rows `position` of `tables` (chunks' tables, one after the other) as {column of
    `schema`: one Arrow array}, taken in one call (a slice where they follow one another); where a
    chunk's column has nulls or another type, every column goes through NumPy (_numpy), as each
    did before the chunks were kept as Arrow (a null float becomes NaN)."""
    parts = [t.select(schema.names) for t in tables]
    whole = pa.concat_tables(parts) if all(t.schema.equals(schema) for t in parts) else None  # metadata aside
    if whole is None or any(c.null_count for c in whole.columns):
        return {f.name: store.arrow_array(np.concatenate([_numpy(t.column(f.name), f.type) for t in tables])[position],
                                          f.type) for f in schema}
    n = len(position)
    if n and position[-1] - position[0] == n - 1 and bool(np.all(np.diff(position) == 1)):
        taken = whole.slice(int(position[0]), n)  # the runs in their order: the scenes of the block shared none
    else:
        taken = whole.take(store.arrow_array(position, pa.int64()))
    return {name: col.combine_chunks() for name, col in zip(taken.column_names, taken.columns)}


def _numpy(col, typ: pa.DataType) -> np.ndarray:
    """An Arrow column as a NumPy array of the dtype of `typ`'s values (objects for strings and
    lists): a null float is NaN."""
    np_type = {"double": np.float64, "int64": np.int64, "bool": np.bool_}
    out = np.empty(len(col), dtype=np_type.get(str(typ), object))
    out[:] = store.numpy_column(col)
    return out
