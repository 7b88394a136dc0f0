"""The engine against the independent reference, scene by scene.

benchmarks/reference_results.csv holds, for every scene of
benchmarks/validation_scenes.yaml, the fully resolved docs/model.md §12 parameters and the
results of benchmarks/reference.py (SciPy DOP853 at rtol 1e-10 with event restarts;
regenerate with `python benchmarks/make_reference.py --force`).  Each row is run through
the engine with every §12 parameter of the row (make_reference.row_params), and the
engine must give

  (a) the same outcome,
  (b) the same contacts: a load-fence contact (corner or tip, §5.1-§5.2) seen or not,
      i.e. t_first_contact finite, and a rail contact (§5.3) seen or not, i.e.
      peak_rail_force > 0.  The engine's results do not tell a tip contact from a corner
      contact, so the reference's touch_fence and touch_tip are compared together;
  (c) peak_force, deflection_max and t_exit within ERR_BOUND (relative, with floors).

The grazing scenes (graze_* / miss_*: a contact of ~2e-5 m penetration and a gap of
~2e-5 m) make (b) a sharp test of contact detection.  No wall-clock time is measured.
"""
from __future__ import annotations

import functools
import math

import make_reference  # benchmarks/ (pyproject's pytest pythonpath): reads the CSV, never the engine
import pandas as pd
import pytest

import fencesweep
from fencesweep.study.sweep import accuracy
from fencesweep.study.sweep.accuracy import ANGLE_FLOOR, ENGINE_TARGET, FORCE_FLOOR, TIME_FLOOR  # noqa: F401

#: Relative error allowed in peak_force, deflection_max and t_exit.  MODEL.md asks two
#: independent implementations to agree to 1e-3 (accuracy.AGREEMENT); the engine's default
#: settings must do ten times better, a margin over the spec.  The reference is far below
#: the bound: its CSV (rtol 1e-10) and a rerun at rtol 1e-11 differ by at most 1.3e-9 in
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

ROWS = pd.read_csv(make_reference.OUT).to_dict("records")


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
    for k, e in errors(res, ref).items():
        if not e <= ERR_BOUND:          # NaN fails too
            out.append(f"{k} {res[k]:.9g}, reference {ref[k]:.9g}: error {e:.2e} > {ERR_BOUND:g}")
    return out


def test_csv_matches_the_scenes():
    """The CSV is complete and made from the current scene file; the reference ran fine
    everywhere and its per-kind touches agree with its own contact results."""
    scenes = make_reference.load_scenes()
    by_id = {r["id"]: r for r in ROWS}
    assert [s["id"] for s in scenes] == [r["id"] for r in ROWS]
    for s in scenes:
        ref = by_id[s["id"]]
        assert ref["scene_hash"] == make_reference.scene_hash(s), s["id"]
        assert ref["status"] == "ok", s["id"]
        fence, rail = touches(ref)
        assert fence == math.isfinite(ref["t_first_contact"]), s["id"]
        assert rail == (ref["peak_rail_force"] > 0.0), s["id"]
    # the grazes are what their names say (docs/model.md §5 kinds; see validation_scenes.yaml)
    for kind, col in (("corner_fence", "fence"), ("tip_edge", "tip"), ("corner_rail", "rail"),
                      ("tip_clip", "tip")):
        graze, miss = by_id["graze_" + kind], by_id["miss_" + kind]
        assert graze["touch_" + col] and 5e-6 <= graze["max_pen_" + col] <= 5e-5
        assert not miss["touch_" + col] and 5e-6 <= miss["min_gap_" + col] <= 5e-5


#: Scenes the engine does not meet at its default tolerance, with the measured miss. None now:
#: graze_tip_clip (a 2e-5 m tip clip, N ~ D^1.5 so dN/N = 1.5 dD/D, ill-conditioned in the
#: positions) was 1.2e-3 off while the approach ran at the cycle's tolerance; the approach is
#: now integrated APPROACH_TOL tighter (kernel/numerics.py) and it is ~3e-5 off.
KNOWN_MISSES: dict[str, str] = {}


def _param(ref):
    marks = [pytest.mark.xfail(strict=True, reason=KNOWN_MISSES[ref["id"]])] if ref["id"] in KNOWN_MISSES else []
    return pytest.param(ref, marks=marks, id=ref["id"])


@functools.lru_cache(maxsize=None)
def engine(scene_id: str) -> dict:
    """The engine's results of one scene at the default settings (run once per session)."""
    ref = next(r for r in ROWS if r["id"] == scene_id)
    return fencesweep.simulate("cycle", **make_reference.row_params(ref))


@pytest.mark.parametrize("ref", [_param(r) for r in ROWS])
def test_engine_matches_reference(ref):
    bad = mismatches(engine(ref["id"]), ref)
    assert not bad, f"{ref['id']}: " + "; ".join(bad)


#: A true error below this is rounding, where an estimate cannot be judged (the reference
#: itself is good to ~1e-9).
ROUNDING = 1e-10
#: The error estimate is judged by whether it lies within this factor of the true error.
ESTIMATE_WITHIN = 10.0


def test_error_estimate_follows_the_true_error():
    """The recorded error_estimate (the root-sum-square of the local error estimates) is within
    10x of the true error against the reference in at least 70% of the judged scenes (measured:
    86%, results/error_estimate.md; the plain sum it replaced: 20%), and never above 1e-3 where
    the true error is within the bound: an estimate that says nothing would fail one or the
    other."""
    within = judged = 0
    for ref in ROWS:
        res = engine(ref["id"])
        true = max(errors(res, ref).values())
        est = res["error_estimate"]
        assert est >= 0.0, ref["id"]
        if true < ROUNDING:
            continue
        judged += 1
        within += true / ESTIMATE_WITHIN <= est <= ESTIMATE_WITHIN * true
        if true <= ERR_BOUND:
            assert est <= 1e-3, f"{ref['id']}: error_estimate {est:.2e}, true error {true:.2e}"
    assert judged >= 90
    assert within >= 0.7 * judged, f"estimate within 10x of the true error in {within} of {judged} scenes"


#: Scenes whose impact ends (N back to 0, docs/model.md §4) inside a long step. With the state at the
#: release read off that step's dense output (whose later stages lie past the kink of max(N, 0))
#: their largest errors were 6.7e-5, 9.4e-6, 1.9e-5 and 1.4e-6; located on the method's flow
#: (cycle.release_state) 1.7e-6, 5.9e-7, 1.6e-6 and 4.4e-9.
RELEASE_SCENES = ("mid_tc0.6_rigid", "square_far_rigid", "small_far_free", "small_far_linear_rigid")
RELEASE_BOUND = 5e-6


@pytest.mark.parametrize("scene_id", RELEASE_SCENES)
def test_release_inside_a_step_is_located_on_the_methods_flow(scene_id):
    ref = next(r for r in ROWS if r["id"] == scene_id)
    res = engine(scene_id)
    assert res["n_impacts"] >= 1
    err = errors(res, ref)
    assert max(err.values()) <= RELEASE_BOUND, f"{scene_id}: {err}"


def test_tip_clip_converges_with_the_tolerance():
    """The clip is the conditioning's hard case, not the detection's: at a tighter tolerance the
    same clip is found at the reference's instant and its peak stays within the bound."""
    ref = next(r for r in ROWS if r["id"] == "graze_tip_clip")
    res = fencesweep.simulate("cycle", **{**make_reference.row_params(ref), "step_factor": 0.4})
    assert not mismatches(res, ref)
    assert res["t_first_contact"] == pytest.approx(ref["t_first_contact"], abs=1e-7)
