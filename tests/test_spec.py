"""Sweep specs: expansion (grid, zip, cases, linspace/logspace/range, Psi) and rejection of bad specs."""
import textwrap

import numpy as np
import pytest
import yaml

from fencesweep.model import params as P
from fencesweep.study.spec import spec as S
from fencesweep.study.spec import file as specfile
from fencesweep.study.spec import risk as risk_spec


def load(text: str) -> S.Spec:
    return specfile.loads(textwrap.dedent(text))


def all_inputs(sp: S.Spec) -> list:
    return [sp.inputs(i) for i in range(sp.n_scenes)]


# ------------------------------------------------------------------ expansion
def test_grid_is_cartesian_last_axis_fastest():
    sp = load("""
        grid:
          B2: [10, 20, 30]
          K2: [100, 200]
        """)
    assert sp.n_scenes == 6
    got = [(over["B2"], over["K2"]) for _, over in all_inputs(sp)]
    assert got == [(10, 100), (10, 200), (20, 100), (20, 200), (30, 100), (30, 200)]


def test_zip_varies_together_and_crosses_grid():
    sp = load("""
        grid: {drive: [rigid, flexible]}
        zip:
          t_c: [1.0, 1.36, 2.0]
          v: [1.5, 2.0, 3.0]
        """)
    assert sp.n_scenes == 6
    rows = [(o["drive"], o["t_c"], o["v"]) for _, o in all_inputs(sp)]
    assert rows[:3] == [("rigid", 1.0, 1.5), ("rigid", 1.36, 2.0), ("rigid", 2.0, 3.0)]
    assert rows[3] == ("flexible", 1.0, 1.5)


def test_several_zip_groups_are_crossed():
    sp = load("""
        zip:
          - {B2: [1, 2], K2: [10, 20]}
          - {v: [1, 2, 3], t_c: [1, 2, 3]}
        """)
    assert sp.n_scenes == 6
    assert sp.inputs(5)[1] == {"B2": 2, "K2": 20, "v": 3, "t_c": 3}


def test_cases_are_outermost_and_override_params():
    sp = load("""
        params: {m1: 12, drive: flexible}
        grid: {B2: [10, 20]}
        cases:
          - small_far
          - long_near
          - {case: small_far, drive: rigid}
          - {L: 0.3, A: 0.2, dP: 0.1}
        """)
    assert sp.n_scenes == 8
    assert [c for c, _ in all_inputs(sp)] == ["small_far"] * 2 + ["long_near"] * 2 + ["small_far"] * 2 + [None] * 2
    vals = sp.resolve(4)
    assert vals["drive"] == "rigid" and vals["m1"] == 12 and vals["L"] == 0.2 and vals["case"] == "small_far"
    vals = sp.resolve(7)
    assert (vals["L"], vals["A"], vals["dP"], vals["B2"], vals["case"]) == (0.3, 0.2, 0.1, 20, None)


def test_axis_overrides_the_named_case_value():
    sp = load("""
        case: small_far
        grid: {dP: [0.0, 0.3]}
        """)
    assert [sp.resolve(i)["dP"] for i in range(2)] == [0.0, 0.3]
    assert sp.resolve(0)["L"] == 0.2


@pytest.mark.parametrize("form, expected", [
    ("{linspace: [0, 1, 11]}", [k / 10 for k in range(11)]),
    ("{linspace: {start: 10, stop: 30, num: 3}}", [10.0, 20.0, 30.0]),
    ("{logspace: [0.5, 100, 4]}", list(np.geomspace(0.5, 100, 4))),
    ("{range: [0, 1, 0.25]}", [0.0, 0.25, 0.5, 0.75, 1.0]),
    ("{range: [0, 0.9, 0.25]}", [0.0, 0.25, 0.5, 0.75]),
    ("{range: [1, 0.4, -0.3]}", [1.0, 0.7, 0.4]),
    ("{range: {start: 0, stop: 0.3, step: 0.1}}", [0.0, 0.1, 0.2, 0.3]),
    ("[5]", [5]),
])
def test_axis_forms(form, expected):
    sp = load(f"grid: {{B2: {form}}}")
    got = [over["B2"] for _, over in all_inputs(sp)]
    assert got == pytest.approx(expected, rel=1e-11)
    assert len(got) == len(expected)


def test_generated_values_are_clean():
    sp = load("grid: {v: {linspace: [0.1, 1.0, 10]}}")
    assert [o["v"] for _, o in all_inputs(sp)][2] == 0.3  # not 0.30000000000000004
    sp = load("grid: {m2: {logspace: [0.5, 100, 9]}}")
    vals = [o["m2"] for _, o in all_inputs(sp)]
    assert vals[0] == 0.5 and vals[-1] == 100.0


def test_yaml_exponent_without_dot_is_a_number():
    sp = load("params: {k1: 4e6}\ngrid: {B2: {linspace: [0, 1e3, 3]}}")
    assert sp.params["k1"] == 4e6
    assert [o["B2"] for _, o in all_inputs(sp)] == [0.0, 500.0, 1000.0]


