"""Scene `freefall` (MODEL.md §7): the load dropped from H onto an undeformable surface:
speed v_H = sqrt(2 g H), rigid wall, 1 DOF, no gravity during the contact. Its peak force is
the permitted dynamic load that a cycle's overload is measured against."""
from __future__ import annotations

from fencesweep.kernel.jit import kernel

from fencesweep.model import layout as Lp
from fencesweep.model.contact import drop_speed
from fencesweep.model.scenes.impact import impact_kernel


@kernel()
def freefall_kernel(p, out):
    """The free fall of MODEL.md §7 (IMPACT_RESULTS into out): the impact scene on a rigid wall."""
    impact_kernel(p, True, False, drop_speed(p[Lp.H]), out)
