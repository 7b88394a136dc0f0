"""The finished chunks of a sweep, each read from its file once (ChunkTables): the verification's
sample (sweep/sample.py) scores every chunk, the verification reads the table's values of its
runs (sweep/verify.py) and the assembly (sweep/assemble.py) reads every chunk again. A sweep reads each
chunk as it finishes, while the workers run the others (sweep/pipeline.py), and these steps take it
from memory. Measured on the main job with 2 jobs (16 chunks): the three reads after the
last chunk took ~0.06 s of the ~0.2 s between it and the table.

On the GPU path the process that wrote a chunk hands its table over with it (handed, as Arrow
IPC bytes: sweep/gpu.py), and it is not read back from its file.

The tables held take at most HOLD_BYTES; a chunk past it is read from its file each time
(as each step did before, the sample's scores only the columns they need), so a sweep of any
size holds what it did.
"""
from __future__ import annotations

import contextlib
from pathlib import Path

import pyarrow as pa

from fencesweep.study.store import table as store
from fencesweep.study.sweep import plan as PL

#: the most the chunks held take, in bytes of their Arrow tables (the main job's: ~230 B a run,
#: so ~3 MB; this holds a sweep of ~500,000 runs)
HOLD_BYTES = 128 * 2**20


class ChunkTables:
    """The chunks of `plan` in the work directory `work`, as Arrow tables, each read once while
    they fit in `hold` bytes (default HOLD_BYTES; module docstring)."""

    def __init__(self, plan: PL.Plan, work: Path, hold: int | None = None):
        self.plan, self.work = plan, Path(work)
        self.hold = HOLD_BYTES if hold is None else hold
        self._tables: dict = {}
        self._bytes = 0
        self._room = True  # until a chunk did not fit
        self.reads = 0  # files read (a test counts them)

    def read(self, c: int, columns: list | None = None) -> pa.Table:
        """Chunk `c`'s table (its `columns`, or all): held, or read from its file and held while
        there is room; once a chunk did not fit, only `columns` are read, and not held."""
        table = self._tables.get(c)
        if table is None:
            table = store.read_chunk(self.work / self.plan.chunk_name(c), None if self._room else columns)
            self.reads += 1
            if self._room and self._bytes + table.nbytes <= self.hold:
                self._tables[c] = table
                self._bytes += table.nbytes
            else:
                self._room = False
        return table if columns is None else table.select(columns)

    def finished(self, c: int) -> None:
        """Chunk `c` has just been written: take its table as handed over (handed), else read it
        now, while the sweep's workers run the others, if there is room to hold it."""
        data = _HANDED.pop(str(self.work / self.plan.chunk_name(c)), None)
        if not self._room or c in self._tables:
            return
        if data is None:
            self.read(c)
            return
        table = pa.ipc.open_stream(data).read_all()
        if self._bytes + table.nbytes <= self.hold:
            self._tables[c] = table
            self._bytes += table.nbytes
        else:
            self._room = False


#: chunks' tables handed over by the process that wrote them, as Arrow IPC bytes, by file
#: (handed): ChunkTables.finished takes a chunk's from here instead of reading the file back
_HANDED: dict = {}


def ipc_bytes(table: pa.Table) -> pa.Buffer:
    """`table` as the bytes of an Arrow IPC stream: written and read back in ~0.05 ms for a chunk of
    1,600 runs (its Parquet file is read back in 0.5-1 ms), in Arrow's own layout."""
    sink = pa.BufferOutputStream()
    with pa.ipc.new_stream(sink, table.schema) as writer:
        writer.write_table(table)
    return sink.getvalue()


@contextlib.contextmanager
def handed(path: Path, data: pa.Buffer):
    """Within the block, the table of the chunk file `path` is `data` (ipc_bytes) for
    ChunkTables.finished to take; forgotten after it, taken or not."""
    key = str(path)
    _HANDED[key] = data
    try:
        yield
    finally:
        _HANDED.pop(key, None)


def tables_of(plan: PL.Plan, work: Path, tables: ChunkTables | None) -> ChunkTables:
    """`tables`, or new ones for a caller that has none."""
    return tables if tables is not None else ChunkTables(plan, work)
