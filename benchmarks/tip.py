"""The fence's tip band, before and after "one overlap, one force" (docs/model.md §5.2).

    python benchmarks/tip.py [--before 8a6dc2a] [--step 0.0025]
    python benchmarks/tip.py --tables [--before 8a6dc2a]    # the committed tables against REV's

Runs dP cuts across the belt through the tip band, peak_force at each dP, in this tree and in an
earlier revision's (common.export, its own process with PYTHONPATH set to its tree), and the
hump measure of each cut: the largest peak(dP) / max(peak(dP - 0.02), peak(dP + 0.02)) over the
cut (dP +- 0.02 read off the cut, which holds them). A ratio near 2 is one overlap pushed twice;
near 1, no hump. Writes results/tip.csv, results/tip_table.md and results/figures/tip_cuts.png.

With --tables: every committed table of results/ (the regenerated ones) against the same file at
REV (git show), row by row in their (same) order: the rows whose peak_force, deflection_max or
t_exit moved by more than 1e-3 (docs/model.md (15.15), with its floors) or whose outcome changed,
and the largest move; writes results/tip_tables.md.
"""
from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

import numpy as np
from common import ROOT, export, pyplot, run_json, save

#: the cuts: (name, simulate's arguments): small_far at R_s 0.5 on three drives, a long and a short load
CUTS = (
    ("small_far rigid, R_s 0.5", dict(case="small_far", R_s=0.5, drive="rigid")),
    ("small_far flexible, R_s 0.5", dict(case="small_far", R_s=0.5, drive="flexible")),
    ("small_far free, R_s 0.5", dict(case="small_far", R_s=0.5, drive="free")),
    ("long 0.7 x 0.1 rigid, R_s 0.3", dict(L=0.7, A=0.1, m1=15.0, R_s=0.3, drive="rigid")),
    ("long 0.7 x 0.1 flexible, R_s 0.3", dict(L=0.7, A=0.1, m1=15.0, R_s=0.3, drive="flexible")),
    ("short 0.1 x 0.1 rigid, R_s 0.5", dict(L=0.1, A=0.1, m1=2.0, R_s=0.5, drive="rigid")),
    ("short 0.1 x 0.1 flexible, R_s 0.5", dict(L=0.1, A=0.1, m1=2.0, R_s=0.5, drive="flexible")),
)
DP_LO, DP_HI, SIDE = 0.05, 0.6, 0.02

WORKER = r"""
import json, sys, math
import numpy as np
import fencesweep
cuts, dps = json.loads(sys.argv[1]), json.loads(sys.argv[2])
out = {}
for name, kw in cuts:
    rows = []
    for dP in dps:
        try:
            r = fencesweep.simulate("cycle", dP=dP, **kw)
            rows.append([dP, r["peak_force"], r["outcome"], r["status"]])
        except Exception as e:  # a start outside the belt: the load does not fit
            rows.append([dP, float("nan"), "invalid", str(e).splitlines()[0]])
    out[name] = rows
print(json.dumps(out))
"""


def run_tree(tree: Path, dps: list[float]) -> dict:
    """The cuts' peak forces computed by the package in `tree`, in a process of its own."""
    return run_json(WORKER, json.dumps(CUTS), json.dumps(dps), env={"PYTHONPATH": str(tree)}, cwd=tree)


def hump(dps: np.ndarray, peaks: np.ndarray, side: float = SIDE) -> tuple[float, float]:
    """The largest peak(dP) / max(peak(dP - side), peak(dP + side)) over a cut and where it is;
    points whose neighbours fall off the cut or have no contact are left out."""
    best, at = 0.0, float("nan")
    for i, dP in enumerate(dps):
        j = np.flatnonzero(np.isclose(dps, dP - side))
        k = np.flatnonzero(np.isclose(dps, dP + side))
        if not (len(j) and len(k)) or not np.isfinite(peaks[i]):
            continue
        ref = np.nanmax([peaks[j[0]], peaks[k[0]]])
        if not (ref > 0.0):
            continue
        if peaks[i] / ref > best:
            best, at = peaks[i] / ref, dP
    return best, at


