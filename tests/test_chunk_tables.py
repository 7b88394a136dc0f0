"""A sweep's chunks kept as Arrow from the worker to the table (sweep/chunks.py, sweep/assemble.py,
sweep/gpu.py, store/columns.py): the table the assembly takes from the chunks' Arrow columns is
the table gathered through NumPy, as every sweep assembled it before, bit for bit (shared runs,
blocks across chunks, strings, NaN, a null); the GPU path hands each chunk's table to the sweep's
process instead of its file being read back, with the same table; a long column of few strings
is made from its distinct values, the same array."""
import types

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from fencesweep.model import results as R
from fencesweep.study.store import columns as C
from fencesweep.study.store import table as store
from fencesweep.study.sweep import assemble, chunks, output
from fencesweep.study.sweep import pipeline as sweep
from fencesweep.study.sweep import plan as PL
from helpers import SWEEP_SPEC, fake_engine
from helpers import load_spec as spec


def numpy_gathered(plan: PL.Plan, work, rows: np.ndarray) -> dict:
    """The result columns of the scenes `rows` as the assembly gathered them through NumPy: each
    chunk as {column: NumPy} (store.chunk_arrays), each column into an array of its type."""
    models = plan.row_model[rows]
    dtype = {"double": np.float64, "int64": np.int64, "bool": np.bool_}
    fields = store.result_schema(plan.spec.scene)
    cols = {f.name: np.empty(len(models), dtype=dtype.get(str(f.type), object)) for f in fields}
    which = models // plan.chunk_size
    for c in np.unique(which):
        sel = which == c
        data = store.chunk_arrays(store.read_chunk(work / plan.chunk_name(int(c))))
        for f in fields:
            cols[f.name][sel] = data[f.name][models[sel] - c * plan.chunk_size]
    return {f.name: C.arrow_array(cols[f.name], f.type) for f in fields}


def kept_work(monkeypatch):
    """Keep the sweep's work directory (its chunks) when the table is written."""
    monkeypatch.setattr(sweep, "shutil", types.SimpleNamespace(rmtree=lambda path: None))


