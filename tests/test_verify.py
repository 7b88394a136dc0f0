"""Every table checks itself (fencesweep/study/sweep/verify.py): a sample of its runs, the extremes
first, re-run at tol / 10 and compared; the record in the table's metadata (`fencesweep.verify`),
the API's attrs and the command's summary; --verify N, --no-verify; the same record whatever
--jobs and after a resume.

Most tests run a cheap deterministic stand-in for the engine (`fake_engine`, tests/helpers.py);
`test_real_*` run the real one on a few scenes.
"""
import json
import math
import textwrap

import numpy as np
import pandas as pd
import pytest

import fencesweep
from fencesweep import cli
from fencesweep.model import simulate as model_simulate
from fencesweep.study.sweep import accuracy
from fencesweep.study.sweep import compute
from fencesweep.study.store import table as store
from fencesweep.study.sweep import pipeline as sweep
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import verify as V
from fencesweep.study.sweep import sample as VS
from helpers import GRID_SPEC, fake_engine, load_spec, write_spec

#: flexible only, every scene its own run: 2 cases x 20 x 20 = 800 runs (a default sample of 16)
SPEC = """
    params: {drive: flexible}
    grid:
      B2: {linspace: [0, 190, 20]}
      K2: {linspace: [100, 2000, 20]}
    cases: [small_far, long_near]
    chunk_size: 50
"""


def drifting(vals, trajectory=False):
    return fake_engine(vals, trajectory, drift=0.01)


def flipping(vals, trajectory=False):
    """The re-run of every run whose B2 is 0 has another outcome."""
    out, _ = fake_engine(vals)
    if vals["step_factor"] != 1.0 and vals["B2"] == 0.0:
        out["outcome"] = "timeout" if out["outcome"] != "timeout" else "escaped"
    return out, None


def spec(text=SPEC):
    return load_spec(text)


def run(tmp_path, name="t.parquet", text=SPEC, **kw):
    kw.setdefault("simulate", fake_engine)
    kw.setdefault("jobs", 1)
    return sweep.run_sweep(spec(text), tmp_path / name, **kw)


@pytest.fixture
def reruns(monkeypatch):
    """The scenes each verification re-ran, in order of the calls (in this process or on
    workers of its own: rerun_scenes; on the sweep's workers: submit_reruns)."""
    calls = []
    real, real_submit = compute.rerun_scenes, compute.submit_reruns

    def recording(spec, rows, *a, **k):
        calls.append(list(rows))
        return real(spec, rows, *a, **k)

    def recording_submit(pool, rows, *a, **k):
        calls.append(list(rows))
        return real_submit(pool, rows, *a, **k)

    monkeypatch.setattr(compute, "rerun_scenes", recording)
    monkeypatch.setattr(compute, "submit_reruns", recording_submit)
    return calls


# ------------------------------------------------------------------ the record
def test_record_in_the_metadata_with_the_default_sample(tmp_path, reruns):
    res = run(tmp_path)
    rec = store.read_metadata(res.out)["verify"]
    assert rec == res.verify and rec["ok"] is True
    assert rec["n"] == 16 == len(reruns[0]) and rec["of"] == 800  # max(16, 1 % of 800)
    assert rec["tolerance"] == {"table": 1e-6, "rerun": pytest.approx(1e-7)}
    assert rec["step_factor_scale"] == pytest.approx(10 ** -0.2) and rec["threshold"] == 1e-3
    assert set(rec["quantities"]) == set(accuracy.QUANTITIES["cycle"])
    for q, v in rec["quantities"].items():
        assert v["max_rel_diff"] == 0.0 and v["undefined"] == 0 and v["floor"] == accuracy.floor_text(q)
    assert rec["outcome_mismatches"] == 0 and rec["outcomes_differ"] == []
    assert rec["sample"]["extremes"] + rec["sample"]["random"] == 16 and not rec["sample"]["capped"]
    assert rec["cost"]["measure"] == "integrator steps (n_steps)" and rec["cost"]["table_steps"] > 0
    json.dumps(rec, allow_nan=False)  # plain JSON: no NaN, no infinity


