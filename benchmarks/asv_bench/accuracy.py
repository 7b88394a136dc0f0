"""Accuracy, as numbers asv tracks (lower is better): the named cases against a step 100 x finer,
and every validation scene against the independent reference of this checkout (tests/reference/)."""
import math
import sys

import fencesweep

from . import CASES, DRIVES, ROOT


class StepConvergence:
    """peak_force at the default step against step_factor 0.01: |a - fine| / max(|fine|, 0.1 x the
    load's freefall_force), the floored relative difference of docs/model.md (15.15)."""
    params = (list(CASES), list(DRIVES))
    param_names = ["case", "drive"]
    timeout = 600

    def track_peak_force_difference(self, case, drive):
        a = fencesweep.simulate("cycle", case=case, drive=drive)
        fine = fencesweep.simulate("cycle", case=case, drive=drive, step_factor=0.01)
        return abs(a["peak_force"] - fine["peak_force"]) / max(abs(fine["peak_force"]), 0.1 * fine["freefall_force"])

    track_peak_force_difference.unit = "relative"


class Validation:
    """Every scene of tests/reference/results.csv run at the default setting with the reference row's
    fully resolved parameters and judged as tests/test_validation.py judges it
    (tests/reference/compare.py): the largest floored relative error of peak_force, deflection_max and
    t_exit over the scenes (a non-finite one counts as 1), and the scenes that disagree in any way
    (outcome, contacts, or an error over the test's bound)."""
    timeout = 900

    def setup_cache(self):
        sys.path.insert(0, str(ROOT / "tests"))
        import reference
        from reference import compare

        worst, missed = 0.0, 0
        for ref in reference.rows():
            res = fencesweep.simulate("cycle", **reference.row_params(ref))
            errors = [e if math.isfinite(e) else 1.0 for e in compare.errors(res, ref).values()]
            worst = max(worst, *errors)
            missed += bool(compare.mismatches(res, ref))
        return {"worst": worst, "missed": missed}

    def track_max_error(self, measured):
        return measured["worst"]

    track_max_error.unit = "relative"

    def track_scenes_missed(self, measured):
        return measured["missed"]

    track_scenes_missed.unit = "scenes"