def tables(before: str) -> None:
    """The committed tables against REV's (module docstring)."""
    import io

    import pandas as pd

    from fencesweep.study.sweep.accuracy import relative_difference
    lines = ["| table | rows | outcome changed | peak_force > 1e-3 | deflection_max > 1e-3 | t_exit > 1e-3 | "
             "largest move (column, relative) |", "|---|---:|---:|---:|---:|---:|---|"]
    for path in sorted((ROOT / "results").glob("*.parquet")):
        name = path.relative_to(ROOT).as_posix()
        old = subprocess.run(["git", "show", f"{before}:{name}"], cwd=ROOT, capture_output=True)
        if old.returncode:
            continue
        a, b = pd.read_parquet(io.BytesIO(old.stdout)), pd.read_parquet(path)
        if len(a) != len(b) or "peak_force" not in a:
            lines.append(f"| {name} | {len(b)} (was {len(a)}) | | | | | not comparable row by row |")
            continue
        ff = a["freefall_force"].to_numpy(float) if "freefall_force" in a else np.full(len(a), np.nan)
        counts, worst = {}, (0.0, "")
        for col in ("peak_force", "deflection_max", "t_exit"):
            if col not in a:
                counts[col] = "-"
                continue
            d = np.array([relative_difference(x, y, col, f) for x, y, f in
                          zip(a[col].to_numpy(float), b[col].to_numpy(float), ff)])
            counts[col] = int(np.sum(~(d <= 1e-3)))
            if np.nanmax(np.where(np.isfinite(d), d, 0.0), initial=0.0) > worst[0]:
                worst = (float(np.nanmax(np.where(np.isfinite(d), d, 0.0))), col)
        oc = int((a["outcome"].astype(str) != b["outcome"].astype(str)).sum()) if "outcome" in a else "-"
        lines.append(f"| {name} | {len(b):,} | {oc} | {counts['peak_force']} | {counts['deflection_max']} | "
                     f"{counts['t_exit']} | {worst[1]} {worst[0]:.3g} |")
    print("\n".join(lines))
    (ROOT / "results" / "tip_tables.md").write_text("\n".join(lines) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="8a6dc2a")
    ap.add_argument("--step", type=float, default=0.0025)
    ap.add_argument("--tables", action="store_true", help="compare the committed tables with REV's")
    a = ap.parse_args()
    if a.tables:
        tables(a.before)
        return
    n = int(round((DP_HI - DP_LO) / a.step))
    dps = [round(DP_LO + i * a.step, 6) for i in range(n + 1)]
    before = run_tree(export(a.before), dps)
    after = run_tree(ROOT, dps)
    import pandas as pd
    rows = []
    for name, _ in CUTS:
        for (dP, pb, ob, _), (_, pa, oa, sa) in zip(before[name], after[name]):
            rows.append(dict(cut=name, dP=dP, peak_before=pb, outcome_before=ob, peak_after=pa, outcome_after=oa,
                             status_after=sa))
    df = pd.DataFrame(rows)
    (ROOT / "results").mkdir(exist_ok=True)
    df.to_csv(ROOT / "results" / "tip.csv", index=False)
    lines = [f"| cut | hump before ({a.before}) | at dP | hump after | at dP | max peak before [N] | max peak after [N] |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for name, _ in CUTS:
        d = df[df.cut == name]
        x = d.dP.to_numpy()
        hb, xb = hump(x, d.peak_before.to_numpy(float))
        ha, xa = hump(x, d.peak_after.to_numpy(float))
        lines.append(f"| {name} | {hb:.2f} | {xb:.4f} | {ha:.2f} | {xa:.4f} | {np.nanmax(d.peak_before):,.0f} | "
                     f"{np.nanmax(d.peak_after):,.0f} |")
    print("\n".join(lines))
    (ROOT / "results" / "tip_table.md").write_text("\n".join(lines) + "\n")
    figure(df, ROOT / "results" / "figures" / "tip_cuts.png", a.before)


def figure(df, path: Path, before: str) -> None:
    """The cuts, peak force against dP, before and after, one panel a cut."""
    plt = pyplot()
    names = list(dict.fromkeys(df.cut))
    fig, axes = plt.subplots((len(names) + 1) // 2, 2, figsize=(11, 2.6 * ((len(names) + 1) // 2)), sharex=True)
    for ax, name in zip(axes.flat, names):
        d = df[df.cut == name]
        ax.plot(d.dP, d.peak_before / 1e3, color="0.6", lw=1.2, label=f"before ({before}): corner + tip summed")
        ax.plot(d.dP, d.peak_after / 1e3, color="C3", lw=1.2, label="after: one manifold")
        ax.set_title(name, fontsize=9)
        ax.set_ylabel("peak force [kN]")
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(names):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("dP [m] (load's lowest corner across the belt)")
    axes.flat[0].legend(fontsize=8, loc="upper left")
    fig.suptitle("Peak fence force across the belt, through the tip band", fontsize=11)
    fig.tight_layout()
    save(fig, path)


if __name__ == "__main__":
    main()
