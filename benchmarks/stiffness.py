"""Is the cycle stiff at the engine's tolerance? Explicit against implicit methods on the
independent reference model, at the same tolerance.

    python benchmarks/stiffness.py        -> prints a table, writes results/stiffness.md

Would a linearly implicit (Rosenbrock) step beat the explicit one where sustained contact or
a stiff Kelvin element could make the explicit step stability-bound? Before building one:
would an implicit method take longer steps here at all?
This script answers with the reference (tests/reference/model.py, scipy's solve_ivp, sharing
no code with the engine) on the named cases, integrated at rtol = numerics.TOL by two
explicit Runge-Kutta pairs (RK45: Dormand-Prince 5(4), the engine's pair; DOP853) and two
implicit methods (Radau IIA of order 5; BDF of orders 1-5), each with the same events and
restarts. If the contact phases were stability-bound, the implicit methods would need far
fewer steps than the explicit ones; if they are accuracy-bound, the higher-order explicit
pair needs about as few. Counted: steps (accepted, summed over the segments between events)
and right-hand-side evaluations (the reference's own count of its model's rhs calls,
finite-difference Jacobians and the fence's run alone after the exit included); the error
is peak_force's against the reference at rtol 1e-10.
The engine's own row (DOPRI5, its default) is given beside them.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# this tree's package; tests/: the independent reference (tests/reference/)
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from reference import model as R  # noqa: E402

METHODS = ("RK45", "DOP853", "Radau", "BDF")
CASES = ("small_far", "long_near")


def counted(vals: dict, method: str, rtol: float) -> dict:
    """One reference cycle: its steps, rhs evaluations (the reference's own count), peak_force
    and wall time."""
    t0 = time.perf_counter()
    res, nfev = R.simulate_cycle(dict(vals), method=method, rtol=rtol)
    wall = time.perf_counter() - t0
    return {"steps": res["n_steps"], "rhs": nfev, "peak_force": res["peak_force"], "wall": wall}


def main() -> None:
    from fencesweep.model import simulate as api
    from fencesweep.kernel import numerics as NU
    from fencesweep.model import params as P

    rows = []
    for case in CASES:
        vals = P.resolve("cycle", case)
        ref = counted(vals, "DOP853", 1e-10)["peak_force"]
        eng, _ = api.simulate_resolved(vals)
        rows.append((case, "engine DOPRI5 (default)", eng["n_steps"], None,
                     abs(eng["peak_force"] - ref) / abs(ref), None))
        for m in METHODS:
            r = counted(vals, m, NU.TOL)
            rows.append((case, f"reference {m}", r["steps"], r["rhs"], abs(r["peak_force"] - ref) / abs(ref), r["wall"]))
    lines = [
        "# Is the cycle stiff at the engine's tolerance?",
        "",
        "Regenerate: `python benchmarks/stiffness.py` (the method is in its docstring). The reference model "
        f"(tests/reference/model.py) integrated by solve_ivp at rtol = {NU.TOL:g}, its own atol, with the same "
        "events and restarts for every method; the error is peak_force's against the reference at rtol 1e-10 "
        "(DOP853). *rhs*: the reference's count of its right-hand side's evaluations (finite-difference "
        "Jacobians and the fence's run after the exit included). "
        "The engine's row: its default (DOPRI5 at numerics.TOL); it counts RHS evaluations in "
        "results/throughput.md (about 6.5-7 per step).",
        "",
        "| case | method | steps | rhs evaluations | peak_force error | wall [s] |",
        "|---|---|---|---|---|---|",
    ]
    for case, m, steps, rhs, err, wall in rows:
        lines.append(f"| {case} | {m} | {steps} | {'-' if rhs is None else rhs} | {err:.1e} | "
                     f"{'-' if wall is None else f'{wall:.2f}'} |")
    lines += ["", "Ratios per case (implicit against explicit, from the rows above):", ""]
    for case in CASES:
        by = {m: (st, rhs) for c, m, st, rhs, _, _ in rows if c == case}
        st = {m.split()[-1]: v[0] for m, v in by.items()}
        ev = {m.split()[-1]: v[1] for m, v in by.items()}
        lines.append(f"* {case}: steps Radau / DOP853 = {st['Radau'] / st['DOP853']:.2f}, "
                     f"BDF / RK45 = {st['BDF'] / st['RK45']:.2f}; rhs evaluations Radau / DOP853 = "
                     f"{ev['Radau'] / ev['DOP853']:.2f}, BDF / RK45 = {ev['BDF'] / ev['RK45']:.2f}.")
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "results" / "stiffness.md").write_text(text)


if __name__ == "__main__":
    main()
