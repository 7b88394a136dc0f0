"""Python API: `simulate(scene, case, **params) -> dict`.

Orchestration only: checks parameters (params.resolve), prepares the kernel's parameter
vector (prepare.prepare), calls the compiled kernel of the scene and unpacks its results.
"""
from __future__ import annotations

import contextlib
from typing import Any

import numpy as np

from fencesweep import resources
from fencesweep.errors import ParameterError

from fencesweep.model import params as P
from fencesweep.model.results import N_CYCLE_RESULTS, N_IMPACT_RESULTS, unpack


def simulate(scene: str = "cycle", case: str | None = None, **params: Any) -> dict:
    """Simulate one scene; return the results of docs/model.md §11 (cycle), §8 (impact, freefall)
    or §14 (stream).

    Parameters take the names and defaults of docs/model.md §12; `case` ('small_far' or
    'long_near') is applied first and explicit parameters override it. Bad input raises
    ParameterError (a ValueError) naming the parameter, the value and what is allowed.

    `stream` (docs/model.md §14) also takes n_cycles, period [s] (>= t_c, default t_c) and loads:
    None (every cycle has the scene's load) or one load per cycle, a pandas DataFrame with
    columns among L, A, m1, dP, R_s, phi0 (or a list of named cases / mappings); what a row
    does not give is the scene's. It returns the stream's results (results.STREAM_RESULTS)
    and "cycles": a DataFrame with one row per cycle (results.STREAM_CYCLE_RESULTS, times
    from the cycle's start; units in df.attrs["units"]).
    """
    vals = P.resolve(scene, case, **params)
    res, _ = simulate_resolved(vals)
    return res


#: the cycle kernels' compile plan (kernel/share.py)
CYCLE_PLAN = "fencesweep.model.scenes.stream:compile_plan"


def _cycle_compile(vals: dict):
    """Around a cold compile of the cycle kernels for a run on vals: on two cores (kernel/share.py)."""
    from fencesweep.kernel import share

    return share.shared_compile(CYCLE_PLAN, vals)


#: trajectory rows allocated first; a run that needs more is rerun with the count it reported
TRAJECTORY_ROWS = 4096


def simulate_resolved(vals: dict, trajectory: bool = False, p: np.ndarray | None = None):
    """Run an already-resolved parameter set (params.resolve); `p`, its parameter vector if it
    is already prepared (prepare.prepare_columns: a sweep's chunk), else prepared here.

    Returns (results dict, trajectory DataFrame or None). The trajectory (cycle and stream) has
    the columns of scenes.cycle.layout.TRAJ_COLUMNS (units in df.attrs["units"]), one row per
    integrator step and event: time, load pose and velocities, alpha, alpha_w, alpha_dot (the
    fence's rate), fence and rail normal forces, the moment of the load on the fence, the
    stage and the energy integrals (damper, contact damping, drive work, belt work, contact
    friction). A first run on a machine compiles the scene's kernels and says so on stderr
    (kernel/cache.py `compiling`).
    """
    from fencesweep.kernel import cache
    from fencesweep.model.prepare import prepare

    scene = vals["scene"]
    cycles = scene in ("cycle", "stream")
    cold = (lambda: _cycle_compile(vals)) if cycles else contextlib.nullcontext
    with cache.compiling("cycle" if cycles else "impact", cold=cold):
        if p is None:
            p = prepare(vals)
        if scene == "stream":
            return _stream(p, vals, trajectory)
        if scene == "cycle":
            return _cycle(p, vals, trajectory)
        return _impact(p, vals)


def _impact(p: np.ndarray, vals: dict):
    """An impact or a free fall (docs/model.md §8, §7): (results dict, None)."""
    from fencesweep.model.scenes.freefall import freefall
    from fencesweep.model.scenes.impact import impact_kernel

    out = np.empty(N_IMPACT_RESULTS)
    if vals["scene"] == "freefall":
        freefall(p, out)
    else:
        impact_kernel(p, vals["drive"] == "rigid", vals["drive"] == "free", float(vals["w"]), out)
    return unpack(vals["scene"], out), None


