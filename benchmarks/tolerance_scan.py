"""The default tolerance, measured: the widened validation set at several tolerances.

    python benchmarks/tolerance_scan.py     -> prints a table, writes results/tolerance_scan.md

For each tolerance (numerics.TOL x step_factor^5) every scene of
tests/reference/results.csv is run with its fully resolved parameters and compared
with the independent reference exactly as tests/test_validation.py does
(tests/reference/compare.py): scenes that
disagree (outcome, touches, or an error above the test's bound), the largest errors in
peak_force, deflection_max and t_exit, and the steps over all scenes. numerics.TOL is the
loosest of these at which the misses are those of the tightest.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# this tree's package first; tests/: the independent reference (tests/reference/)
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import reference  # noqa: E402
from reference import compare  # noqa: E402

import fencesweep  # noqa: E402
from fencesweep.kernel import numerics  # noqa: E402

TOLS = (1e-8, 1e-7, numerics.TOL, 2e-6, 4e-6, 1e-5)


def step_factor(tol: float) -> float:
    """The step_factor that gives tolerance tol (numerics.py: TOL x step_factor^TOL_EXPONENT)."""
    return (tol / numerics.TOL) ** (1.0 / numerics.TOL_EXPONENT)


ROWS = reference.rows()


def scan(tol: float) -> dict:
    sf = step_factor(tol)
    worst = {k: (0.0, "") for k in ("peak_force", "deflection_max", "t_exit")}
    missed, steps = [], 0
    for ref in ROWS:
        res = fencesweep.simulate("cycle", **{**reference.row_params(ref), "step_factor": sf})
        if compare.mismatches(res, ref):
            missed.append(ref["id"])
        for k, e in compare.errors(res, ref).items():
            if e > worst[k][0]:
                worst[k] = (e, ref["id"])
        steps += int(res["n_steps"])
    return {"tol": tol, "step_factor": sf, "missed": missed, "worst": worst, "steps": steps}


def main() -> None:
    rows = [scan(t) for t in TOLS]
    lines = ["# Tolerance scan: the validation set at several tolerances", "",
             f"Regenerate: `python benchmarks/tolerance_scan.py`. {len(ROWS)} scenes, each with its fully "
             f"resolved parameters, judged as in tests/test_validation.py (bound {compare.ERR_BOUND:g}, with its "
             f"floors). Default tolerance (numerics.TOL): {numerics.TOL:g}.", "",
             "| tol | step_factor | scenes missed | worst peak_force | worst deflection_max | worst t_exit | steps, all scenes |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        w = r["worst"]
        cell = lambda k: f"{w[k][0]:.1e} ({w[k][1]})"  # noqa: E731
        missed = ", ".join(r["missed"]) if len(r["missed"]) <= 3 else f"{len(r['missed'])}: " + ", ".join(r["missed"][:3]) + ", ..."
        lines.append(f"| {r['tol']:g} | {r['step_factor']:.3f} | {missed or 'none'} | {cell('peak_force')} | "
                     f"{cell('deflection_max')} | {cell('t_exit')} | {r['steps']} |")
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "results" / "tolerance_scan.md").write_text(text)


if __name__ == "__main__":
    main()
