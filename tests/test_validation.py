"""The engine against the independent reference, scene by scene.

tests/reference/results.csv holds, for every scene of tests/reference/scenes.yaml, the fully
resolved docs/model.md §12 parameters and the results of the reference model
(tests/reference/model.py: SciPy DOP853 at rtol 1e-10 with event restarts; regenerate with
`python tests/reference/make.py --force`).  Each row is run through the engine with every §12
parameter of the row (reference.row_params), and the engine must give the same outcome, the
same contacts and peak_force, deflection_max and t_exit within ERR_BOUND (relative, with
floors): reference/compare.py says how each is judged.

The grazing scenes (graze_* / miss_*: a contact of ~2e-5 m penetration and a gap of
~2e-5 m) make the contacts a sharp test of contact detection.  No wall-clock time is measured.
"""
from __future__ import annotations

import functools
import math

import pytest
import reference  # tests/reference/ (pyproject's pytest pythonpath): the scenes and the CSV, never the engine
from reference.compare import ERR_BOUND, ESTIMATE_WITHIN, ROUNDING, errors, mismatches, touches

import fencesweep

ROWS = reference.rows()


def test_csv_matches_the_scenes():
    """The CSV is complete and made from the current scene file; the reference ran fine
    everywhere and its per-kind touches agree with its own contact results."""
    scenes = reference.load_scenes()
    by_id = {r["id"]: r for r in ROWS}
    assert [s["id"] for s in scenes] == [r["id"] for r in ROWS]
    for s in scenes:
        ref = by_id[s["id"]]
        assert ref["scene_hash"] == reference.scene_hash(s), s["id"]
        if s["id"] in REFERENCE_CHATTERS:
            assert ref["status"].startswith("failed: more than"), s["id"]
            continue
        assert ref["status"] == "ok", s["id"]
        if s["id"] in REFERENCE_ZERO_TOUCH:
            assert ref["peak_rail_force"] == 0.0 and ref["touch_rail"], s["id"]
            continue
        fence, rail = touches(ref)
        assert fence == math.isfinite(ref["t_first_contact"]), s["id"]
        assert rail == (ref["peak_rail_force"] > 0.0), s["id"]
    # the grazes are what their names say (docs/model.md §5 kinds; see reference/scenes.yaml)
    for kind, col in (("corner_fence", "fence"), ("tip_edge", "tip"), ("corner_rail", "rail"),
                      ("tip_clip", "tip")):
        graze, miss = by_id["graze_" + kind], by_id["miss_" + kind]
        assert graze["touch_" + col] and 5e-6 <= graze["max_pen_" + col] <= 5e-5
        assert not miss["touch_" + col] and 5e-6 <= miss["min_gap_" + col] <= 5e-5


#: Scenes the engine does not meet at its default tolerance, with the measured miss (a strict
#: xfail). None: the hardest, graze_tip_clip (a 2e-5 m tip clip, N ~ D^1.5 so dN/N = 1.5 dD/D,
#: ill-conditioned in the positions), is met because the approach is integrated APPROACH_TOL
#: tighter than the cycle (kernel/numerics.py).
KNOWN_MISSES: dict[str, str] = {}  # slow_long_near_tc0.9, the last (peak_force 1.2e-4 off), is
#: met since a change of any of the fence's slots is searched over all of them (docs/model.md §15,
#: Events): its pivot end pushed for 6.6e-7 s, unseen, while a corner left the rail.

#: Scenes on which the reference itself fails (its event handling chatters); the CSV test
#: expects exactly that. None now.
REFERENCE_CHATTERS: set[str] = set()
#: ... and those where its rail touch flag disagrees with its own rail force (a touch at zero
#: force at the pivot). None now.
REFERENCE_ZERO_TOUCH: set[str] = set()


def _param(ref):
    marks = [pytest.mark.xfail(strict=True, reason=KNOWN_MISSES[ref["id"]])] if ref["id"] in KNOWN_MISSES else []
    return pytest.param(ref, marks=marks, id=ref["id"])


@functools.lru_cache(maxsize=None)
def engine(scene_id: str) -> dict:
    """The engine's results of one scene at the default settings (run once per session)."""
    ref = next(r for r in ROWS if r["id"] == scene_id)
    return fencesweep.simulate("cycle", **reference.row_params(ref))


@pytest.mark.parametrize("ref", [_param(r) for r in ROWS])
def test_engine_matches_reference(ref):
    bad = mismatches(engine(ref["id"]), ref)
    assert not bad, f"{ref['id']}: " + "; ".join(bad)


def test_error_estimate_follows_the_true_error():
    """The recorded error_estimate (the root-sum-square of the local error estimates) is within
    10x of the true error against the reference in at least 70% of the judged scenes
    (results/error_estimate.md measures the share), and never above 1e-3 where the true error
    is within the bound: an estimate that says nothing would fail one or the other."""
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


#: Scenes whose impact ends (N back to 0, docs/model.md §4) inside a long step. The state at the
#: release must be located on the method's flow (cycle/events.py release_state): read off the
#: step's dense output, whose later stages lie past the kink of max(N, 0), it is several times
#: further from the reference than RELEASE_BOUND.
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
    res = fencesweep.simulate("cycle", **{**reference.row_params(ref), "step_factor": 0.4})
    assert not mismatches(res, ref)
    assert res["t_first_contact"] == pytest.approx(ref["t_first_contact"], abs=1e-7)
