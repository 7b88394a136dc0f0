"""Figures of the design for every package: the robust feasible region over B2 x K2,
the operating window over t_c x v, the sensitivity bars. Drawn from the tables in results/
(`fencesweep plot-design`); matplotlib is imported only here.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from fencesweep.errors import MissingTable


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _need(path: Path, how: str) -> Path:
    if not path.exists():
        raise MissingTable(f"{path} is missing; make it with: {how}")
    return path


def _save(fig, out: Path, name: str) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / name
    fig.savefig(path, dpi=110)
    _plt().close(fig)
    return path


def _edges(v: np.ndarray) -> np.ndarray:
    mid = (v[1:] + v[:-1]) / 2
    return np.concatenate([[v[0] - (mid[0] - v[0])], mid, [v[-1] + (v[-1] - mid[-1])]])


BINDING = ["scraped", "overload", "deflection_max", "residual_amplitude"]
#: colours of the binding constraint (right panel). The left panel's diverging map gives red to a
#: broken margin and blue to a kept one, so these hues are neither red nor blue: one colour, one meaning.
BINDING_COLORS = ["#984ea3", "#e6ab02", "#8c510a", "#1b9e77"]
#: markers of the compared elements on both panels: the element to build, and every other one
BUILD_MARK = dict(marker="*", ms=17, mfc="white", mec="k", mew=1.2, ls="")
OTHER_MARK = dict(marker="o", ms=8, mfc="0.55", mec="k", mew=1.0, ls="")


def _mark_elements(axes, rec: dict, K2: np.ndarray) -> None:
    """The compared elements of recommended.json on both panels, each named; the element to build
    (its design variables) with BUILD_MARK, the others with OTHER_MARK."""
    dv = rec["design_variables"]
    for row in rec["comparison"]:
        if row.get("B2") is None or row.get("K2") is None:
            continue
        build = math.isclose(row["B2"], dv["B2"]) and math.isclose(row["K2"], dv["K2"])
        nums = f"{row['B2']:g}/{row['K2']:g}"
        text = f"to build: {nums}" if build else (row["design"] if nums in row["design"] else f"{row['design']} {nums}")
        high = row["K2"] > K2.min() + 0.85 * (K2.max() - K2.min())
        for a in axes:
            a.plot(row["B2"], row["K2"], zorder=5, **(BUILD_MARK if build else OTHER_MARK))
            a.annotate(text, (row["B2"], row["K2"]), fontsize=7.5 if build else 7, xytext=(8, -14 if high else 7),
                       textcoords="offset points", zorder=6, weight="bold" if build else "normal",
                       bbox={"boxstyle": "round,pad=0.15", "fc": "white", "alpha": 0.8, "lw": 0})


def _legends(axes, rec: dict, present: set) -> None:
    """Each panel says under it what its colours, line and markers mean (`present`: the binding
    constraints the right panel shows)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    ok = "the element to build" if str(rec.get("status")).startswith("feasible") else "the design's best (infeasible)"
    marks = [Line2D([], [], color="k", lw=1.2, label="margin 0: the edge of the robust feasible region"),
             Line2D([], [], label=ok + " (design/recommended.json)", **BUILD_MARK),
             Line2D([], [], label="compared elements", **OTHER_MARK)]
    axes[0].legend(handles=[Patch(color="#b2182b", label="red: margin < 0, some load breaks a constraint"),
                            Patch(color="#2166ac", label="blue: margin > 0, every load keeps every constraint"),
                            *marks], loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=2, fontsize=7.5,
                   frameon=False)
    axes[1].legend(handles=[Patch(color=c, label=f"{b} binds") for c, b in zip(BINDING_COLORS, BINDING)
                            if b in present] + marks,
                   loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=2, fontsize=7.5, frameon=False,
                   title="the constraint with the smallest margin (inside the black line it still holds)",
                   title_fontsize=7.5)


