"""The error of every validation scene at the default setting and the warm cost of a cycle, an
earlier revision and this tree side by side in one run.

    python benchmarks/edges.py [--before 536da18] [--rounds 5]   -> prints, writes results/edges.md

For each tree (the earlier one exported from git by benchmarks/revisions.py, this one the working
tree), in a process of its own with a warm Numba cache of its own:
  * errors: every scene of tests/reference/scenes.yaml run at the default setting with the
    reference row's fully resolved parameters, compared with tests/reference/results.csv
    (SciPy DOP853 at rtol 1e-10, tests/reference/model.py: independent of the engine) as
    tests/test_validation.py compares (tests/reference/compare.py, in this process: the
    floored relative errors of peak_force, deflection_max and t_exit, a non-finite one
    counted as 1), plus the outcome and the contacts;
  * steps: the mean integrator steps of a cycle on 60 scenes of the main job (sweeps/b2k2.yaml:
    B2 x K2 x case, a seeded sample) - deterministic;
  * warm time: CPU ms per cycle on the same 60 scenes, 5 passes a round, of the kernel alone
    (run_cycles; n/a for a revision before the layered package) and of the whole public call
    `fencesweep.simulate` (any revision); the rounds of the two trees alternate (before, this
    tree, before, ...) so that the machine's drift hits both.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from revisions import export  # benchmarks/revisions.py: a revision's tree, exported from git

ROOT = Path(__file__).resolve().parents[1]
# this tree's package; tests/: the independent reference (tests/reference/)
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import reference  # noqa: E402
from reference import compare  # noqa: E402  (the validation's judge)

BEFORE = "536da18"

WORKER = r"""
import json, sys, time
import numpy as np
sys.path.insert(0, TESTS)  # tests/reference/: the independent reference
import reference
import fencesweep

what = sys.argv[1]
if what == "errors":  # the results that the judge reads, judged by the parent process
    keys = ("outcome", "peak_force", "deflection_max", "t_exit", "t_first_contact", "peak_rail_force",
            "freefall_force")
    out = {}
    for ref in reference.rows():
        res = fencesweep.simulate("cycle", **reference.row_params(ref))
        out[ref["id"]] = {k: res[k] for k in keys}
    print(json.dumps(out))
    sys.exit()

