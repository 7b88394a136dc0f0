"""The sweep layer: deduplication, parallel determinism, streaming chunks, resume, metadata, Dask.

Most tests run against `fake_engine` (tests/helpers.py), a cheap deterministic function of the
parameters, passed as `simulate=` (pickled by value, so loky workers need not import a test file),
on SPEC (helpers.SWEEP_SPEC).
`test_real_engine_*` run the real engine on a few scenes.
"""
import gc
import math
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import cloudpickle
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from fencesweep.model import simulate as api
from fencesweep import cli
from fencesweep.study.spec.scenes import key_bytes
from fencesweep.study.sweep import assemble
from fencesweep.study.sweep import chunks
from fencesweep.study.sweep import compute
from fencesweep.study.sweep import output
from fencesweep.study.sweep import runs
from fencesweep.study.store import table as store
from fencesweep.study.sweep import pipeline as sweep
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import verify as V
from fencesweep.model import params as P
from fencesweep.model import results as R
from fencesweep.study.spec import pieces as SP
from fencesweep.study.spec import spec as S
from fencesweep import resources
from fencesweep.errors import UsageError
from helpers import SWEEP_SPEC as SPEC, fake_engine
from helpers import load_spec as spec

cloudpickle.register_pickle_by_value(sys.modules[__name__])


class Counting:
    """Counts the runs made for chunks (not the warm-up and timing runs); in this process: jobs = 1."""

    def __init__(self, monkeypatch):
        self.calls = []
        real = runs.run_models

        def counting(scene, vals_list, simulate=None, vectors=None):
            self.calls += [P.model_key(v) for v in vals_list]
            return real(scene, vals_list, simulate, vectors)

        monkeypatch.setattr(runs, "run_models", counting)


def run(tmp_path, name="t.parquet", text=SPEC, **kw) -> sweep.Outcome:
    kw.setdefault("simulate", fake_engine)
    kw.setdefault("jobs", 1)
    return sweep.run_sweep(spec(text), tmp_path / name, **kw)


def interrupted_run(monkeypatch, tmp_path, after: int, **kw) -> list:
    """Run a sweep that is interrupted (KeyboardInterrupt, as if killed) once `after` chunks
    are written; return the paths of the chunks written."""
    real_write = store.write_chunk
    written = []

    def dying_write(path, *a, **k):
        if len(written) == after:
            raise KeyboardInterrupt
        real_write(path, *a, **k)
        written.append(Path(path))

    monkeypatch.setattr(store, "write_chunk", dying_write)
    with pytest.raises(KeyboardInterrupt):
        run(tmp_path, **kw)
    monkeypatch.setattr(store, "write_chunk", real_write)
    return written



# ------------------------------------------------------------------ plan and dedup
def test_dedup_simulates_each_model_once_and_fills_all_rows(tmp_path, monkeypatch):
    sp = spec()
    plan = PL.make_plan(sp)
    # rigid: B2, K2 unused -> 1 run per case; flexible: 5 x 2 per case
    assert sp.n_scenes == 2 * 2 * 5 * 2 == 40
    assert plan.n_models == 2 * (1 + 10) == 22
    assert plan.n_chunks == math.ceil(22 / 4)
    eng = Counting(monkeypatch)
    res = run(tmp_path)
    assert len(eng.calls) == 22 and len(set(eng.calls)) == 22  # each run once
    df = pd.read_parquet(res.out)
    assert len(df) == 40
    rigid = df[(df.drive == "rigid") & (df.case == "small_far")]
    assert len(rigid) == 10 and rigid.peak_force.nunique() == 1 and rigid.B2.nunique() == 5
    # every row holds the results of its own parameters
    for i in (0, 13, 39):
        vals = sp.resolve(i)
        expect, _ = fake_engine(vals)
        row = df.iloc[i]
        for name, value in expect.items():
            if isinstance(value, float) and math.isnan(value):
                assert math.isnan(row[name])
            else:
                assert row[name] == value, name


