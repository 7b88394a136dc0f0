"""Scene `stream` (docs/model.md §14): work cycles back to back, the fence's state carried over.

The reductions of §14: a stream of one is a `cycle`, bit for bit; a period long enough for
the element to settle makes every cycle the first; a lightly damped element at T = t_c starts
later cycles swinging. Then the outcome `jammed`, the fence's continuity across cycles, and
bad input.
"""
import math

import numpy as np
import pandas as pd
import pytest

from fencesweep import ParameterError, resolve, simulate
from fencesweep.kernel import numerics as NU
from fencesweep.model import simulate as api
from fencesweep.model.results import CYCLE_RESULTS, STREAM_CYCLE_RESULTS, STREAM_RESULTS

#: results that count the integrator's work, not the physics (a stream's cycle also steps its rest)
WORK = {"n_steps", "n_rejected", "error_estimate"}


def same_value(a, b) -> bool:
    return a == b or (isinstance(a, float) and math.isnan(a) and math.isnan(b))


def settling_time(vals: dict) -> float:
    """docs/model.md §14: tau, the element's slowest decay time (2 I2 / B2 when Psi <= 1, else 1 / lambda_slow)."""
    B2, K2, I2 = vals["B2"], vals["K2"], vals["I2"]
    if B2 * B2 <= 4 * K2 * I2:
        return 2 * I2 / B2
    return 2 * I2 / (B2 - math.sqrt(B2 * B2 - 4 * K2 * I2))


@pytest.mark.plain_python  # also run without Numba's JIT: tests/test_plain_python.py
def test_a_stream_of_one_is_the_cycle_bit_for_bit():
    vals = resolve("stream", "long_near")
    res, traj = api.simulate_resolved(vals, trajectory=True)
    ref, ref_traj = api.simulate_resolved(resolve("cycle", "long_near"), trajectory=True)
    row = res["cycles"].iloc[0]
    for name, _, _ in CYCLE_RESULTS:
        assert same_value(row[name], ref[name]), name
    assert (row.start_deflection, row.start_rate, row.start_amplitude) == (0.0, 0.0, 0.0)
    pd.testing.assert_frame_equal(traj.drop(columns="cycle"), ref_traj, check_exact=True)
    assert res["n_cycles"] == 1 and res["first_failure"] == (-1 if ref["outcome"] == "scraped" else 0)


@pytest.mark.parametrize("case, drive", [("small_far", "flexible"), ("small_far", "rigid"), ("long_near", "rigid")])
def test_a_stream_of_one_is_the_cycle_for_each_drive(case, drive):
    row = simulate("stream", case, drive=drive, n_cycles=1)["cycles"].iloc[0]
    ref = simulate("cycle", case, drive=drive)
    for name, _, _ in CYCLE_RESULTS:
        assert same_value(row[name], ref[name]), name


@pytest.mark.parametrize("B2, K2", [(72.0, 570.0), (150.0, 300.0)])  # Psi 0.97 and 2.8 (> 1: lambda_slow)
def test_a_settled_element_makes_every_cycle_the_first(B2, K2):
    vals = resolve("stream", "small_far", B2=B2, K2=K2)
    period = vals["t_c"] + 20 * settling_time(vals)
    cycles = simulate("stream", "small_far", B2=B2, K2=K2, n_cycles=3, period=period)["cycles"]
    first = cycles.iloc[0]
    for k in (1, 2):
        row = cycles.iloc[k]
        for name, _, _ in STREAM_CYCLE_RESULTS:
            if name in WORK or isinstance(first[name], str) or name.startswith("t_S") or name == "t_rail":
                continue
            # within 10 x the step's tolerance TOL: the start differs from the first cycle's by the
            # settled remainder, which can change the step sequence (on one 2-core machine with
            # AVX-512: contact_energy 1.8e-6 apart)
            assert row[name] == pytest.approx(first[name], rel=10 * NU.TOL, abs=1e-6, nan_ok=True), (k, name)
        assert row.outcome == first.outcome == "scraped"
        assert abs(row.start_amplitude) < 1e-6


def test_a_lightly_damped_element_at_the_cycle_time_starts_later_cycles_swinging():
    light = simulate("stream", "small_far", B2=5.0, n_cycles=3)["cycles"]  # Psi = 0.07
    paper = simulate("stream", "small_far", n_cycles=3)["cycles"]  # Psi = 0.97
    assert light.start_amplitude[0] == 0.0
    assert (light.start_amplitude[1:] > 0.1).all()  # ~7 deg of swing left at each start
    assert (light.start_amplitude[1:] > 3 * paper.start_amplitude[1:]).all()
    # T = t_c: a cycle starts with the state its predecessor ended with
    np.testing.assert_allclose(light.start_amplitude[1:], light.residual_amplitude[:-1], rtol=1e-12)
    np.testing.assert_allclose(np.abs(light.start_deflection[1:]), light.residual_deflection[:-1], rtol=1e-12)