b2, k2 = np.linspace(0, 200, 81), np.linspace(100, 2100, 81)
idx = np.random.default_rng(20261123).choice(81 * 81 * 2, 60, replace=False)
sample = [(("small_far", "long_near")[i // 6561], float(b2[i % 6561 // 81]), float(k2[i % 81]))
          for i in idx]
if what == "steps":
    n = [fencesweep.simulate("cycle", case=c, B2=b, K2=k)["n_steps"] for c, b, k in sample]
    print(json.dumps(float(np.mean(n))))
    sys.exit()
if what == "api":  # the whole public call, the same code in any revision
    for c, b, k in sample:
        fencesweep.simulate("cycle", case=c, B2=b, K2=k)
    t = time.process_time()
    for _ in range(5):
        for c, b, k in sample:
            fencesweep.simulate("cycle", case=c, B2=b, K2=k)
    print(json.dumps((time.process_time() - t) / (5 * len(sample)) * 1e3))
    sys.exit()
from pathlib import Path
if not (Path(fencesweep.__file__).parent / "model").is_dir():
    # a revision before the layered package: its kernel is not called the same way (and an
    # editable install of this tree would supply the modules it lacks: ask its folder, not import)
    print(json.dumps(None))
    sys.exit()

from fencesweep.model.params import resolve
from fencesweep.model.prepare import prepare
from fencesweep.model.scenes.stream import run_cycles
from fencesweep.model import layout as Lp
from fencesweep.model.results import N_STREAM_CYCLE_RESULTS

def make(p):
    loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
    out = np.empty((1, N_STREAM_CYCLE_RESULTS)); traj = np.empty((0, 19))
    st = np.empty(2, np.int64); tc = float(p[Lp.TC])
    return lambda: run_cycles(p, loads, tc, out, traj, st)

fs = [make(prepare(resolve("cycle", c, B2=b, K2=k))) for c, b, k in sample]
for f in fs:
    f()
t = time.process_time()
for _ in range(5):
    for f in fs:
        f()
print(json.dumps((time.process_time() - t) / (5 * len(fs)) * 1e3))
"""


def run(tree: Path, cache: Path, what: str):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH"))}
    env.update(NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(tree))
    code = f"TESTS = {str(ROOT / 'tests')!r}\n" + WORKER
    r = subprocess.run([sys.executable, "-c", code, what], env=env, capture_output=True,
                       text=True, cwd=tree)
    if r.returncode:
        raise SystemExit(f"{tree} {what} failed:\n{r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def judged(results: dict[str, dict]) -> dict[str, dict]:
    """Per scene, the errors of its results against the reference (non-finite: 1), and whether
    the outcome and the contacts agree (tests/reference/compare.py)."""
    refs = {r["id"]: r for r in reference.rows()}
    out = {}
    for i, res in results.items():
        ref = refs[i]
        e = {k: (v if math.isfinite(v) else 1.0) for k, v in compare.errors(res, ref).items()}
        e["outcome"] = res["outcome"] == ref["outcome"]
        e["touch"] = not compare.contact_mismatches(res, ref)
        out[i] = e
    return out


GROUPS = (("free_harmonic", "free fences, harmonic profile, t_c 1.0-1.2 s"),
          ("clip_tip", "tip clips (the region of graze_tip_clip)"),
          ("graze_tip_clip", "graze_tip_clip"))


def table(errs: dict[str, dict], names: list[str]) -> list[str]:
    keys = ("peak_force", "deflection_max", "t_exit")
    lines = ["| scenes | n | " + " | ".join(f"max error {k} ({n})" for k in keys for n in names)
             + " | outcomes and touches right |",
             "|---|---:|" + "---:|" * (len(keys) * len(names)) + "---|"]
    first = errs[names[0]]
    groups = [(p, d) for p, d in GROUPS] + [("", "all validation scenes")]
    for prefix, desc in groups:
        ids = [i for i in first if i.startswith(prefix)]
        cells = []
        for k in keys:
            for n in names:
                cells.append(f"{max(errs[n][i][k] for i in ids):.1e}")
        right = ", ".join(f"{n}: {sum(errs[n][i]['outcome'] and errs[n][i]['touch'] for i in ids)}"
                          f"/{len(ids)}" for n in names)
        lines.append(f"| {desc} | {len(ids)} | " + " | ".join(cells) + f" | {right} |")
    return lines


def _ms(x) -> str:
    return "n/a" if x is None else f"{x:.3f}"


def _change(a, b) -> str:
    return "" if a is None or b is None else f"{b / a - 1:+.1%}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default=BEFORE)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "results" / "edges.md"))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {a.before: export(a.before), "this tree": ROOT}
        caches = {n: Path(tmp) / f"cache-{i}" for i, n in enumerate(trees)}
        errs, steps, times, calls = {}, {}, {n: [] for n in trees}, {n: [] for n in trees}
        for n, t in trees.items():
            errs[n] = judged(run(t, caches[n], "errors"))
            steps[n] = run(t, caches[n], "steps")
            print(f"{n}: errors of {len(errs[n])} scenes, {steps[n]:.1f} steps a cycle", flush=True)
        for r in range(a.rounds):
            for n, t in trees.items():
                times[n].append(run(t, caches[n], "time"))
                calls[n].append(run(t, caches[n], "api"))
            print(f"round {r + 1}: " + ", ".join(f"{n} kernel {_ms(times[n][-1])}, simulate {calls[n][-1]:.3f} ms"
                                                 for n in trees), flush=True)
    names = list(trees)
    med = {n: statistics.median(times[n]) if None not in times[n] else None for n in names}
    medc = {n: statistics.median(calls[n]) for n in names}
    worst = {n: max(errs[n], key=lambda i: max(errs[n][i][k] for k in ("peak_force", "deflection_max", "t_exit")))
             for n in names}
    lines = ["# Errors at the default setting and the warm cost, an earlier revision and this tree",
             "", f"Regenerate: `python benchmarks/edges.py --before {a.before} --rounds {a.rounds}` "
             "(what is measured: its docstring). Errors are floored relative errors against the "
             "independent reference (tests/reference/results.csv).", ""]
    lines += table(errs, names)
    lines += ["", "Worst scene: " + "; ".join(
        f"{n}: {worst[n]} ({max(errs[n][worst[n]][k] for k in ('peak_force', 'deflection_max', 't_exit')):.1e})"
        for n in names), "",
        "| | " + " | ".join(names) + " | change |", "|---|---:|---:|---:|",
        f"| mean steps a cycle (b2k2 sample of 60) | {steps[names[0]]:.1f} | {steps[names[1]]:.1f} | "
        f"{steps[names[1]] / steps[names[0]] - 1:+.1%} |",
        f"| warm CPU ms a cycle, the kernel (run_cycles), median of {a.rounds} rounds | {_ms(med[names[0]])} | "
        f"{_ms(med[names[1]])} | {_change(med[names[0]], med[names[1]])} |",
        f"| warm CPU ms a cycle, the whole `fencesweep.simulate` call, median of {a.rounds} rounds | "
        f"{medc[names[0]]:.3f} | {medc[names[1]]:.3f} | {_change(medc[names[0]], medc[names[1]])} |",
        "", "Rounds (ms a cycle), kernel: " + "; ".join(f"{n}: " + ", ".join(_ms(x) for x in times[n])
                                                       for n in names),
        "", "Rounds (ms a cycle), simulate: " + "; ".join(f"{n}: " + ", ".join(f"{x:.3f}" for x in calls[n])
                                                         for n in names),
        "", "n/a: a revision before the layered package, whose kernel is not called the same way; the "
            "simulate row times the same public call in both.", ""]
    text = "\n".join(lines)
    print(text)
    Path(a.out).write_text(text)


if __name__ == "__main__":
    main()
