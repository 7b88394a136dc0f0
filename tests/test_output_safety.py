"""Nothing lost to a second writer or a full disk (fencesweep/study/store/lock.py, output.check_writable,
store's atomic writes): one run per output at a time (a second refuses, or with --wait waits);
an output that cannot be written stops the run before it computes; a write that fails (ENOSPC)
says what was kept, leaves no half-written file and the same command again finishes the table.

The sweeps run a cheap deterministic stand-in for the engine (tests/helpers.py's fake_engine;
`engine` below holds it at a gate), in this process or, pickled by value, in another
(`sweep_process`), on helpers.SWEEP_SPEC; `--wait` runs the real engine on 40 scenes.
"""
import errno
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cloudpickle
import pyarrow.parquet as pq
import pytest

import fencesweep
from fencesweep import cli
from fencesweep.errors import UsageError, WriteError
from fencesweep.model import simulate as model_simulate
from fencesweep.study.store import lock
from fencesweep.study.sweep import output
from fencesweep.study.spec import file as specfile
from fencesweep.study.store import table as store
from fencesweep.study.sweep import pipeline as sweep
from fencesweep.study.sweep import plan as PL
from helpers import fake_engine

cloudpickle.register_pickle_by_value(sys.modules[__name__])

ROOT = Path(__file__).resolve().parents[1]
N_CHUNKS = 6  # helpers.SWEEP_SPEC: 22 distinct runs in chunks of 4
GATE = "FENCESWEEP_TEST_GATE"


def engine(vals, trajectory=False):
    """helpers.fake_engine, which waits while the file named by $FENCESWEEP_TEST_GATE is missing
    (and says so by making GATE.waiting)."""
    gate = os.environ.get(GATE)
    if gate and not os.path.exists(gate):
        Path(gate + ".waiting").touch()  # the run is at its first model run: planned, its lock held
        while not os.path.exists(gate):
            time.sleep(0.01)
    return fake_engine(vals, trajectory)


@pytest.fixture
def spec_file(sweep_spec_file):
    """helpers.SWEEP_SPEC in a file (conftest.py's sweep_spec_file)."""
    return sweep_spec_file


@pytest.fixture
def fake(faked_engine, monkeypatch):
    """The CLI and the API run the stand-in engine (forked workers inherit it), the gate open."""
    monkeypatch.delenv(GATE, raising=False)


def lone(spec_file: Path, out: Path) -> bytes:
    """The table of a lone run of the spec (the gate open), as bytes."""
    sweep.run_sweep(specfile.load(spec_file), out, jobs=1, simulate=engine)
    return out.read_bytes()


def env() -> dict:
    return dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))


def sweep_process(tmp_path, spec_file: Path, out: Path, gate: Path) -> subprocess.Popen:
    """A process that runs the spec into `out` with `engine`, held at its first run until `gate` exists."""
    job = tmp_path / "job.pickle"
    job.write_bytes(cloudpickle.dumps((str(spec_file), str(out), engine)))
    code = ("import pickle, sys; from fencesweep.study.spec import file as specfile; from fencesweep.study.sweep import pipeline as sweep; "
            "path, out, engine = pickle.loads(open(sys.argv[1], 'rb').read()); "
            "sweep.run_sweep(specfile.load(path), out, jobs=1, simulate=engine)")
    return subprocess.Popen([sys.executable, "-c", code, str(job)], env=dict(env(), **{GATE: str(gate)}))


def wait_for(path: Path, proc: subprocess.Popen) -> None:
    for _ in range(6000):  # 60 s
        if path.exists():
            return
        assert proc.poll() is None, "the first run ended before it took the lock"
        time.sleep(0.01)
    raise AssertionError(f"{path} never appeared")


def cli_process(spec_file: Path, out: Path, *flags, stderr=subprocess.PIPE) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fencesweep.cli", "grid", str(spec_file), "--out", str(out),
                             "--jobs", "1", *flags], env=env(), stderr=stderr, stdout=subprocess.DEVNULL, text=True)


# ------------------------------------------------------------------ one writer per output
def test_second_run_on_the_same_output_refuses_and_touches_nothing(tmp_path, spec_file):
    out, gate = tmp_path / "t.parquet", tmp_path / "gate"
    first = sweep_process(tmp_path, spec_file, out, gate)
    try:
        wait_for(Path(f"{gate}.waiting"), first)
        before = sorted((p.name, p.stat().st_mtime_ns) for p in output.work_root(out).rglob("*"))
        second = cli_process(spec_file, out)
        _, err = second.communicate(timeout=120)
        assert second.returncode == 2 and "Traceback" not in err
        assert err.splitlines() == [err.strip()] and err.startswith(
            f"fencesweep: error: {out} is being written by another run (pid {first.pid} on ")
        assert "started 20" in err and "--wait" in err
        assert sorted((p.name, p.stat().st_mtime_ns) for p in output.work_root(out).rglob("*")) == before
        gate.touch()
        assert first.wait(timeout=120) == 0
    finally:
        gate.touch()
        first.kill() if first.poll() is None else None
    assert out.read_bytes() == lone(spec_file, tmp_path / "lone.parquet")
    assert not lock.holder_path(out).exists()  # the holder's record goes with it


