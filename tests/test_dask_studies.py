"""The dask backend for every study (sweep/cluster.py), on a local cluster of two worker processes:
a sweep, a design and a sensitivity give the local results; every worker warms up before its
first task; the timed sample runs on a worker; a worker without fencesweep is named, and the
chunks finished are kept."""
import os
import textwrap

import pandas as pd
import pytest
import yaml
from helpers import DESIGN_SPEC, SENSITIVITY_SPEC, fake_engine
from helpers import load_spec as spec

import fencesweep
from fencesweep import cli
from fencesweep.errors import UsageError, WorkerError
from fencesweep.study.spec import file as specfile
from fencesweep.study.store import table as store
from fencesweep.study.sweep import cluster as C
from fencesweep.study.sweep import compute, output, runs
from fencesweep.study.sweep import pipeline as sweep
from fencesweep.study.sweep import plan as PL

distributed = pytest.importorskip("distributed")

DESIGN, SENSITIVITY = DESIGN_SPEC, SENSITIVITY_SPEC

#: a worker's preload that makes fencesweep impossible to import there, as on a machine without it
NO_FENCESWEEP = """
    import sys

    class NoFencesweep:
        def find_spec(self, name, path=None, target=None):
            if name == "fencesweep" or name.startswith("fencesweep."):
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return None

    sys.meta_path.insert(0, NoFencesweep())
    for name in [n for n in sys.modules if n == "fencesweep" or n.startswith("fencesweep.")]:
        del sys.modules[name]
    """


@pytest.fixture(scope="module")
def two_workers():
    """A local Dask cluster of two worker processes, one thread each."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:
        yield cluster


def _warmed(cluster) -> dict:
    """{worker: the seconds its warm-up's scenes took (None: not warmed up)}."""
    with distributed.Client(cluster) as client:
        return client.run(lambda dask_worker: getattr(dask_worker.plugins.get(C.PLUGIN), "seconds", None))


def test_a_sweep_on_two_worker_processes_is_the_local_table(tmp_path, two_workers):
    ref = sweep.run_sweep(spec(), tmp_path / "ref.parquet", jobs=1, simulate=fake_engine)
    res = sweep.run_sweep(spec(), tmp_path / "dask.parquet", backend="dask", scheduler=two_workers.scheduler_address,
                          simulate=fake_engine)
    assert res.jobs is None and res.computed == ref.computed == 6
    a, b = store.read_table(ref.out), store.read_table(res.out)
    pd.testing.assert_frame_equal(a, b, check_exact=True)  # every result column, bit for bit
    assert res.out.read_bytes() == ref.out.read_bytes()
    warmed = _warmed(two_workers)
    assert len(warmed) == 2 and all(isinstance(s, float) for s in warmed.values()), warmed


def test_the_timed_sample_runs_on_a_worker_and_is_the_local_ones(two_workers, monkeypatch):
    plan = PL.make_plan(spec())
    per_run, n, timed = runs.time_sample(plan, fake_engine, budget=60.0, most=8)

    def not_here(*a, **k):
        raise AssertionError("the client ran the engine")

    for name in ("warm_up", "time_sample", "warm_scenes", "run_one"):  # the workers' modules are their own
        monkeypatch.setattr(runs, name, not_here)
    warmed, (per_run_there, n_there, timed_there) = C.time_sample(two_workers.scheduler_address, plan, fake_engine,
                                                                  budget=60.0, most=8)
    assert sorted(timed_there) == sorted(timed) and n_there == n == 8
    assert per_run_there > 0 and warmed > 0


def test_a_design_on_the_cluster_is_the_local_design(tmp_path, two_workers):
    data = yaml.safe_load(textwrap.dedent(DESIGN))
    here = fencesweep.design(data, out=tmp_path / "here", jobs=1, progress=False)
    there = fencesweep.design(data, out=tmp_path / "there", backend="dask", scheduler=two_workers.scheduler_address,
                              progress=False)

    def plain(rec):  # the same but for the seconds it took (and the versions: a source may change meanwhile)
        return {k: v for k, v in rec.items() if k not in ("seconds", "versions")} | {
            "optimizer": {k: v for k, v in rec["optimizer"].items() if k != "seconds"}}

    assert plain(there) == plain(here)  # the optimum, raw and rounded, its evaluations, the comparison
    assert there["optimizer"]["evaluations"] > 0 and all(isinstance(s, float) for s in _warmed(two_workers).values())


def test_a_worker_with_another_fencesweep_is_named():
    import cloudpickle

    payload = cloudpickle.dumps((spec(), [0], fake_engine))
    assert C.warm_worker(payload, C.identity(), "tcp://10.0.0.7:4000") >= 0  # the same: it warms up
    other = dict(C.identity(), version="0.0.1")
    with pytest.raises(WorkerError, match=r"the Dask worker tcp://10.0.0.7:4000 runs fencesweep .* this client 0.0.1"):
        C.warm_worker(payload, other, "tcp://10.0.0.7:4000")


def test_a_sensitivity_on_the_cluster_is_the_local_one(tmp_path, two_workers):
    pytest.importorskip("SALib")
    data = yaml.safe_load(textwrap.dedent(SENSITIVITY))
    here = fencesweep.sensitivity(data, out=tmp_path / "here.parquet", jobs=1, progress=False)
    there = fencesweep.sensitivity(data, out=tmp_path / "there.parquet", backend="dask",
                                   scheduler=two_workers.scheduler_address, progress=False)
    pd.testing.assert_frame_equal(here, there, check_exact=True)
    assert pd.read_parquet(tmp_path / "there_runs.parquet").equals(pd.read_parquet(tmp_path / "here_runs.parquet"))


@pytest.fixture
def no_fencesweep(tmp_path):
    """A local Dask cluster of one worker process that cannot import fencesweep; (cluster, its address)."""
    preload = tmp_path / "no_fencesweep.py"
    preload.write_text(textwrap.dedent(NO_FENCESWEEP))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  preload=[str(preload)]) as cluster:
        [address] = cluster.scheduler_info["workers"]
        yield cluster, address


