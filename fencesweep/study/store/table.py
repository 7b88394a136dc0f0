"""Parquet out and in: sweep tables with their provenance, resumable chunks, trajectories.

A sweep table is one Parquet file, one row per scene: `scene`, `case`, every parameter of
docs/model.md §12 (step_factor included), the derived input `Psi`, then every result of the
scene (docs/model.md §11 for `cycle`, §8 for `impact` and `freefall`) under its name there.
Each column carries `unit`, `doc` and `role` (label / parameter / result) in its field
metadata; the schema metadata records how the file was made (`fencesweep.spec`, its
`fencesweep.spec_hash`, `fencesweep.versions`, ...; every value JSON-encoded). Nothing in it depends on the number of
workers or the time of day, so a sweep writes the same bytes whatever `--jobs` is.

Every file is written atomically: to a temporary file in the same directory, then
`os.replace`d over the target, so a killed process leaves either the old file or the new
(tables and trajectories are fsync'd first; chunks are checked when reused instead).
"""
from __future__ import annotations

import base64
import contextlib
import hashlib
import json
import math
import os
import platform
from pathlib import Path
from typing import Iterable

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from fencesweep.errors import write_error
from fencesweep.model import params as P
from fencesweep.model import results as R
from fencesweep.study.store.columns import arrow_array, numpy_column

COMPRESSION = "zstd"
META_PREFIX = "fencesweep."
#: label columns before the parameters
LABELS = (("scene", "-", "scene: cycle / impact / freefall (docs/model.md §8)"),
          ("case", "-", "named case of docs/model.md §12 the scene starts from (null: none)"))
DERIVED = (("Psi", "-", "relative damping B2 / (2 sqrt(K2 I2)) (docs/model.md §3; NaN when K2 I2 = 0)"),)

_INT = getattr(R, "_INT_RESULTS", {"n_impacts", "n_steps"})
_BOOL = getattr(R, "_BOOL_RESULTS", {"safe", "deflection_ok"})
_STR = {"outcome", "status"}


# ---------------------------------------------------------------------------- provenance
#: the package's folder (this file is fencesweep/study/store/table.py)
PACKAGE = Path(__file__).resolve().parents[2]


def source_files() -> list:
    """The package's Python sources, every one of them (kernel/, model/, study/, ...)."""
    return sorted(PACKAGE.rglob("*.py"))


