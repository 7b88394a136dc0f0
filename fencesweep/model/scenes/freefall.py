"""Scene `freefall` (docs/model.md §7): the load dropped from H onto an undeformable surface:
speed v_H = sqrt(2 g H), rigid wall, 1 DOF, no gravity during the contact. Its peak force is
the permitted dynamic load that a cycle's overload is measured against. It is the impact
scene on a rigid wall (scenes/impact.py), run with that scene's one compiled entry point."""
from __future__ import annotations

import numpy as np

from fencesweep.model import layout as Lp
from fencesweep.model.contact import drop_speed
from fencesweep.model.scenes.impact import impact_kernel


def freefall(p: np.ndarray, out: np.ndarray) -> None:
    """The free fall of docs/model.md (7.2) (IMPACT_RESULTS into out): the impact scene on a rigid
    wall at the drop speed v_H (7.1); its peak force is F_ff."""
    impact_kernel(p, True, False, float(drop_speed(float(p[Lp.H]))), out)
