"""REPORT.md's opening (the element to build), its design section and the design figures: built
from small tables, every number read from them (changing a table changes the text)."""
import colorsys
import json
import math
import re
import shutil
import textwrap
from types import SimpleNamespace

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
        two-case 15/2075: {B2: 15, K2: 2075}
        rigid fence: {drive: rigid}
    """
#: the picks of the two named loads' maps (analysis.Design's best and damped), as the opening names them
PICKS = SimpleNamespace(best={"B2": 15.0, "K2": 2075.0}, damped=None)
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
    assert len(PD.plot(["all"], res, tmp_path, log=notes.append)) == 2  # window, sensitivity, risk_map: no tables
    assert len(notes) == 3 and "sensitivity" in notes[1] and "fencesweep risk sweeps/risk.yaml" in notes[2]


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


# ---------------------------------------------------------------------------- the opening
def opening(res, picks=PICKS) -> list:
    """The report's first lines: the title, then the answer (document.py puts them first)."""
    from fencesweep.report import answer_text as A
    from fencesweep.report import document as DOC

    return DOC._title(None) + A.answer_lines(res, picks)


def test_report_opens_with_the_element_of_recommended_json(res, tmp_path):
    rec = json.loads((res / "design" / "recommended.json").read_text())
    dv, lines = rec["design_variables"], opening(res)
    assert lines[0].startswith("# ")
    first = next(line for line in lines[1:] if line)
    assert first.startswith(f"**The element to build: B2 = {dv['B2']:g} N m s/rad, K2 = {dv['K2']:g} N m/rad**")
    assert f"status {rec['status']}" in first and "t_c = 1.36 s" in first
    head = "\n".join(lines[:6])
    for name, m in rec["margins"].items():
        if m is not None:
            assert f"{name} {m:.3f} (worst " in head, name
    assert f"**Binding: {rec['worst']['binding']}.**" in head
    assert f"searched on {rec['optimisation_sample']['n_loads']} loads of the envelope" in head
    assert f"verified on {rec['verification']['n_loads']} fresh ones" in head
    # the two-case pick follows as a comparison, by its name in section 2
    pick = next(line for line in lines if "15/2075" in line)
    assert pick.startswith("* the two-case pick 15/2075 (section 2") and "build" not in pick
    # another element in recommended.json: another opening (nothing typed in)
    shutil.copytree(res / "design", tmp_path / "design")
    (tmp_path / "design" / "comparison.parquet").unlink()  # the copy in recommended.json stands in
    (tmp_path / "design" / "recommended.json").write_text(json.dumps(dict(rec, design_variables={"B2": 123.0,
                                                                                                  "K2": 456.0})))
    assert "**The element to build: B2 = 123 N m s/rad, K2 = 456 N m/rad**" in opening(tmp_path)[2]


def test_no_other_element_is_called_the_one_to_build(res, tmp_path):
    from fencesweep.report.maps_text import _envelope_pointer

    rec = json.loads((res / "design" / "recommended.json").read_text())
    b2, k2 = rec["design_variables"]["B2"], rec["design_variables"]["K2"]
    names = (f"B2 = {b2:g}", f"{b2:g}/{k2:g}", f"{b2:g} / {k2:g}", f"B2 = {b2:g}, K2 = {k2:g}")
    text = "\n".join(opening(res) + R.design_section(res) + _envelope_pointer(res))
    assert "would build" not in text
    hits = list(re.finditer(r"\bbuild\b", text))
    assert len(hits) >= 3  # the opening, the pointer of section 2, the heading of section 7
    for hit in hits:
        after = text[hit.end():hit.end() + 300]
        at = min(after.find(n) for n in names if n in after)  # ValueError: the element is not named
        assert not any(other in after[:at] for other in ("15/2075", "72/570", "rigid")), after[:at]
    # no feasible element: nothing is to be built
    shutil.copytree(res / "design", tmp_path / "design")
    (tmp_path / "design" / "recommended.json").write_text(json.dumps(dict(rec, status="infeasible: none")))
    lines = opening(tmp_path)
    assert lines[2].startswith("**No element keeps every constraint") and "build" not in "\n".join(lines)
    assert _envelope_pointer(tmp_path) == []


def test_recommended_figure_draws_only_the_cycles_of_the_element_to_build(res):
    from fencesweep.errors import MissingInput
    from fencesweep.report.figures_maps import _envelope_trajectories

    with pytest.raises(MissingInput, match="fencesweep plot trajectories"):
        _envelope_trajectories(res)  # the design has run, its cycles have not


def _hue(color) -> float:
    from matplotlib.colors import to_rgb

    return 360 * colorsys.rgb_to_hsv(*to_rgb(color))[0]


def test_envelope_map_gives_red_one_meaning(res, tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    from fencesweep.report import design_figures as PD

    redish = lambda h: h < 20 or h > 340  # noqa: E731
    bluish = lambda h: 190 < h < 250  # noqa: E731
    assert not any(redish(_hue(c)) or bluish(_hue(c)) for c in PD.BINDING_COLORS)
    monkeypatch.setattr(PD, "_save", lambda fig, out, name: fig)
    fig = PD.envelope_map(res, tmp_path)
    left, right = (a.get_legend() for a in fig.axes[:2])
    assert [t.get_text().split(":")[0] for t in left.get_texts()[:2]] == ["red", "blue"]
    assert "the element to build (design/recommended.json)" in [t.get_text() for t in left.get_texts()]
    for patch in right.get_patches():
        assert not redish(_hue(patch.get_facecolor())) and not bluish(_hue(patch.get_facecolor()))
