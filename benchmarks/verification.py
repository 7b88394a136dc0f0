"""Does a table's verification tell its error? The difference a sweep's verification reports
(each run against a re-run at tol / 10, fencesweep/study/sweep/verify.py) and the per-row
error_estimate, both against the true error of the validation scenes.

    python benchmarks/verification.py   -> prints; writes results/figures/verification.png and
                                           the section "A table's own check" of
                                           results/work_precision.md (work_precision.py writes
                                           the same section when it regenerates the page)

For every scene of tests/reference/results.csv (the independent reference: SciPy DOP853 at
rtol 1e-10, tests/reference/model.py), with its fully resolved parameters:
  * true error e: the engine at the default setting against the reference;
  * verification difference d: the engine at the default setting against the engine at
    step_factor x verify.STEP_FACTOR_SCALE (tol / 10), exactly what a sweep's verification
    computes for the runs it samples;
both as relative differences with the floors of fencesweep/study/sweep/accuracy.py, for peak_force,
deflection_max and t_exit (the results the reference gives). And the per-row error_estimate
(a relative error of the state) against the largest of the three true errors. No time is
measured: the page's timings are work_precision.py's.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
from common import ROOT, pyplot, save

sys.path[:0] = [str(ROOT), str(ROOT / "tests")]  # this tree's package first; tests/reference/: the reference

import reference  # noqa: E402

import fencesweep  # noqa: E402
from fencesweep.study.sweep import accuracy  # noqa: E402
from fencesweep.study.sweep.verify import STEP_FACTOR_SCALE  # noqa: E402

QUANTITIES = ("peak_force", "deflection_max", "t_exit")
#: an error below this is "exact" on the page (both are at the reference's own accuracy)
RESOLVED = 1e-9
START = "## A table's own check: the verification against the true error"


def measure() -> pd.DataFrame:
    """One row per (scene, quantity): the true error e, the verification difference d, the
    row's error_estimate."""
    rows = []
    for ref in reference.rows():
        params = reference.row_params(ref)
        a = fencesweep.simulate("cycle", **params)
        t = fencesweep.simulate("cycle", **{**params, "step_factor": params.get("step_factor", 1.0)
                                            * STEP_FACTOR_SCALE})
        ff = a["freefall_force"]
        for q in QUANTITIES:
            e = accuracy.relative_difference(a[q], ref[q], q, ff)
            d = accuracy.relative_difference(a[q], t[q], q, ff)
            rows.append({"id": ref["id"], "quantity": q, "error": e, "verify": d,
                         "error_estimate": a["error_estimate"], "same_outcome": a["outcome"] == t["outcome"]})
    return pd.DataFrame(rows)


def _ratio_text(g: pd.DataFrame) -> str:
    both = g[(g.error > RESOLVED) & (g.verify > RESOLVED)]
    r = both.verify / both.error
    return (f"{len(both)} scenes with both above {RESOLVED:g}: d / e median {r.median():.2f}, "
            f"5 % {r.quantile(0.05):.2f}, 95 % {r.quantile(0.95):.2f}, min {r.min():.2f} ({both.id[r.idxmin()]})")


