"""Bad input gets a clear error naming the parameter, the value and what is allowed."""
import math

import pytest

from fencesweep import ParameterError, resolve, simulate
from fencesweep.model.params import CASES, TABLE, model_key, parse_value


def test_defaults_follow_model_table():
    v = resolve()
    assert v["v"] == 2.0 and v["P_max"] == 0.7 and v["m1"] == 15.0 and v["B2"] == 72.0
    assert v["K2"] == 570.0 and v["t_c"] == 1.36 and v["drive"] == "flexible"
    assert v["swing"] == pytest.approx(0.7330, abs=1e-4) and v["dalpha_perm"] == pytest.approx(0.2618, abs=1e-4)
    assert v["I2"] == pytest.approx(5.0 * 1.2**2 / 3) and v["t_max"] == pytest.approx(2.36)


def test_case_then_explicit_override():
    v = resolve("cycle", "small_far", L=0.25)
    assert (v["L"], v["A"], v["dP"]) == (0.25, 0.1, 0.6)
    assert set(CASES) == {"small_far", "long_near"}


def test_unknown_name_suggests_the_nearest():
    with pytest.raises(ParameterError, match=r"unknown parameter 'B3'.*did you mean 'B2'"):
        simulate(B3=10)


@pytest.mark.parametrize("name, value, pattern", [
    ("m1", -1.0, r"m1 = -1\.0 is out of range: m1 must be a number with 0 < m1"),
    ("e", 0.0, r"e = 0\.0 is out of range"),
    ("v", "fast", r"v = 'fast' \(str\) is not allowed: v must be a number"),
    ("drive", "stiff", r"drive = 'stiff' is not allowed: drive must be one of 'flexible', 'rigid', 'free'"),
    ("B2", math.nan, r"B2 = nan is not allowed"),
    ("K2", True, r"K2 = True \(bool\) is not allowed"),
])
def test_bad_values_rejected_with_name_value_and_allowed(name, value, pattern):
    with pytest.raises(ParameterError, match=pattern):
        simulate(**{name: value})


def test_invalid_start_rejected():
    with pytest.raises(ParameterError, match=r"dP = 0\.65 is not allowed.*P_max = 0\.7.*dP must be <= 0\.6"):
        resolve(dP=0.65, A=0.1)
    with pytest.raises(ParameterError, match=r"R_s = 1\.3 is not allowed.*R_s must be < l = 1\.2"):
        resolve(R_s=1.3)
    with pytest.raises(ParameterError, match=r"phi0"):
        resolve(phi0=0.5, dP=0.55)  # a tilted long load sticks out over the far edge


def test_bad_scene_case_and_coupler():
    with pytest.raises(ParameterError, match="scene = 'cycles'"):
        resolve("cycles")
    with pytest.raises(ParameterError, match="case = 'far'"):
        resolve("cycle", "far")
    with pytest.raises(ParameterError, match=r"coupler_ratio = 0\.2 .*sin\(swing/2\)"):
        resolve(coupler_ratio=0.2)


def test_parse_value_from_text():
    assert parse_value("B2", "40") == 40.0
    assert parse_value("drive", "rigid") == "rigid"
    assert parse_value("I2", "none") is None
    with pytest.raises(ParameterError, match="B2 = 'abc' is not a number"):
        parse_value("B2", "abc")


def test_every_parameter_has_unit_and_doc():
    for p in TABLE:
        assert p.unit and p.doc


def test_model_key_ignores_what_the_model_does_not_use():
    # (m2 and the load's size are read after all: tests/test_model_key.py)
    a = model_key(resolve(drive="rigid", B2=10.0, K2=20.0))
    b = model_key(resolve(drive="rigid", B2=99.0, K2=1.0))
    assert a == b
    assert model_key(resolve(B2=10.0)) != model_key(resolve(B2=11.0))
    assert model_key(resolve("freefall", v=1.0, l=0.9)) == model_key(resolve("freefall", v=3.0, l=1.5))
