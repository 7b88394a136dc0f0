"""Python API: `simulate(scene, case, **params) -> dict`.

Orchestration only: checks parameters (params.resolve), prepares the kernel's parameter
vector (setup.prepare), calls the compiled kernel of the scene and unpacks its results.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import params as P
from .results import N_CYCLE_RESULTS, N_IMPACT_RESULTS, unpack


def simulate(scene: str = "cycle", case: str | None = None, **params: Any) -> dict:
    """Simulate one scene; return the results of MODEL.md §11 (cycle) or §8 (impact, freefall).

    Parameters take the names and defaults of MODEL.md §12; `case` ('small_far' or
    'long_near') is applied first and explicit parameters override it. Bad input raises
    ParameterError (a ValueError) naming the parameter, the value and what is allowed.
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
    from .setup import prepare, run_freefall

    p = prepare(vals)
    scene = vals["scene"]
    if scene == "cycle":
        from .scenes.cycle import TRAJ_COLUMNS, TRAJ_UNITS
        from .scenes.stream import cycle_kernel

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
    from .scenes.impact import impact_kernel

    out = np.empty(N_IMPACT_RESULTS)
    if scene == "freefall":
        run_freefall(p, out)
    else:
        impact_kernel(p, vals["drive"] == "rigid", vals["drive"] == "free", vals["w"], out)
    return unpack(scene, out), None
