"""The paper's figures drawn from sweep tables (analysis.TABLES): Fig. 5a (overload against v and t_c,
the named cases and the worst over the load's placements), Fig. 5b (the quotient of peak forces
against m2) and Fig. 6 (damper energy and maximal deflection at Psi = 1).
Drawing only: every number comes from a Parquet file the engine wrote.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fencesweep.report import analysis as RP
from fencesweep.report.figures_common import DRIVE_COLORS, DRIVE_LABELS, WORKING_POINT, pyplot, save


# ---------------------------------------------------------------------------- Fig 5a
def fig5a(res: Path, out: Path) -> Path:
    """Paper Fig. 5a: overload against v (t_c = 1.36 s) and t_c (v = 2 m/s); rigid, flexible, free. The named
    cases, and (when its tables are there) the worst over the load's placements, the paper's §4.1 arrangement."""
    plt = pyplot()
    df = RP.read_table(res, "fig5a")
    ff = RP.read_table(res, "freefall_H").sort_values("H")
    ref = float(ff.loc[(ff["H"] - 0.3).abs().idxmin(), "peak_force"])
    levels = [(h, float(ff.loc[(ff["H"] - h).abs().idxmin(), "peak_force"]) / ref) for h in RP.FREEFALL_LEVELS_H]
    cases = [c for c in RP.CASES if c in set(df["case"])]
    worst = {axis: RP.worst_over_placements(RP.read_table(res, n)) for n, axis in RP.WORST_TABLES.items()
             if RP.table_path(res, n).exists()}
    nrow = len(cases) + (1 if worst else 0)
    fig, axes = plt.subplots(nrow, 2, figsize=(10, 3.6 * nrow), squeeze=False)
    tc0 = min(set(df["t_c"]), key=lambda x: abs(x - 1.36))
    v0 = min(set(df["v"]), key=lambda x: abs(x - 2.0))
    cuts = (("v", "t_c", tc0, "belt speed v [m/s]"), ("t_c", "v", v0, "work cycle time t_c [s]"))
    ymax = max(1.15, float(df["overload"].max()) * 1.08)
    for r, case in enumerate(cases):
        d = df[df["case"] == case]
        for c, (axis, fixed, fval, label) in enumerate(cuts):
            ax = axes[r, c]
            for drive in ("rigid", "flexible", "free"):
                s = d[(d["drive"] == drive) & (d[fixed] == fval)].sort_values(axis)
                if s.empty or (drive == "free" and not (s["t_first_contact"] > 1e-3).any()):
                    continue  # a load touching at t = 0 releases the free fence at once: nothing to show
                _overload_curve(ax, s, axis, drive)
            if case == "long_near":
                ax.text(0.02, 0.97, "free fence not shown: this load touches the fence at t = 0,\nwhich releases "
                        "it at once", transform=ax.transAxes, fontsize=7, va="top", color=DRIVE_COLORS["free"])
            unit = "s" if fixed == "t_c" else "m/s"
            _fig5a_axes(ax, levels, label, f"{case}: against {axis} at {fixed} = {fval:g} {unit}", ymax)
    if worst:
        _fig5a_worst_row(axes[-1], worst, df[df["case"] == "small_far"], cuts, levels,
                         max(ymax, max(float(w["overload"].max()) for w in worst.values()) * 1.08))
    from matplotlib.lines import Line2D

    h, lab = axes[0, 0].get_legend_handles_labels()
    h += [Line2D([], [], ls="", marker="o", color="0.3", ms=4), Line2D([], [], ls="", marker="x", color="0.3", ms=6),
          Line2D([], [], ls="--", color="0.35")]
    lab += ["load scraped", "load NOT scraped (escaped)",
            f"free fall from H = {' / '.join(f'{x:g}' for x in RP.FREEFALL_LEVELS_H)} m"]
    if worst:
        h += [Line2D([], [], ls=":", color="0.3", lw=0.8),
              Line2D([], [], ls="", marker="o", ms=9, mfc="none", color="0.3")]
        lab += ["bottom row, dotted: the named small_far (top row)",
                "bottom row, ringed: two fence contact points at once (S3) in that contact"]
    fig.legend(h, lab, loc="lower center", ncol=3, fontsize=8, bbox_to_anchor=(0.5, -0.01))
    fig.suptitle("Paper Fig. 5a: overload = peak fence force / peak of a free fall from H = 0.3 m (m1 = 15 kg, "
                 "m2 = 5 kg)\nThe free fence is released at the first contact (an idealisation of the impact, "
                 "not a working drive)")
    fig.tight_layout(rect=(0, 0.08 if worst else 0.06, 1, 1))
    return save(fig, out, "fig5a_overload_v_tc.png")


def _fig5a_worst_row(axes, worst: dict, sf, cuts, levels, ymax: float) -> None:
    """Fig. 5a's bottom row: the worst overload over the load's placements (§4.1), the named small_far dotted."""
    for ax, (axis, fixed, fval, label) in zip(axes, cuts):
        if axis not in worst:
            ax.axis("off")
            continue
        w = worst[axis]
        for drive in ("rigid", "flexible", "free"):
            named = sf[(sf["drive"] == drive) & (sf[fixed] == fval)].sort_values(axis)
            ax.plot(named[axis], named["overload"], color=DRIVE_COLORS[drive], lw=0.8, ls=":")
            s = w[w["drive"] == drive].sort_values(axis)
            _overload_curve(ax, s, axis, drive)
            two = s[s["two_points"]]
            ax.plot(two[axis], two["overload"], "o", ms=9, mfc="none", mew=0.9, color=DRIVE_COLORS[drive])
        unit = "s" if fixed == "t_c" else "m/s"
        _fig5a_axes(ax, levels, label, f"worst of {int(w['n_placements'].iloc[0])} placements of the small_far "
                    f"load (paper §4.1)\nagainst {axis} at {fixed} = {fval:g} {unit}", ymax)


def _overload_curve(ax, s, axis: str, drive: str) -> None:
    """One drive's overload along a cut: line, dots where the load is scraped, crosses where it is not."""
    col = DRIVE_COLORS[drive]
    ax.plot(s[axis], s["overload"], color=col, lw=1.4, label=DRIVE_LABELS[drive])
    ok = s["outcome"] == "scraped"
    ax.plot(s[axis][ok], s["overload"][ok], "o", ms=3.5, color=col)
    ax.plot(s[axis][~ok], s["overload"][~ok], "x", ms=6, mew=1.5, color=col)