@pytest.mark.plain_python
def test_a_load_still_on_the_belt_at_the_next_start_is_jammed():
    # 3 m upstream at 2 m/s: the load reaches the pivot after 1.5 s > T = t_c = 1.36 s
    res = simulate("stream", "small_far", R_s=-3.0, n_cycles=2)
    c = res["cycles"]
    assert c.outcome[0] == "jammed" and c.t_exit[0] == res["cycles"].t_exit[0] == 1.36
    assert c.x_exit[0] == pytest.approx(-3.0 - 0.1 + 2.0 * 1.36, abs=1e-9)  # rode the belt to T
    assert c.outcome[1] == "escaped"  # the last cycle has no next start: it ends as a cycle does
    assert res["first_failure"] == 0 and res["n_scraped"] == 0


@pytest.mark.plain_python
def test_a_timeout_before_the_next_start_is_a_timeout_and_the_fence_rests_to_it():
    res, traj = api.simulate_resolved(resolve("stream", "small_far", R_s=-3.0, t_max=1.5, period=2.0, n_cycles=2),
                                      trajectory=True)
    c = res["cycles"]
    assert list(c.outcome) == ["timeout", "timeout"] and list(c.t_exit) == [1.5, 1.5]
    first = traj[traj.cycle == 0]
    assert first.t.iloc[-1] == 2.0 and first.t.iloc[0] == 0.0  # the rest reaches the next start
    assert traj[traj.cycle == 1].t.iloc[0] == 2.0
    assert (np.diff(traj.t) >= 0).all()


def test_the_fence_carries_over_and_the_trajectory_is_one_series():
    res, traj = api.simulate_resolved(resolve("stream", loads=["small_far", "long_near", "small_far"],
                                              period=1.6, B2=20.0), trajectory=True)
    assert list(traj.cycle.unique()) == [0, 1, 2]
    assert (np.diff(traj.t) >= 0).all() and traj.t.iloc[-1] >= 2 * 1.6 + 1.36
    for k in (1, 2):
        end, start = traj[traj.cycle == k - 1].iloc[-1], traj[traj.cycle == k].iloc[0]
        assert end.t == start.t == k * 1.6
        assert (end.alpha, end.alpha_dot) == (start.alpha, start.alpha_dot)  # nothing is reset (§14)
        assert res["cycles"].start_deflection[k] == start.alpha - start.alpha_w
    assert res["throughput"] == 3600 / 1.6
    assert set(res) == {n for n, _, _ in STREAM_RESULTS} | {"cycles"}
    assert res["cycles"].attrs["units"]["start_rate"] == "rad/s"


def test_each_cycle_has_its_own_load():
    loads = pd.DataFrame({"L": [0.2, 0.7], "dP": [0.6, 0.0]})  # small_far, long_near
    vals = resolve("stream", loads=loads, period=1.36 + 2.0)
    cycles = simulate("stream", loads=loads, period=1.36 + 2.0)["cycles"]
    assert vals["n_cycles"] == 2
    for k, case in enumerate(("small_far", "long_near")):
        ref = simulate("cycle", case)
        assert cycles.overload[k] == pytest.approx(ref["overload"], rel=1e-6)
        assert cycles.x_exit[k] == pytest.approx(ref["x_exit"], rel=1e-6)


@pytest.mark.parametrize("kwargs, words", [
    (dict(period=1.0), ["period = 1.0", "period must be >= t_c = 1.36"]),
    (dict(n_cycles=0), ["n_cycles = 0", "1 <= n_cycles"]),
    (dict(n_cycles=2.5), ["n_cycles = 2.5", "an integer"]),
    (dict(drive="free"), ["drive = 'free'", "'flexible' or 'rigid'"]),
    (dict(loads=pd.DataFrame({"L": [0.2], "mass": [3.0]})), ["unknown column 'mass'", "L, A, m1, dP, R_s, phi0"]),
    (dict(loads=["small_far", "long_near"], n_cycles=3), ["loads has 2 rows and n_cycles = 3", "one load per cycle"]),
    (dict(loads=["small_far", "far_small"]), ["loads[1].case = 'far_small'", "small_far, long_near"]),
    (dict(loads=[{"dP": 0.65}]), ["loads[0]: dP = 0.65", "dP must be <= 0.6"]),
    (dict(loads=[]), ["loads = []", "one load per cycle"]),
])
def test_bad_stream_input_is_refused_naming_the_value_and_what_is_allowed(kwargs, words):
    with pytest.raises(ParameterError) as err:
        simulate("stream", "small_far", **kwargs)
    for w in words:
        assert w in str(err.value)


def test_loads_belong_to_the_stream_only():
    with pytest.raises(ParameterError, match="scene 'stream' only"):
        resolve("cycle", loads=["small_far"])


