"""The damping coefficient of the contact law solved from the restitution e (docs/model.md §4).

In the dimensionless rigid-wall impact x'' = -max(x^1.5 + q x^0.25 x', 0) (hertz) or
x'' = -max(x + beta x', 0) (linear), x(0) = 0, x'(0) = 1, the rebound speed at the first
return of the force to 0 is e(q), independent of speed, mass and stiffness; q(e) is its
inverse, found by Brent's method. The impact scene's compiled kernel integrates it.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from fencesweep.model import layout as Lp
from fencesweep.kernel.cache import solved

#: tolerance of the calibration's impacts: e(q) to ~1e-10, far below the 2e-4 of docs/model.md §4
CALIBRATION_TOL = 1e-12


def restitution(c: float, law: str) -> float:
    """e of the dimensionless rigid-wall impact with damping c (module docstring; docs/model.md (4.5),
    (4.6), (4.7))."""
    from fencesweep.model.results import N_IMPACT_RESULTS, RJ_E_EFF
    from fencesweep.model.scenes.impact import impact_kernel

    p = np.zeros(Lp.N_P)
    p[Lp.LAW] = Lp.LAW_HERTZ if law == "hertz" else Lp.LAW_LINEAR
    p[Lp.M1] = p[Lp.KC] = p[Lp.R] = p[Lp.I2] = 1.0  # unit mass, stiffness, speed (R, I2 unused)
    p[Lp.CD] = c
    p[Lp.LL] = p[Lp.AA] = np.inf
    p[Lp.TOL] = CALIBRATION_TOL
    out = np.empty(N_IMPACT_RESULTS)
    impact_kernel(p, True, False, 1.0, out)
    return float(out[RJ_E_EFF])


@lru_cache(maxsize=None)
def damping_coefficient(e: float, law: str = "hertz") -> float:
    """Dimensionless damping q (hertz) or beta (linear) that gives restitution e (docs/model.md §4);
    b_lin = beta sqrt(m1 k_lin), q enters as q sqrt(m1 k1). Solved once per (e, law) and kept
    beside the compiled kernels (_cache.solved)."""
    return solved("damping_coefficient", (float(e), law), lambda: solve_damping_coefficient(float(e), law))


def solve_damping_coefficient(e: float, law: str) -> float:
    """damping_coefficient by Brent's method on e(q) (decreasing; docs/model.md (4.8))."""
    from scipy.optimize import brentq

    if e >= 1.0:
        return 0.0
    hi = 1.0
    while restitution(hi, law) > e:
        hi *= 2.0
        if hi > 1e4:
            raise ValueError(f"e = {e!r} is too small to calibrate the damping")
    return brentq(lambda c: restitution(c, law) - e, 0.0, hi, xtol=1e-12, rtol=1e-12)
