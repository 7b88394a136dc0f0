"""An envelope sweep's per-design-point table (`NAME_points.parquet` beside the per-load
table): the judge's verdicts (design/judge.py), written batch by batch so that memory stays flat
in the table's size.
"""
from __future__ import annotations

from typing import Any

from fencesweep.study.design.judge import WORST, Limits, combine, finish, load_index, partial, spec_limits


def design_columns(spec) -> list:
    """The columns that name a design point of an envelope sweep: its other axes (and case)."""
    names = [n_ for a in spec.axes if a.where != "envelope" for n_ in a.names]
    if "Psi" in names:  # the table holds K2 too; Psi is derived
        names = [n_ for n_ in names if n_ != "Psi"] + ["K2"]
    if len(spec.cases) > 1:  # the cases' own parameters tell them apart (and their names, if named)
        named = ["case"] if any(c["case"] for c in spec.cases) else []
        names = named + list(dict.fromkeys(n_ for c in spec.cases for n_ in c["params"])) + names
    return names


def points_path(out) -> Any:
    """Where `fencesweep grid` writes the per-design-point table of an envelope sweep table `out`."""
    from pathlib import Path

    out = Path(out)
    return out.with_name(out.stem + "_points.parquet")


#: rows of the per-load table read at once when it is judged (the memory stays flat in its size)
POINTS_BATCH = 65_536


def write_points(spec, table_path, limits: Limits | None = None):
    """Judge an envelope sweep's per-load table, batch by batch, and write its per-design-point
    table (points_path); returns (path, DataFrame)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from fencesweep.study.store import table as store

    env = spec.envelope
    limits = limits or spec_limits(spec)
    by = design_columns(spec)
    cols = list(dict.fromkeys(by + list(env.names) + ["outcome", *WORST, "dalpha_perm"]))
    parts = []
    for batch in pq.ParquetFile(table_path).iter_batches(batch_size=POINTS_BATCH, columns=cols):
        df = batch.to_pandas()
        df["load"] = load_index(df, env)
        parts.append(partial(df, by, limits))
        if len(parts) > 8:
            parts = [combine(parts)]
    pts = finish(combine(parts), by, limits)
    path = points_path(table_path)
    meta = {"spec_hash": spec.hash, "spec_path": spec.path, "envelope": env.definition(),
            "limits": limits.as_dict(), "per_load_table": str(table_path), "versions": store.versions()}
    table = pa.Table.from_pandas(pts, preserve_index=False)
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), **store._meta_bytes(meta)})
    store.write_table_atomic(table, path)
    return path, pts