def test_second_run_with_wait_waits_then_finishes(tmp_path, spec_file):
    out, gate = tmp_path / "t.parquet", tmp_path / "gate"
    first = sweep_process(tmp_path, spec_file, out, gate)
    log = tmp_path / "second.err"
    try:
        wait_for(Path(f"{gate}.waiting"), first)
        with open(log, "w") as fh:
            second = cli_process(spec_file, out, "--wait", stderr=fh)
            for _ in range(6000):
                if "waiting for the run writing" in log.read_text():
                    break
                assert second.poll() is None, log.read_text()
                time.sleep(0.01)
            assert second.poll() is None and not out.exists()  # still waiting, nothing written
            gate.touch()
            assert first.wait(timeout=120) == 0
            assert second.wait(timeout=300) == 0
    finally:
        gate.touch()
        for p in (first, locals().get("second")):
            if p is not None and p.poll() is None:
                p.kill()
    err = log.read_text()
    assert f"waiting for the run writing {out} (pid {first.pid} on " in err and "Traceback" not in err
    ref = tmp_path / "ref.parquet"  # the CLI runs the real engine
    assert cli.main(["grid", str(spec_file), "--out", str(ref), "--jobs", "1", "--quiet"]) == 0
    assert out.read_bytes() == ref.read_bytes()


HOLD = ("import sys, time; from pathlib import Path; from fencesweep.study.store import lock\n"
        "with lock.one_writer(Path(sys.argv[1])):\n"
        "    while not Path(sys.argv[2]).exists():\n"
        "        time.sleep(0.01)\n")


def test_api_refuses_or_waits(tmp_path, spec_file, fake):
    import threading

    out, gate = tmp_path / "t.parquet", tmp_path / "gate"
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(out), str(gate)], env=env())
    try:
        wait_for(lock.holder_path(out), holder)
        with pytest.raises(UsageError, match=rf"is being written by another run \(pid {holder.pid} on .*wait=True"):
            fencesweep.grid(spec_file, out=out, jobs=1)
        assert not out.exists() and not output.work_root(out).exists()
        notes = []
        threading.Timer(1.0, gate.touch).start()
        df = fencesweep.grid(spec_file, out=out, jobs=1, wait=True, log=notes.append)
        assert len(df) == 40 and any(n.startswith(f"waiting for the run writing {out}") for n in notes)
    finally:
        gate.touch()
        holder.wait(timeout=60)
    assert out.read_bytes() == lone(spec_file, tmp_path / "lone.parquet")


def test_lock_is_reentrant_in_one_process(tmp_path):
    out = tmp_path / "t.parquet"
    with lock.one_writer(out):
        with lock.one_writer(out):
            assert lock.holder_path(out).exists()
        assert lock.holder_path(out).exists()
    assert not lock.holder_path(out).exists()


