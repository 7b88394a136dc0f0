"""`fencesweep design`: the design section, the search, its verification, bad input."""
import json
import math
import textwrap

import pandas as pd
import pytest

from fencesweep.study.design import search as D
from fencesweep.study.spec import design as design_section
from fencesweep.study.spec import spec as S
from fencesweep.study.spec import file as specfile
from fencesweep.cli import main
from helpers import DESIGN_SPEC

TINY = DESIGN_SPEC


def load(text: str) -> S.Spec:
    return specfile.loads(textwrap.dedent(text))


@pytest.mark.parametrize("change, words", [
    (("envelope:", "envelope_:"), ["unknown key 'envelope_'"]),
    (("    envelope:\n      L: [0.2, 0.7]\n      m1: [5, 15]\n      A: 0.1\n      dP: across\n      seed: 1\n", ""),
     ["needs an envelope"]),
    (("B2: {min: 10, max: 200}", "L: {min: 0.2, max: 0.7}"), ["dimension of the envelope"]),
    (("B2: {min: 10, max: 200}", "B2: {min: 200, max: 10}"), ["min = 200.0 must be < max = 10.0"]),
    (("B2: {min: 10, max: 200}", "drive: {min: 0, max: 1}"), ["not a numeric parameter"]),
    (("optimizer:", "objective: cheapest\n      optimizer:"), ["design.objective = 'cheapest'", "max_min_margin"]),
    (("seed: 9", "seed: 1"), ["fresh sample"]),
    (("params: {drive: flexible}", "params: {drive: flexible}\n    grid: {t_c: [1.0, 1.36]}"),
     ["grid.t_c", "neither a design variable"]),
    (("refine: 4", "refine: 4, speed: 3"), ["unknown key 'speed'"]),
    (("paper: {B2: 72, K2: 570}", "paper: {B2: -72}"), ["design.compare.paper", "B2"]),
])
def test_bad_design_sections_are_rejected(change, words):
    with pytest.raises(S.SpecError) as exc:
        load(TINY.replace(*change))
    for w in words:
        assert w in str(exc.value)


def test_design_finds_verifies_and_writes_a_checkable_recommendation(tmp_path, capsys):
    path = tmp_path / "tiny.yaml"
    path.write_text(textwrap.dedent(TINY))
    assert main(["design", str(path), "--out", str(tmp_path / "d"), "--quiet"]) == 0
    rec = json.loads((tmp_path / "d" / "recommended.json").read_text())
    sp = specfile.load(path)
    point = rec["design_variables"]
    assert set(point) == {"B2", "K2"} and 10 <= point["B2"] <= 200 and 500 <= point["K2"] <= 2100
    assert rec["envelope"]["loads"] == [list(x) for x in sp.envelope.loads]
    assert rec["constraints"]["overload"] == 1.0 and rec["fixed"]["drive"] == "flexible"
    # anyone can re-check it: the same judge on the same fresh loads gives the recorded margins
    loads, _ = D.dense_loads(sp, sp.design)
    assert rec["verification"]["n_loads"] == len(loads) > len(sp.envelope.loads)
    again = D.judge(D.evaluate(sp, point, loads), sp.design.limits)
    assert rec["verification"]["min_margin"] == pytest.approx(again["min_margin"], abs=1e-12)
    assert rec["margins"]["overload"] == pytest.approx(1 - again["worst_overload"])
    assert rec["status"].startswith("feasible" if again["feasible"] else "infeasible")
    on_sample = D.judge(D.evaluate(sp, point, sp.envelope.loads), sp.design.limits)
    assert rec["verification"]["min_margin_change"] == pytest.approx(again["min_margin"] - on_sample["min_margin"])
    assert ("did not converge" in rec["status"]) == (again["feasible"] and not rec["optimizer"]["converged"])
    cmp = pd.read_parquet(tmp_path / "d" / "comparison.parquet")
    assert list(cmp["design"]) == ["envelope recommendation", "paper", "rigid"]
    per_load = pd.read_parquet(tmp_path / "d" / "verify_loads.parquet")
    for _, row in cmp.iterrows():
        assert row["worst_overload"] == per_load.loc[per_load["design"] == row["design"], "overload"].max()


def test_empty_feasible_region_names_the_binding_constraint(tmp_path):
    sp = load(TINY.replace("verify:", "constraints: {overload: 0.05}\n      verify:")
              .replace("maxiter: 2", "maxiter: 1, tol: 0"))
    rec = D.run_design(sp, out_dir=tmp_path)
    assert rec["status"].startswith("infeasible") and "overload" in rec["status"]
    assert rec["worst"]["binding"] == "overload" and rec["margins"]["overload"] < 0
    assert set(rec["design_variables"]) == {"B2", "K2"}  # the best infeasible point is still reported
    lines = D.summary_lines(rec)
    assert not rec["optimizer"]["converged"]  # one generation, tol 0: said in the output
    assert lines[0].startswith("status: infeasible") and any("NOT converged" in x for x in lines)


