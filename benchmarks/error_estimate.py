"""How close is the recorded error_estimate to the true error? Before (the plain sum of the
accepted steps' local error estimates, commit BEFORE) and now (their root-sum-square, this
tree), side by side in one run.

Every scene of tests/reference/results.csv is run by both engines with its fully resolved
docs/model.md §12 parameters (reference.row_params) at step_factor 1 (and, for this tree, at
the other FACTORS: does the estimate follow the tolerance?). The true error of a scene is the
largest of its relative errors in peak_force, deflection_max and t_exit against the independent
reference, with the floors with which tests/test_validation.py judges the engine
(tests/reference/compare.py, `errors`); the estimate is judged by the ratio estimate / true
error. A scene whose true error is below ROUNDING is at the level of rounding, where neither
number means anything, and is listed apart. The older engine is exported from git
(benchmarks/revisions.py) and run in a subprocess (its package has the same name).

    python benchmarks/error_estimate.py    -> results/error_estimate.md,
                                              results/figures/error_estimate.png
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
# this tree's package first; tests/: the independent reference (tests/reference/)
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import reference  # noqa: E402
from reference import compare  # noqa: E402  (the validation's error definition and floors)
from revisions import export  # noqa: E402  (benchmarks/revisions.py: a revision's tree, exported from git)

#: the engine with the plain-sum estimate (the commit before the root-sum-square)
BEFORE = "657f627"
#: step_factors run with this tree (1 is the default, the setting whose estimate is judged)
FACTORS = (4.0, 1.0, 0.25)
#: a true error below this is rounding, and the band an estimate should lie in: within this
#: factor of the true error (both as tests/test_validation.py judges the estimate)
ROUNDING, WITHIN = compare.ROUNDING, compare.ESTIMATE_WITHIN
QUANTITIES = ("peak_force", "deflection_max", "t_exit")

CODE = r"""
import json, sys
import reference, fencesweep
out = []
for sf in json.loads(sys.argv[1]):
    for ref in reference.rows():
        r = fencesweep.simulate("cycle", **{**reference.row_params(ref), "step_factor": sf})
        out.append({"id": ref["id"], "step_factor": sf, "error_estimate": r["error_estimate"],
                    "n_steps": r["n_steps"], **{k: r[k] for k in %r}})
print(json.dumps(out))
""" % (QUANTITIES,)


def run(where: Path, factors) -> pd.DataFrame:
    """The engine at `where` on every reference scene at `factors`, in a subprocess."""
    res = subprocess.run([sys.executable, "-c", CODE, json.dumps(list(factors))], cwd=where, capture_output=True,
                         text=True, check=True,
                         env={"PYTHONPATH": f"{where}:{ROOT / 'tests'}", "PATH": "/usr/bin:/bin"})
    return pd.DataFrame(json.loads(res.stdout.strip().splitlines()[-1]))


def judge(df: pd.DataFrame) -> pd.DataFrame:
    """True error (compare.errors, largest of the three) and the ratio estimate / true error."""
    refs = {r["id"]: r for r in reference.rows()}
    true = [max(compare.errors(r, refs[r["id"]]).values()) for r in df.to_dict("records")]
    df = df.assign(true_error=true)
    df["ratio"] = df.error_estimate / df.true_error
    df["judged"] = df.true_error >= ROUNDING
    df["within"] = df.judged & (df.ratio >= 1 / WITHIN) & (df.ratio <= WITHIN)
    return df


def summary_row(label: str, g: pd.DataFrame) -> str:
    j = g[g.judged]
    lr = np.log10(j.ratio[j.ratio > 0])
    return (f"| {label} | {len(j)} | {int(j.within.sum())} ({j.within.mean():.0%}) | {10 ** lr.median():.3g} | "
            f"{10 ** lr.quantile(0.1):.3g} – {10 ** lr.quantile(0.9):.3g} | {int((j.ratio < 1 / WITHIN).sum())} | "
            f"{int((j.ratio > WITHIN).sum())} |")


def plot(before: pd.DataFrame, now: pd.DataFrame, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    floor = 1e-13
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    lo, hi = 1e-9, 3e-2
    x = np.logspace(math.log10(lo), math.log10(hi), 2)
    ax.fill_between(x, x / WITHIN, x * WITHIN, color="0.9", label=f"within {WITHIN:g}x of the true error")
    ax.plot(x, x, color="0.5", lw=0.8)
    for df, label, style in ((before, f"before ({BEFORE}): plain sum", dict(marker="x", color="C3")),
                             (now, "now: root-sum-square", dict(marker="o", mfc="none", color="C0"))):
        j = df[df.judged]
        ax.plot(j.true_error, np.maximum(j.error_estimate, floor), ls="none", ms=5, label=label, **style)
    ax.set(xscale="log", yscale="log", xlim=(lo, hi), ylim=(lo, hi),
           xlabel="true error (largest of peak_force, deflection_max, t_exit; relative, with floors)",
           ylabel="recorded error_estimate",
           title="error_estimate against the reference, step_factor 1")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(exist_ok=True)
    fig.savefig(path, dpi=120)


def main() -> None:
    before = judge(run(export(BEFORE), (1.0,)))
    now = judge(run(ROOT, FACTORS))
    now1 = now[now.step_factor == 1.0]
    n = len(now1)
    lines = ["# The recorded error_estimate against the true error", "",
             "Regenerate: `python benchmarks/error_estimate.py` (both engines in one run). Figure: "
             "`results/figures/error_estimate.png`.", "",
             f"Each of the {n} validation scenes (`tests/reference/results.csv`) is run with its fully resolved "
             "§12 parameters. True error: the largest relative error of peak_force, deflection_max and t_exit "
             "against the independent reference, with the floors of `tests/test_validation.py` "
             "(`tests/reference/compare.py`). Ratio: "
             f"error_estimate / true error; an estimate should lie within 1/{WITHIN:g} … {WITHIN:g} of it. Scenes "
             f"with a true error below {ROUNDING:g} are at rounding level and not judged "
             f"({int((~now1.judged).sum())} at step_factor 1: "
             + ", ".join(now1[~now1.judged].id) + ").", "",
             "| estimate | scenes judged | within 10x | median ratio | 10–90% of ratios | under 1/10 | over 10 |",
             "|---|---|---|---|---|---|---|",
             summary_row(f"before ({BEFORE}): sum of the local errors, step_factor 1", before)]
    for sf in FACTORS:
        lines.append(summary_row(f"now: root-sum-square, step_factor {sf:g}", now[now.step_factor == sf]))
    j = now1[now1.judged]
    out = j[~j.within].sort_values("ratio")
    lines += ["", "Scenes outside the band now (step_factor 1):", "",
              "| scene | true error | error_estimate | ratio | steps |", "|---|---|---|---|---|"]
    lines += [f"| {r.id} | {r.true_error:.2e} | {r.error_estimate:.2e} | {r.ratio:.3g} | {r.n_steps} |"
              for r in out.itertuples()]
    text = "\n".join(lines) + "\n"
    print(text)
    (ROOT / "results" / "error_estimate.md").write_text(text)
    plot(before, now1, ROOT / "results" / "figures" / "error_estimate.png")
    print("wrote results/error_estimate.md, results/figures/error_estimate.png")


if __name__ == "__main__":
    main()