def _fig5a_axes(ax, levels, xlabel: str, title: str, ymax: float) -> None:
    for h, lev in levels:
        ax.axhline(lev, color="0.35", lw=0.9, ls="--")
        ax.text(1.01, lev, f"H = {h:g} m", va="center", fontsize=7, color="0.3", transform=ax.get_yaxis_transform())
    ax.set_xlabel(xlabel)
    ax.set_ylabel("overload [-]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.set_ylim(0, ymax)


# ---------------------------------------------------------------------------- Fig 5b
def fig5b(res: Path, out: Path) -> Path:
    """Paper Fig. 5b: peak force against a rigid fence over that against a free fence, against m2."""
    plt = pyplot()
    df = RP.read_table(res, "fig5b")
    p = df.pivot_table(index="m2", columns="drive", values="peak_force").sort_index()
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    q = p["rigid"] / p["free"]
    ax.plot(q.index, q.values, "o-", color=DRIVE_COLORS["free"], ms=3.5, lw=1.5,
            label="N_max(rigid) / N_max(free fence of mass m2)")
    if "flexible" in p:
        qf = p["rigid"] / p["flexible"]
        ax.plot(qf.index, qf.values, "--", color=DRIVE_COLORS["flexible"], lw=1.2,
                label="N_max(rigid) / N_max(flexible 72/570, mass m2)")
    if 5.0 in q.index:
        ax.plot([5.0], [q.loc[5.0]], "s", ms=7, mfc="none", color="k")
        ax.annotate(f"ours: {q.loc[5.0]:.2f} at m2 = 5 kg", (5.0, q.loc[5.0]), xytext=(12, 18),
                    textcoords="offset points", fontsize=8, arrowprops={"arrowstyle": "-", "lw": 0.6})
    ax.plot([5.0], [1.7], "*", ms=11, color="#ff7f0e", label="paper: ~ 1.7 at m2 = 5 kg")
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("fence mass m2 [kg] (I2 = m2 l^2 / 3, l = 1.2 m)")
    ax.set_ylabel("quotient of peak forces [-]")
    ax.set_title("Paper Fig. 5b: point load m1 = 15 kg hits the fence at R = 1.2 m, w = 2 m/s\n"
                 "(impact scene, modified Kelvin law, e = 0.2)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper right")
    fig.tight_layout()
    return save(fig, out, "fig5b_quotient_m2.png")


# ---------------------------------------------------------------------------- Fig 6
def fig6(res: Path, out: Path) -> Path:
    """Paper Fig. 6: damper energy and maximal deflection against B2 at Psi = 1."""
    plt = pyplot()
    df = RP.read_table(res, "psi_b2")
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.9))
    styles = {"small_far": ("#1f77b4", "-"), "long_near": ("#ff7f0e", "--")}
    perm = float(df["dalpha_perm"].iloc[0])
    for case in [c for c in RP.CASES if c in set(df["case"])]:
        d = df[df["case"] == case].sort_values("B2")
        col, ls = styles[case]
        ok = d["outcome"] == "scraped"
        for ax, y in ((axes[0], d["damper_energy"]), (axes[1], np.degrees(d["deflection_max"]))):
            ax.plot(d["B2"], y, ls=ls, color=col, lw=1.4, label=RP.CASE_TEXT[case])
            ax.plot(d["B2"][ok], y[ok], "o", ms=3, color=col)
            ax.plot(d["B2"][~ok], y[~ok], "x", ms=6, mew=1.4, color=col)
    axes[1].axhline(math.degrees(perm), color="k", lw=0.9, ls=":")
    axes[1].text(axes[1].get_xlim()[1], math.degrees(perm), f"dalpha_perm = {math.degrees(perm):.0f} deg ",
                 ha="right", va="bottom", fontsize=8)
    for ax in axes:
        ax.axvline(72.0, color="0.5", lw=0.8, ls="-.")
        ax.text(72.0, 0.98, " B2 = 72", transform=ax.get_xaxis_transform(), va="top", fontsize=7, color="0.35")
        ax.set_xlabel("damping of the flexible element B2 [N m s/rad]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("energy absorbed by the damper over one cycle [J]")
    axes[0].set_title("(a) energy absorbed by the damping element")
    axes[1].set_ylabel("maximal deflection |alpha - alpha_w| [deg]")
    axes[1].set_title("(b) maximal deflection of the fence from its drive")
    from matplotlib.lines import Line2D

    h, lab = axes[0].get_legend_handles_labels()
    h += [Line2D([], [], ls="", marker="o", color="0.3", ms=4), Line2D([], [], ls="", marker="x", color="0.3", ms=6)]
    lab += ["scraped", "NOT scraped (escaped)"]
    axes[0].legend(h, lab, loc="center right")
    fig.suptitle("Paper Fig. 6: the springy-damping element at relative damping Psi = 1\n"
                 "(K2 = B2^2 / (4 I2)" + (f", I2 = {float(df['I2'].iloc[0]):.3g} kg m^2" if "I2" in df else "")
                 + f"), {WORKING_POINT}, m2 = 5 kg")
    fig.tight_layout()
    return save(fig, out, "fig6_psi1_b2.png")