def test_table_has_every_parameter_and_result_with_units(tmp_path):
    res = run(tmp_path)
    schema = pq.read_schema(res.out)
    names = schema.names
    assert names[:2] == ["scene", "case"]
    assert names[2:2 + len(P.NAMES)] == list(P.NAMES)  # docs/model.md §12 order, step_factor included
    assert "Psi" in names
    assert names[-len(R.CYCLE_RESULTS):] == [n for n, _, _ in R.CYCLE_RESULTS]
    u = store.units(res.out)
    assert u["B2"] == "N m s/rad" and u["k1"] == "N/m^1.5" and u["peak_force"] == "N"
    assert u["deflection_max"] == "rad" and u["outcome"] == "-"
    assert schema.field("B2").metadata[b"role"] == b"parameter"
    assert schema.field("peak_force").metadata[b"role"] == b"result"
    df = pd.read_parquet(res.out)
    assert df["n_steps"].dtype == np.int64 and df["safe"].dtype == bool
    assert df["B2"].dtype == np.float64 and set(df["outcome"]) <= set(R.OUTCOMES)
    assert set(df["case"]) == {"small_far", "long_near"}
    assert df.loc[0, "I2"] == pytest.approx(5.0 * 1.2 ** 2 / 3)  # derived values filled in
    assert df["Psi"].iloc[-1] == pytest.approx(100 / (2 * math.sqrt(570 * 2.4)))


def test_metadata_records_spec_hash_and_versions(tmp_path):
    import numba

    import fencesweep

    res = run(tmp_path)
    meta = store.read_metadata(res.out)
    sp = spec()
    assert meta["spec_hash"] == sp.hash
    assert meta["spec"] == sp.normalized()
    assert "chunk_size: 4" in meta["spec_source"]
    v = meta["versions"]
    assert v["fencesweep"] == fencesweep.__version__
    assert v["numba"] == numba.__version__ and v["numpy"] == np.__version__
    assert len(v["source_hash"]) == 64
    assert meta["counts"] == {"scenes": 40, "skipped": 0, "model_runs": 22}
    df = store.read_table(res.out)
    assert df.attrs["units"]["K2"] == "N m/rad" and df.attrs["fencesweep"]["spec_hash"] == sp.hash


def test_the_source_hash_covers_the_engine_not_only_the_study():
    """A sweep's chunks are salted with the hash of the package's sources (plan.plan_salt): an
    edit of a kernel or a model module must change it, or a resumed sweep would reuse chunks
    of the old engine."""
    import fencesweep

    names = {f.relative_to(store.PACKAGE).as_posix() for f in store.source_files()}
    assert {"kernel/rk.py", "model/drive.py", "model/scenes/stream.py", "study/sweep/plan.py", "cli.py"} <= names
    assert store.PACKAGE == Path(fencesweep.__file__).resolve().parent


def test_pandas_round_trip(tmp_path):
    res = run(tmp_path)
    df = pd.read_parquet(res.out)
    again = tmp_path / "again.parquet"
    df.to_parquet(again)
    back = pd.read_parquet(again)
    pd.testing.assert_frame_equal(df, back)
    assert len(df) == 40 and df.index.equals(pd.RangeIndex(40))


def test_same_table_bit_for_bit_for_1_and_2_jobs(tmp_path):
    a = run(tmp_path, "one.parquet", jobs=1)
    b = run(tmp_path, "two.parquet", jobs=2, serial_below=0.0)  # really on 2 loky workers
    assert a.out.read_bytes() == b.out.read_bytes()
    pd.testing.assert_frame_equal(pd.read_parquet(a.out), pd.read_parquet(b.out))
    assert not output.work_root(a.out).exists()  # the work directory is removed when done
    assert gc.get_freeze_count() == 0  # the objects frozen while the forked workers lived are collectable again


def test_same_table_from_loky_workers(tmp_path, monkeypatch):
    """Where the workers are not forked (loky: fresh processes) the table is the same."""
    ref = run(tmp_path, "ref.parquet")
    monkeypatch.setattr(compute, "START_METHOD", "loky")
    res = run(tmp_path, "loky.parquet", jobs=2, serial_below=0.0)
    assert res.jobs == 2 and res.out.read_bytes() == ref.out.read_bytes()


def test_same_table_from_a_plan_made_beforehand(tmp_path):
    """A plan made beforehand (its columns resolved outside the sweep) writes the same table."""
    ref = run(tmp_path, "ref.parquet")
    res = run(tmp_path, "planned.parquet", plan=PL.make_plan(spec()))
    assert res.out.read_bytes() == ref.out.read_bytes()


def test_model_key_bytes_do_not_depend_on_string_identity():
    digest = key_bytes
    literal, flexible = "flexible", "".join(["flex", "ible"])  # equal, not the same object
    assert flexible is not literal
    a = digest(("cycle", ("drive", "flexible"), ("contact_law", "flexible"), ("B2", 72.0)))
    b = digest(("cycle", ("drive", flexible), ("contact_law", "flexible"), ("B2", 72.0)))
    assert a == b
    assert digest(("cycle", ("B2", 72.0))) != digest(("cycle", ("B2", 72.5)))


