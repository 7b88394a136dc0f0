"""The Python API of the studies (fencesweep.grid, estimate, points, design, sensitivity):
the same tables as the CLI, the envelope's per-design-point table, the dry run, bad input."""
import subprocess
import sys
import textwrap

import pandas as pd
import pytest
import yaml

import fencesweep
from fencesweep import cli
from fencesweep.errors import UsageError
from fencesweep.study import api
from fencesweep.study.sweep import estimate
from fencesweep.study.sweep import sample as verify_sample
from fencesweep.study.spec import spec as S
from helpers import GRID_SPEC as SPEC  # 3 x 3 B2 x K2 over both named cases: 18 cycles of the real engine
from helpers import write_spec

#: 2 design points over 2^3 x 2 corners (L, A, dP across; m1) plus 2 Sobol loads: 36 cycles
ENVELOPE = """
    params: {drive: flexible}
    grid: {B2: [15, 140], K2: [2075]}
    envelope:
      L: {min: 0.2, max: 0.7}
      A: {min: 0.1, max: 0.2}
      m1: [5, 15]
      dP: across
      sobol: 2
      seed: 3
"""


def test_grid_returns_the_table_the_cli_writes(tmp_path):
    path = write_spec(tmp_path, SPEC)
    df = fencesweep.grid(path, out=tmp_path / "api.parquet", jobs=1)
    assert cli.main(["grid", str(path), "--out", str(tmp_path / "cli.parquet"), "--jobs", "1", "--quiet"]) == 0
    pd.testing.assert_frame_equal(df, pd.read_parquet(tmp_path / "cli.parquet"))
    assert len(df) == 18 and (df["status"] == "ok").all()
    assert df.attrs["units"]["B2"] == "N m s/rad" and df.attrs["units"]["peak_force"] == "N"
    meta = df.attrs["fencesweep"]
    assert meta["spec_hash"] == fencesweep.study.spec.file.load(path).hash and meta["counts"]["scenes"] == 18
    run = df.attrs["run"]
    assert run["out"] == str(tmp_path / "api.parquet") and run["scenes"] == run["model_runs"] == 18
    assert run["chunks_computed"] == run["chunks"] and run["chunks_reused"] == 0
    assert run["failed_runs"] == 0 and run["jobs"] == 1 and run["seconds"] > 0 and run["points"] is None
    assert "points_path" not in df.attrs
    # the spec as a dict (its parsed YAML) is the same spec: the same table
    again = fencesweep.grid(yaml.safe_load(textwrap.dedent(SPEC)), out=tmp_path / "dict.parquet", jobs=1)
    pd.testing.assert_frame_equal(again, df)
    assert again.attrs["fencesweep"]["spec_hash"] == meta["spec_hash"]
    assert yaml.safe_load(again.attrs["fencesweep"]["spec_source"]) == yaml.safe_load(textwrap.dedent(SPEC))


def test_envelope_points_are_reachable_from_the_table(tmp_path):
    path = write_spec(tmp_path, ENVELOPE)
    df = fencesweep.grid(path, out=tmp_path / "env.parquet", jobs=1)
    assert df.attrs["points_path"] == str(tmp_path / "env_points.parquet")
    pts = fencesweep.points(df)
    pd.testing.assert_frame_equal(pts, pd.read_parquet(tmp_path / "env_points.parquet"))
    pd.testing.assert_frame_equal(fencesweep.points(tmp_path / "env.parquet"), pts)  # or from the table's path
    assert list(pts["B2"]) == [15.0, 140.0] and (pts["n_loads"] == 18).all()
    assert pts.attrs["fencesweep"]["per_load_table"] == str(tmp_path / "env.parquet")
    summary = df.attrs["run"]["points"]
    best = pts.loc[pts["min_margin"].idxmax()]
    assert summary["design_points"] == 2 and summary["loads"] == 18
    assert summary["feasible"] == int(pts["feasible"].sum()) and summary["best"] == {"B2": best["B2"], "K2": 2075.0}
    assert summary["min_margin"] == best["min_margin"] and summary["binding"] == best["binding"]
    worst = df.groupby("B2")["overload"].max()  # the per-load table is the table of every load
    assert list(pts["worst_overload"]) == list(worst.loc[[15.0, 140.0]])
    # only a path in attrs: pandas copies and compares attrs in its operations (a DataFrame there
    # makes pd.concat raise), and the per-load tables of two studies still concatenate
    both = pd.concat([df, fencesweep.grid(path, out=tmp_path / "env2.parquet", jobs=1)])
    assert len(both) == 72 and fencesweep.points(df.copy()).equals(pts)
    plain = fencesweep.grid(write_spec(tmp_path, SPEC, "plain.yaml"), out=tmp_path / "plain.parquet", jobs=1)
    with pytest.raises(UsageError, match="no per-design-point table"):
        fencesweep.points(plain)
    with pytest.raises(UsageError, match="plain_points.parquet does not exist"):
        fencesweep.points(tmp_path / "plain.parquet")


