"""Load envelopes: sampling, loads that cannot start, the per-design-point judge."""
import itertools
import math
import textwrap

import numpy as np
import pandas as pd
import pytest

from fencesweep.study.spec import envelope as E

from fencesweep.study.spec import design as DS

from fencesweep.study.design import judge as J

from fencesweep.study.design import points as PT
from fencesweep.study.spec import spec as S
from fencesweep.study.spec import file as specfile
from fencesweep.study.sweep import plan as PL
from fencesweep.study.sweep import pipeline as sweep
from fencesweep.cli import main

BOX = """
    params: {drive: flexible}
    grid: {B2: [15, 140], K2: [2075]}
    envelope:
      L: {min: 0.2, max: 0.7}
      A: {min: 0.1, max: 0.2}
      m1: [5, 15]
      dP: across
      R_s: 0.0
      sobol: 8
      seed: 3
    """


def load(text: str) -> S.Spec:
    return specfile.loads(textwrap.dedent(text))


def test_corners_then_sobol_points_same_for_every_design_point():
    sp = load(BOX)
    env = sp.envelope
    assert env.names == ("L", "A", "m1", "dP", "R_s")
    assert len(env.loads) == 2 ** 4 + 8  # the box's corners (m1 a choice of two) and the Sobol points
    loads = env.load_dicts()
    for L, A, m1, far in itertools.product((0.2, 0.7), (0.1, 0.2), (5.0, 15.0), (False, True)):
        dP = round(0.7 - A, 6) if far else 0.0
        assert {"L": L, "A": A, "m1": m1, "dP": dP, "R_s": 0.0} in loads
    # the loads are the innermost axis: every design point meets the same ones, in the same order
    n = len(env.loads)
    per_point = [[tuple(sp.inputs(i)[1][k] for k in env.names) for i in range(p * n, (p + 1) * n)] for p in (0, 1)]
    assert per_point[0] == per_point[1] == env.loads
    assert sp.inputs(0)[1]["B2"] == 15 and sp.inputs(n)[1]["B2"] == 140


def test_sample_is_seeded_and_loads_fit_across_the_belt():
    a, b = load(BOX).envelope, load(BOX).envelope
    assert a.loads == b.loads
    c = load(BOX.replace("seed: 3", "seed: 4")).envelope
    assert a.loads[:16] == c.loads[:16] and a.loads[16:] != c.loads[16:]
    assert load(BOX).hash != load(BOX.replace("seed: 3", "seed: 4")).hash
    for ld in a.load_dicts():
        assert 0.2 <= ld["L"] <= 0.7 and 0.1 <= ld["A"] <= 0.2 and ld["m1"] in (5.0, 15.0)
        assert 0.0 <= ld["dP"] <= 0.7 - ld["A"] + 1e-9


def test_loads_that_cannot_start_are_named_or_skipped():
    bad = BOX.replace("dP: across", "dP: {min: 0.0, max: 0.55}")
    with pytest.raises(S.SpecError) as exc:
        load(bad)
    msg = str(exc.value)
    assert "cannot start on the belt" in msg and "'dP': 0.55" in msg and "P_max = 0.7" in msg
    assert "envelope.invalid: skip" in msg
    env = load(bad.replace("seed: 3", "seed: 3\n      invalid: skip")).envelope
    assert env.skipped and all("dP" in why for _, why in env.skipped)
    assert all(ld["dP"] + ld["A"] <= 0.7 + 1e-12 for ld in env.load_dicts())