def section(df: pd.DataFrame, main_job: dict | None) -> list[str]:
    """The page's section (markdown lines)."""
    n = df.id.nunique()
    lines = [START, "",
             f"Regenerate: `python benchmarks/verification.py` (its docstring says what is measured). Every "
             f"table `fencesweep grid` writes re-runs a sample of its runs at tol / 10 and records the largest "
             f"difference per result (sweeps/README.md, Verification). Here that difference d is computed for "
             f"each of the {n} validation scenes at the default setting and set against the true error e "
             f"(against the independent reference), with the validation's floors. Figure: "
             f"`results/figures/verification.png`.", "",
             "| result | max e | max d | scenes where d >= e / 3 | scenes where d < e / 3 (e > 1e-7) | d / e |",
             "|---|---:|---:|---:|---|---|"]
    for q, g in df.groupby("quantity", sort=False):
        ok = (g.verify >= g.error / 3) | (g.error <= RESOLVED)
        under = g[~ok & (g.error > 1e-7)]
        names = ", ".join(f"{r.id} (e {r.error:.1e}, d {r.verify:.1e})" for r in under.itertuples()) or "none"
        lines.append(f"| {q} | {g.error.max():.1e} | {g.verify.max():.1e} | {ok.sum()} of {len(g)} | {names} | "
                     f"{_ratio_text(g)} |")
    worst = df.groupby("id").agg(error=("error", "max"), est=("error_estimate", "first"), d=("verify", "max"))
    worst = worst[worst.error > RESOLVED]
    r_est = worst.est / worst.error
    r_d = worst.d / worst.error
    lines += ["", f"**Per scene** (the largest of the three errors, {len(worst)} scenes above {RESOLVED:g}): the "
              f"verification's d / e has median {r_d.median():.2f} (5-95 %: {r_d.quantile(0.05):.2f}-"
              f"{r_d.quantile(0.95):.2f}); the per-row error_estimate / e has median {r_est.median():.2g} "
              f"(5-95 %: {r_est.quantile(0.05):.2g}-{r_est.quantile(0.95):.2g}, min {r_est.min():.2g}, max "
              f"{r_est.max():.2g}). The verification measures the error of the results themselves, the "
              f"error_estimate only the local errors of the state, which a result may amplify or damp.",
              "", f"Outcomes at the two tolerances: {int(df.groupby('id').same_outcome.first().sum())} of {n} "
              "scenes the same."]
    if main_job:
        q = main_job.get("quantities", {})
        figs = ", ".join(f"{k} {v['max_rel_diff']:.1g}" for k, v in q.items() if v.get("max_rel_diff") is not None)
        lines += ["", f"**The main job** (results/b2k2.parquet, its metadata `fencesweep.verify`): "
                  f"{main_job.get('n')} runs re-run, largest differences {figs}; ok {main_job.get('ok')}."]
    return lines


def main_job_record() -> dict | None:
    path = ROOT / "results" / "b2k2.parquet"
    if not path.exists():
        return None
    import json

    import pyarrow.parquet as pq
    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(b"fencesweep.verify")
    return json.loads(raw) if raw else None


def plot(df: pd.DataFrame, path: Path) -> None:
    fig, axes = pyplot().subplots(1, 2, figsize=(11, 4.6))
    lo = 1e-12
    ax = axes[0]
    for (q, g), m in zip(df.groupby("quantity", sort=False), ("o", "s", "^")):
        ax.scatter(np.maximum(g.error, lo), np.maximum(g.verify, lo), s=16, marker=m, alpha=0.7, label=q)
    ax.plot([lo, 1], [lo, 1], "k-", lw=0.8, label="d = e")
    ax.plot([lo, 1], [lo / 10, 0.1], "k:", lw=0.8, label="d = e / 10")
    ax.set(xscale="log", yscale="log", xlim=(lo, 1e-2), ylim=(lo, 1e-2),
           xlabel="true error e (against the reference)", ylabel="verification difference d (against tol / 10)",
           title="What a table's verification reports, per scene")
    ax.legend(fontsize=8, loc="upper left")
    ax = axes[1]
    per = df.groupby("id").agg(error=("error", "max"), est=("error_estimate", "first"), d=("verify", "max"))
    ax.scatter(np.maximum(per.error, lo), np.maximum(per.d, lo), s=16, label="verification difference d")
    ax.scatter(np.maximum(per.error, lo), np.maximum(per.est, lo), s=16, marker="x", label="per-row error_estimate")
    ax.plot([lo, 1], [lo, 1], "k-", lw=0.8)
    ax.set(xscale="log", yscale="log", xlim=(lo, 1e-2), ylim=(lo, 1e-2),
           xlabel="largest true error of the scene", ylabel="what the table says",
           title="Verification against the per-row estimate")
    ax.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    save(fig, path)


def replace_section(page: Path, lines: list[str]) -> None:
    """Put the section into the page, in place of its earlier version (or at the end)."""
    text = page.read_text() if page.exists() else ""
    head = text.split(START)[0].rstrip()
    page.write_text((head + "\n\n" if head else "") + "\n".join(lines).rstrip() + "\n")


def main() -> None:
    df = measure()
    lines = section(df, main_job_record())
    print("\n".join(lines))
    plot(df, ROOT / "results" / "figures" / "verification.png")
    replace_section(ROOT / "results" / "work_precision.md", lines)


if __name__ == "__main__":
    main()