def test_extremes_are_in_the_sample(tmp_path, reruns):
    res = run(tmp_path)
    df = pd.read_parquet(res.out)  # one run per scene: scene numbers are row numbers
    sample = set(reruns[0])
    with np.errstate(divide="ignore"):
        expect = {
            "highest peak_force": df.peak_force.idxmax(), "highest overload": df.overload.idxmax(),
            "largest deflection_max": df.deflection_max.idxmax(),
            "overload closest to 1": (df.overload - 1).abs().idxmin(),
            "deflection_max closest to dalpha_perm": (df.deflection_max / df.dalpha_perm - 1).abs().idxmin(),
            "most steps": df.n_steps.idxmax(), "most rejected steps": df.n_rejected.idxmax(),
            "shallowest fence contact": df.max_penetration.where(df.t_first_contact.notna()).idxmin(),
            "weakest rail contact": df.peak_rail_force.where(df.peak_rail_force > 0).idxmin(),
        }
    assert res.verify["sample"]["extreme_scenes"] == {k: int(v) for k, v in expect.items()}
    assert set(expect.values()) <= sample


def test_sample_is_deterministic_whatever_the_jobs(tmp_path, reruns, monkeypatch):
    a = run(tmp_path, "a.parquet")
    started = []
    real_start = compute.start_pool
    monkeypatch.setattr(compute, "start_pool", lambda *a: started.append(a) or real_start(*a))
    b = run(tmp_path, "b.parquet", jobs=2, serial_below=0.0)  # the re-runs on the sweep's 2 forked workers
    assert len(started) == 1  # one pool of workers for the chunks and the re-runs
    # on workers, the sample's likely random rows are re-run beside the chunks, the rest after them
    early, later = reruns[1:]
    assert set(early).isdisjoint(later) and set(reruns[0]) == set(later) | (set(early) & set(reruns[0]))
    assert len(set(early) - set(reruns[0])) <= len(early) // 4  # few re-run in vain
    assert a.verify == b.verify
    assert a.out.read_bytes() == b.out.read_bytes()


def test_resumed_run_writes_the_same_record(tmp_path, monkeypatch):
    ref = run(tmp_path, "ref.parquet")
    real_write, written = store.write_chunk, []

    def dying_write(path, *a, **k):
        if len(written) == 5:
            raise KeyboardInterrupt
        real_write(path, *a, **k)
        written.append(path)

    monkeypatch.setattr(store, "write_chunk", dying_write)
    with pytest.raises(KeyboardInterrupt):
        run(tmp_path)
    monkeypatch.setattr(store, "write_chunk", real_write)
    res = run(tmp_path, jobs=2, serial_below=0.0)
    assert res.reused == 5 and res.verify == ref.verify
    assert res.out.read_bytes() == ref.out.read_bytes()


def test_no_verify_writes_no_record(tmp_path, reruns, monkeypatch, capsys):
    res = run(tmp_path, verify=False)
    assert res.verify is None and "verify" not in store.read_metadata(res.out) and reruns == []
    monkeypatch.setattr(model_simulate, "simulate_resolved", fake_engine)
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(SPEC))
    out = tmp_path / "cli.parquet"
    assert cli.main(["grid", str(path), "--out", str(out), "--jobs", "1", "--no-verify"]) == 0
    assert "verified" not in capsys.readouterr().err and "verify" not in store.read_metadata(out)
    df = fencesweep.grid(path, out=tmp_path / "api.parquet", jobs=1, verify=False)
    assert "verify" not in df.attrs["fencesweep"] and df.attrs["run"]["verify"] is None