def test_an_optimum_on_a_bound_is_said(tmp_path):
    cfg = load(TINY).design  # B2 10-200, K2 500-2100: 1 % of the ranges is 1.9 and 16
    assert D.at_bounds({"B2": 199.0, "K2": 1000.0}, cfg) == {"B2": "upper"}
    assert D.at_bounds({"B2": 11.0, "K2": 515.0}, cfg) == {"B2": "lower", "K2": "lower"}
    assert D.at_bounds({"B2": 100.0, "K2": 1000.0}, cfg) == {}
    sp = load(TINY.replace("B2: {min: 10, max: 200}", "B2: {min: 10, max: 11}"))
    rec = D.run_design(sp, out_dir=tmp_path)
    assert rec["at_bounds"] == D.at_bounds(rec["design_variables"], sp.design)
    rec["at_bounds"] = {"B2": "upper"}
    assert any("B2 = " in x and "upper bound of its range [10, 11]" in x for x in D.summary_lines(rec))


def test_scores_rank_feasible_points_before_infeasible_ones():
    ok = {"min_margin": 0.1, "feasible": True, "worst_overload": 0.9}
    bad = {"min_margin": -0.01, "feasible": False, "worst_overload": 0.5}
    for obj in design_section.OBJECTIVES:
        assert D.score(ok, obj) < D.score(bad, obj)
    assert D.score(ok, "max_min_margin") == -0.1
    assert D.score(ok, "min_worst_overload") == 0.9
    assert math.isclose(D.round_sig(1234.5678, 3), 1230.0)


def test_prefer_the_least_damping_within_the_best_margin(tmp_path):
    sp = load(TINY.replace("optimizer:", "prefer: {B2: min}\n      within: 0.05\n      optimizer:")
              .replace("maxiter: 2, popsize: 2", "maxiter: 4, popsize: 4"))
    assert sp.design.prefer == ("B2", "min") and sp.design.within == 0.05
    rec = D.run_design(sp, out_dir=tmp_path)
    big = rec["largest_margin"]
    assert rec["design_variables"]["B2"] <= big["design_variables"]["B2"]
    assert rec["optimisation_sample"]["min_margin"] >= big["min_margin"] - 0.05 - 0.01  # rounding to 3 digits
    assert any("least B2 within 0.05" in x for x in D.summary_lines(rec))
    with pytest.raises(S.SpecError, match="design.prefer"):
        load(TINY.replace("optimizer:", "prefer: {L: min}\n      optimizer:"))


def test_stream_check_runs_the_loads_back_to_back():
    sp = load(TINY)
    loads = sp.envelope.loads
    point = {"B2": 72.0, "K2": 570.0}
    st = D.stream_check(sp, point, loads, sp.design.limits)
    single = D.evaluate(sp, point, loads)
    assert st["n_cycles"] == len(loads) and st["period"] == 1.36
    # the first cycle starts from rest: it is the single cycle of the first load
    first = D.stream_check(sp, point, loads[:1], sp.design.limits)
    assert first["worst_overload"] == pytest.approx(single["overload"].iloc[0], rel=1e-9)
    assert st["safe"] == (st["n_scraped"] == st["n_cycles"] and st["worst_overload"] <= 1.0
                          and st["worst_deflection"] <= 0.2618)
    assert D.stream_check(sp, {"drive": "free"}, loads, sp.design.limits) is None  # a free fence has no stream


def test_the_search_is_the_same_for_any_number_of_jobs():
    sp = load(TINY)
    one = D.search(sp, sp.design, jobs=1)
    two = D.search(sp, sp.design, jobs=2)
    assert one.raw == two.raw and one.point == two.point and one.nfev == two.nfev


def test_cli_refuses_specs_without_the_section(tmp_path, capsys):
    path = tmp_path / "plain.yaml"
    path.write_text("params: {drive: flexible}\nenvelope: {L: [0.2, 0.7]}\n")
    assert main(["design", str(path), "--quiet"]) == 2
    assert "has no design: section" in capsys.readouterr().err
    assert main(["sensitivity", str(path), "--quiet"]) == 2
    assert "has no sensitivity: section" in capsys.readouterr().err
    assert main(["design", str(path), "--jobs", "0"]) == 2
    assert "--jobs must be >= 1" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()  # bad input changes nothing
