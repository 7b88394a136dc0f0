"""Are whole tables converged? A spec run at the default setting and at a tighter one, every row compared.

    python benchmarks/audit.py SPEC [SPEC ...] [--step-factor 0.398] [--jobs N] [--worst 10]
                               [--page results/audit.md --notes benchmarks/audit_notes.md] [--reuse | --rerun]

Each spec runs twice through `fencesweep.grid` (its own verification off): as written, and with
`params: {step_factor: F}` (F = 0.398: the local error tolerance TOL x F^5 is 1/100 of the default's).
The two tables are compared row by row in COLUMNS, as |tight - default| / max(|tight|, floor); the
outcomes must be equal on every row, and for an envelope study every design point's feasible verdict.
Printed per column: the rows over 1e-3 and 1e-2 and the largest difference, then the worst rows with
their parameters; `--page` writes the same as a section per spec (the page rewritten whole from this
call's sections), after the text of `--notes` (the causes traced by hand, from the rows' trajectories).

The tables are kept in .fencesweep-audit/ (git-ignored): `--reuse` compares the kept tables again;
`--rerun` runs again, with this tree, only the kept tables' rows over the bound (at both settings, one
scene at a time): a quick check of a fix on the rows it is meant for, not an audit.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import fencesweep  # noqa: E402

#: the tighter setting: tolerance TOL x 0.398^5 = TOL / 100
TIGHT = 0.398
#: a row differs when a column moves by more than this (relative, floored)
BOUND = 1e-3
#: the compared columns and the floor under each one's scale: a result near 0 (no contact, a
#: rigid fence's deflection) is compared on the scale of the values that matter
COLUMNS = {
    "peak_force": 50.0,          # N
    "overload": None,            # the peak_force floor over the row's freefall_force (docs/model.md §7)
    "deflection_max": 0.01,      # rad
    "t_exit": 1e-3,              # s
    "residual_amplitude": 0.01,  # rad
    "contact_time": 0.01,        # s
}
#: the parameters shown with a worst row (those that vary in the studies audited)
SHOW = ("case", "drive", "B2", "K2", "t_c", "v", "L", "A", "m1", "dP")
WORK = ROOT / ".fencesweep-audit"


def run(spec_path: Path, step_factor: float | None, jobs: int | None, reuse: bool) -> tuple[pd.DataFrame, Path]:
    """The spec's table (at its own setting, or with params.step_factor), and its path."""
    data = yaml.safe_load(spec_path.read_text())
    data.pop("design", None)
    tag = "default" if step_factor is None else f"sf{step_factor:g}"
    out = WORK / f"{spec_path.stem}-{tag}.parquet"
    if step_factor is not None:
        data.setdefault("params", {})["step_factor"] = step_factor
    if reuse and out.exists():
        return pd.read_parquet(out), out
    WORK.mkdir(exist_ok=True)
    t0 = time.perf_counter()
    df = fencesweep.grid(data, out=out, jobs=jobs, verify=False, overwrite=True, progress=sys.stderr.isatty())
    print(f"  {spec_path.name} at {tag}: {len(df)} rows in {time.perf_counter() - t0:.1f} s", flush=True)
    return df, out


def differences(a: pd.DataFrame, b: pd.DataFrame) -> pd.DataFrame:
    """Per row and column, |b - a| / max(|b|, floor) (a: the default table, b: the tighter one);
    NaN in both counts as equal, NaN in one as infinitely different."""
    out = {}
    for c, fl in COLUMNS.items():
        x = a[c].to_numpy(float)
        y = b[c].to_numpy(float)
        if fl is None:
            fl = COLUMNS["peak_force"] / b["freefall_force"].to_numpy(float)
        d = np.abs(y - x) / np.maximum(np.abs(y), fl)
        both = np.isnan(x) & np.isnan(y)
        one = np.isnan(x) ^ np.isnan(y)
        d[both] = 0.0
        d[one] = np.inf
        out[c] = d
    return pd.DataFrame(out, index=a.index)


def feasible_changed(pa: Path, pb: Path) -> tuple[int, int] | None:
    """(design points whose feasible verdict differs, design points) of an envelope study."""
    fa, fb = pa.with_name(pa.stem + "_points.parquet"), pb.with_name(pb.stem + "_points.parquet")
    if not (fa.exists() and fb.exists()):
        return None
    a, b = pd.read_parquet(fa), pd.read_parquet(fb)
    return int((a["feasible"].to_numpy() != b["feasible"].to_numpy()).sum()), len(a)