# ------------------------------------------------------------------ a place that cannot be written
def test_output_under_a_file_stops_before_it_computes(tmp_path, spec_file, fake, capsys):
    (tmp_path / "file").write_text("x")
    out = tmp_path / "file" / "sub" / "x.parquet"
    assert cli.main(["grid", str(spec_file), "--out", str(out), "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert err == f"fencesweep: error: cannot write {out}: {tmp_path / 'file'} is not a directory\n"
    with pytest.raises(UsageError, match="is not a directory"):
        fencesweep.grid(spec_file, out=out)


def test_read_only_directory_stops_before_it_computes(tmp_path, spec_file, fake, capsys, monkeypatch):
    out = tmp_path / "ro" / "x.parquet"
    if os.geteuid() != 0:  # root writes anywhere: then the file system's answer is simulated
        out.parent.mkdir()
        out.parent.chmod(0o555)
    else:
        def read_only(*a, **k):
            raise OSError(errno.EROFS, "Read-only file system")

        monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    try:
        assert cli.main(["grid", str(spec_file), "--out", str(out), "--jobs", "1"]) == 2
    finally:
        out.parent.chmod(0o755) if out.parent.exists() else None
    err = capsys.readouterr().err
    assert err.startswith(f"fencesweep: error: cannot write {out}: {out.parent} is not writable: ")
    assert err.count("\n") == 1 and not output.work_root(out).exists()


# ------------------------------------------------------------------ a full disk
def full_disk_after(monkeypatch, k: int) -> None:
    """Writing chunk k or later fails as on a full disk, after some bytes of its temporary file."""
    real = pq.write_table

    def write_table(table, where, *a, **kw):
        name = Path(str(where)).name
        if "chunk-" in name and int(name.split("chunk-")[1][:6]) >= k:
            Path(where).write_bytes(b"PAR1 half a chunk")
            raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space left on device")
        return real(table, where, *a, **kw)

    monkeypatch.setattr(pq, "write_table", write_table)


def no_temporary_files(root: Path) -> bool:
    return not [p for p in root.rglob("*") if p.name.startswith(".fencesweep-tmp-")]


@pytest.mark.parametrize("jobs", [1, 2])
def test_full_disk_writing_chunks_keeps_them_and_the_rerun_finishes(tmp_path, spec_file, fake, monkeypatch,
                                                                      capfd, jobs):
    out = tmp_path / "t.parquet"
    work = output.work_root(out) / PL.plan_salt(specfile.load(spec_file))[:16]
    full_disk_after(monkeypatch, 3)
    monkeypatch.setattr(sweep.runs, "SERIAL_BELOW", 0.0)  # 2 jobs: really on forked workers
    # the chunks in their own order, as one process runs them (workers start the lightest ones
    # last, runs.dispatch_order, which with the fake engine's timings could be any): 0, 1, 2 fit
    monkeypatch.setattr(sweep.runs, "dispatch_order", lambda plan, chunks, timed, jobs: list(chunks))
    assert cli.main(["grid", str(spec_file), "--out", str(out), "--jobs", str(jobs), "--quiet"]) == 1
    err = capfd.readouterr().err  # (the workers' stderr too)
    saved = sorted(p.name for p in work.glob("chunk-*.parquet"))
    assert len(saved) == 3 if jobs == 1 else 0 < len(saved) <= 3
    assert err.startswith(f"fencesweep: error: no space left on device writing {work}/chunk-00000")
    assert err.endswith(f"; the {len(saved)} finished chunks are kept in {work} — free space and run the same "
                        f"command again\n")
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists() and no_temporary_files(tmp_path)
    monkeypatch.undo()
    monkeypatch.setattr(model_simulate, "simulate_resolved", engine)
    assert cli.main(["grid", str(spec_file), "--out", str(out), "--jobs", str(jobs)]) == 0
    assert f"resuming: {len(saved)} of {N_CHUNKS} chunks already in {work}" in capfd.readouterr().err
    assert out.read_bytes() == lone(spec_file, tmp_path / "lone.parquet")


def test_full_disk_writing_the_table_keeps_the_old_one(tmp_path, spec_file, fake, monkeypatch, capsys):
    out = tmp_path / "t.parquet"
    old = lone(spec_file, out)  # the same spec's table, from before
    monkeypatch.setattr(PL, "ASSEMBLY_BLOCK", 7)  # a row group is written before the disk is full
    real, calls = pq.ParquetWriter.write_table, []

    def write_table(self, *a, **k):
        if Path(str(self.where)).name.endswith("-t.parquet"):  # the table's temporary file (not a chunk)
            calls.append(1)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space left on device")
        return real(self, *a, **k)

    monkeypatch.setattr(pq.ParquetWriter, "write_table", write_table)
    assert cli.main(["grid", str(spec_file), "--out", str(out), "--jobs", "1", "--quiet"]) == 1
    work = output.work_root(out) / PL.plan_salt(specfile.load(spec_file))[:16]
    saved = len(list(work.glob("chunk-*.parquet")))  # the table is written as its chunks arrive:
    assert 0 < saved < N_CHUNKS  # its second block failed before the last chunk was computed
    assert capsys.readouterr().err == (f"fencesweep: error: no space left on device writing {out}; the {saved} "
                                       f"finished chunks are kept in {work} — free space and run the same command "
                                       f"again\n")
    assert out.read_bytes() == old and no_temporary_files(tmp_path)  # no half-written table in its place
    monkeypatch.setattr(pq.ParquetWriter, "write_table", real)
    assert cli.main(["grid", str(spec_file), "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    assert not output.work_root(out).exists()
    pq.read_table(out)  # whole


def test_full_disk_writing_the_state_says_nothing_was_finished(tmp_path, spec_file, fake, monkeypatch):
    real = Path.write_text

    def write_text(self, *a, **k):
        if self.name.endswith(output.PLAN_FILE):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, *a, **k)

    monkeypatch.setattr(Path, "write_text", write_text)
    with pytest.raises(WriteError) as exc:
        fencesweep.grid(spec_file, out=tmp_path / "t.parquet", jobs=1)
    assert isinstance(exc.value, OSError) and exc.value.errno == errno.ENOSPC
    assert str(exc.value).startswith("no space left on device writing ")
    assert str(exc.value).endswith(f"{output.PLAN_FILE}; no chunk was finished yet — free space and run the same "
                                   f"command again")


def test_write_error_crosses_processes_as_itself():
    import pickle

    exc = pickle.loads(pickle.dumps(WriteError(errno.ENOSPC, "x", "/a/b.parquet")))
    assert isinstance(exc, WriteError) and str(exc) == "no space left on device writing /a/b.parquet"
    with pytest.raises(WriteError, match="no space left on device writing .*t.parquet"):
        with store.atomic_path(Path(tempfile.gettempdir()) / "t.parquet") as tmp:
            tmp.write_text("half")
            raise OSError(errno.ENOSPC, "disk full")
    assert not (Path(tempfile.gettempdir()) / "t.parquet").exists()
    assert not list(Path(tempfile.gettempdir()).glob(f".fencesweep-tmp-{os.getpid()}-t.parquet"))
