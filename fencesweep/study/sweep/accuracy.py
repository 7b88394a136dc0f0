"""How closely two results of the model must agree, in one place: the bounds, and the floors
under the relative differences (a result near 0 is compared on the scale of the results that
matter, not relative to ~0).

Shared by the sweep's verification (sweep/verify.py: a table against a re-run at a tighter
tolerance) and the validation of the engine against the independent reference
(tests/test_validation.py, and the benchmarks that judge as it does).
"""
from __future__ import annotations

import math

#: docs/model.md (15.15) asks two independent implementations of the model to agree to 1e-3 (relative,
#: with the floors below): a result that moves by more when the tolerance is tightened is not
#: the model's answer to that bound. The verification's threshold (verify.THRESHOLD).
AGREEMENT = 1e-3
#: What the engine's default settings must meet against the reference (tests/test_validation.py):
#: ten times better than AGREEMENT, a margin over the specification.
ENGINE_TARGET = 1e-4

#: Floor of the force scale [fraction of the scene's freefall_force, docs/model.md §7]: a scene whose
#: peak force is 0 (no contact) or a few N (a graze, a load resting on the fence) is judged on
#: the scale of the forces that matter for its overload, not relative to ~0. The overload (a
#: force in units of freefall_force) has the same floor.
FORCE_FLOOR = 0.1
#: Floor of the angle scale [rad]: deflections of rigid fences (0) and of barely touched
#: flexible ones are compared to 0.01 rad (0.6 deg, 4 % of the 15 deg limit).
ANGLE_FLOOR = 0.01
#: Floor of the time scale [s]: no outcome time is near 0, but a 1 ms floor keeps the bound
#: from becoming absurd if one is (a contact time of a graze).
TIME_FLOOR = 1e-3
#: Floor of a coefficient of restitution (e_eff of an impact, 0..1).
COEFFICIENT_FLOOR = 0.01

#: the kind of each compared result: its floor
KINDS = {
    "peak_force": "force", "overload": "overload", "impulse": "impulse", "e_eff": "coefficient",
    "deflection_max": "angle", "residual_amplitude": "angle", "alpha_max": "angle", "start_amplitude": "angle",
    "t_exit": "time", "contact_time": "time",
}
#: the results compared, per scene (a stream's: every cycle's)
QUANTITIES = {
    "cycle": ("peak_force", "overload", "deflection_max", "t_exit", "residual_amplitude", "alpha_max",
              "contact_time"),
    "stream": ("peak_force", "overload", "deflection_max", "t_exit", "residual_amplitude", "alpha_max",
               "contact_time", "start_amplitude"),
    "impact": ("peak_force", "impulse", "contact_time", "e_eff"),
    "freefall": ("peak_force", "impulse", "contact_time", "e_eff"),
}


def floor(quantity: str, freefall_force: float) -> float:
    """The floor of `quantity`'s scale (freefall_force [N]: the scene's, docs/model.md §7)."""
    kind = KINDS[quantity]
    if kind == "force":
        return FORCE_FLOOR * abs(freefall_force)
    if kind == "overload":
        return FORCE_FLOOR
    if kind == "impulse":
        return FORCE_FLOOR * abs(freefall_force) * TIME_FLOOR
    return {"angle": ANGLE_FLOOR, "time": TIME_FLOOR, "coefficient": COEFFICIENT_FLOOR}[kind]


def floor_text(quantity: str) -> str:
    """The floor of `quantity` as the verification records it."""
    kind = KINDS[quantity]
    return {"force": f"{FORCE_FLOOR:g} x freefall_force [N]", "overload": f"{FORCE_FLOOR:g}",
            "impulse": f"{FORCE_FLOOR:g} x freefall_force x {TIME_FLOOR:g} s [N s]",
            "angle": f"{ANGLE_FLOOR:g} rad", "time": f"{TIME_FLOOR:g} s",
            "coefficient": f"{COEFFICIENT_FLOOR:g}"}[kind]


def relative_difference(value: float, other: float, quantity: str, freefall_force: float) -> float:
    """|other - value| / max(|value|, floor), docs/model.md (15.15): `value` is the one judged (the table's, the
    reference's). NaN when either is NaN; 0 when both are the same infinity."""
    if value == other:
        return 0.0
    if math.isnan(value) or math.isnan(other):
        return math.nan
    scale = max(abs(value), floor(quantity, freefall_force))  # (a NaN floor is passed over)
    return abs(other - value) / scale if scale > 0 else math.inf