def source_hash() -> str:
    """sha256 over the package's Python sources (source_files): a changed engine never reuses old
    chunks (sweep/plan.py plan_salt)."""
    h = hashlib.sha256()
    for f in source_files():
        h.update(f.relative_to(PACKAGE).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def versions() -> dict:
    """Versions that a table records (fencesweep, its source hash, numba, numpy, pyarrow, python)."""
    from importlib import metadata

    from fencesweep.version import __version__

    try:  # from the installed metadata: importing numba here would cost a quarter second
        numba_version = metadata.version("numba")
    except metadata.PackageNotFoundError:  # pragma: no cover
        numba_version = None
    return {"fencesweep": __version__, "source_hash": source_hash(), "numba": numba_version,
            "numpy": np.__version__, "pyarrow": pa.__version__, "python": platform.python_version()}


def _meta_bytes(meta: dict) -> dict:
    out = {}
    for k, v in meta.items():  # every value is JSON (strings too), so reading is uniform
        text = json.dumps(v, sort_keys=True, default=_json_default)
        out[(META_PREFIX + k).encode()] = text.encode()
    return out


def _json_default(x):
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


#: pandas' own schema key for DataFrame.attrs (pandas >= 2.1): `pd.read_parquet` of a table gives
#: df.attrs = {"units": {column: unit}, "fencesweep": provenance}, as read_table does
PANDAS_ATTRS = b"PANDAS_ATTRS"
#: the Parquet key-value entry where Arrow keeps a file's Arrow schema (base64 of its IPC form)
ARROW_SCHEMA = b"ARROW:schema"


def stamp(schema: pa.Schema, attrs: dict | None = None) -> pa.Schema:
    """`schema` with PANDAS_ATTRS beside its fencesweep.* keys: `attrs`, by default the table's
    units (field metadata) and provenance (fencesweep.* keys), so that plain pandas reads them."""
    meta = dict(schema.metadata or {})
    if attrs is None:
        attrs = {"units": _units_of(schema), "fencesweep": _provenance_of(meta)}
    meta[PANDAS_ATTRS] = json.dumps(attrs, sort_keys=True, default=_json_default).encode()
    return schema.with_metadata(meta)


def _field(name: str, typ: pa.DataType, unit: str, doc: str, role: str) -> pa.Field:
    return pa.field(name, typ, nullable=True,
                    metadata={b"unit": unit.encode(), b"doc": doc.encode(), b"role": role.encode()})


def result_type(name: str) -> pa.DataType:
    if name in _STR:
        return pa.string()
    if name in _INT:
        return pa.int64()
    if name in _BOOL:
        return pa.bool_()
    return pa.float64()


#: a stream sweep's row is one cycle of one stream (docs/model.md §14): its index, then the cycle's
#: results, then the results of its stream (n_cycles is a parameter column already)
CYCLE_INDEX = ("cycle", "-", "index k of the work cycle in its stream (stream scene; it starts at t_k = k period)")
STREAM_LEVEL = tuple(r for r in R.STREAM_RESULTS if r[0] != "n_cycles")


def result_schema(scene: str) -> pa.Schema:
    """The result columns of a chunk: one row per model run. A stream's run holds a list per
    cycle result (its cycles in order) and its stream results."""
    if scene == "stream":
        return pa.schema([_field(n, pa.list_(result_type(n)), u, d, "result") for n, u, d in R.STREAM_CYCLE_RESULTS]
                         + [_field(n, result_type(n), u, d, "result") for n, u, d in STREAM_LEVEL])
    return pa.schema([_field(n, result_type(n), u, d, "result") for n, u, d in R.SCENE_RESULTS[scene]])


def table_result_fields(scene: str) -> list:
    """The result columns of a sweep table (for `stream`: the cycle index, the cycle's results
    and its stream's, one row per cycle)."""
    if scene != "stream":
        return list(result_schema(scene))
    rows = (CYCLE_INDEX,) + R.STREAM_CYCLE_RESULTS + STREAM_LEVEL
    return [_field(n, pa.int64() if n == "cycle" else result_type(n), u, d, "result") for n, u, d in rows]


def stream_row(res: dict) -> dict:
    """A stream's results (api: the stream's plus its "cycles" DataFrame) as one chunk row."""
    cycles = res["cycles"]
    row = {n: cycles[n].tolist() for n, _, _ in R.STREAM_CYCLE_RESULTS}
    row.update({n: res[n] for n, _, _ in STREAM_LEVEL})
    return row


def param_columns() -> list:
    """(name, arrow type) of the label, parameter and derived columns, in table order."""
    cols = [(n, pa.string()) for n, _, _ in LABELS]
    cols += [(p.name, pa.string() if p.kind == "choice" else pa.float64()) for p in P.TABLE]
    cols += [(n, pa.float64()) for n, _, _ in DERIVED]
    return cols


def table_schema(scene: str, meta: dict | None = None) -> pa.Schema:
    """The schema of a sweep table of `scene`: labels, parameters, Psi, results; units in metadata."""
    fields = [_field(n, pa.string(), u, d, "label") for n, u, d in LABELS]
    fields += [_field(p.name, pa.string() if p.kind == "choice" else pa.float64(), p.unit, p.doc, "parameter")
               for p in P.TABLE]
    fields += [_field(n, pa.float64(), u, d, "parameter") for n, u, d in DERIVED]
    fields += table_result_fields(scene)
    names = [f.name for f in fields]
    assert len(set(names)) == len(names), "a result shares a parameter's name"
    return pa.schema(fields, metadata=_meta_bytes(meta) if meta else None)


def failed_result(scene: str, reason: str) -> dict:
    """The row of a run that raised instead of returning: outcome failed, NaN numbers."""
    out = {}
    for name, _, _ in R.SCENE_RESULTS[scene]:
        if name == "outcome":
            out[name] = "failed"
        elif name == "status":
            out[name] = reason
        elif name in _INT:
            out[name] = 0
        elif name in _BOOL:
            out[name] = False
        else:
            out[name] = math.nan
    if scene == "stream":  # one row, cycle 0, says why; the stream's results are undefined
        out = {k: [v] for k, v in out.items()}
        out.update({n: (-1 if n in _INT else math.nan) for n, _, _ in STREAM_LEVEL})
        out["first_failure"] = 0
    return out


def explode_streams(cols: dict, n_params: int) -> dict:
    """A block of stream runs ({column: values}, one entry per scene: its parameter columns
    first, then the chunk's result columns) -> one entry per cycle: parameters and stream
    results repeated, the cycle index and the cycle's results laid out (docs/model.md §14)."""
    names = list(cols)
    cycle_cols = {n for n, _, _ in R.STREAM_CYCLE_RESULTS}
    counts = np.array([len(v) for v in cols["outcome"]], dtype=np.int64)
    which = np.repeat(np.arange(len(counts)), counts)
    out = {}
    for name in names[:n_params]:
        col = cols[name]
        out[name] = col.take(arrow_array(which, pa.int64())) if isinstance(col, (pa.Array, pa.ChunkedArray)) else \
            np.asarray(col, dtype=object)[which]
    out["cycle"] = np.concatenate([np.arange(c, dtype=np.int64) for c in counts]) if len(counts) else \
        np.empty(0, np.int64)
    for name in names[n_params:]:
        if name in cycle_cols:
            out[name] = np.concatenate([np.asarray(vs) for vs in cols[name]]) if len(counts) else []
        else:
            out[name] = np.asarray(cols[name])[which]
    return out


def results_table(scene: str, rows: list, model_ids: Iterable[int] | None = None) -> pa.Table:
    """Result dicts (exactly the keys of results.SCENE_RESULTS[scene]) -> an Arrow table."""
    schema = result_schema(scene)
    names = schema.names
    for k, row in enumerate(rows):
        if set(row) != set(names):
            missing = sorted(set(names) - set(row))
            extra = sorted(set(row) - set(names))
            raise ValueError(f"result {k} of scene {scene!r} has missing keys {missing} / extra keys {extra}")
    arrays = [arrow_array([row[n] for row in rows], schema.field(n).type) for n in names]
    table = pa.Table.from_arrays(arrays, schema=schema)
    if model_ids is not None:
        table = table.append_column("_model", arrow_array(list(model_ids), pa.int64()))
    return table


def columns_table(scene: str, cols: dict, model_ids: Iterable[int]) -> pa.Table:
    """Result columns ({name: values}, exactly the keys of results.SCENE_RESULTS[scene]; e.g.
    results.unpack_columns) -> the Arrow table results_table makes of the same rows."""
    schema = result_schema(scene)
    if set(cols) != set(schema.names):
        raise ValueError(f"result columns of scene {scene!r}: missing {sorted(set(schema.names) - set(cols))} / "
                         f"extra {sorted(set(cols) - set(schema.names))}")
    arrays = [arrow_array(cols[n], schema.field(n).type) for n in schema.names]
    table = pa.Table.from_arrays(arrays, schema=schema)
    return table.append_column("_model", arrow_array(list(model_ids), pa.int64()))


def write_chunk_columns(path: str | Path, scene: str, model_ids: list, cols: dict, meta: dict) -> pa.Table:
    """write_chunk of result columns (columns_table); returns the table written."""
    table = columns_table(scene, cols, model_ids).replace_schema_metadata(_meta_bytes(meta))
    _write_chunk_table(table, path)
    return table


# ---------------------------------------------------------------------------- atomic files
@contextlib.contextmanager
def atomic_path(path: str | Path, fsync: bool = True):
    """Yield a temporary path beside `path`; on success fsync it and os.replace it onto `path`.
    The temporary file is removed whatever happens; an OSError (ENOSPC: the disk is full) is
    raised as a WriteError naming `path`, and `path` keeps what it held before.

    Without fsync a power loss may leave a damaged file under the final name (never a
    killed process: the rename is atomic); chunks skip it, as store.chunk_complete rejects a
    damaged chunk and the sweep recomputes it."""
    path = Path(path)
    tmp = path.with_name(f".fencesweep-tmp-{os.getpid()}-{path.name}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        yield tmp
        if fsync:
            with open(tmp, "rb") as fh:
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:  # a full disk, a read-only place: one error that names the file
        raise write_error(exc, path) from exc
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)


def write_table_atomic(table: pa.Table, path: str | Path, fsync: bool = True, attrs: dict | None = None) -> None:
    """Write `table` to `path` atomically, stamped for pandas (stamp; `attrs`: its default)."""
    table = table.replace_schema_metadata(stamp(table.schema, attrs).metadata)
    with atomic_path(path, fsync) as tmp:
        pq.write_table(table, tmp, compression=COMPRESSION)


# ---------------------------------------------------------------------------- chunks
#: a chunk (write_chunk) is written once and read back once (sweep/chunks.py): Parquet, compressed
#: with LZ4, without dictionaries or statistics, and without the pandas stamp (stamp: no one reads
#: a chunk with pandas). On a chunk of the main job (821 runs), against the tables' zstd: written
#: in 0.9-1.1 ms instead of 3.2, read in 0.47-0.6 ms instead of 1.5-1.9, 134 kB instead of 141
#: (Arrow IPC with LZ4: 0.4 and 0.2 ms, 142 kB)
CHUNK_OPTIONS = {"compression": "lz4", "use_dictionary": False, "write_statistics": False}


def write_chunk(path: str | Path, scene: str, model_ids: list, rows: list, meta: dict) -> None:
    """One finished chunk: the results of its model runs, with their model numbers."""
    table = results_table(scene, rows, model_ids)
    _write_chunk_table(table.replace_schema_metadata(_meta_bytes(meta)), path)


def _write_chunk_table(table: pa.Table, path: str | Path) -> None:
    """A chunk's table into `path`, atomically (not fsync'd: chunk_complete checks it when reused)."""
    with atomic_path(path, fsync=False) as tmp:
        pq.write_table(table, tmp, **CHUNK_OPTIONS)


def read_chunk(path: str | Path, columns: list | None = None) -> pa.Table:
    """A chunk's table (its `columns`, or all), in this thread (a small file: threads cost more)."""
    return pq.ParquetFile(path).read(columns=columns, use_threads=False)


def chunk_complete(path: str | Path, n_rows: int) -> bool:
    """True if `path` is a readable chunk of `n_rows` runs (anything else is recomputed)."""
    try:
        return pq.read_metadata(path).num_rows == n_rows
    except (OSError, pa.ArrowInvalid):
        return False


def chunk_arrays(table: pa.Table) -> dict:
    """A chunk's table (study/chunks.py) as {column: numpy array} (strings as object arrays),
    `_model` included."""
    return {name: numpy_column(table.column(name)) for name in table.column_names}


class TableWriter:
    """Write a sweep table block by block into one Parquet file, atomically at close."""

    def __init__(self, path: str | Path, schema: pa.Schema):
        self.path = Path(path)
        self.schema = stamp(schema)
        self._cm = atomic_path(self.path)
        self._tmp = self._cm.__enter__()
        try:
            self._writer = pq.ParquetWriter(self._tmp, self.schema, compression=COMPRESSION)
        except OSError as exc:
            with contextlib.suppress(OSError):
                self._cm.__exit__(type(exc), exc, None)  # removes the temporary file
            raise write_error(exc, self.path) from exc
        self.n_rows = 0

    def write(self, columns: dict) -> None:
        """One row group: {name: values}, each a sequence, a numpy array or an Arrow array."""
        arrays = [arrow_array(columns[f.name], f.type) for f in self.schema]
        try:
            self._writer.write_table(pa.Table.from_arrays(arrays, schema=self.schema))
        except OSError as exc:
            raise write_error(exc, self.path) from exc
        self.n_rows += len(arrays[0]) if arrays else 0

    def close(self, meta: dict | None = None) -> None:
        """Finish the file and put it in place; on an error, remove the temporary file and raise
        a WriteError (the file at `path` keeps what it held). `meta`, known only now (a sweep's
        verification: sweep/assemble.py), joins the schema's metadata (add_metadata)."""
        try:
            if meta:
                self.add_metadata(meta)
            self._writer.close()
        except OSError as exc:
            self.abort()
            raise write_error(exc, self.path) from exc
        self._cm.__exit__(None, None, None)

    def add_metadata(self, meta: dict) -> None:
        """Add `meta` ({key: JSON value}) to the file's schema metadata after its row groups are
        written, the pandas attrs (stamp) included: the Parquet footer's key-value metadata is
        written at close, and its ARROW:schema entry, the Arrow schema that readers take the
        schema's metadata from, is replaced by the new schema's (ParquetWriter's
        add_key_value_metadata replaces a key's value)."""
        self.schema = stamp(self.schema.with_metadata({k: v for k, v in (self.schema.metadata or {}).items()
                                                       if k != PANDAS_ATTRS} | _meta_bytes(meta)))
        kv = dict(self.schema.metadata)
        kv[ARROW_SCHEMA] = base64.b64encode(self.schema.serialize().to_pybytes())
        self._writer.add_key_value_metadata({k.decode(): v.decode() for k, v in kv.items()})

    def abort(self) -> None:
        with contextlib.suppress(Exception):
            self._writer.close()
        with contextlib.suppress(Exception):
            self._cm.__exit__(RuntimeError, RuntimeError("aborted"), None)

    def __enter__(self):
        return self

    def __exit__(self, typ, exc, tb):
        if typ is None:
            self.close()
        else:
            self.abort()
        return False


# ---------------------------------------------------------------------------- reading
def _provenance_of(raw: dict) -> dict:
    out = {}
    for k, v in raw.items():
        k = k.decode()
        if k.startswith(META_PREFIX):
            out[k[len(META_PREFIX):]] = json.loads(v.decode())
    return out


def _units_of(schema: pa.Schema) -> dict:
    return {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in schema}


def read_metadata(path: str | Path) -> dict:
    """The provenance of a table: {'spec': ..., 'spec_hash': ..., 'versions': ..., ...}."""
    return _provenance_of(pq.read_schema(path).metadata or {})


def units(path: str | Path) -> dict:
    """{column: unit} from the field metadata of a table."""
    return _units_of(pq.read_schema(path))


def read_table(path: str | Path):
    """A table of fencesweep's as a pandas DataFrame; df.attrs holds 'units' and 'fencesweep'
    (provenance). `pd.read_parquet(path)` gives the same (PANDAS_ATTRS); a table written before
    that key existed gets its attrs from the schema here."""
    import pandas as pd

    df = pd.read_parquet(path)
    if "fencesweep" not in df.attrs:  # written before PANDAS_ATTRS (attrs empty, or a DataFrame's own)
        df.attrs.update(units=units(path), fencesweep=read_metadata(path))
    return df


# ---------------------------------------------------------------------------- trajectories
def write_trajectory(traj_df, path: str | Path, vals: dict, results: dict) -> None:
    """Write one run's time series to Parquet, atomically, with its parameters and results.

    Schema metadata: `fencesweep.params` and `fencesweep.results` (JSON) and
    `fencesweep.versions`. Column units come from `traj_df.attrs['units']` when the engine
    gives them.
    """
    table = pa.Table.from_pandas(traj_df, preserve_index=False)
    col_units = dict(getattr(traj_df, "attrs", {}).get("units", {}) or {})
    if col_units:
        fields = []
        for f in table.schema:
            md = dict(f.metadata or {})
            if f.name in col_units:
                md[b"unit"] = str(col_units[f.name]).encode()
            fields.append(f.with_metadata(md))
        table = table.cast(pa.schema(fields, metadata=table.schema.metadata))
    meta = dict(table.schema.metadata or {})
    prov = {"params": _plain(vals), "results": _plain(results), "versions": versions()}
    meta.update(_meta_bytes(prov))
    table = table.replace_schema_metadata(meta)
    write_table_atomic(table, path, attrs={**prov, "units": {k: v for k, v in _units_of(table.schema).items() if v}})


def _plain(d: dict) -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not math.isfinite(v):
            v = None if math.isnan(v) else ("inf" if v > 0 else "-inf")
        out[k] = v
    return out


def read_trajectory(path: str | Path):
    """A trajectory written by write_trajectory; df.attrs has 'params', 'results', 'versions',
    'units' (`pd.read_parquet` gives the same)."""
    import pandas as pd

    df = pd.read_parquet(path)
    if "params" not in df.attrs:  # written before PANDAS_ATTRS (attrs empty, or the DataFrame's own units)
        meta = read_metadata(path)
        df.attrs.update({k: meta.get(k) for k in ("params", "results", "versions")})
        df.attrs["units"] = {k: v for k, v in units(path).items() if v}
    return df