def test_verify_n_reruns_n(tmp_path, reruns, monkeypatch, capsys):
    res = run(tmp_path, verify=40)
    assert len(reruns[-1]) == 40 == res.verify["n"] and res.verify["sample"]["rule"] == "requested: 40 runs"
    assert res.verify["sample"]["extremes"] == 20  # half of them
    assert run(tmp_path, "all.parquet", verify=10**6).verify["n"] == 800  # at most every run
    monkeypatch.setattr(model_simulate, "simulate_resolved", fake_engine)
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(SPEC))
    out = str(tmp_path / "cli.parquet")
    assert cli.main(["grid", str(path), "--out", out, "--jobs", "1", "--verify", "5", "--quiet"]) == 0
    assert store.read_metadata(out)["verify"]["n"] == 5 and len(reruns[-1]) == 5
    assert cli.main(["grid", str(path), "--out", out, "--jobs", "1", "--verify", "5"]) == 0
    assert "verified 5 of 800 runs at tol/10: max rel. difference peak_force 0, " in capsys.readouterr().err
    assert cli.main(["grid", str(path), "--out", out, "--verify", "0"]) == 2
    assert "--verify 0 is not allowed" in capsys.readouterr().err
    with pytest.raises(fencesweep.errors.UsageError, match="verify = 0 is not allowed"):
        fencesweep.grid(path, out=out, verify=0)


def test_dry_run_counts_the_verification(tmp_path, faked_engine, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(SPEC))
    assert cli.main(["grid", str(path), "--dry-run", "--jobs", "1", "--verify", "30"]) == 0
    text = capsys.readouterr().out
    assert "  verification: up to 30 of the 800 runs re-run at tol/10" in text and "and 30 re-runs" in text
    est = fencesweep.estimate(path, jobs=1)
    assert est.verify_runs == 16 and not est.verify_requested
    assert fencesweep.estimate(path, jobs=1, verify=False).verify_runs is None


def test_cost_cap_limits_the_default_sample_but_not_its_floor(tmp_path, reruns, monkeypatch):
    monkeypatch.setattr(VS, "COST_SHARE", 0.01)  # on the 800 runs here: the steps of ~8 / 1.58 runs
    assert run(tmp_path).verify["n"] == 16  # the first MIN_RUNS are always re-run
    monkeypatch.setattr(VS, "MIN_RUNS", 4)
    monkeypatch.setattr(VS, "SHARE", 0.05)  # 40 wanted
    rec = run(tmp_path, "capped.parquet").verify
    assert rec["sample"]["capped"] and 4 <= rec["n"] < 40 and len(reruns[-1]) == rec["n"]
    if rec["n"] > 4:  # runs beyond the floor are taken only while the re-runs stay under the cap
        assert rec["cost"]["sample_steps"] * VS.RERUN_COST <= 0.01 * (rec["cost"]["table_steps"] + 800)  # (>= 1 a run)
    assert run(tmp_path, "asked.parquet", verify=40).verify["n"] == 40  # an explicit N is not capped