def audit(spec_path: Path, step_factor: float, jobs: int | None, worst: int, reuse: bool) -> list[str]:
    """Run and compare one spec; returns its page section's lines (also printed)."""
    a, pa = run(spec_path, None, jobs, reuse)
    b, pb = run(spec_path, step_factor, jobs, reuse)
    keys = [c for c in SHOW if c in a.columns]
    same = all(a[c].equals(b[c]) for c in keys)
    if len(a) != len(b) or not same:
        raise SystemExit(f"{spec_path}: the two tables do not have the same rows")
    d = differences(a, b)
    lines = [f"## {spec_path.as_posix()}", "",
             f"{len(a):,} rows; default against step_factor {step_factor:g} (tolerance / {1 / step_factor ** 5:.0f}).",
             ""]
    outcomes = int((a["outcome"].to_numpy() != b["outcome"].to_numpy()).sum())
    lines.append(f"Outcomes that differ: {outcomes}.")
    fc = feasible_changed(pa, pb)
    if fc is not None:
        lines.append(f"Feasible verdicts that differ: {fc[0]} of {fc[1]:,} design points.")
    lines += ["", f"| column | floor | rows over {BOUND:g} | over 1e-2 | max |", "|---|---:|---:|---:|---:|"]
    for c, fl in COLUMNS.items():
        col = d[c].to_numpy()
        lines.append(f"| {c} | {'50 N / freefall_force' if fl is None else f'{fl:.3g}'} | {int((col > BOUND).sum()):,} | {int((col > 1e-2).sum()):,} | "
                     f"{np.nanmax(col):.2g} |")
    worst_d = d.max(axis=1)
    over = worst_d[worst_d > BOUND].sort_values(ascending=False)
    lines += ["", f"Rows over {BOUND:g} in any column: {len(over):,}."]
    if len(over):
        lines += ["", f"The worst {min(worst, len(over))}:", "",
                  "| " + " | ".join(keys) + " | column | default | tight | difference |",
                  "|" + "---|" * (len(keys) + 4)]
        for i in over.index[:worst]:
            c = d.loc[i].idxmax()
            vals = " | ".join(f"{a.at[i, k]:.6g}" if isinstance(a.at[i, k], float) else str(a.at[i, k]) for k in keys)
            lines.append(f"| {vals} | {c} | {a.at[i, c]:.6g} | {b.at[i, c]:.6g} | {d.at[i, c]:.2g} |")
    lines.append("")
    print("\n".join(lines), flush=True)
    return lines


def rerun(spec_path: Path, step_factor: float) -> None:
    """Run again, with this tree, the rows of the kept tables over BOUND; print the counts before and now."""
    from fencesweep.model import params as P
    from fencesweep.model.simulate import simulate_resolved

    a, _ = run(spec_path, None, None, True)
    b, _ = run(spec_path, step_factor, None, True)
    d = differences(a, b)
    rows = d.index[(d > BOUND).any(axis=1)]
    given = [c for c in a.columns[:a.columns.get_loc("Psi")] if c not in ("scene", "case", "n_cycles", "period",
                                                                          "step_factor")]
    again = []
    for i in rows:
        kw = {c: a.at[i, c] for c in given if not (isinstance(a.at[i, c], float) and math.isnan(a.at[i, c]))}
        pair = [simulate_resolved(P.resolve(a.at[i, "scene"], None, step_factor=f, **kw))[0] for f in (1.0, step_factor)]
        again.append(differences(pd.DataFrame([pair[0]]), pd.DataFrame([pair[1]])).iloc[0])
    now = pd.DataFrame(again, index=rows, columns=d.columns)
    print(f"{spec_path.name}: {len(rows)} rows over {BOUND:g} in the kept tables, run again with this tree")
    for c in d.columns:
        print(f"  {c:20s} kept: {int((d.loc[rows, c] > BOUND).sum()):5d}   now: {int((now[c] > BOUND).sum()):5d}"
              f"   now's max {now[c].max() if len(now) else 0.0:.2g}")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("specs", nargs="+", type=Path)
    ap.add_argument("--step-factor", type=float, default=TIGHT)
    ap.add_argument("--jobs", type=int, default=None)
    ap.add_argument("--worst", type=int, default=10)
    ap.add_argument("--reuse", action="store_true", help="compare the tables kept by an earlier call")
    ap.add_argument("--rerun", action="store_true", help="run again only the kept tables' rows over the bound")
    ap.add_argument("--page", type=Path, default=None, help="write the sections to this Markdown page")
    ap.add_argument("--notes", type=Path, default=None, help="Markdown put on the page before the sections")
    args = ap.parse_args(argv)
    if not 0.0 < args.step_factor < 1.0:
        raise SystemExit(f"--step-factor {args.step_factor} is not allowed: it must lie in (0, 1)")
    if args.rerun:
        for s in args.specs:
            rerun(s, args.step_factor)
        return
    sections = []
    for s in args.specs:
        sections += audit(s, args.step_factor, args.jobs, args.worst, args.reuse)
    if args.page:
        head = ["# Whole-table audit", "",
                "Every row of each study at the default setting against the same study at a 100x tighter",
                "tolerance (`python benchmarks/audit.py SPEC ... --page results/audit.md`). Differences are",
                "relative, |tight - default| / max(|tight|, floor), floors as in the table's header.", ""]
        notes = [args.notes.read_text().rstrip("\n"), ""] if args.notes else []
        args.page.write_text("\n".join(head + notes + sections))


if __name__ == "__main__":
    main()