def test_psi_fixes_K2_from_B2_and_I2():
    sp = load("""
        params: {Psi: 1.0}
        grid:
          B2: [20, 72, 150]
          m2: [2, 5]
        """)
    for i in range(sp.n_scenes):
        vals = sp.resolve(i)
        assert vals["I2"] == pytest.approx(vals["m2"] * vals["l"] ** 2 / 3)
        assert vals["K2"] == pytest.approx((vals["B2"] / 2) ** 2 / vals["I2"], rel=1e-11)
        assert S.psi_of(vals) == pytest.approx(1.0, rel=1e-11)
    assert "Psi" not in sp.resolve(0)


def test_psi_as_an_axis_and_paper_value():
    sp = load("grid: {Psi: [0.5, 0.973, 2]}")
    vals = [sp.resolve(i) for i in range(3)]
    assert [S.psi_of(v) for v in vals] == pytest.approx([0.5, 0.973, 2.0], rel=1e-11)
    # docs/model.md §3: 72/570 with m2 = 5, l = 1.2 gives Psi = 0.973
    assert S.psi_of(P.resolve("cycle")) == pytest.approx(0.973, abs=5e-4)


def test_single_scene_spec_and_defaults():
    sp = load("scene: freefall")
    assert sp.n_scenes == 1 and sp.scene == "freefall" and sp.invalid == "error"
    assert sp.resolve(0)["m1"] == 15.0


def test_hash_depends_on_values_not_formatting():
    a = load("grid: {B2: {linspace: [0, 20, 3]}}\noutput: a.parquet\ndescription: x")
    b = load("grid:\n  B2: [0, 10.0, 20]\noutput: b.parquet")
    c = load("grid: {B2: [0, 10, 21]}")
    assert a.hash == b.hash
    assert a.hash != c.hash


def test_decode_round_trip():
    sp = load("grid: {B2: [1, 2, 3], K2: [1, 2]}\ncases: [small_far, long_near]")
    assert sp.n_scenes == 12
    assert sp.decode(0) == (0, (0, 0)) and sp.decode(11) == (1, (2, 1)) and sp.decode(7) == (1, (0, 1))
    with pytest.raises(IndexError):
        sp.decode(12)


def test_shipped_sweeps_parse():
    import pathlib

    specs = sorted(pathlib.Path(__file__).parent.parent.joinpath("sweeps").glob("*.yaml"))
    assert {p.stem for p in specs} >= {"b2k2", "tc_v", "placement", "impact_m2", "psi_b2"}
    for p in specs:
        data = yaml.safe_load(p.read_text())
        if "population" in data:  # a risk spec (fencesweep risk), not a grid
            rs = risk_spec.parse(data, p.name, str(p))
            assert rs.elements and rs.operating and rs.output and rs.output.endswith(".parquet")
            continue
        sp = specfile.load(p)
        assert sp.n_scenes >= 1 and sp.output and sp.output.endswith(".parquet")


# ------------------------------------------------------------------ rejection
BAD = [
    ("grdi: {B2: [1]}", ["unknown key 'grdi'", "did you mean 'grid'", "allowed: scene"]),
    ("grid: {B3: [1, 2]}", ["grid.B3", "unknown parameter 'B3'", "did you mean 'B2'"]),
    ("params: {kk1: 3}", ["params.kk1", "did you mean 'k1'"]),
    ("grid: {B2: {linspace: [0, 10, 0]}}", ["grid.B2.linspace", "num = 0", "num must be >= 1"]),
    ("grid: {B2: {linspace: [0, 10, 2.5]}}", ["num = 2.5", "whole number"]),
    ("grid: {B2: {linspace: [0, 10]}}", ["grid.B2.linspace", "expected {linspace: [start, stop, num]}"]),
    ("grid: {B2: {logspace: [0, 10, 3]}}", ["grid.B2.logspace", "start = 0", "both must be > 0"]),
    ("grid: {B2: {range: [10, 0, 1]}}", ["grid.B2.range", "is empty", "stop must be >= start"]),
    ("grid: {B2: {range: [0, 10, 0]}}", ["step = 0", "non-zero"]),
    ("grid: {B2: {linspac: [0, 1, 3]}}", ["unknown axis form 'linspac'", "did you mean 'linspace'"]),
    ("grid: {B2: []}", ["grid.B2 = []", "empty"]),
    ("grid: {B2: 40}", ["grid.B2 = 40 is a single value", "goes under params"]),
    ("grid: {B2: [1, -1]}", ["grid.B2[1]", "B2 = -1", "0 <= B2"]),
    ("grid: {B2: [1, 2, 1]}", ["grid.B2", "appears twice"]),
    ("grid: {drive: [rigid, flexibel]}", ["grid.drive[1]", "'flexibel'", "one of 'flexible', 'rigid', 'free'"]),
    ("grid: {drive: {linspace: [0, 1, 2]}}", ["drive takes one of", "give a list"]),
    ("params: {K2: 300, Psi: 1}", ["K2 (in params.K2) and Psi (in params.Psi)", "set one of them"]),
    ("params: {Psi: 1}\ngrid: {K2: [1, 2]}", ["K2 (in grid.K2) and Psi (in params.Psi)"]),
    ("grid: {Psi: [1]}\ncases: [{K2: 3}]", ["K2 (in cases[0].K2) and Psi (in grid.Psi)"]),
    ("grid: {Psi: [0, 1]}", ["grid.Psi[0]", "0 < Psi"]),
    ("grid: {B2: [1, 2]}\nzip: {B2: [1, 2], K2: [1, 2]}", ["zip.B2", "already varies in grid.B2"]),
    ("params: {B2: 3}\ngrid: {B2: [1, 2]}", ["grid.B2", "also fixed in params"]),
    ("grid: {B2: [1, 2]}\ncases: [{B2: 4}]", ["cases[0].B2", "also varies in grid.B2"]),
    ("zip: {B2: [1, 2, 3], K2: [1, 2]}", ["zip", "same length", "B2: 3, K2: 2"]),
    ("case: small_fra", ["case = 'small_fra'", "did you mean 'small_far'", "small_far, long_near"]),
    ("case: small_far\ncases: [long_near]", ["cases[0].case = 'long_near' conflicts", "top-level case"]),
    ("cases: []", ["cases = []", "non-empty list"]),
    ("cases: [small_far, small_far]", ["cases[1] repeats cases[0]"]),
    ("scene: cylce", ["scene = 'cylce'", "did you mean 'cycle'"]),
    ("params: {B2: [1, 2]}", ["params.B2", "axes go under grid or zip"]),
    ("output: out.csv", ["output = 'out.csv'", ".parquet"]),
    ("invalid: ignore", ["invalid = 'ignore'", "error, skip"]),
    ("chunk_size: 0", ["chunk_size = 0", ">= 1"]),
    ("grid: {B2: [1]}\ngrid: {K2: [2]}", ["key 'grid' appears twice"]),
    ("grid: {B2: [1], B2: [2]}", ["key 'B2' appears twice"]),
    ("grid: [B2, K2]", ["grid = ['B2', 'K2']", "expected a mapping"]),
    ("grid: {B2: [1, 2}", ["not valid YAML"]),
    ("- just a list", ["a spec is a mapping"]),
]