def test_a_stream_too_large_for_the_memory_is_refused(monkeypatch):
    monkeypatch.setattr("fencesweep.resources.available_memory", lambda: 2**30)  # 1 GiB
    with pytest.raises(ParameterError, match=r"n_cycles = 1000000 is too large .* n_cycles must be <= 262144"):
        simulate("stream", n_cycles=1_000_000)
    with pytest.raises(ParameterError, match="n_cycles = 2000000 is out of range"):
        simulate("stream", n_cycles=2_000_000)


@pytest.mark.plain_python
def test_a_failed_cycle_stops_the_stream():
    res = simulate("stream", "small_far", k1=3e3, n_cycles=3)  # too soft: the penetration bound (§5)
    c = res["cycles"]
    assert list(c.outcome) == ["failed"] * 3 and c.status[0].startswith("failed: penetration")
    assert list(c.status[1:]) == ["failed: not run, an earlier cycle of the stream failed"] * 2
    assert res["first_failure"] == 0 and math.isnan(c.overload[2])


# ---------------------------------------------------------------- sweeps and the command line

STREAM_SPEC = """
scene: stream
loads: [small_far, long_near]
grid:
  period: [1.36, 2.0]
"""


def test_a_stream_sweep_writes_one_row_per_cycle_with_its_stream_results(tmp_path):
    from fencesweep.study.spec import file as specfile
    from fencesweep.study.store import table as store
    from fencesweep.study.sweep import pipeline as sweep

    sweep.run_sweep(specfile.loads(STREAM_SPEC), tmp_path / "s.parquet", jobs=1, progress=False)
    df = store.read_table(tmp_path / "s.parquet")
    assert list(df.cycle) == [0, 1, 0, 1] and list(df.period) == [1.36, 1.36, 2.0, 2.0]
    assert df.attrs["units"]["start_amplitude"] == "rad" and df.attrs["units"]["throughput"] == "1/h"
    for period, rows in df.groupby("period"):
        ref = simulate("stream", loads=["small_far", "long_near"], period=period)
        for name, _, _ in STREAM_CYCLE_RESULTS:
            assert [same_value(a, b) for a, b in zip(rows[name], ref["cycles"][name])] == [True, True], name
        for name, _, _ in STREAM_RESULTS:
            if name != "n_cycles":
                assert (rows[name] == ref[name]).all(), name
    streams = df[df.cycle == 0]  # the stream level: one row per stream (sweeps/README.md)
    assert list(streams.throughput) == [3600 / 1.36, 3600 / 2.0]


@pytest.mark.parametrize("text, words", [
    ("scene: cycle\nloads: [small_far]\n", ["loads is given with scene = 'cycle'", "scene: stream only"]),
    ("scene: stream\nloads: [small_far, {mass: 3}]\n", ["loads[1] has the unknown key 'mass'", "L, A, m1"]),
    ("scene: stream\nloads: small_far\n", ["loads = 'small_far'", "non-empty list"]),
])
def test_a_bad_loads_list_in_a_spec_is_refused(text, words):
    from fencesweep.study.spec import spec as S
    from fencesweep.study.spec import file as specfile

    with pytest.raises(S.SpecError) as err:
        specfile.loads(text)
    for w in words:
        assert w in str(err.value)


def test_cli_prints_the_cycles_and_the_summary_and_writes_the_whole_series(tmp_path, capsys):
    import json

    from fencesweep import cli
    from fencesweep.study.store.table import read_trajectory

    path = tmp_path / "t.parquet"
    assert cli.main(["run", "--scene", "stream", "--loads", "small_far,long_near", "--set", "period=2",
                     "--trajectory", str(path)]) == 0
    text = capsys.readouterr().out
    assert "worst_start_amplitude" in text and "throughput" in text and "1800 1/h" in text
    assert "start_amplitude [rad]" in text and len([ln for ln in text.splitlines() if " scraped " in ln]) == 2
    traj = read_trajectory(path)
    assert list(traj.cycle.unique()) == [0, 1] and traj.t.iloc[-1] > 2.0 and traj.attrs["results"]["n_cycles"] == 2
    assert cli.main(["run", "--scene", "stream", "--case", "small_far", "--set", "n_cycles=2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_cycles"] == 2 and len(out["cycles"]) == 2 and out["cycles"][1]["start_amplitude"] > 0
    assert cli.main(["run", "--scene", "stream", "--set", "drive=free"]) == 2
    assert "drive = 'free' is not allowed" in capsys.readouterr().err


def test_the_shortest_safe_period_is_the_one_from_which_every_longer_period_is_safe():
    from fencesweep.report.stream_text import shortest_safe_period

    g = pd.DataFrame({"period": [1.0, 1.1, 1.2, 1.3], "ok": [True, False, True, True]})
    assert shortest_safe_period(g) == 1.2
    assert shortest_safe_period(g.assign(ok=True)) == 1.0
    assert math.isnan(shortest_safe_period(g.assign(ok=[True, True, True, False])))
