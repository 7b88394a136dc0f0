"""The risk map (`fencesweep plot-design risk_map`): P(any constraint broken) under a parcel mix,
in parcels per 10,000, over B2 x K2, from the table of `fencesweep risk` (results/risk.parquet):
the p_max contour, each cell's decision, the element of least risk and the spec's compared
elements (compare:) marked with their numbers. matplotlib is imported only when drawing.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fencesweep.errors import MissingTable

LEAST = dict(marker="*", ms=17, mfc="white", mec="k", mew=1.2, ls="")
COMPARED = dict(ms=9, mfc="tab:green", mec="k", mew=1.0, ls="")
MARKS = ("o", "s", "D", "^", "v", "P", "X")


def least_risk(df):
    """The row of least risk: the smallest upper end of the P(any) interval (the element whose risk
    its sample bounds lowest), then the smallest estimate. Not the smallest estimate alone: the
    sequential stop leaves a unit at 0 failures after a few hundred parcels with an estimate of 0
    and a wide interval, and a unit that ran on with a few failures may well be the safer one."""
    return df.sort_values(["p_any_hi", "p_any", "B2", "K2"], kind="stable").iloc[0]


def ties(df, best) -> int:
    """Units other than `best` whose P(any) interval overlaps best's: the sample does not rank them."""
    return int(((df["p_any_lo"] <= best["p_any_hi"]) & (df["p_any_hi"] >= best["p_any_lo"])).sum()) - 1


def _edges(v: np.ndarray) -> np.ndarray:
    mid = (v[1:] + v[:-1]) / 2
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


def _panel(fig, ax, g, p_max: float) -> None:
    from matplotlib.colors import LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    grid = g[g["label"].isna()]
    B2, K2 = np.sort(grid["B2"].unique()), np.sort(grid["K2"].unique())
    per = grid.pivot(index="K2", columns="B2", values="in_10000_any").loc[K2, B2].to_numpy()
    dec = grid.pivot(index="K2", columns="B2", values="decision").loc[K2, B2].to_numpy()
    floor = 0.5 * 1e4 / max(int(grid["n"].max()), 1)  # half a parcel of the largest sample: where 0 is drawn
    m = ax.pcolormesh(_edges(B2), _edges(K2), np.clip(per, floor, 1e4), cmap="magma_r",
                      norm=LogNorm(floor, 1e4), shading="flat")
    fig.colorbar(m, ax=ax, label="parcels in 10,000 that break a constraint (P(any) x 10,000; 0 drawn at the "
                                 "bottom of the scale)")
    # the contour on log10 of the estimates: between two cells it lies where the log-linear interpolation crosses p_max
    ax.contour(B2, K2, np.log10(np.clip(per, floor, 1e4)), levels=[np.log10(p_max * 1e4)], colors="tab:cyan",
               linewidths=2.0)
    for i, k in enumerate(K2):
        for j, b in enumerate(B2):
            v = per[i, j]
            ax.text(b, k, f"{v:.0f}" + ("?" if dec[i, j] == "undecided" else ""), ha="center", va="center",
                    fontsize=7, color="white" if v > 300 else "k", weight="bold" if dec[i, j] == "above" else "normal")
    best = least_risk(g)
    handles = [Line2D([], [], label=f"least risk (the lowest upper end): {best['B2']:g}/{best['K2']:g}, "
                                    f"{best['in_10000_any']:.0f} in 10,000 ({best['p_any_lo'] * 1e4:.0f}-"
                                    f"{best['p_any_hi'] * 1e4:.0f}); {ties(g, best)} others' intervals overlap it",
                      **LEAST)]
    ax.plot(best["B2"], best["K2"], zorder=5, **LEAST)
    for row, mark in zip(g[g["label"].notna()].to_dict("records"), MARKS):
        ax.plot(row["B2"], row["K2"], zorder=6, **COMPARED, marker=mark)
        handles.append(Line2D([], [], **COMPARED, marker=mark, label=(
            f"{row['label']}: {row['in_10000_any']:.0f} in 10,000 ({row['p_any_lo'] * 1e4:.0f}-"
            f"{row['p_any_hi'] * 1e4:.0f}): {row['in_10000_overload']:.0f} hit too hard, "
            f"{row['in_10000_not_scraped']:.0f} not sorted")))
    handles += [Line2D([], [], color="tab:cyan", lw=2, label=f"p_max = {p_max * 1e4:g} in 10,000 (on the estimates)"),
                Patch(color="none", label="cell: parcels in 10,000 that break a constraint; bold: decided above p_max, "
                                          "plain: below, ?: undecided at the cap")]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=1, fontsize=7.5, frameon=False)
    ax.set_xlabel("B2 [N m s/rad]")
    ax.set_ylabel("K2 [N m/rad]")


def risk_map(res: Path, out: Path) -> Path:
    """P(any) per 10,000 over B2 x K2 for each operating point of results/risk.parquet."""
    import pandas as pd

    path = Path(res) / "risk.parquet"
    if not path.exists():
        raise MissingTable(f"{path} is missing; make it with: fencesweep risk sweeps/risk.yaml")
    df = pd.read_parquet(path)
    prov = df.attrs.get("fencesweep", {})
    p_max = float(prov["risk"]["p_max"])
    ops = df[["t_c", "v"]].drop_duplicates().to_records(index=False).tolist()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(ops), figsize=(8.2 * len(ops), 8.4), layout="constrained", squeeze=False)
    for ax, (t_c, v) in zip(axes[0], ops):
        g = df[(df["t_c"] == t_c) & (df["v"] == v)]
        _panel(fig, ax, g, p_max)
        ax.set_title(f"Risk under the parcel mix of {Path(prov.get('spec_path') or 'the spec').name} "
                     f"(assumed; seed {prov['population']['seed']}): t_c = {t_c:g} s, v = {v:g} m/s", fontsize=9)
    Path(out).mkdir(parents=True, exist_ok=True)
    fig.savefig(Path(out) / "risk_map.png", dpi=110)
    plt.close(fig)
    return Path(out) / "risk_map.png"
