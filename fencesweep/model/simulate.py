"""Python API: `simulate(scene, case, **params) -> dict`.

Orchestration only: checks parameters (params.resolve), prepares the kernel's parameter
vector (setup.prepare), calls the compiled kernel of the scene and unpacks its results.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from fencesweep import resources
from fencesweep.errors import ParameterError

from fencesweep.model import params as P
from fencesweep.model.results import N_CYCLE_RESULTS, N_IMPACT_RESULTS, unpack


def simulate(scene: str = "cycle", case: str | None = None, **params: Any) -> dict:
    """Simulate one scene; return the results of MODEL.md §11 (cycle), §8 (impact, freefall)
    or §14 (stream).

    Parameters take the names and defaults of MODEL.md §12; `case` ('small_far' or
    'long_near') is applied first and explicit parameters override it. Bad input raises
    ParameterError (a ValueError) naming the parameter, the value and what is allowed.

    `stream` (MODEL.md §14) also takes n_cycles, period [s] (>= t_c, default t_c) and loads:
    None (every cycle has the scene's load) or one load per cycle, a pandas DataFrame with
    columns among L, A, m1, dP, R_s, phi0 (or a list of named cases / mappings); what a row
    does not give is the scene's. It returns the stream's results (results.STREAM_RESULTS)
    and "cycles": a DataFrame with one row per cycle (results.STREAM_CYCLE_RESULTS, times
    from the cycle's start; units in df.attrs["units"]).
    """
    vals = P.resolve(scene, case, **params)
    res, _ = simulate_resolved(vals)
    return res


#: trajectory rows allocated first; a run that needs more is rerun with the count it reported
TRAJECTORY_ROWS = 4096


def simulate_resolved(vals: dict, trajectory: bool = False):
    """Run an already-resolved parameter set (params.resolve).

    Returns (results dict, trajectory DataFrame or None). The trajectory (cycle only) has
    the columns of scenes.cycle.TRAJ_COLUMNS (units in df.attrs["units"]), one row per
    integrator step and event: time, load pose and velocities, alpha, alpha_w, alpha_dot (the
    fence's rate), fence and rail normal forces, the moment of the load on the fence, the
    stage and the energy integrals (damper, contact damping, drive work, belt work, contact
    friction).
    """
    from fencesweep.model.prepare import prepare, run_freefall

    p = prepare(vals)
    scene = vals["scene"]
    if scene == "stream":
        return _stream(p, vals, trajectory)
    if scene == "cycle":
        from fencesweep.model.scenes.cycle import TRAJ_COLUMNS, TRAJ_UNITS
        from fencesweep.model.scenes.stream import cycle_kernel

        out = np.empty(N_CYCLE_RESULTS)
        traj = np.empty((TRAJECTORY_ROWS if trajectory else 0, len(TRAJ_COLUMNS)))
        rows = cycle_kernel(p, out, traj)
        res = unpack("cycle", out)
        if not trajectory:
            return res, None
        if rows > traj.shape[0]:  # the buffer was too short: run again with the count it needed
            traj = np.empty((rows, len(TRAJ_COLUMNS)))
            rows = cycle_kernel(p, out, traj)
            if rows > traj.shape[0]:  # a trajectory is never silently short
                raise RuntimeError(f"the cycle kernel produced {rows} trajectory rows when rerun with the "
                                   f"{traj.shape[0]} its first run needed: it is not deterministic")
        import pandas as pd

        df = pd.DataFrame(traj[:rows], columns=list(TRAJ_COLUMNS))
        df["stage"] = df["stage"].astype("int8")  # 0 S1, 1 S2, 2 S3, 3 S4, 4 rail, -1 after exit
        df.attrs["units"] = dict(zip(TRAJ_COLUMNS, TRAJ_UNITS))
        return res, df
    from fencesweep.model.scenes.impact import impact_kernel

    out = np.empty(N_IMPACT_RESULTS)
    if scene == "freefall":
        run_freefall(p, out)
    else:
        impact_kernel(p, vals["drive"] == "rigid", vals["drive"] == "free", vals["w"], out)
    return unpack(scene, out), None


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
    """A stream (MODEL.md §14): (results dict with "cycles", trajectory DataFrame or None); the
    trajectory has the columns of a cycle's plus `cycle`, t from the stream's start."""
    from fencesweep.model.results import N_STREAM_CYCLE_RESULTS, stream_results
    from fencesweep.model.scenes.cycle import TRAJ_COLUMNS, TRAJ_UNITS
    from fencesweep.model.scenes.stream import stream_kernel
    from fencesweep.model.prepare import load_table

    n = int(vals["n_cycles"])
    check_stream_memory(n)
    loads = load_table(vals)
    out = np.empty((n, N_STREAM_CYCLE_RESULTS))
    starts = np.empty(n + 1, np.int64)
    traj = np.empty((TRAJECTORY_ROWS * n if trajectory else 0, len(TRAJ_COLUMNS)))
    rows = stream_kernel(p, loads, float(vals["period"]), out, traj, starts)
    res = stream_results(out, float(vals["period"]))
    if not trajectory:
        return res, None
    if rows > traj.shape[0]:  # the buffer was too short: run again with the count it needed
        traj = np.empty((rows, len(TRAJ_COLUMNS)))
        if stream_kernel(p, loads, float(vals["period"]), out, traj, starts) > traj.shape[0]:
            raise RuntimeError("the stream kernel produced more trajectory rows when rerun: it is not deterministic")
    import pandas as pd

    df = pd.DataFrame(traj[:rows], columns=list(TRAJ_COLUMNS))
    df["stage"] = df["stage"].astype("int8")
    df.insert(0, "cycle", np.repeat(np.arange(n, dtype=np.int64), np.diff(starts)))
    df.attrs["units"] = dict(zip(("cycle",) + TRAJ_COLUMNS, ("-",) + TRAJ_UNITS))
    return res, df