@pytest.mark.parametrize("body, words", [
    ("envelope: {L2: {min: 0.2, max: 0.7}}", ["unknown parameter 'L2'"]),
    ("envelope: {L: across}", ["only for dP"]),
    ("envelope: {L: {min: 0.7, max: 0.2}}", ["min = 0.7 must be < max = 0.2"]),
    ("envelope: {L: {min: 0.2, max: 0.7}, sobol: 4, lhs: 4}", ["one of sobol"]),
    ("envelope: {L: {min: 0.2, max: 0.7}, sobol: -1}", ["envelope.sobol = -1"]),
    ("envelope: {L: {min: 0.2, max: 0.7}, corners: false}", ["no load"]),
    ("envelope: {L: {min: 0.2, max: 0.7}, invalid: ignore}", ["envelope.invalid = 'ignore'"]),
    ("envelope: {m1: {min: -1, max: 5}}", ["m1"]),
    ("grid: {L: [0.2, 0.3]}\nenvelope: {L: {min: 0.2, max: 0.7}}", ["envelope.L", "grid.L"]),
    ("grid: {P_max: [0.7, 0.8]}\nenvelope: {dP: across}", ["P_max varies"]),
    ("scene: impact\nenvelope: {L: {min: 0.2, max: 0.7}}", ["needs scene: cycle"]),
    ("scene: stream\nenvelope: {L: {min: 0.2, max: 0.7}}", ["needs scene: cycle"]),
])
def test_bad_envelopes_are_rejected(body, words):
    with pytest.raises(S.SpecError) as exc:
        load(body)
    for w in words:
        assert w in str(exc.value)


def test_worst_per_design_point_is_the_max_over_its_loads(tmp_path, capsys):
    text = textwrap.dedent(BOX).replace("sobol: 8", "sobol: 2")
    path = tmp_path / "env.yaml"
    path.write_text(text + "output: env.parquet\n")
    assert main(["grid", str(path), "--out", str(tmp_path / "env.parquet"), "--jobs", "1"]) == 0
    assert "design points" in capsys.readouterr().err
    per_load = pd.read_parquet(tmp_path / "env.parquet")
    pts = pd.read_parquet(tmp_path / "env_points.parquet")
    sp = specfile.load(path)
    assert len(per_load) == 2 * len(sp.envelope.loads) and len(pts) == 2
    per_load["load"] = J.load_index(per_load, sp.envelope)
    assert (per_load["load"] >= 0).all()
    for _, p in pts.iterrows():
        mine = per_load[per_load["B2"] == p["B2"]]
        for col in ("overload", "deflection_max", "residual_amplitude"):
            assert p[f"worst_{col}"] == mine[col].max()
            assert mine.loc[mine["load"] == p[f"worst_{col}_load"], col].iloc[0] == mine[col].max()
        assert p["share_scraped"] == (mine["outcome"] == "scraped").mean()
        assert p["margin_overload"] == pytest.approx(1 - mine["overload"].max())
        assert p["margin_residual_amplitude"] == pytest.approx(1 - mine["residual_amplitude"].max() / math.radians(1))
        margins = [p[m] for m in J.MARGINS]
        assert p["min_margin"] == min(margins) and p["feasible"] == (min(margins) >= 0)


def test_summarize_margins_and_binding():
    df = pd.DataFrame({"B2": [1, 1, 2, 2], "load": [0, 1, 0, 1],
                       "outcome": ["scraped", "escaped", "scraped", "scraped"],
                       "overload": [0.5, 0.9, 1.2, np.nan], "deflection_max": [0.1, 0.2, 0.1, 0.1],
                       "residual_amplitude": [0.0, 0.001, 0.0, 0.0], "dalpha_perm": [0.4] * 4})
    pts = J.summarize(df, ["B2"], DS.Limits()).set_index("B2")
    assert pts.loc[1, "share_scraped"] == 0.5 and pts.loc[1, "margin_scraped"] == -0.5
    assert pts.loc[1, "binding"] == "scraped" and not pts.loc[1, "feasible"]
    assert pts.loc[2, "margin_scraped"] == np.inf and pts.loc[2, "worst_overload"] == 1.2
    assert pts.loc[2, "binding"] == "overload" and pts.loc[2, "margin_overload"] == pytest.approx(-0.2)
    assert pts.loc[1, "margin_deflection_max"] == pytest.approx(0.5)