def test_spec_error_in_planning_leaves_no_work_directory(tmp_path):
    text = """
        grid: {dP: [0, 0.5, 0.7]}
    """
    for jobs in (1, 2):
        with pytest.raises(S.SpecError, match="dP = 0.7"):
            run(tmp_path, text=text, jobs=jobs, serial_below=0.0)
        assert not output.work_root(tmp_path / "t.parquet").exists()


def test_impact_scene_columns(tmp_path):
    text = """
        scene: impact
        grid: {m2: {logspace: [0.5, 100, 5]}}
        cases: [{drive: rigid}, {drive: free}]
    """
    res = run(tmp_path, text=text)
    df = pd.read_parquet(res.out)
    assert len(df) == 10 and res.n_models == 6  # rigid ignores m2
    assert list(df.columns[-len(R.IMPACT_RESULTS):]) == [n for n, _, _ in R.IMPACT_RESULTS]
    assert "outcome" not in df.columns


def test_invalid_skip_rows_are_left_out(tmp_path):
    text = """
        invalid: skip
        grid: {dP: [0.0, 0.6], phi0: [0.0, 0.3]}
        cases: [small_far]
    """
    res = run(tmp_path, text=text)
    df = pd.read_parquet(res.out)
    # small load 0.2 x 0.1 at phi0 = 0.3: height 0.2 sin 0.3 + 0.1 cos 0.3 = 0.155 > 0.1
    assert len(df) == 3 and res.n_scenes == 3
    assert store.read_metadata(res.out)["counts"]["skipped"] == 1


def test_engine_exception_becomes_a_failed_row(tmp_path):
    def flaky(vals, trajectory=False):
        if vals["B2"] == 50.0 and vals["drive"] == "flexible":
            raise FloatingPointError("boom")
        return fake_engine(vals)

    res = run(tmp_path, simulate=flaky)
    df = pd.read_parquet(res.out)
    bad = df[df.status.str.startswith("failed: exception")]
    assert len(bad) == 4 and res.failed_runs == 4  # 2 cases x 2 K2
    assert (bad.outcome == "failed").all() and bad.peak_force.isna().all()
    assert "FloatingPointError: boom" in bad.status.iloc[0]


def test_engine_failing_at_warm_up_stops_before_dispatch(tmp_path):
    def broken(vals, trajectory=False):
        raise NotImplementedError("engine not yet in place")

    with pytest.raises(RuntimeError, match="engine not yet in place"):
        run(tmp_path, simulate=broken)
    assert not (tmp_path / "t.parquet").exists()


# ------------------------------------------------------------------ streaming and resume
def test_killed_sweep_resumes_computing_only_missing_chunks(tmp_path, monkeypatch):
    ref = run(tmp_path, "ref.parquet")
    plan = PL.make_plan(spec())
    out = tmp_path / "t.parquet"
    written = [p.name for p in interrupted_run(monkeypatch, tmp_path, 3, simulate=fake_engine)]
    work = output.work_root(out) / plan.salt[:16]
    assert sorted(p.name for p in work.glob("chunk-*.parquet")) == sorted(written)
    assert not out.exists() and not list(work.glob(".fencesweep-tmp-*"))

    eng = Counting(monkeypatch)
    res = run(tmp_path)
    assert res.reused == 3 and res.computed == plan.n_chunks - 3
    assert len(eng.calls) == plan.n_models - 3 * plan.chunk_size  # only the missing runs
    assert out.read_bytes() == ref.out.read_bytes()  # nothing lost, nothing different


def test_no_resume_recomputes_everything(tmp_path, monkeypatch):
    plan = PL.make_plan(spec())
    interrupted_run(monkeypatch, tmp_path, 2)
    res = run(tmp_path, resume=False)
    assert res.reused == 0 and res.computed == plan.n_chunks


def test_changed_spec_never_reuses_stale_chunks(tmp_path, monkeypatch):
    saved = interrupted_run(monkeypatch, tmp_path, 2)
    changed = SPEC.replace("m1: 12.0", "m1: 13.0")
    # another spec's unfinished run is not discarded unless asked (test_cli_grid_refuses_...)
    with pytest.raises(UsageError, match=r"unfinished run of another spec.*\(2 of \d+ chunks saved\)"):
        run(tmp_path, text=changed)
    assert all(p.exists() for p in saved)
    res = run(tmp_path, text=changed, overwrite=True)
    assert res.reused == 0 and not any(p.exists() for p in saved)
    df = pd.read_parquet(res.out)
    assert (df.m1 == 13.0).all()
    expect, _ = fake_engine(spec(changed).resolve(0))
    assert df.loc[0, "peak_force"] == expect["peak_force"]


