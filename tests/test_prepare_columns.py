"""A chunk's parameter vectors prepared on whole columns (prepare.prepare_columns, the sweep's
workers and the GPU path) are bit for bit those of the per-run prepare (`simulate`), and a sweep's
table is the same either way."""
import itertools

import numpy as np
import pandas as pd
import pytest

from fencesweep.model import layout as Lp
from fencesweep.model import params as P
from fencesweep.model.prepare import COLUMNS, prepare, prepare_columns
from fencesweep.study.spec.scenes import Scenes
from fencesweep.study.sweep import compute, runs
from fencesweep.study.sweep import pipeline as sweep
from helpers import load_spec

#: what varies from set to set besides the scene, the case and the branches (law, drive, profile)
EXTRAS = ({}, {"k_lin": 2.0e5}, {"K2": 0.0}, {"step_factor": 0.3, "integrator": "rk4", "dt": 1e-5},
          {"swing": 0.9, "coupler_ratio": 1.7, "t_c": 0.9}, {"e": 0.55, "m1": 7.3, "L": 0.3, "H": 0.25, "dP": 0.1})


def varied_sets() -> list:
    """Resolved parameter sets over every scene, case, law, drive and profile, each with EXTRAS
    (the combinations that do not resolve left out)."""
    out = []
    for scene, case, law, drive, profile, extra in itertools.product(
            ("cycle", "impact", "freefall", "stream"), ("small_far", "long_near"), ("hertz", "linear"),
            ("flexible", "rigid", "free"), ("crank_rocker", "harmonic"), EXTRAS):
        try:
            out.append(P.resolve(scene, case, contact_law=law, drive=drive, profile=profile, **extra))
        except P.ParameterError:
            pass
    return out


def columns_of(sets: list) -> dict:
    """The sets as columns: a float64 column where every value is a float, else objects."""
    cols = {}
    for name in COLUMNS:
        values = [v[name] for v in sets]
        if all(isinstance(x, float) for x in values):
            cols[name] = np.array(values)
        else:
            cols[name] = np.empty(len(values), dtype=object)
            cols[name][:] = values
    return cols


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


@pytest.fixture(scope="module")
def sets():
    out = varied_sets()
    assert len(out) > 400 and {v["scene"] for v in out} == {"cycle", "impact", "freefall", "stream"}
    return out


@pytest.mark.parametrize("table", [True, False])
def test_columns_give_the_per_run_vectors_bit_for_bit(sets, table):
    """All the sets in one call (their branches grouped), and each set alone (its values plain)."""
    vectors = prepare_columns(columns_of(sets), len(sets), table)
    assert len(vectors) == len(sets) and vectors.header.shape == (len(sets), Lp.N_P)
    for k, vals in enumerate(sets):
        one = prepare(vals, table)
        assert same_bits(vectors[k], one), (k, vals)
        assert same_bits(prepare_columns({n: vals[n] for n in COLUMNS}, 1, table)[0], one)
    if table:  # a crank-rocker's table, once per (swing, coupler_ratio)
        assert len({(v["swing"], v["coupler_ratio"]) for v in sets if v["profile"] == "crank_rocker"}) \
            == len({id(t) for t in vectors.tables})
    else:
        assert not vectors.tables and (vectors.which == -1).all()


def test_shared_values_and_columns_mixed(sets):
    """One group (one scene, law, drive, profile) whose numbers are partly shared, partly columns."""
    group = [v for v in sets if (v["scene"], v["contact_law"], v["drive"], v["profile"], v["dt"], v["k_lin"])
             == ("cycle", "linear", "flexible", "crank_rocker", None, None)]
    assert len(group) > 4
    cols = columns_of(group)
    for name in ("scene", "contact_law", "drive", "profile", "integrator", "dt", "k_lin", "v", "R", "H"):
        if len({repr(v[name]) for v in group}) == 1:
            cols[name] = group[0][name]
    vectors = prepare_columns(cols, len(group))
    assert all(same_bits(vectors[k], prepare(v)) for k, v in enumerate(group))


SPEC = """
    scene: cycle
    params: {m1: 12.0}
    grid:
      drive: [flexible, rigid]
      profile: [crank_rocker, harmonic]
      e: [0.2, 0.6]
      B2: [15, 140]
      K2: [0, 570, 2075]
    cases: [small_far, long_near]
    chunk_size: 7
"""


def test_a_specs_columns_give_its_runs_vectors():
    """Scenes.value_columns of a spec's scenes (free axes B2, K2; the rest slot by slot) through
    prepare_columns: each run's vector as prepare gives it for spec.resolve."""
    spec = load_spec(SPEC)
    scenes = Scenes(spec)
    rows = np.arange(0, spec.n_scenes, 3)
    cols = scenes.value_columns(rows, COLUMNS)
    assert isinstance(cols["B2"], np.ndarray) and cols["m1"] == 12.0 and cols["drive"].dtype == object
    for table in (True, False):
        vectors = prepare_columns(cols, len(rows), table)
        assert all(same_bits(vectors[k], prepare(v, table)) for k, v in enumerate(scenes.resolved(rows)))


def test_a_chunk_that_cannot_be_prepared_on_columns_runs_run_by_run(monkeypatch):
    """Where the columns' preparation raises, each run prepares its own: a run that cannot is a
    failed row naming the exception, the others run (runs.run_one)."""
    from fencesweep.model import prepare as prep

    spec = load_spec(SPEC)
    real = prep.prepare

    def fails_for_e_06(vals, table=True):
        if vals["e"] == 0.6:
            raise ValueError("no")
        return real(vals, table)

    monkeypatch.setattr(prep, "prepare", fails_for_e_06)
    monkeypatch.setattr(prep, "prepare_columns", lambda *a, **k: 1 / 0)
    assert compute.prepared(spec, np.arange(4)) is None
    rows = np.arange(0, 48, 6)  # e = 0.2, 0.6, 0.2, ... (e's stride: 2 B2 x 3 K2)
    _, results, _ = compute._run_chunk(0, range(8), rows, None, {}, (spec, None))
    assert [r["status"] for r in results[1::2]] == ["failed: exception ValueError: no"] * 4
    assert [r["status"] for r in results[::2]] == ["ok"] * 4


def sweep_table(tmp_path, name: str, text: str) -> pd.DataFrame:
    res = sweep.run_sweep(load_spec(text), tmp_path / name, jobs=1, verify=False, progress=False)
    return pd.read_parquet(res.out)


@pytest.mark.parametrize("text", [SPEC, """
    scene: impact
    grid: {m2: {logspace: [1, 50, 3]}, contact_law: [hertz, linear]}
    cases: [{drive: rigid}, {drive: free}, {drive: flexible}]
"""], ids=["cycle", "impact"])
def test_a_sweeps_table_is_the_same_with_the_vectors_prepared_run_by_run(tmp_path, monkeypatch, text):
    """The real engine on a small spec: the table with each chunk's vectors prepared on columns
    equals, exactly, the one with each run preparing its own (as before prepare_columns)."""
    columns = sweep_table(tmp_path, "columns.parquet", text)
    monkeypatch.setattr(runs, "takes_vectors", lambda fn: False)
    one_by_one = sweep_table(tmp_path, "runs.parquet", text)
    pd.testing.assert_frame_equal(columns, one_by_one, check_exact=True)
    assert (columns["status"] == "ok").all()