def envelope_map(res: Path, out: Path) -> Path:
    """The smallest margin over the envelope's loads on B2 x K2, its zero contour (the robust
    feasible region), the binding constraint, and the compared elements. Red and blue mean a
    broken and a kept margin on the left panel only; the binding constraints on the right have
    colours of their own (BINDING_COLORS), and each panel's legend says what its colours are."""
    import pandas as pd

    pts = pd.read_parquet(_need(res / "envelope_points.parquet", "fencesweep grid sweeps/envelope.yaml"))
    rec = json.loads(_need(res / "design" / "recommended.json",
                           "fencesweep design sweeps/envelope.yaml").read_text())
    B2, K2 = np.sort(pts["B2"].unique()), np.sort(pts["K2"].unique())
    grid = pts.pivot(index="K2", columns="B2", values="min_margin").loc[K2, B2].to_numpy()
    bind = pts.assign(code=pts["binding"].map({b: i for i, b in enumerate(BINDING)})) \
        .pivot(index="K2", columns="B2", values="code").loc[K2, B2].to_numpy()
    plt = _plt()
    from matplotlib.colors import ListedColormap, TwoSlopeNorm

    fig, axes = plt.subplots(1, 2, figsize=(13, 6.6), layout="constrained")
    ax = axes[0]
    top = max(0.02, float(np.nanmax(grid)))
    m = ax.pcolormesh(_edges(B2), _edges(K2), np.clip(grid, -1.0, top), cmap="RdBu",
                      norm=TwoSlopeNorm(0.0, -1.0, top), shading="flat")
    fig.colorbar(m, ax=ax, label="smallest margin over the loads, 1 - worst / limit [-] (below -1: -1)")
    ax.set_title(f"Smallest margin over {int(pts['n_loads'].iloc[0])} loads of the envelope: "
                 f"{int(pts['feasible'].sum())} of {len(pts)} elements keep every constraint", fontsize=9)
    ax = axes[1]
    ax.pcolormesh(_edges(B2), _edges(K2), bind, cmap=ListedColormap(BINDING_COLORS), vmin=-0.5, vmax=3.5,
                  shading="flat")
    ax.set_title("The constraint with the smallest margin (the one that binds)", fontsize=9)
    for a in axes:
        a.contour(B2, K2, grid, levels=[0.0], colors="k", linewidths=1.2)
        a.set_xlabel("B2 [N m s/rad]")
        a.set_ylabel("K2 [N m/rad]")
    _mark_elements(axes, rec, K2)
    _legends(axes, rec, set(pts["binding"]))
    fixed = rec["fixed"]
    fig.suptitle(f"Design for every package: B2 x K2 over the load envelope (t_c = {fixed.get('t_c', 1.36):g} s, "
                 f"v = {fixed.get('v', 2.0):g} m/s; residual amplitude <= "
                 f"{math.degrees(rec['constraints']['residual_amplitude']):.3g} deg)", fontsize=10)
    return _save(fig, out, "envelope_map.png")


def worst_loads(res: Path, out: Path) -> Path:
    """Overload of every load of the verification sample across the belt, per compared element:
    where on the belt the worst loads start."""
    import pandas as pd

    per = pd.read_parquet(_need(res / "design" / "verify_loads.parquet", "fencesweep design sweeps/envelope.yaml"))
    rec = json.loads((res / "design" / "recommended.json").read_text())
    p_max = float(rec["fixed"].get("P_max", 0.7))
    designs = list(dict.fromkeys(per["design"]))
    plt = _plt()
    fig, axes = plt.subplots(1, len(designs), figsize=(3.3 * len(designs), 3.8), layout="constrained",
                             sharey=True)
    for ax, d in zip(np.atleast_1d(axes), designs):
        s = per[per["design"] == d]
        frac = s["dP"] / (p_max - s["A"])
        ok = s["outcome"] == "scraped"
        color = s.loc[ok, "m1"] if "m1" in s else np.full(int(ok.sum()), 15.0)
        size = 10 + 30 * (s.loc[ok, "L"] if "L" in s else 0.7)
        sc = ax.scatter(frac[ok], s.loc[ok, "overload"], c=color, cmap="viridis", s=size)
        if (~ok).any():
            ax.scatter(frac[~ok], s.loc[~ok, "overload"], marker="x", color="r", label="not scraped")
            ax.legend(fontsize=7)
        ax.axhline(1.0, color="k", ls="--", lw=0.8)
        ax.set_title(f"{d}\nworst {s['overload'].max():.3f}", fontsize=8)
        ax.set_xlabel("start across the belt, dP / (P_max - A) [-]")
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel("overload [-]")
    fig.colorbar(sc, ax=axes, label="m1 [kg] (marker size: L)")
    fig.suptitle(f"Overload of each of the {per['load'].nunique()} loads of the verification sample", fontsize=10)
    return _save(fig, out, "envelope_loads.png")


def element_label(drive: str, B2: float, K2: float) -> str:
    return "rigid fence" if drive == "rigid" else f"{B2:g} / {K2:g}"