def test_auto_chunk_size_is_recorded_and_reused_on_resume(tmp_path, monkeypatch):
    text = SPEC.replace("    chunk_size: 4\n", "")
    ref = run(tmp_path, "ref.parquet", text=text)
    # a fake run takes microseconds: chunks are capped to give MIN_CHUNKS of them
    assert ref.n_chunks == math.ceil(22 / math.ceil(22 / runs.MIN_CHUNKS))
    interrupted_run(monkeypatch, tmp_path, 3, text=text)
    monkeypatch.setattr(runs, "auto_chunk_size", lambda *a: 5)  # the timing would differ now
    res = run(tmp_path, text=text)
    assert res.reused == 3 and res.n_chunks == ref.n_chunks
    assert res.out.read_bytes() == ref.out.read_bytes()
    # the table does not depend on the chunking
    explicit = run(tmp_path, "explicit.parquet")
    pd.testing.assert_frame_equal(pd.read_parquet(explicit.out), pd.read_parquet(ref.out))


def test_chunks_start_in_order_with_the_lightest_last():
    """runs.dispatch_order: a chunk's work is its runs times the seconds per run interpolated at
    its middle run; the chunks start in their own order but the LIGHT_LAST x jobs lightest,
    which start last, the heaviest of them first."""
    plan = PL.make_plan(spec())
    assert (plan.n_models, plan.chunk_size) == (22, 4)  # chunks 0-4 of 4 runs, chunk 5 of 2
    assert runs.LIGHT_LAST == 2
    rising = {0: 1e-3, 21: 3e-3}  # 1 ms at run 0 to 3 ms at run 21, linear in between
    # work [ms]: 4 x 1.14, 4 x 1.52, 4 x 1.90, 4 x 2.29, 4 x 2.67 and 2 x 2.95 (runs 20-21)
    assert runs.dispatch_order(plan, list(range(6)), rising, 1) == [1, 2, 3, 4, 5, 0]
    assert runs.dispatch_order(plan, list(range(6)), rising, 2) == [3, 4, 2, 1, 5, 0]
    falling = {0: 3e-3, 21: 1e-3}  # work: 4 x 2.86, 4 x 2.48, ..., 4 x 1.33, 2 x 1.05
    assert runs.dispatch_order(plan, list(range(6)), falling, 1) == [0, 1, 2, 3, 4, 5]
    assert runs.dispatch_order(plan, [5, 1, 3], rising, 1) == [3, 1, 5]  # only the chunks asked for
    assert runs.dispatch_order(plan, [5, 1, 3], {7: 1e-3}, 4) == [5, 1, 3]  # one timed run: no estimate