def _run_cycles(p: np.ndarray, loads: np.ndarray, period: float, trajectory: bool) -> tuple:
    """The cycles' kernel (scenes/stream.py run_cycles) on `loads`: (per-cycle rows, trajectory
    array or None, the first trajectory row of each cycle). A trajectory buffer found too short
    is grown to the count the run reported and the run repeated."""
    from fencesweep.model.results import N_STREAM_CYCLE_RESULTS
    from fencesweep.model.scenes.cycle.layout import N_TRAJ
    from fencesweep.model.scenes.stream import run_cycles

    n = loads.shape[0]
    out = np.empty((n, N_STREAM_CYCLE_RESULTS))
    starts = np.empty(n + 1, np.int64)
    traj = np.empty((TRAJECTORY_ROWS * n if trajectory else 0, N_TRAJ))
    rows = run_cycles(p, loads, period, out, traj, starts)
    if not trajectory:
        return out, None, starts
    if rows > traj.shape[0]:  # the buffer was too short: run again with the count it needed
        traj = np.empty((rows, N_TRAJ))
        if run_cycles(p, loads, period, out, traj, starts) > traj.shape[0]:  # never silently short
            raise RuntimeError(f"the cycle kernel produced more than the {rows} trajectory rows its first run "
                               f"needed when rerun: it is not deterministic")
    return out, traj[:rows], starts


def _trajectory_frame(traj: np.ndarray, starts: np.ndarray | None):
    """A trajectory array as a DataFrame (with a `cycle` column for a stream's)."""
    import pandas as pd

    from fencesweep.model.scenes.cycle.layout import TRAJ_COLUMNS, TRAJ_UNITS

    df = pd.DataFrame(traj, columns=list(TRAJ_COLUMNS))
    df["stage"] = df["stage"].astype("int8")  # 0 S1, 1 S2, 2 S3, 3 S4, 4 rail, -1 after exit
    units = dict(zip(TRAJ_COLUMNS, TRAJ_UNITS))
    if starts is not None:
        n = len(starts) - 1
        df.insert(0, "cycle", np.repeat(np.arange(n, dtype=np.int64), np.diff(starts)))
        units = {"cycle": "-", **units}
    df.attrs["units"] = units
    return df


def _cycle(p: np.ndarray, vals: dict, trajectory: bool):
    """One work cycle (docs/model.md §8 `cycle`): a stream of one. (results dict, trajectory or None)."""
    from fencesweep.model import layout as Lp

    loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
    out, traj, _ = _run_cycles(p, loads, float(p[Lp.TC]), trajectory)
    res = unpack("cycle", out[0, :N_CYCLE_RESULTS])
    return res, (_trajectory_frame(traj, None) if trajectory else None)


#: bytes per cycle of a stream held at once: the kernel's row and its load, the DataFrame of
#: the cycles and the Python objects on the way (~40 per cycle), with a margin
STREAM_BYTES_PER_CYCLE = 2048


def check_stream_memory(n_cycles: int) -> None:
    """A stream whose per-cycle results would not fit in the memory available is bad input."""
    avail = resources.available_memory()
    if avail is not None and n_cycles * STREAM_BYTES_PER_CYCLE > 0.5 * avail:
        most = int(0.5 * avail // STREAM_BYTES_PER_CYCLE)
        raise ParameterError(f"n_cycles = {n_cycles} is too large for the memory here: its per-cycle results need "
                             f"about {n_cycles * STREAM_BYTES_PER_CYCLE / 2**30:.1f} GiB, over half the "
                             f"{avail / 2**30:.1f} GiB available; n_cycles must be <= {most}")


def _stream(p: np.ndarray, vals: dict, trajectory: bool):
    """A stream (docs/model.md §14): (results dict with "cycles", trajectory DataFrame or None); the
    trajectory has the columns of a cycle's plus `cycle`, t from the stream's start."""
    from fencesweep.model.prepare import load_table
    from fencesweep.model.results import stream_results

    check_stream_memory(int(vals["n_cycles"]))
    period = float(vals["period"])
    out, traj, starts = _run_cycles(p, load_table(vals), period, trajectory)
    res = stream_results(out, period)
    return res, (_trajectory_frame(traj, starts) if trajectory else None)