# ------------------------------------------------------------------ a failed verification
def test_rerun_that_differs_makes_the_flag_false_and_warns(tmp_path, monkeypatch, capsys):
    res = run(tmp_path, simulate=drifting)
    rec = res.verify
    assert rec["ok"] is False and rec["quantities"]["peak_force"]["max_rel_diff"] == pytest.approx(0.01)
    assert rec["quantities"]["overload"]["max_rel_diff"] == 0.0  # the engine moved only peak_force
    assert rec["worst"][0]["quantity"] == "peak_force" and rec["worst"][0]["label"].startswith("scene #")
    lines = V.warning_lines(rec)
    assert lines[0].startswith("warning: verification failed: peak_force differs by 0.01 (> 0.001) from a re-run "
                               "at tol/10 in scene #")
    monkeypatch.setattr(model_simulate, "simulate_resolved", drifting)
    path = tmp_path / "s.yaml"
    path.write_text(textwrap.dedent(SPEC))
    assert cli.main(["grid", str(path), "--out", str(tmp_path / "cli.parquet"), "--jobs", "1", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning: verification failed: peak_force differs by 0.01" in err and "Traceback" not in err
    with pytest.warns(V.VerificationWarning, match="peak_force differs by 0.01"):
        df = fencesweep.grid(path, out=tmp_path / "api.parquet", jobs=1)
    assert df.attrs["fencesweep"]["verify"]["ok"] is False


def test_outcomes_that_differ_are_counted_and_named(tmp_path):
    rec = run(tmp_path, simulate=flipping, verify=800).verify
    assert rec["ok"] is False and rec["outcome_mismatches"] == 40  # B2 = 0: 20 K2 x 2 cases
    first = rec["outcomes_differ"][0]
    assert first["table"] != first["rerun"] and "B2 = 0.0" in first["label"]
    assert any("is escaped in the table but timeout at tol/10" in line or "but escaped at tol/10" in line
               for line in V.warning_lines(rec))


# ------------------------------------------------------------------ the floors, shared with the validation
def test_relative_difference_uses_the_validation_floors():
    assert accuracy.relative_difference(0.0, 5.0, "peak_force", 1000.0) == 5.0 / 100.0
    assert accuracy.relative_difference(2.0, 2.002, "t_exit", 0.0) == pytest.approx(1e-3)
    assert accuracy.relative_difference(0.0, 1e-4, "deflection_max", 0.0) == pytest.approx(1e-2)
    assert math.isnan(accuracy.relative_difference(math.nan, 1.0, "t_exit", 0.0))
    assert accuracy.relative_difference(math.inf, math.inf, "t_exit", 0.0) == 0.0
    from reference import compare  # the validation's judge (tests/reference/compare.py): benchmarks read the floors

    assert (compare.FORCE_FLOOR, compare.ANGLE_FLOOR, compare.TIME_FLOOR) == \
        (accuracy.FORCE_FLOOR, accuracy.ANGLE_FLOOR, accuracy.TIME_FLOOR)


# ------------------------------------------------------------------ the real engine
def test_real_cycle_sweep_verifies_itself(tmp_path, capsys):
    path = write_spec(tmp_path, GRID_SPEC, "s.yaml")
    df = fencesweep.grid(path, out=tmp_path / "t.parquet", jobs=1)
    rec = df.attrs["fencesweep"]["verify"]
    assert rec == df.attrs["run"]["verify"] and rec["n"] >= 16 and rec["of"] == 18
    for q in ("peak_force", "overload", "deflection_max", "t_exit", "residual_amplitude", "alpha_max", "contact_time"):
        d = rec["quantities"][q]["max_rel_diff"]
        assert d is not None and math.isfinite(d) and d < V.THRESHOLD, q
    assert rec["ok"] and rec["outcome_mismatches"] == 0
    assert cli.main(["grid", str(path), "--out", str(tmp_path / "c.parquet"), "--jobs", "1"]) == 0
    assert "verified 16 of 18 runs at tol/10: max rel. difference peak_force " in capsys.readouterr().err


def test_real_stream_and_impact_sweeps_verify_themselves(tmp_path):
    stream = """
        scene: stream
        case: small_far
        params: {n_cycles: 3, period: 1.5}
        grid: {B2: [15, 72]}
    """
    rec = run(tmp_path, "s.parquet", stream, simulate=None).verify
    assert rec["n"] == 2 and rec["ok"] and "start_amplitude" in rec["quantities"]  # each stream re-run whole
    impact = """
        scene: impact
        grid: {m2: [1.0, 5.0, 50.0]}
        cases: [{drive: rigid}, {drive: free}]
    """
    rec = run(tmp_path, "i.parquet", impact, simulate=None).verify
    assert rec["n"] == 4 and rec["ok"] and rec["tolerance"] == {"table": 1e-11, "rerun": pytest.approx(1e-12)}
    assert set(rec["quantities"]) == {"peak_force", "impulse", "contact_time", "e_eff"}
    assert PL.make_plan(spec(impact)).n_models == 4  # a rigid fence's m2 is not used: 1 run; a free fence: 3


# ------------------------------------------------------------------ what it did not see
def test_share_bound_is_clopper_pearson():
    """0 of n: 1 - 0.05^(1/n) exactly (~3 / n); k of n: the binomial tail at the bound is 5 %."""
    from scipy.stats import binom

    for n in (10, 130, 2100):
        assert V.share_bound(0, n) == pytest.approx(1 - 0.05 ** (1 / n), rel=1e-9)
    for n in (130, 2100):  # the rule of three, for large n
        assert V.share_bound(0, n) == pytest.approx(3 / n, rel=0.02)
    for k, n in ((1, 100), (7, 400), (50, 60)):
        p = V.share_bound(k, n)
        assert binom.cdf(k, n, p) == pytest.approx(0.05, rel=1e-6)
        assert V.share_bound(k - 1, n) < p < V.share_bound(k + 1, n)
    assert V.share_bound(5, 5) == 1.0 and V.share_bound(0, 0) == 1.0


def test_random_rows_bound_the_share_over(tmp_path):
    """The rows whose B2 is 0 (20 of 400 per case: 5 %) have another outcome at tol / 10. Of the
    rows drawn uniformly, the share over estimates 5 %, the bound lies above it, the record and
    the summary line say so."""
    res = run(tmp_path, simulate=flipping, verify=400)
    r = res.verify["random"]
    assert r["n"] >= 190 and r["of_rows"] == 800 and r["threshold"] == 1e-3 and r["confidence"] == 0.95
    assert r["share_over_bound"] == V.share_bound(r["over"], r["n"])
    assert 0.05 < r["share_over_bound"] < 0.15 and 0.0 < r["over"] / r["n"] < 0.1
    assert store.read_metadata(res.out)["verify"]["random"] == r
    line = V.summary_line(res.verify)
    assert f"at most {100 * r['share_over_bound']:.2g} % of rows over 0.001, 95 % confidence" in line


def test_random_rows_are_a_uniform_draw_not_the_cheap_ones(monkeypatch):
    """The cost cap ends the random draw instead of skipping costly rows: the rows drawn are a
    prefix of the seeded permutation of all rows, each re-run through its model run."""
    sp = spec()
    plan = PL.make_plan(sp)
    rng = np.random.default_rng(0)
    steps = rng.uniform(100, 10000, plan.n_models)  # costs that vary 100-fold
    crit = {name: np.full(plan.n_models, np.inf) for name, _ in VS.EXTREMES["cycle"]}
    crit["highest peak_force"] = -rng.uniform(size=plan.n_models)
    monkeypatch.setattr(VS.Scores, "result", lambda self, tables: (crit, steps))
    sample = VS.choose(plan, "no chunks are read")
    perm = VS._random_rows(plan, int(sp.hash[:16], 16))
    assert len(sample.random_rows) >= 1 and sample.random_rows == perm[:len(sample.random_rows)].tolist()
    assert {int(plan.row_model[r]) for r in sample.random_rows} <= set(sample.models)
    assert sorted(perm.tolist()) == list(range(800))


def test_scores_added_chunk_by_chunk_in_any_order_equal_the_whole_tables(tmp_path, monkeypatch):
    """sample.Scores: a sweep scores each chunk as it arrives (in whatever order the workers end
    them); the scores are those of all the chunks read at once."""
    from fencesweep.study.sweep.chunks import ChunkTables

    kept = []
    monkeypatch.setattr(sweep.shutil, "rmtree", lambda path: kept.append(path))  # keep the chunks
    res = run(tmp_path, jobs=1)
    plan = PL.make_plan(load_spec(SPEC))
    work = next(p for p in kept[0].iterdir() if p.is_dir())
    plan.chunk_size = json.loads((work / "plan.json").read_text())["chunk_size"]
    assert plan.n_chunks == res.n_chunks > 1
    whole = VS.scores(plan, work)
    scored, tables = VS.Scores(plan), ChunkTables(plan, work)
    for c in np.random.default_rng(1).permutation(plan.n_chunks):
        scored.add(int(c), tables)
        scored.add(int(c), tables)  # a chunk added twice counts once
    crit, steps = scored.result(tables)
    assert np.array_equal(steps, whole[1]) and steps.sum() > 0
    assert all(np.array_equal(crit[k], whole[0][k]) for k in whole[0])
