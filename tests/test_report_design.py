"""REPORT.md's design section and the design figures (issue 10, item 5): built from small tables,
every number read from them (changing a table changes the text)."""
import json
import math
import textwrap

import pandas as pd
import pytest

from fencesweep.study.design import search as D
from fencesweep.report import design_text as R
from fencesweep.study.spec import file as specfile
from fencesweep.study.sweep import pipeline as sweep

SPEC = """
    params: {drive: flexible}
    grid: {B2: [15, 231], K2: [925, 2075]}
    envelope:
      L: [0.2, 0.7]
      A: 0.1
      dP: across
      seed: 1
    design:
      variables:
        B2: {min: 10, max: 300}
        K2: {min: 500, max: 2100}
      optimizer: {seed: 2, maxiter: 1, popsize: 2, refine: 2}
      verify: {sobol: 2, seed: 9}
      compare:
        paper 72/570: {B2: 72, K2: 570}
        rigid fence: {drive: rigid}
    """
SWING = """
    params: {drive: rigid}
    grid: {swing: [0.663225115758, 0.733038285838, 0.802851455917]}
    cases: [small_far, long_near]
    """


@pytest.fixture(scope="module")
def res(tmp_path_factory):
    from fencesweep.study.design import points as PT

    res = tmp_path_factory.mktemp("results")
    sp = specfile.loads(textwrap.dedent(SPEC))
    sweep.run_sweep(sp, res / "envelope.parquet", jobs=1)
    PT.write_points(sp, res / "envelope.parquet")
    D.run_design(sp, out_dir=res / "design")
    sweep.run_sweep(specfile.loads(textwrap.dedent(SWING)), res / "swing.parquet", jobs=1)
    return res


def text(res) -> str:
    return "\n".join(R.design_section(res))


def test_section_reads_its_numbers_from_the_tables(res):
    t = text(res)
    pts = pd.read_parquet(res / "envelope_points.parquet")
    rec = json.loads((res / "design" / "recommended.json").read_text())
    assert f"**{int(pts['feasible'].sum())} of {len(pts)} elements keep every constraint" in t
    dv = ", ".join(f"{k} = {v:g}" for k, v in rec["design_variables"].items())
    assert f"recommends **{dv}**" in t
    sw = pd.read_parquet(res / "swing.parquet")
    at42 = sw[(sw["case"] == "small_far") & (abs(sw["swing"] - math.radians(42)) < 1e-9)]["overload"].iloc[0]
    assert f"{at42:.3f} at 42 deg" in t and "calibrated, not measured" in t
    assert "whole accessible width" in t
    cmp_path = res / "design" / "comparison.parquet"
    cmp = pd.read_parquet(cmp_path)
    cmp.loc[cmp["design"] == "paper 72/570", "worst_overload"] = 0.123456
    cmp.to_parquet(cmp_path)
    assert "| paper 72/570 | " in text(res) and "| 0.123 |" in text(res)


def test_no_section_before_design_has_run(tmp_path):
    assert R.design_section(tmp_path) == []


def test_design_figures_are_drawn(res, tmp_path):
    pytest.importorskip("matplotlib")
    from fencesweep.report import design_figures as PD

    paths = PD.plot(["envelope_map", "envelope_loads"], res, tmp_path)
    assert [p.name for p in paths] == ["envelope_map.png", "envelope_loads.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)
    with pytest.raises(PD.MissingTable, match="fencesweep grid sweeps/window.yaml"):
        PD.plot(["window"], res, tmp_path)
    notes = []
    assert len(PD.plot(["all"], res, tmp_path, log=notes.append)) == 2  # window, sensitivity: no tables
    assert len(notes) == 2 and "sensitivity" in notes[1]


def test_section_2_points_to_the_envelope_recommendation_only_when_there_is_one(tmp_path):
    from fencesweep.report.maps_text import _envelope_pointer

    assert _envelope_pointer(tmp_path) == []
    (tmp_path / "design").mkdir()
    path = tmp_path / "design" / "recommended.json"
    path.write_text(json.dumps({"status": "feasible", "design_variables": {"B2": 231.0, "K2": 925.0}}))
    text = " ".join(_envelope_pointer(tmp_path))
    assert "B2 = 231, K2 = 925" in text
    path.write_text(json.dumps({"status": "infeasible", "design_variables": {"B2": 231.0, "K2": 925.0}}))
    assert _envelope_pointer(tmp_path) == []