def test_estimate_is_the_dry_run_and_writes_nothing(tmp_path, capsys):
    path = write_spec(tmp_path, SPEC)
    out = tmp_path / "t.parquet"
    est = fencesweep.estimate(path, out=out, jobs=2)
    assert isinstance(est, estimate.Estimate)
    assert (est.n_scenes, est.n_models, est.skipped) == (18, 18, 0)
    assert est.chunk_size >= 1 and est.n_chunks * est.chunk_size >= 18 and est.chunks_done == 0
    assert est.per_run > 0 and est.timed_runs >= 1 and est.warm_up >= 0 and est.runs_left == 18
    assert est.jobs == 1  # a few milliseconds of work: a real run would not start workers
    assert est.verify_runs == 16 and est.verify_seconds == pytest.approx(16 * verify_sample.RERUN_COST * est.per_run)
    assert est.seconds == pytest.approx(est.per_run * 18 + est.verify_seconds) and est.stop is None
    assert est.notes == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["spec.yaml"]  # nothing written
    assert cli.main(["grid", str(path), "--out", str(out), "--dry-run", "--jobs", "2"]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[:2] == est.lines()[:2] == [f"{path}: scene cycle, 18 scenes (2 cases x B2 3 x K2 3) -> {out}",
                                              "  distinct model runs: 18"]
    assert printed[-1].startswith("  estimated time on 1 job: ") and printed[-1].endswith(" for 18 runs and 16 re-runs")
    assert printed[-2].startswith("  verification: up to 16 of the 18 runs re-run at tol/10")
    # another spec's table at the output: a real run would stop, and the estimate says why
    fencesweep.grid(write_spec(tmp_path, SPEC.replace("B2: [15, 72, 140]", "B2: [15, 72]"), "other.yaml"), out=out, jobs=1)
    est = fencesweep.estimate(path, out=out, backend="dask")
    assert "holds the results of another spec" in est.stop and est.jobs is None
    assert est.notes == [f"a real run would stop before it starts: {est.stop}"]
    assert est.lines()[-1].endswith("of work for 18 runs and 16 re-runs, divided by the cluster's workers")
    assert fencesweep.estimate(path, out=out, overwrite=True).stop is None


@pytest.mark.parametrize("spec, error, words", [
    ({"grid": {"B3": [1, 2]}}, S.SpecError, ["grid.B3: unknown parameter 'B3'; did you mean 'B2'?"]),
    ({"grid": {"dP": [0, 0.5, 0.7]}}, S.SpecError, ["scene #2 (dP = 0.7)", "dP = 0.7 is not allowed"]),
    ({"grid": {"B2": {"linspace": [0, 10]}}}, S.SpecError, ["grid.B2.linspace = [0, 10]", "expected {linspace"]),
    (["B2", 1], TypeError, ["spec must be the path of a YAML spec, a dict", "not list"]),
])
def test_bad_input_raises_a_clear_error_and_writes_nothing(tmp_path, spec, error, words):
    with pytest.raises(error) as exc:
        fencesweep.grid(spec, out=tmp_path / "t.parquet", jobs=1)
    assert all(w in str(exc.value) for w in words), str(exc.value)
    if error is S.SpecError:
        assert isinstance(exc.value, fencesweep.ParameterError)
    # no table, no work directory: only the empty lock file of a run that got as far as planning
    # (lock.py: a lock file is never removed, as a run waiting on it would then hold a lock of its own)
    assert [p.name for p in tmp_path.iterdir()] in ([], ["t.parquet.lock"])


@pytest.mark.parametrize("call, words", [
    (lambda p, t: fencesweep.grid(p, out=t / "t.csv"), "out = "),
    (lambda p, t: fencesweep.grid(p, out=t / "t.parquet", jobs=0), "jobs = 0 is not allowed"),
    (lambda p, t: fencesweep.grid(p, out=t / "t.parquet", backend="dask"), "needs scheduler"),
    (lambda p, t: fencesweep.estimate(p, out=t / "t.parquet", backend="ray"), "backend = 'ray' is not allowed"),
    (lambda p, t: fencesweep.design(p, out=t / "d"), "has no design: section"),
    (lambda p, t: fencesweep.sensitivity(p, out=t / "s.parquet"), "has no sensitivity: section"),
])
def test_bad_arguments_raise_usage_errors_before_anything_runs(tmp_path, call, words):
    path = write_spec(tmp_path, SPEC)
    with pytest.raises(UsageError, match=words):
        call(path, tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["spec.yaml"]


def test_an_interrupted_grid_says_what_is_saved_and_resumes(tmp_path, monkeypatch, faked_engine):
    from fencesweep.study.store import table as store

    path = write_spec(tmp_path, SPEC + "    chunk_size: 3\n")
    real_write, written = store.write_chunk, []

    def dying_write(*a, **k):
        if len(written) == 2:
            raise KeyboardInterrupt
        real_write(*a, **k)
        written.append(1)

    monkeypatch.setattr(store, "write_chunk", dying_write)
    with pytest.raises(api.SweepInterrupted) as exc:
        fencesweep.grid(path, out=tmp_path / "t.parquet", jobs=1)
    assert isinstance(exc.value, KeyboardInterrupt) and (exc.value.saved, exc.value.total) == (2, 6)
    assert str(exc.value).startswith("interrupted; 2 of 6 chunks are saved in ") and "same call again" in str(exc.value)
    monkeypatch.setattr(store, "write_chunk", real_write)
    notes = []
    df = fencesweep.grid(path, out=tmp_path / "t.parquet", jobs=1, log=notes.append)
    assert df.attrs["run"]["chunks_reused"] == 2 and df.attrs["run"]["chunks_computed"] == 4 and len(df) == 18
    assert notes == [f"resuming: 2 of 6 chunks already in {exc.value.work}"]


def test_import_fencesweep_stays_cheap():
    code = ("import sys\nimport fencesweep\n"
            "print(sorted(m for m in ('pandas', 'pyarrow', 'joblib', 'numba') if m in sys.modules))\n"
            "fencesweep.grid, fencesweep.estimate, fencesweep.points\n"
            "print('grid' in dir(fencesweep) and 'pandas' not in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[:2] == ["[]", "True"]
    assert set(fencesweep.__all__) >= {"simulate", "simulate_resolved", "resolve", "CASES", "ParameterError",
                                       "__version__", "grid", "estimate", "design", "sensitivity", "points"}
    with pytest.raises(AttributeError):
        fencesweep.no_such_thing  # noqa: B018