@pytest.mark.parametrize("jobs", [1, 2])
def test_the_table_taken_from_the_chunks_arrow_columns_is_the_table_gathered_through_numpy(tmp_path, monkeypatch,
                                                                                          jobs):
    monkeypatch.setattr(PL, "ASSEMBLY_BLOCK", 7)  # blocks across chunks of 4 runs
    kept_work(monkeypatch)
    sp = spec(SWEEP_SPEC)
    out = sweep.run_sweep(sp, tmp_path / "t.parquet", jobs=jobs, simulate=fake_engine, serial_below=0.0)
    plan = PL.make_plan(sp)
    plan.chunk_size = 4
    assert plan.n_models < plan.n_scenes  # runs shared by scenes: rows taken out of order
    rows = np.flatnonzero(plan.row_model >= 0)
    expected = plan.columns().columns(rows) | numpy_gathered(plan, output.work_root(out.out) / plan.salt[:16], rows)
    schema = store.table_schema("cycle")
    expected = pa.Table.from_arrays([C.arrow_array(expected[f.name], f.type) for f in schema], schema=schema)
    table = pq.read_table(out.out)
    assert table.replace_schema_metadata(None).equals(expected, check_metadata=True)
    assert pq.ParquetFile(out.out).metadata.num_row_groups == -(-len(rows) // 7)


def test_a_null_or_another_type_in_a_chunk_goes_through_numpy_as_before():
    """A column with a null (a float: NaN) or of another type (int64 as float64) makes every
    column of the block go through NumPy, as the assembly did before (nothing the sweep writes
    has either: the fallback keeps the old tables of anything else)."""
    schema = pa.schema([("x", pa.float64()), ("s", pa.string()), ("n", pa.int64())])
    one = pa.table({"x": [1.0, None], "s": ["a", "b"], "n": [1, 2]}, schema=schema)
    two = pa.table({"x": [3.0, 4.0], "s": ["c", None], "n": pa.array([5.0, 6.0])})
    got = assemble._taken([one, two], schema, np.array([3, 1, 0, 2]))
    x = got["x"].to_numpy()
    assert got["x"].null_count == 0 and x[[0, 2, 3]].tolist() == [4.0, 1.0, 3.0] and np.isnan(x[1])
    assert got["s"].to_pylist() == [None, "b", "a", "c"] and got["n"].to_pylist() == [6, 2, 1, 5]
    plain = assemble._taken([one.drop_null(), two.drop_null().cast(schema)], schema, np.array([1, 0]))
    assert {k: v.to_pylist() for k, v in plain.items()} == {"x": [3.0, 1.0], "s": ["c", "a"], "n": [5, 1]}


def test_the_gpu_paths_chunks_handed_over_give_the_table_their_files_give(tmp_path, monkeypatch):
    """The GPU path's workers hand each chunk's table over (chunks.handed) and no chunk file is
    read back; with the hand-over off, every file is read: the same table, bit for bit, on 1 and
    2 jobs; nothing handed over is left behind."""
    from fencesweep.study.sweep import gpu

    class Card:  # each run's results a function of its vector, outcomes among them
        def free_memory(self):
            return None

        def launch(self, P):
            x = np.sin(P.sum(axis=1))
            out = np.zeros((P.shape[0], R.N_STREAM_CYCLE_RESULTS))
            out[:, :R.N_CYCLE_RESULTS] = x[:, None] * np.arange(1, R.N_CYCLE_RESULTS + 1)
            out[:, R.RI["outcome"]] = (np.abs(x) * 1000).astype(np.int64) % 3
            out[:, R.RI["status"]] = 0
            return types.SimpleNamespace(result=lambda: out)

    monkeypatch.setattr(sweep, "gpu_device", lambda sp: {"backend": "cuda", "name": "stand-in"})
    monkeypatch.setattr(gpu, "runner", lambda: Card())
    monkeypatch.setattr(gpu, "BATCH_RUNS", 9)
    made, real = [], chunks.ChunkTables.__init__
    monkeypatch.setattr(chunks.ChunkTables, "__init__", lambda self, *a, **k: real(self, *a, **k) or made.append(self))
    sp = spec(SWEEP_SPEC.replace("drive: [rigid, flexible]", "drive: [flexible]"))
    run = [sweep.run_sweep(sp, tmp_path / f"h{j}.parquet", jobs=j, backend="cuda", verify=False, serial_below=0.0)
           for j in (1, 2)]
    assert [t.reads for t in made] == [0, 0] and not chunks._HANDED
    monkeypatch.setattr(chunks, "handed", lambda path, data: __import__("contextlib").nullcontext())
    read = sweep.run_sweep(sp, tmp_path / "r.parquet", jobs=1, backend="cuda", verify=False)
    assert made[-1].reads == read.n_chunks > 2
    assert run[0].out.read_bytes() == run[1].out.read_bytes() == read.out.read_bytes()


@pytest.mark.parametrize("values", [
    ["scraped", "overload", None, "failed: exception ValueError: é"] * 30,
    np.array(["a", "b"] * 50, dtype=object),
    np.array(["x", "yy"] * 50),  # NumPy strings
    [f"distinct {k}" for k in range(100)],  # mostly distinct: one by one
    [None] * 40,
])
def test_a_long_column_of_few_strings_is_the_array_made_one_by_one(values):
    got = C.arrow_array(values, pa.string())
    assert got.equals(C._strings(list(values), len(values))) and got.type == pa.string()


def test_values_that_are_not_strings_still_go_to_pyarrow():
    with pytest.raises(pa.ArrowTypeError):
        C.arrow_array([1, 2] * 40, pa.string())
    assert C._few_strings([[1], [2]] * 40, 80) is None and C._few_strings(["a", 1] * 40, 80) is None
