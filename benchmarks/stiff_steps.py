"""Would a stiff integrator take fewer steps? The engine's accepted steps a cycle beside those of
SciPy's stiff methods (BDF, LSODA) and of its explicit RK45 (the engine's DOPRI5 pair), each
integrating the independent reference (tests/reference/model.py) at the engine's tolerance, on the
main job's fixed sample (benchmarks/asv_bench main_job_sample, the sample of instructions.py);
and how close each comes to the reference at its own default, DOP853 at rtol 1e-10.

    python benchmarks/stiff_steps.py [--n 60] [--jobs 2]     -> results/stiff_steps.md

Every scene's parameters are resolved by the reference (its case, B2, K2, the flexible drive) and
the same fully resolved values go to the engine. The SciPy runs use rtol 1e-6 and one atol 1e-6 for
every component, near the engine's (TOL = 1e-6 times each component's scale: the fence length,
~1 m, or the fastest speed, ~2 m/s). Steps: the points each solve_ivp call returns (every accepted
step), summed over the reference's event restarts. Radau is left out: on long_near (B2 75, K2 1425)
the reference under Radau ran 20,001 segments in 74 s and returned peak_force 0 and t_exit 2e-5 s,
where every other method finds the impact.

Beside it, the engine alone at looser tolerances (step_factor s: TOL x s^5): its accepted and
rejected steps a cycle on the same sample, and ms a cycle through `fencesweep.simulate` (the
fastest of PASSES passes over the sample, the settings alternated in each round; seconds, so
this machine's noise enters).
"""
from __future__ import annotations

import argparse
import math
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from asv_bench import main_job_sample
from common import ROOT, md_table

sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # this tree's package first; tests/reference/: the reference

OUT = ROOT / "results" / "stiff_steps.md"
METHODS = ("BDF", "LSODA", "RK45")
RTOL = ATOL = 1e-6
STEP_FACTORS = (1.0, 1.5, 2.0, 3.0)
PASSES = 8


def scene(item: tuple) -> dict:
    """One scene: the engine's steps and results, and each method's steps, right-hand sides and results."""
    import fencesweep
    from reference import PARAM_COLS, model

    case, b2, k2 = item
    resolved = model.resolve_params({"case": case, "B2": b2, "K2": k2, "drive": "flexible"})
    params = {k: resolved[k] for k in PARAM_COLS if not (k == "k_lin" and resolved["contact_law"] != "linear")}
    steps = []
    solve = model.solve_ivp

    def counted(*a, **kw):
        s = solve(*a, **kw)
        steps.append(len(s.t) - 1)
        return s

    model.solve_ivp = counted
    try:
        out = {"case": case, "truth": model.simulate_reference(params)}
        for m in METHODS:
            steps.clear()
            out[m] = {**model.simulate_reference(params, method=m, rtol=RTOL, atol=ATOL), "steps": sum(steps)}
    finally:
        model.solve_ivp = solve
    engine = fencesweep.simulate("cycle", **params)
    out["engine"] = {**engine, "steps": engine["n_steps"]}
    return out


def errors(rows: list, who: str) -> tuple:
    """`who`'s relative errors of peak_force and errors of t_exit [s] against the truth, and the
    scenes whose outcome differs from the truth's."""
    pf = np.array([abs(r[who]["peak_force"] - r["truth"]["peak_force"]) / r["truth"]["peak_force"] for r in rows])
    te = np.array([abs(r[who]["t_exit"] - r["truth"]["t_exit"]) for r in rows])
    return pf, te, sum(r[who]["outcome"] != r["truth"]["outcome"] for r in rows)


def looser(n: int) -> list:
    """The engine on the sample at each of STEP_FACTORS: [step_factor, steps, rejected, ms a cycle]."""
    import time

    from fencesweep.model import params as P
    from fencesweep.model.simulate import simulate_resolved

    vals = {sf: [P.resolve("cycle", c, B2=b, K2=k, step_factor=sf) for c, b, k in main_job_sample(n)]
            for sf in STEP_FACTORS}
    res = {sf: [simulate_resolved(v)[0] for v in vs] for sf, vs in vals.items()}
    best = dict.fromkeys(STEP_FACTORS, math.inf)
    for _ in range(PASSES):  # the settings alternated within each round
        for sf, vs in vals.items():
            t = time.perf_counter()
            for v in vs:
                simulate_resolved(v)
            best[sf] = min(best[sf], time.perf_counter() - t)
    return [[sf, np.mean([r["n_steps"] for r in res[sf]]), np.mean([r["n_rejected"] for r in res[sf]]),
             best[sf] / n * 1e3] for sf in STEP_FACTORS]


def page(rows: list, n: int, loose: list) -> str:
    table = []
    for case in sorted({r["case"] for r in rows}):
        sub = [r for r in rows if r["case"] == case]
        for who in ("engine", *METHODS):
            st = np.array([r[who]["steps"] for r in sub])
            rhs = "" if who == "engine" else f"{np.mean([r[who]['n_rhs'] for r in sub]):,.0f}"
            pf, te, other = errors(sub, who)
            table.append([f"{case} ({len(sub)})", who, f"{st.mean():.0f}", f"{np.median(st):.0f}", f"{st.max()}", rhs,
                          f"{np.median(pf):.1e}, {pf.max():.1e}", f"{np.median(te):.1e}, {te.max():.1e}", other])
    return "\n".join([
        "# Would a stiff integrator take fewer steps?", "",
        f"Regenerate: `python benchmarks/stiff_steps.py` (what is measured: its docstring). The main job's "
        f"sample of {n} scenes; SciPy's methods integrate the independent reference at rtol {RTOL:g}, atol {ATOL:g}. "
        "Errors: over the case's scenes, against the reference at DOP853 rtol 1e-10.", "",
        *md_table(["case (scenes)", "integrator", "steps a cycle: mean>", "median>", "max>", "right-hand sides, mean>",
                   "peak_force rel. error: median, max>", "t_exit error [s]: median, max>", "outcome differs>"],
                  table), "",
        f"The engine at looser tolerances, the same sample ({PASSES} rounds, the settings alternated in each; the fastest pass):", "",
        *md_table(["step_factor>", "tolerance>", "steps a cycle>", "rejected>", "ms a cycle>"],
                  [[f"{sf:g}", f"TOL x {sf ** 5:.0f}", f"{st:.1f}", f"{rj:.1f}", f"{ms:.4f}"] for sf, st, rj, ms in loose]),
        ""])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=60, help="scenes of the main job's sample")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()
    with ProcessPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(scene, main_job_sample(args.n)))
    text = page(rows, args.n, looser(args.n))
    print(text)
    with open(args.out, "w") as fh:
        fh.write(text)


if __name__ == "__main__":
    main()