def test_a_worker_without_fencesweep_is_named_and_the_chunks_are_kept(tmp_path, monkeypatch, capsys, faked_engine,
                                                                       sweep_spec_file, no_fencesweep):
    cluster, address = no_fencesweep
    out, real_write, written = tmp_path / "t.parquet", store.write_chunk, []

    def dying_write(path, *a, **k):
        if len(written) == 2:
            raise KeyboardInterrupt
        real_write(path, *a, **k)
        written.append(path)

    monkeypatch.setattr(store, "write_chunk", dying_write)
    assert cli.main(["grid", str(sweep_spec_file), "--out", str(out), "--jobs", "1", "--quiet"]) == 130
    monkeypatch.setattr(store, "write_chunk", real_write)
    capsys.readouterr()
    code = cli.main(["grid", str(sweep_spec_file), "--out", str(out), "--backend", "dask", "--scheduler",
                     cluster.scheduler_address, "--quiet"])
    err = capsys.readouterr().err
    assert code == 1, err
    assert f"the Dask worker {address} cannot import fencesweep (No module named 'fencesweep')" in err
    assert "every Dask worker needs the same fencesweep installed" in err and "Traceback" not in err
    work, saved, total = output.saved_chunks(specfile.load(sweep_spec_file), out)
    assert saved == 2 and f"the 2 chunks finished (of {total}) are kept in {work}" in err
    assert not out.exists()


def test_a_worker_without_fencesweep_stops_a_design_and_a_task(tmp_path, no_fencesweep):
    cluster, address = no_fencesweep
    with pytest.raises(WorkerError, match=f"the Dask worker {address} cannot import fencesweep"):
        fencesweep.design(yaml.safe_load(textwrap.dedent(DESIGN)), out=tmp_path / "d", backend="dask",
                          scheduler=cluster.scheduler_address, progress=False)
    assert not (tmp_path / "d").exists()
    # a task on a worker that was not warmed up (one that joined later): the probe names it
    with pytest.raises(WorkerError, match=f"the Dask worker {address} cannot import fencesweep .No module named"):
        compute.rerun_scenes(spec(), [0, 1], 1.0, 1, False, cluster.scheduler_address, fake_engine)


def test_a_cluster_of_one_thread_runs_the_tasks_on_it(no_fencesweep):
    cluster, address = no_fencesweep
    with distributed.Client(cluster) as client:
        [worker_pid] = client.run(os.getpid).values()
        pids = list(C.results(client, [(os.getpid,)] * 5))  # os.getpid: nothing of fencesweep needed there
    assert pids == [worker_pid] * 5 and worker_pid != os.getpid()


@pytest.mark.parametrize("argv, words", [
    (["design", "{spec}", "--backend", "dask"], "--backend dask needs --scheduler ADDRESS"),
    (["sensitivity", "{spec}", "--backend", "dask"], "--backend dask needs --scheduler ADDRESS"),
    (["design", "{spec}", "--scheduler", "tcp://HOST:8786"], "--scheduler is only used with --backend dask"),
    (["sensitivity", "{spec}", "--scheduler", "tcp://HOST:8786"], "--scheduler is only used with --backend dask"),
])
def test_the_cli_checks_backend_and_scheduler_for_every_study(tmp_path, capsys, argv, words):
    path = tmp_path / "d.yaml"
    path.write_text(textwrap.dedent(DESIGN))
    assert cli.main([a.format(spec=path) for a in argv] + ["--quiet"]) == 2
    assert words in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["d.yaml"]


@pytest.mark.parametrize("study", ["design", "sensitivity"])
@pytest.mark.parametrize("kw, words", [
    ({"backend": "dask"}, "backend = 'dask' needs scheduler = ADDRESS"),
    ({"scheduler": "tcp://HOST:8786"}, "scheduler is only used with backend = 'dask'"),
    ({"backend": "ray"}, "backend = 'ray' is not allowed"),
])
def test_the_api_checks_backend_and_scheduler_for_every_study(tmp_path, study, kw, words):
    with pytest.raises(UsageError, match=words):
        getattr(fencesweep, study)(yaml.safe_load(textwrap.dedent(DESIGN)), out=tmp_path / "x.parquet", **kw)
    assert list(tmp_path.iterdir()) == []


def test_tasks_wait_for_workers_that_join_later(caplog):
    import logging
    import operator
    import threading

    shared = ("spec", "engine")
    with distributed.LocalCluster(n_workers=0, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, distributed.Client(cluster) as client:
        later = threading.Timer(1.0, cluster.scale, [1])  # a batch system starting a worker after a while
        later.start()
        with caplog.at_level(logging.INFO, logger="fencesweep"):
            got = list(C.results(client, [(operator.itemgetter(0), shared)] * 3, shared))
        later.join()
    assert got == ["spec"] * 3
    assert f"waiting for the first Dask worker to join {cluster.scheduler_address}" in caplog.text
