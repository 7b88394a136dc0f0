"""The damping coefficient of the contact law solved from the restitution e (docs/model.md §4).

In the dimensionless rigid-wall impact x'' = -max(x^1.5 + q x^0.25 x', 0) (hertz) or
x'' = -max(x + beta x', 0) (linear), x(0) = 0, x'(0) = 1, the rebound speed at the first
return of the force to 0 is e(q), independent of speed, mass and stiffness; q(e) is its
inverse, found by Brent's method.

The impact is integrated by SciPy (DOP853, with the force's return to zero as a terminal
event) on the law's own formula (contact.kelvin_force, called as plain Python), not by the
compiled impact scene: a first cycle then compiles only the cycle's kernels (the impact
scene's took ~5 s of a cold first run, results/startup.md). The calibration costs ~1 s once
per (e, law) and is kept beside the compiled kernels (kernel/cache.py solved);
tests/test_contact.py checks that the impact scene, run at the solved q, rebounds at e.
The same impact gives the free fall's peak force in its own units (peak_force_factor,
docs/model.md (7.7)), so the overload's reference needs no compiled code either.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from fencesweep.kernel.cache import solved
from fencesweep.model import layout as Lp
from fencesweep.model.contact import kelvin_force

#: tolerance of the calibration's impacts: e(q) to ~1e-10, far below the 2e-4 of docs/model.md §4
CALIBRATION_TOL = 1e-12


def wall_impact(c: float, law: str):
    """The dimensionless rigid-wall impact (docs/model.md (4.5), (4.6)) with damping c, integrated
    until the unclipped force returns to zero (4.7): SciPy's solution, with its dense output, and
    the dimensionless force as a function of the state."""
    from scipy.integrate import solve_ivp

    code = Lp.LAW_HERTZ if law == "hertz" else Lp.LAW_LINEAR
    law_force = getattr(kelvin_force, "py_func", kelvin_force)  # plain Python (module docstring)

    def force(x, xd):
        return law_force(max(x, 0.0), xd, 1.0, c, code)[0]

    def rhs(_t, y):
        return (y[1], -force(y[0], y[1]))

    def released(_t, y):
        return force(y[0], y[1])

    released.terminal, released.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 1e3), (0.0, 1.0), method="DOP853", rtol=CALIBRATION_TOL,
                    atol=CALIBRATION_TOL, events=released, first_step=1e-6, dense_output=True)
    if not sol.t_events[0].size:
        raise ValueError(f"the calibration impact with damping {c!r} did not end")
    return sol, force


def restitution(c: float, law: str) -> float:
    """e of the dimensionless rigid-wall impact with damping c (module docstring; docs/model.md
    (4.5), (4.6), (4.7)): minus the rate at the force's return to zero."""
    sol, _ = wall_impact(c, law)
    return float(-sol.y_events[0][0][1])


def peak_force_factor(e: float, law: str = "hertz") -> float:
    """n(e), the free fall's peak force in units of the wall impact's force scale (docs/model.md
    (7.7)):
    the largest dimensionless force of (4.5) or (4.6) at the damping solved from e. Depends on
    (e, law) only; solved once and kept like the damping coefficient."""
    return solved("peak_force_factor", (float(e), law), lambda: solve_peak_force_factor(float(e), law))


def solve_peak_force_factor(e: float, law: str) -> float:
    """peak_force_factor: the dense output sampled over the impact, its largest sample refined
    by a bounded scalar search (the force is smooth inside the impact), and the force at the
    first instant (the linear law jumps to beta there)."""
    from scipy.optimize import minimize_scalar

    sol, force = wall_impact(damping_coefficient(e, law), law)
    t_end = float(sol.t_events[0][0])

    def at(tau):
        x, xd = sol.sol(tau)
        return force(x, xd)

    grid = np.linspace(0.0, t_end, 401)
    values = [at(tau) for tau in grid]
    k = int(np.argmax(values))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    best = minimize_scalar(lambda tau: -at(tau), bounds=(lo, hi), method="bounded",
                           options={"xatol": 1e-12 * t_end})
    return float(max(values[k], -best.fun, at(0.0)))


@lru_cache(maxsize=None)
def damping_coefficient(e: float, law: str = "hertz") -> float:
    """Dimensionless damping q (hertz) or beta (linear) that gives restitution e (docs/model.md §4);
    b_lin = beta sqrt(m1 k_lin), q enters as q sqrt(m1 k1). Solved once per (e, law) and kept
    beside the compiled kernels (kernel/cache.py solved)."""
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
