"""The Python API around the kernels: the trajectory buffer is grown, never cut short."""
import numpy as np
import pandas as pd
import pytest

from fencesweep.model import simulate as api
from fencesweep import resolve
from fencesweep.model.scenes import stream
from fencesweep.model.scenes.cycle import layout

pytestmark = pytest.mark.plain_python  # also run without Numba's JIT: tests/test_plain_python.py


def _cycle_args(case):
    """run_cycles' arguments for one cycle of a named case (as model/simulate.py passes them)."""
    from fencesweep.model import layout as Lp
    from fencesweep.model.prepare import prepare
    from fencesweep.model.results import N_STREAM_CYCLE_RESULTS

    p = prepare(resolve("cycle", case))
    loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
    return p, loads, float(p[Lp.TC]), np.empty((1, N_STREAM_CYCLE_RESULTS)), np.empty(2, np.int64)


def test_kernel_reports_the_rows_a_short_buffer_could_not_hold():
    p, loads, period, out, starts = _cycle_args("small_far")
    full = np.empty((100_000, len(layout.TRAJ_COLUMNS)))
    needed = stream.run_cycles(p, loads, period, out, full, starts)
    short = np.full((8, len(layout.TRAJ_COLUMNS)), -7.0)
    assert needed > 8
    assert stream.run_cycles(p, loads, period, out, short, starts) == needed  # counts past the capacity ...
    np.testing.assert_array_equal(short, full[:8])  # ... and fills what fits


def test_short_trajectory_buffer_is_grown_not_cut(monkeypatch):
    vals = resolve("cycle", "long_near")
    monkeypatch.setattr(api, "TRAJECTORY_ROWS", 100_000)
    res_big, big = api.simulate_resolved(vals, trajectory=True)
    monkeypatch.setattr(api, "TRAJECTORY_ROWS", 8)
    res, traj = api.simulate_resolved(vals, trajectory=True)
    assert len(big) > 8 and len(traj) == len(big)
    pd.testing.assert_frame_equal(traj, big)
    assert res == res_big  # long_near touches the fence: no NaN among its results
    assert traj.t.iloc[-1] >= min(res["t_exit"], vals["t_c"])  # the series reaches the end of the run


def test_a_kernel_that_needs_more_rows_on_its_rerun_is_an_error(monkeypatch):
    real = stream.run_cycles
    calls = []

    def growing(p, loads, period, out, traj, starts):  # a kernel whose second run needs more rows than its first
        calls.append(traj.shape[0])
        return real(p, loads, period, out, traj, starts) + len(calls)

    monkeypatch.setattr(stream, "run_cycles", growing)
    monkeypatch.setattr(api, "TRAJECTORY_ROWS", 8)
    with pytest.raises(RuntimeError, match="not deterministic"):
        api.simulate_resolved(resolve("cycle", "small_far"), trajectory=True)
    assert len(calls) == 2


@pytest.mark.parametrize("case, drive", [("small_far", "flexible"), ("long_near", "rigid")])
def test_trajectory_holds_the_located_maxima(case, drive):
    """The trajectory has a row at each maximum located inside a step (cycle.record_peaks), so
    its largest force, deflection and alpha are the results', not the samples around them;
    the rows stay in time order and the results do not depend on whether it is recorded."""
    vals = resolve("cycle", case, drive=drive)
    res, traj = api.simulate_resolved(vals, trajectory=True)
    alone, _ = api.simulate_resolved(vals)
    assert res == pytest.approx(alone, nan_ok=True)
    assert np.all(np.diff(traj["t"]) > 0.0)
    assert traj["N_fence"].max() == pytest.approx(res["peak_force"], rel=1e-12)
    assert traj["N_rail"].max() == pytest.approx(res["peak_rail_force"], rel=1e-12, abs=1e-9)
    assert (traj["alpha"] - traj["alpha_w"]).abs().max() == pytest.approx(res["deflection_max"], rel=1e-12, abs=1e-15)
    assert traj["alpha"].max() == pytest.approx(res["alpha_max"], rel=1e-12)
    assert len(traj) > res["n_steps"]  # the peak rows come on top of one row per step