def test_progress_bar_off_shows_nothing_and_imports_no_tqdm():
    """An off bar (a planning pass under 20 000 scenes, --quiet) takes a bar's calls without
    importing tqdm (~35 ms of the planning helper the parent waits for); an on bar off a terminal
    (stderr a pipe here) prints lines (tests/test_messages.py), without tqdm either."""
    code = ("import sys; from fencesweep.study.sweep import progress as P; b = P.bar(5, 'x', False); b.update(2); "
            "b.total += 1; b.close(); assert 'tqdm' not in sys.modules, 'tqdm imported'; "
            "on = P.bar(5, 'x', True); on.close(); print(type(on).__name__, 'tqdm' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["Lines", "False"]


def test_chunk_name_depends_on_spec_and_contents():
    a = PL.make_plan(spec())
    b = PL.make_plan(spec(SPEC.replace("K2: [200, 570]", "K2: [200, 571]")))
    assert a.chunk_name(0) != b.chunk_name(0)
    assert a.chunk_name(0) != a.chunk_name(1)
    assert a.chunk_name(0) == PL.make_plan(spec()).chunk_name(0)


def test_truncated_chunk_is_recomputed(tmp_path, monkeypatch):
    n = interrupted_run(monkeypatch, tmp_path, 2)
    n[0].write_bytes(n[0].read_bytes()[:50])  # damaged by hand
    res = run(tmp_path)
    assert res.reused == 1


def slow_engine(vals, trajectory=False):
    time.sleep(0.02)
    return fake_engine(vals)


def sweep_to_kill(tmp_path, out: Path, **kw) -> list:
    """The command of a process that runs the test spec into `out` with slow_engine; the
    engine goes to it pickled by value (this module is registered with cloudpickle)."""
    job = tmp_path / "job.pickle"
    job.write_bytes(cloudpickle.dumps((spec(), str(out), dict(kw, simulate=slow_engine))))
    code = ("import pickle, sys; from fencesweep.study.sweep import pipeline as sweep; "
            "spec, out, kw = pickle.loads(open(sys.argv[1], 'rb').read()); sweep.run_sweep(spec, out, **kw)")
    return [sys.executable, "-c", code, str(job)]


def test_process_killed_mid_sweep_then_rerun(tmp_path, monkeypatch):
    out = tmp_path / "t.parquet"
    plan = PL.make_plan(spec())
    work = output.work_root(out) / plan.salt[:16]
    proc = subprocess.Popen(sweep_to_kill(tmp_path, out, jobs=1))
    try:
        polls = 0  # at most 12000 polls 5 ms apart (~60 s) for two chunks to appear
        while len(list(work.glob("chunk-*.parquet"))) < 2:
            assert proc.poll() is None and polls < 12000, "the sweep ended before it was killed"
            polls += 1
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
    saved = len(list(work.glob("chunk-*.parquet")))
    assert 2 <= saved < plan.n_chunks and not out.exists()
    eng = Counting(monkeypatch)
    res = run(tmp_path)
    assert res.reused == saved and res.computed == plan.n_chunks - saved
    assert len(eng.calls) == sum(len(plan.chunk_models(c)) for c in range(saved, plan.n_chunks))
    ref = run(tmp_path, "ref.parquet")
    assert out.read_bytes() == ref.out.read_bytes()


def test_process_with_workers_killed_mid_sweep_then_rerun(tmp_path, monkeypatch):
    """SIGKILL of a sweep on 2 workers: its workers exit, what they wrote is reused, the table is whole."""
    psutil = pytest.importorskip("psutil")
    out = tmp_path / "t.parquet"
    plan = PL.make_plan(spec())
    work = output.work_root(out) / plan.salt[:16]
    proc = subprocess.Popen(sweep_to_kill(tmp_path, out, jobs=2, serial_below=0.0))
    try:
        polls = 0
        while len(list(work.glob("chunk-*.parquet"))) < 2:
            assert proc.poll() is None and polls < 12000, "the sweep ended before it was killed"
            polls += 1
            time.sleep(0.005)
        workers = psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
    gone, alive = psutil.wait_procs(workers, timeout=30)  # they watch their parent once a second
    assert not alive, "workers outlived the killed sweep"
    res = run(tmp_path)
    assert res.reused >= 2 and res.reused + res.computed == plan.n_chunks
    assert out.read_bytes() == run(tmp_path, "ref.parquet").out.read_bytes()


def test_cli_interrupted_names_the_saved_chunks(tmp_path, monkeypatch, faked_engine, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(SPEC) + f"output: {tmp_path / 'cli.parquet'}\n")
    real_write = store.write_chunk
    written = []

    def dying_write(*a, **k):
        if len(written) == 2:
            raise KeyboardInterrupt
        real_write(*a, **k)
        written.append(1)

    monkeypatch.setattr(store, "write_chunk", dying_write)
    assert cli.main(["grid", str(path), "--jobs", "1", "--quiet"]) == 130
    assert "interrupted; 2 of 6 chunks are saved" in capsys.readouterr().err
    monkeypatch.setattr(store, "write_chunk", real_write)
    assert cli.main(["grid", str(path), "--jobs", "1", "--quiet"]) == 0
    assert len(pd.read_parquet(tmp_path / "cli.parquet")) == 40


def test_assembly_memory_is_bounded_by_blocks(tmp_path, monkeypatch):
    """Small blocks and a tiny chunk cache give the same table (the streaming path)."""
    ref = run(tmp_path, "ref.parquet")
    monkeypatch.setattr(PL, "ASSEMBLY_BLOCK", 7)
    monkeypatch.setattr(assemble, "CHUNK_CACHE", 1)
    res = run(tmp_path)
    pd.testing.assert_frame_equal(pd.read_parquet(ref.out), pd.read_parquet(res.out))
    assert pq.ParquetFile(res.out).metadata.num_row_groups == math.ceil(40 / 7)


def test_each_chunk_is_read_once_and_holding_none_gives_the_same_table(tmp_path, monkeypatch):
    """The chunks are read as they finish (jobs 1 and 2) and the verification's sample, its table
    values and the assembly take them from memory: one read per chunk. Holding none (HOLD_BYTES
    0, a sweep too large to hold) reads them again each time and writes the same bytes."""
    made = []
    real = chunks.ChunkTables.__init__

    def recording(self, *a, **k):
        real(self, *a, **k)
        made.append(self)

    monkeypatch.setattr(chunks.ChunkTables, "__init__", recording)
    one = run(tmp_path, "one.parquet", jobs=1)
    two = run(tmp_path, "two.parquet", jobs=2, serial_below=0.0)
    assert one.verify is not None and two.verify is not None
    assert [t.reads for t in made] == [one.n_chunks, two.n_chunks] and one.n_chunks > 1
    monkeypatch.setattr(chunks, "HOLD_BYTES", 0)
    made.clear()
    none = run(tmp_path, "none.parquet", jobs=1)
    assert made[0].reads > 2 * none.n_chunks  # the sample's scores, its table values, the assembly
    assert none.out.read_bytes() == one.out.read_bytes() == two.out.read_bytes()


def test_blocks_are_written_as_their_chunks_arrive_and_the_record_at_close(tmp_path, monkeypatch):
    """The assembly writes each block once its chunks are in, while the workers run the others
    (in the feed of the chunk that completed it); the verification begins after the last chunk,
    its record is taken after the last block and goes into the table at close."""
    events = []
    real_write, real_close, real_begin = assemble.Assembly._write, store.TableWriter.close, V.begin
    real_feed, real_finish = assemble.Assembly.feed, assemble.Assembly.finish

    def write(self, k):
        events.append("block")
        real_write(self, k)

    def feed(self, c=None):
        if c is not None:
            events.append("chunk")
        real_feed(self, c)

    def finish(self, meta=None):
        events.append("finish")
        return real_finish(self, meta)

    def closing(self, meta=None):
        events.append("close")
        real_close(self, meta)

    def begin(*a, **k):
        finish = real_begin(*a, **k)
        events.append("begin")
        return lambda: events.append("record") or finish()

    monkeypatch.setattr(assemble.Assembly, "_write", write)
    monkeypatch.setattr(assemble.Assembly, "feed", feed)
    monkeypatch.setattr(assemble.Assembly, "finish", finish)
    monkeypatch.setattr(store.TableWriter, "close", closing)
    monkeypatch.setattr(V, "begin", begin)
    monkeypatch.setattr(PL, "ASSEMBLY_BLOCK", 7)
    res = run(tmp_path, jobs=2, serial_below=0.0)
    n_blocks = math.ceil(40 / 7)
    assert events.count("block") == n_blocks and events.count("chunk") == res.n_chunks
    # each block is written in the feed of the chunk that completed it, not at the close (which
    # block that is, is the workers' order: under load the first block's chunk can come last)
    assert all(events[i - 1] in ("chunk", "block") for i, e in enumerate(events) if e == "block")
    assert "block" not in events[events.index("finish"):]  # none left for the close
    events.remove("finish")
    assert events[-3:] == ["begin", "record", "close"] or events[-2:] == ["record", "close"]
    assert events.index("record") > len(events) - events[::-1].index("block") - 1  # after the last block
    assert res.verify is not None and store.read_metadata(res.out)["verify"] == res.verify
    assert res.out.read_bytes() == run(tmp_path, "one.parquet", jobs=1).out.read_bytes()


# ------------------------------------------------------------------ Dask
def test_dask_backend_on_a_local_cluster_matches_local_run(tmp_path):
    distributed = pytest.importorskip("distributed")
    ref = run(tmp_path, "ref.parquet")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        res = run(tmp_path, "dask.parquet", backend="dask", scheduler=cluster.scheduler_address)
    assert res.out.read_bytes() == ref.out.read_bytes()


# ------------------------------------------------------------------ CLI
def test_cli_grid_dry_run_and_run(tmp_path, faked_engine, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(SPEC) + f"output: {tmp_path / 'cli.parquet'}\n")
    assert cli.main(["grid", str(path), "--dry-run", "--jobs", "2"]) == 0
    text = capsys.readouterr().out
    assert "40 scenes" in text and "distinct model runs: 22" in text and "estimated time on 1 job" in text
    assert not (tmp_path / "cli.parquet").exists()
    assert cli.main(["grid", str(path), "--jobs", "1", "--quiet"]) == 0
    df = pd.read_parquet(tmp_path / "cli.parquet")
    assert len(df) == 40
    other = tmp_path / "other.parquet"
    assert cli.main(["grid", str(path), "--jobs", "1", "--out", str(other)]) == 0
    assert "wrote" in capsys.readouterr().err and other.exists()


def test_cli_grid_refuses_to_replace_another_specs_table(tmp_path, faked_engine, capsys):
    a, b, out = tmp_path / "A.yaml", tmp_path / "B.yaml", tmp_path / "T.parquet"
    a.write_text(textwrap.dedent(SPEC))
    b.write_text(textwrap.dedent(SPEC.replace("m1: 12.0", "m1: 13.0")))
    assert cli.main(["grid", str(a), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    written = out.read_bytes()
    capsys.readouterr()
    assert cli.main(["grid", str(b), "--out", str(out), "--jobs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{out} holds the results of another spec, {a} (spec hash {spec().hash[:12]})" in err
    assert f"this is {b}" in err and "--overwrite" in err and "Traceback" not in err
    assert out.read_bytes() == written and not output.work_root(out).exists()  # nothing changed
    # the dry run says so too, and the same spec may replace its own table
    assert cli.main(["grid", str(b), "--out", str(out), "--dry-run"]) == 0
    assert "a real run would stop before it starts" in capsys.readouterr().out
    assert cli.main(["grid", str(a), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    assert cli.main(["grid", str(b), "--out", str(out), "--jobs", "1", "--quiet", "--overwrite"]) == 0
    assert (pd.read_parquet(out).m1 == 13.0).all()
    assert store.read_metadata(out)["spec_path"] == str(b)


def test_cli_grid_refuses_to_replace_a_file_it_did_not_write(tmp_path, faked_engine, capsys):
    path, out = tmp_path / "s.yaml", tmp_path / "mine.parquet"
    path.write_text(textwrap.dedent(SPEC))
    out.write_bytes(b"not a sweep table")
    assert cli.main(["grid", str(path), "--out", str(out), "--jobs", "1", "--quiet"]) == 2
    assert "is not a table written by fencesweep grid" in capsys.readouterr().err
    assert out.read_bytes() == b"not a sweep table"


HUGE = """
    grid:
      B2: {linspace: [1, 100, 100]}
      K2: {linspace: [1, 1000, 100]}
      m1: {linspace: [1, 30, 100]}
      v: {linspace: [0.5, 3, 100]}
      mu1: {linspace: [0.1, 0.8, 100]}
"""


def test_cli_dry_run_of_1e10_scenes_plans_one_piece(tmp_path, monkeypatch, faked_engine, capsys):
    """10^10 scenes: the dry run plans and times the first piece only (memory bounded by the
    piece, not the spec) and scales its counts; nothing is written."""
    import tracemalloc

    monkeypatch.setattr(SP, "PIECE_SCENES", 100_000)
    path, out = tmp_path / "huge.yaml", tmp_path / "huge.parquet"
    path.write_text(textwrap.dedent(HUGE))
    tracemalloc.start()
    try:
        assert cli.main(["grid", str(path), "--out", str(out), "--dry-run", "--jobs", "1"]) == 0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    text = capsys.readouterr().out
    assert peak < 100 * 2**20  # a piece of 100,000 scenes planned, not 10^10
    assert "10000000000 scenes (B2 100 x K2 100 x m1 100 x v 100 x mu1 100)" in text
    assert "written in 100000 pieces of up to 100,000 scenes" in text
    assert "distinct model runs: about 10000000000" in text and "estimated time on 1 job" in text
    assert list(tmp_path.iterdir()) == [path]  # nothing made


def test_piece_size_follows_the_memory_available(tmp_path, monkeypatch):
    sp = spec()  # 2 cases x 2 x 5 x 2 = 40 scenes
    monkeypatch.setattr(resources, "available_memory", lambda: 2 * 40 * SP.PLAN_BYTES_PER_SCENE)
    assert SP.piece_limit() == 40 and SP.n_pieces(sp) == 1
    whole = run(tmp_path, "whole.parquet")
    monkeypatch.setattr(resources, "available_memory", lambda: 2 * 39 * SP.PLAN_BYTES_PER_SCENE)
    assert SP.piece_limit() == 39 and SP.n_pieces(sp) == 2  # one piece per case
    parts = run(tmp_path, "parts.parquet")
    assert parts.out.is_dir() and len(list(parts.out.iterdir())) == 2
    pd.testing.assert_frame_equal(pd.read_parquet(parts.out), pd.read_parquet(whole.out))
    monkeypatch.setattr(resources, "available_memory", lambda: None)  # unknown: PIECE_SCENES
    assert SP.piece_limit() == SP.PIECE_SCENES


def test_write_trajectory_round_trip(tmp_path):
    traj = pd.DataFrame({"t": np.linspace(0, 1, 5), "alpha": np.arange(5.0), "stage": np.int8([2, 1, 1, 3, 2])})
    traj.attrs["units"] = {"t": "s", "alpha": "rad"}
    vals = P.resolve("cycle", "small_far")
    res, _ = fake_engine(vals)
    path = tmp_path / "traj.parquet"
    store.write_trajectory(traj, path, vals, res)
    back = store.read_trajectory(path)
    pd.testing.assert_frame_equal(back, traj, check_like=False)
    assert back.attrs["params"]["case"] == "small_far" and back.attrs["params"]["L"] == 0.2
    assert back.attrs["results"]["outcome"] == res["outcome"]
    assert back.attrs["units"] == {"t": "s", "alpha": "rad"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


# ------------------------------------------------------------------ the real engine
def test_real_engine_impact_sweep_same_for_1_and_2_jobs(tmp_path):
    text = """
        scene: impact
        grid: {m2: {logspace: [1, 50, 3]}}
        cases: [{drive: rigid}, {drive: free}]
    """
    a = run(tmp_path, "a.parquet", text=text, simulate=None, jobs=1)
    b = run(tmp_path, "b.parquet", text=text, simulate=None, jobs=2, serial_below=0.0)
    assert a.out.read_bytes() == b.out.read_bytes()
    df = pd.read_parquet(a.out)
    assert (df.status == "ok").all()
    rigid = df[df.drive == "rigid"].peak_force.to_numpy()
    free = df[df.drive == "free"].peak_force.to_numpy()
    assert np.all(rigid / free > 1.0)  # docs/model.md §13.3: the rigid fence hits harder
    one = api.simulate("impact", m2=float(df.m2.iloc[4]), drive="free")
    assert one["peak_force"] == df.peak_force.iloc[4]


def test_real_engine_cycle_rows_match_single_runs(tmp_path):
    text = """
        grid: {drive: [rigid, flexible], B2: [40, 72]}
        cases: [small_far]
    """
    res = run(tmp_path, text=text, simulate=None, jobs=1)
    df = pd.read_parquet(res.out)
    assert len(df) == 4 and res.n_models == 3
    one = api.simulate("cycle", "small_far", drive="flexible", B2=40.0)
    row = df[(df.drive == "flexible") & (df.B2 == 40.0)].iloc[0]
    for name in ("outcome", "peak_force", "deflection_max", "n_steps"):
        assert row[name] == one[name]


# ------------------------------------------------------------------ Arrow without pandas
ARROW_CASES = [
    ([1.0, math.nan, 2.5, -0.0], "float64"), (np.arange(11.0), "float64"), ([1, 2], "float64"),
    ([1.0, None, 3.0, None, 5.0, 6.0, 7.0, 8.0, 9.0], "float64"), ([None] * 3, "float64"), ([3, -4, 2**40], "int64"),
    ([True, False, True, True, False, False, True, True, True], "bool"), (["ok", "failed: x é", ""], "string"),
    ([], "float64"), ([], "string"), ([], "bool"), ([None, "a"], "string"),
    (np.array([5, 6]), "int64"), (np.array([True, False]), "bool"),
]


@pytest.mark.parametrize("values,typ", ARROW_CASES)
def test_arrow_array_and_numpy_column_agree_with_pyarrow(values, typ):
    """store.arrow_array builds the same Arrow array as pa.array (values, nulls, type), and
    store.numpy_column reads the same NumPy array as to_numpy, sliced and chunked too."""
    import pyarrow as pa

    t = pa.type_for_alias(typ)
    mine, theirs = store.arrow_array(values, t), pa.array(values, type=t)
    mine.validate(full=True)
    assert mine.type == theirs.type and mine.null_count == theirs.null_count
    same = lambda a, b: len(a) == len(b) and all(x == y or (x != x and y != y) for x, y in zip(a, b))  # noqa: E731
    assert same(mine.to_pylist(), theirs.to_pylist())
    for col in (mine, mine.slice(1), pa.chunked_array([mine, mine.slice(1)], type=t)):
        got, want = store.numpy_column(col), col.to_numpy(zero_copy_only=False)
        assert got.dtype == want.dtype and same(got, want)


def test_a_cycle_sweep_never_imports_pandas(tmp_path):
    """Planning, running, writing the chunks and assembling a cycle sweep import no pandas
    (pa.array's and to_numpy's first call would: 0.2 s in each process of the main job)."""
    spec_path = tmp_path / "s.yaml"
    spec_path.write_text(textwrap.dedent("""
        scene: cycle
        grid: {drive: [rigid, flexible], B2: [40, 72]}
        cases: [small_far]
        chunk_size: 2
    """))
    out = tmp_path / "s.parquet"
    code = (f"import sys\nfrom fencesweep.study.spec import file as specfile\nfrom fencesweep.study.sweep import pipeline as sweep\n"
            f"sweep.run_sweep(specfile.load({str(spec_path)!r}), {str(out)!r}, jobs=1)\n"
            f"print('pandas' in sys.modules)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip().splitlines()[-1] == "False"
    df = pd.read_parquet(out)
    assert len(df) == 4 and df["k_lin"].isna().all() and (df["status"] == "ok").all()