def window(res: Path, out: Path) -> Path:
    """Per element: the smallest margin over the envelope on t_c x v; the zero contour bounds the
    operating window; the title gives the shortest safe t_c and its packages per hour."""
    import pandas as pd

    pts = pd.read_parquet(_need(res / "window_points.parquet", "fencesweep grid sweeps/window.yaml"))
    groups = list(pts.groupby(["drive", "B2", "K2"], sort=False))
    plt = _plt()
    from matplotlib.colors import TwoSlopeNorm

    fig, axes = plt.subplots(1, len(groups), figsize=(3.4 * len(groups) + 1, 4.2), layout="constrained",
                             sharey=True)
    for ax, ((drive, b2, k2), g) in zip(np.atleast_1d(axes), groups):
        tc, v = np.sort(g["t_c"].unique()), np.sort(g["v"].unique())
        grid = g.pivot(index="t_c", columns="v", values="min_margin").loc[tc, v].to_numpy()
        m = ax.pcolormesh(_edges(v), _edges(tc), np.clip(grid, -0.5, 0.5), cmap="RdBu",
                          norm=TwoSlopeNorm(0.0, -0.5, 0.5), shading="flat")
        ok = g[g["feasible"]]
        ax.scatter(ok["v"], ok["t_c"], marker=".", color="k", s=12)
        best = ok["t_c"].min() if len(ok) else math.nan
        ax.set_title(f"{element_label(drive, b2, k2)}\n{len(ok)} of {len(g)} safe; shortest safe t_c "
                     + (f"{best:g} s = {3600 / best:.0f} /h" if len(ok) else "none"), fontsize=8)
        ax.set_xlabel("belt speed v [m/s]")
    np.atleast_1d(axes)[0].set_ylabel("work cycle time t_c [s]")
    fig.colorbar(m, ax=axes, label="smallest margin over the loads (clipped to +-0.5) [-]")
    fig.suptitle(f"Operating window over the load envelope ({int(pts['n_loads'].iloc[0])} loads): dots = every "
                 "load keeps every constraint; one load per work cycle gives 3600 / t_c packages per hour", fontsize=9)
    return _save(fig, out, "window.png")


def sensitivity(res: Path, out: Path) -> Path:
    """Sobol indices (first order S1, total ST, 95 % confidence bars) per output and input."""
    import pandas as pd

    df = pd.read_parquet(_need(res / "sensitivity.parquet", "fencesweep sensitivity sweeps/sensitivity.yaml"))
    outputs = list(dict.fromkeys(df["output"]))
    inputs = list(dict.fromkeys(df["input"]))
    plt = _plt()
    fig, axes = plt.subplots(1, len(outputs), figsize=(3.6 * len(outputs), 3.8), layout="constrained", sharey=True)
    x = np.arange(len(inputs))
    for ax, o in zip(np.atleast_1d(axes), outputs):
        d = df[df["output"] == o].set_index("input").loc[inputs]
        ax.bar(x - 0.2, d["S1"], 0.4, yerr=d["S1_conf"], label="S1 (first order)", color="#4575b4", capsize=2)
        ax.bar(x + 0.2, d["ST"], 0.4, yerr=d["ST_conf"], label="ST (total)", color="#d73027", capsize=2)
        ax.set_xticks(x, inputs)
        ax.axhline(0, color="k", lw=0.6)
        unit = " rad" if o in ("worst_deflection_max", "worst_residual_amplitude") else ""
        ax.set_title(f"{o}\n{d['output_min'].iloc[0]:.3g} .. {d['output_max'].iloc[0]:.3g}{unit} over the sample",
                     fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    np.atleast_1d(axes)[0].set_ylabel("Sobol index [-]")
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.suptitle("Sensitivity of the envelope recommendation's worst results over the loads to the assumed inputs "
                 "(SALib, Saltelli sample)", fontsize=9)
    return _save(fig, out, "sensitivity.png")


def risk_map(res: Path, out: Path) -> Path:
    """The risk map of `fencesweep risk sweeps/risk.yaml` (report/risk_figures.py)."""
    from fencesweep.report.risk_figures import risk_map as draw

    return draw(res, out)


FIGURES = {"envelope_map": envelope_map, "envelope_loads": worst_loads, "window": window, "sensitivity": sensitivity,
           "risk_map": risk_map}


def plot(names, res: Path, out: Path | None = None, log=None) -> list:
    """Draw the named figures ('all' or none: every one whose tables exist, `log` told of the
    others); return the PNG paths written. A named figure whose table is missing raises MissingTable."""
    out = Path(out) if out else Path(res) / "figures"
    every = not names or "all" in names
    paths = []
    for n in (list(FIGURES) if every else names):
        try:
            paths.append(FIGURES[n](Path(res), out))
        except MissingTable as exc:
            if not every:
                raise
            if log:
                log(f"skipping {n}: {exc}")
    return paths

