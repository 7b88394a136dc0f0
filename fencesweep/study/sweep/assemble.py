"""The table of a sweep (step 5 of sweep/pipeline.py), assembled block by block from the parameter blocks
of the planning pass and the chunks of results: rows in scene order, ASSEMBLY_BLOCK rows per
Parquet row group, one file written atomically with the spec, its hash and the versions in its
schema metadata (table_meta).

Memory holds one block of rows and at most CHUNK_CACHE chunks. The assembly depends only on the
plan, so the table is the same, bit for bit, whatever the jobs, backend or chunking.
"""
from __future__ import annotations

import itertools
from collections import OrderedDict
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from fencesweep.study.store import table as store
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep.chunks import ChunkTables, tables_of

CHUNK_CACHE = 8  # chunks held in memory while assembling


def table_meta(plan: PL.Plan) -> dict:
    """The table's provenance (its schema metadata, store.read_metadata): the resolved spec, its
    hash, source and file, the versions used and the counts of scenes, skipped scenes and runs."""
    spec = plan.spec
    return {"spec": spec.normalized(), "spec_hash": spec.hash, "spec_source": spec.source, "spec_path": spec.path,
            "versions": store.versions(), "scene": spec.scene,
            "counts": {"scenes": plan.n_scenes - plan.skipped, "skipped": plan.skipped,
                       "model_runs": plan.n_models}}


def _block_params(plan: PL.Plan, work: Path, block: int, rows: np.ndarray):
    """The label and parameter columns of the scenes `rows` of one block: from the file that
    make_plan wrote, or resolved here if there is none."""
    table = store.read_param_table(PL.params_path(work, block))
    if table is not None and table.num_rows == len(rows):
        return table
    cols = PL.param_columns()
    for i in rows:
        PL.add_params(cols, plan.spec.resolve(int(i)))
    return store.param_table(cols)


def _table_rows(scene: str, cols: dict, n_params: int) -> dict:
    """A block's columns, one entry per scene, as the table's rows: for `stream` one per cycle
    (docs/model.md §14, store.explode_streams), for the other scenes the same."""
    return store.explode_streams(cols, n_params) if scene == "stream" else cols


def assemble(plan: PL.Plan, work: Path, out: Path, meta: dict | Callable[[], dict] | None = None,
             tables: ChunkTables | None = None) -> int:
    """Write the table: rows in scene order, parameters from the planning pass, results from the
    chunks (`tables`: as the sweep read them, sweep/chunks.py); `meta` is added to its schema metadata
    (e.g. {"verify": record}). `meta` may be a function that gives it: it is called once the first
    block is made, before anything is written (a sweep's verification finishes then, its re-runs
    on the workers while this process makes the block: sweep/pipeline.py).

    Memory holds one block of rows and at most CHUNK_CACHE chunks. Returns the number of
    rows whose run raised (status 'failed: exception ...').
    """
    blocks = _blocks(plan, work, tables_of(plan, work, tables))
    first = next(blocks, None)
    meta = meta() if callable(meta) else meta
    schema = store.table_schema(plan.spec.scene, table_meta(plan) | (meta or {}))
    failed = 0
    with store.TableWriter(out, schema) as writer:
        for cols, n_failed in itertools.chain(() if first is None else (first,), blocks):
            failed += n_failed
            writer.write(cols)
    return failed


def _blocks(plan: PL.Plan, work: Path, tables: ChunkTables) -> Iterator[tuple]:
    """The table's blocks in order: ({column: Arrow array}, rows whose run raised)."""
    spec, size = plan.spec, plan.chunk_size
    fields = store.table_schema(spec.scene)
    rcols = [(f.name, f.type) for f in store.result_schema(spec.scene)]
    np_type = {"double": np.float64, "int64": np.int64, "bool": np.bool_}
    cache: OrderedDict = OrderedDict()

    def chunk(c: int) -> dict:
        if c in cache:
            cache.move_to_end(c)
            return cache[c]
        data = store.chunk_arrays(tables.read(c))
        cache[c] = data
        if len(cache) > CHUNK_CACHE:
            cache.popitem(last=False)
        return data

    for block, start in enumerate(range(0, plan.n_scenes, PL.ASSEMBLY_BLOCK)):
        stop = min(plan.n_scenes, start + PL.ASSEMBLY_BLOCK)
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
        n_failed = int(sum(1 for s in cols["status"] if str(s).startswith("failed: exception")))
        yield {f.name: store.arrow_array(cols[f.name], f.type) for f in fields}, n_failed
