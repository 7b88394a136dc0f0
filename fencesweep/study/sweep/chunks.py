"""The finished chunks of a sweep, each read from its file once (ChunkTables): the verification's
sample (sweep/sample.py) scores every chunk, the verification reads the table's values of its
runs (sweep/verify.py) and the assembly (sweep/assemble.py) reads every chunk again. A sweep reads each
chunk as it finishes, while the workers run the others (sweep/pipeline.py), and these steps take it
from memory. Measured on the main job with 2 jobs (16 chunks): the three reads after the
last chunk took ~0.06 s of the ~0.2 s between it and the table.

The tables held take at most HOLD_BYTES; a chunk past it is read from its file each time
(as each step did before, the sample's scores only the columns they need), so a sweep of any
size holds what it did.
"""
from __future__ import annotations

from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

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
            table = pq.ParquetFile(self.work / self.plan.chunk_name(c)).read(columns=None if self._room else columns)
            self.reads += 1
            if self._room and self._bytes + table.nbytes <= self.hold:
                self._tables[c] = table
                self._bytes += table.nbytes
            else:
                self._room = False
        return table if columns is None else table.select(columns)

    def finished(self, c: int) -> None:
        """Chunk `c` has just been written: read it now, while the sweep's workers run the others,
        if there is room to hold it."""
        if self._room:
            self.read(c)


def tables_of(plan: PL.Plan, work: Path, tables: ChunkTables | None) -> ChunkTables:
    """`tables`, or new ones for a caller that has none."""
    return tables if tables is not None else ChunkTables(plan, work)