def test_envelope_sweep_plan_counts_every_load(tmp_path):
    sp = load(BOX)
    plan = PL.make_plan(sp)
    assert plan.n_scenes == 2 * len(sp.envelope.loads) == plan.n_models


def test_batches_combine_to_the_one_pass_judgement():
    rng = np.random.default_rng(0)
    n = 40
    df = pd.DataFrame({"B2": np.repeat([1.0, 2.0, 3.0, 4.0], n // 4), "load": np.tile(np.arange(n // 4), 4),
                       "outcome": rng.choice(["scraped", "scraped", "escaped"], n),
                       "overload": rng.random(n) * 1.2, "deflection_max": rng.random(n) * 0.3,
                       "residual_amplitude": rng.random(n) * 0.02, "dalpha_perm": 0.2618})
    whole = J.summarize(df, ["B2"], DS.Limits())
    for cuts in ([5, 23], [1, 2, 3, 39], [17]):  # batches that split design points
        edges = [0, *cuts, n]
        parts = [J.partial(df.iloc[a:b], ["B2"], DS.Limits()) for a, b in zip(edges, edges[1:])]
        pd.testing.assert_frame_equal(J.finish(J.combine(parts), ["B2"], DS.Limits()), whole)


def test_cases_that_override_params_tell_the_design_points_apart():
    sp = load("""
        params: {drive: flexible}
        cases:
          - {drive: rigid}
          - {B2: 72, K2: 570}
        envelope: {L: [0.2, 0.7], dP: across}
        """)
    assert PT.design_columns(sp) == ["drive", "B2", "K2"]
    assert len(sp.envelope.loads) == 4 and sp.n_scenes == 2 * 4  # two lengths x the rail and the far edge
    assert sp.resolve(0)["drive"] == "rigid" and sp.resolve(4)["B2"] == 72


def test_an_interrupted_envelope_sweep_resumes_and_dask_gives_the_same_table(tmp_path, monkeypatch):
    from pathlib import Path

    from fencesweep.study.store import table as store

    sp = specfile.loads(textwrap.dedent(BOX).replace("sobol: 8", "sobol: 2") + "chunk_size: 5\n")
    ref = sweep.run_sweep(sp, tmp_path / "ref.parquet", jobs=1)
    real_write, written = store.write_chunk, []

    def dying_write(path, *a, **k):
        if len(written) == 3:
            raise KeyboardInterrupt
        real_write(path, *a, **k)
        written.append(Path(path))

    monkeypatch.setattr(store, "write_chunk", dying_write)
    with pytest.raises(KeyboardInterrupt):
        sweep.run_sweep(sp, tmp_path / "cut.parquet", jobs=1)
    monkeypatch.setattr(store, "write_chunk", real_write)
    again = sweep.run_sweep(sp, tmp_path / "cut.parquet", jobs=1)
    assert again.reused == 3 and again.computed == again.n_chunks - 3
    assert again.out.read_bytes() == ref.out.read_bytes()
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        res = sweep.run_sweep(sp, tmp_path / "dask.parquet", backend="dask", scheduler=cluster.scheduler_address)
    assert res.out.read_bytes() == ref.out.read_bytes()


def test_across_keeps_turned_loads_on_the_belt():
    sp = load("""
        envelope:
          L: {min: 0.2, max: 0.7}
          A: {min: 0.1, max: 0.2}
          dP: across
          phi0: {min: -0.3, max: 0.3}
          R_s: {min: -0.4, max: 0.6}
          sobol: 16
          seed: 5
        """)
    env = sp.envelope
    assert not env.skipped and len(env.loads) == 2 ** 5 + 16  # the far-edge corners included
    far = [ld for ld in env.load_dicts() if ld["dP"] > 0.44 and ld["L"] == 0.2 and ld["A"] == 0.2]
    assert far and all(ld["dP"] <= 0.7 - E._extent(0.2, 0.2, ld["phi0"]) for ld in far)