@pytest.mark.parametrize("text, parts", BAD, ids=[t.splitlines()[0][:40] for t, _ in BAD])
def test_bad_spec_is_rejected_with_key_value_and_allowed(text, parts):
    with pytest.raises(S.SpecError) as info:
        specfile.loads(text)
    msg = str(info.value)
    for part in parts:
        assert part in msg, msg
    assert isinstance(info.value, P.ParameterError)  # the CLI prints it and exits 2


def test_spec_error_message_names_the_parameter_for_an_invalid_start():
    from fencesweep.study.sweep import plan as PL

    sp = load("grid: {dP: [0, 0.5, 0.7]}")  # long default load: 0.7 + 0.1 > P_max
    with pytest.raises(S.SpecError) as info:
        PL.make_plan(sp)
    msg = str(info.value)
    assert "scene #2 (dP = 0.7)" in msg and "P_max = 0.7" in msg and "dP must be <= 0.6" in msg


def test_psi_giving_K2_out_of_range_is_reported_up_front():
    from fencesweep.study.sweep import plan as PL

    sp = load("params: {Psi: 0.01}\ngrid: {B2: [10, 1000]}")
    with pytest.raises(S.SpecError) as info:
        PL.make_plan(sp)
    assert "scene #1 (B2 = 1000.0)" in str(info.value) and "Psi = 0.01" in str(info.value)
    assert "K2 must be" in str(info.value)


def test_invalid_skip_drops_bad_starts_and_reports_them():
    from fencesweep.study.sweep import plan as PL

    sp = load("""
        invalid: skip
        grid:
          dP: [0.0, 0.3, 0.6]
          phi0: [0.0, 0.5]
        """)
    plan = PL.make_plan(sp)
    # long load (0.7 x 0.1): at phi0 = 0.5 it spans 0.7 sin 0.5 + 0.1 cos 0.5 = 0.42 in y
    assert plan.skipped == 2 and plan.n_scenes == 6
    assert list(plan.row_model < 0) == [False, False, False, True, False, True]
    assert "phi0 = 0.5" in plan.skipped_examples[0]


def test_cli_reports_spec_errors_with_exit_2(tmp_path, capsys):
    from fencesweep import cli

    bad = tmp_path / "bad.yaml"
    bad.write_text("grid: {B3: [1]}\n")
    assert cli.main(["grid", str(bad), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "grid.B3" in err and "did you mean 'B2'" in err
    assert cli.main(["grid", str(tmp_path / "missing.yaml")]) == 2
    assert "cannot read spec" in capsys.readouterr().err
    ok = tmp_path / "ok.yaml"
    ok.write_text("grid: {B2: [1]}\n")
    assert cli.main(["grid", str(ok), "--backend", "dask"]) == 2
    assert "--scheduler" in capsys.readouterr().err
    assert cli.main(["grid", str(ok), "--jobs", "0"]) == 2
    assert cli.main(["grid", str(ok), "--out", "x.csv"]) == 2
