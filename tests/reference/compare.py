"""An engine's results of one scene against the reference's row: how tests/test_validation.py
judges the engine, and how the benchmarks that measure errors judge every solver alike.

  (a) the same outcome,
  (b) the same contacts: a load-fence contact (corner or tip, docs/model.md §5.1-§5.2) seen or
      not, i.e. t_first_contact finite, and a rail contact (§5.3) seen or not, i.e.
      peak_rail_force > 0.  The engine's results do not tell a tip contact from a corner
      contact, so the reference's touch_fence and touch_tip are compared together;
  (c) peak_force, deflection_max and t_exit within ERR_BOUND (relative, with floors).

The relative errors are the agreement metric of docs/model.md (15.15), imported from
fencesweep/study/sweep/accuracy.py (the one that a sweep's verification applies), so that the
validation and a table's own check measure alike. The reference model (model.py) does not
import this module.
"""
from __future__ import annotations

import math

from fencesweep.study.sweep import accuracy
from fencesweep.study.sweep.accuracy import ANGLE_FLOOR, ENGINE_TARGET, FORCE_FLOOR, TIME_FLOOR  # noqa: F401

#: Relative error allowed in peak_force, deflection_max and t_exit.  Two independent
#: implementations must agree to 1e-3 (docs/model.md (15.15), accuracy.AGREEMENT); the engine's
#: default settings must do ten times better, a margin over that.  The reference is far below
#: the bound: results.csv (rtol 1e-10) and a rerun at rtol 1e-11 differ by at most 1.3e-9 in
#: these three measures (with the floors below) over the 103 scenes checked.
ERR_BOUND = ENGINE_TARGET
# The floors of the scales (fencesweep/study/sweep/accuracy.py, shared with a sweep's verification):
# forces against max(|ref|, FORCE_FLOOR x the scene's freefall_force), angles against
# max(|ref|, ANGLE_FLOOR), times against max(|ref|, TIME_FLOOR); imported here under their
# names, which the benchmarks read from this module.
#: A rail contact counts as seen when its peak force exceeds this fraction of the scene's
#: freefall_force (~6 uN by default): a corner resting exactly on the rail line (dP = 0) is
#: at zero depth, where rounding leaves a force of ~1e-9 N that is no contact.
RAIL_TOUCH = 1e-9
#: A fence contact is a touch when its force exceeds this fraction of freefall_force
#: (docs/model.md (11.10)): the engine counts t_first_contact only then. The reference reports any
#: contact that carries force; two scenes rest on a free fence at zero depth (long_near_free,
#: resting_on_free_fence: a rounding-size force), which are no touch by that definition.
FENCE_TOUCH = 1e-9
#: A true error below this is rounding, where an error estimate cannot be judged (the
#: reference itself is good to ~1e-9).
ROUNDING = 1e-10
#: An error estimate is judged by whether it lies within this factor of the true error.
ESTIMATE_WITHIN = 10.0


def touches(ref: dict) -> tuple[bool, bool]:
    """(load-fence contact, rail contact) seen by the reference (corner or tip for the fence)."""
    return bool(ref["touch_fence"] or ref["touch_tip"]), bool(ref["touch_rail"])


def errors(res: dict, ref: dict) -> dict:
    """Relative errors of the engine's results against the reference row (with floors)."""
    return {k: accuracy.relative_difference(ref[k], res[k], k, ref["freefall_force"])
            for k in ("peak_force", "deflection_max", "t_exit")}


def mismatches(res: dict, ref: dict) -> list[str]:
    """Every way in which the engine's results of one scene disagree with the reference."""
    out = []
    if res["outcome"] != ref["outcome"]:
        out.append(f"outcome {res['outcome']} (status {res['status']!r}), "
                   f"reference {ref['outcome']}")
    out += contact_mismatches(res, ref)
    for k, e in errors(res, ref).items():
        if not e <= ERR_BOUND:          # NaN fails too
            out.append(f"{k} {res[k]:.9g}, reference {ref[k]:.9g}: error {e:.2e} > {ERR_BOUND:g}")
    return out


def contact_mismatches(res: dict, ref: dict) -> list[str]:
    """The contacts (b) that the engine sees and the reference does not, or the other way round."""
    out = []
    fence, rail = touches(ref)
    fence = fence and ref["peak_force"] > FENCE_TOUCH * ref["freefall_force"]
    got_fence = math.isfinite(res["t_first_contact"])
    got_rail = res["peak_rail_force"] > RAIL_TOUCH * res["freefall_force"]
    if got_fence != fence:
        out.append(f"fence contact {'seen' if got_fence else 'missed'} "
                   f"(t_first_contact {res['t_first_contact']:.6g} s), reference "
                   f"{'touches' if fence else 'misses'} (corner {ref['max_pen_fence']:.3g} m, "
                   f"tip {ref['max_pen_tip']:.3g} m deep; gaps {ref['min_gap_fence']:.3g} m, "
                   f"{ref['min_gap_tip']:.3g} m)")
    if got_rail != rail:
        out.append(f"rail contact {'seen' if got_rail else 'missed'} "
                   f"(peak_rail_force {res['peak_rail_force']:.6g} N), reference "
                   f"{'touches' if rail else 'misses'} ({ref['max_pen_rail']:.3g} m deep, "
                   f"gap {ref['min_gap_rail']:.3g} m)")
    return out
