"""Figures: the paper's Figs 2-8 recomputed, B2 x K2 design maps, one cycle in frames.

`fencesweep plot [NAME ...]` draws PNGs into <results>/figures/ from the sweep tables and
trajectories in <results>/ (fencesweep.report.document lists which: TABLES, TRAJECTORIES). Drawing
only: no physics here; every number comes from a Parquet file the engine wrote.

    fencesweep plot trajectories     # run the single cycles the figures need (engine)
    fencesweep plot all              # every figure
    fencesweep plot fig5a maps       # some of them
    fencesweep plot report           # results/REPORT.md

matplotlib is the optional extra `[plot]`; it is imported inside the functions (Agg
backend), so this module imports without it.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fencesweep.report import analysis as RP

DPI = 110
DRIVE_COLORS = {"rigid": "#1f77b4", "flexible": "#d62728", "free": "#2ca02c"}
DRIVE_LABELS = {"rigid": "(1) rigid fence (m2 = inf)", "flexible": "(2) flexible, B2 = 72, K2 = 570",
                "free": "(3) free fence (B2 = K2 = 0)"}
STAGE_COLORS = {0: "#f4a582", 1: "#f0f0f0", 2: "#92c5de", 3: "#c2a5cf", 4: "#bababa"}
OUTCOME_COLORS = {"scraped": "#4daf4a", "escaped": "#e41a1c", "timeout": "#ff7f00", "failed": "#000000"}
WORKING_POINT = "t_c = 1.36 s, v = 2 m/s, R_s = 0"


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "legend.fontsize": 8,
                         "figure.titlesize": 11})
    return plt


def _save(fig, out: Path, name: str) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / name
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def _case_title(df) -> str:
    p = df.attrs.get("params") or {}
    return f"{p.get('case')}: {p.get('L'):g} x {p.get('A'):g} m load, dP = {p.get('dP'):g} m"


def _levels(xs, min_sep: float) -> list:
    """A stacking level (0, 1, 2, ...) for labels at the sorted positions xs: labels on one level
    are at least min_sep apart, so neighbours close in x go one level up instead of overprinting."""
    last: list = []
    out = []
    for x in xs:
        k = next((k for k, lx in enumerate(last) if x - lx >= min_sep), len(last))
        if k == len(last):
            last.append(x)
        else:
            last[k] = x
        out.append(k)
    return out


def _event_points(ev) -> list:
    """[(t, letter)] of A, B and the C's (C1, C2, ... when there are several), sorted by time."""
    cs = [(t, f"C{k + 1}" if len(ev.C) > 1 else "C") for k, (t, _, _) in enumerate(ev.C)]
    return sorted(p for p in [(ev.A, "A"), (ev.B, "B")] + cs if math.isfinite(p[0]))


def _mark_events(ax, ev, t_scale=1.0, label=True, color="k") -> int:
    """Vertical lines at A, B and the C's; letters above the axes, stacked where they are close
    (call after the x limits are set). Returns the number of letter rows, for the title's pad."""
    pts = _event_points(ev)
    lo, hi = ax.get_xlim()
    for t, _ in pts:
        ax.axvline(t * t_scale, color=color, lw=0.7, ls=":", zorder=1)
    shown = [(t, s) for t, s in pts if lo <= t * t_scale <= hi]
    if not label or not shown:
        return 0
    lev = _levels([t * t_scale for t, _ in shown], 0.035 * (hi - lo))
    for (t, letter), k in zip(shown, lev):
        ax.annotate(letter, (t * t_scale, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 2 + 10 * k),
                    textcoords="offset points", ha="center", va="bottom", fontsize=8, fontweight="bold",
                    color=color)
    return max(lev) + 1


def _shade_stages(ax, ev, alpha=0.6):
    for t0, t1, s in ev.runs:
        if s != 1:  # S2 (no contact) stays white
            ax.axvspan(t0, t1, color=STAGE_COLORS.get(s, "#dddddd"), alpha=alpha, lw=0, zorder=0)


def _stage_legend_handles(stages):
    from matplotlib.patches import Patch

    return [Patch(color=STAGE_COLORS[s], label=RP.STAGE_NAMES[s]) for s in sorted(stages) if s != 1]


# ---------------------------------------------------------------------------- Figs 2-3
def _fig_impact(res: Path, out: Path, law: str) -> Path:
    plt = _plt()
    suf = "_linear" if law == "linear" else ""
    name = {"linear": "fig2_linear_law.png", "hertz": "fig3_modified_law.png"}[law]
    law_text = {"linear": "linear Kelvin law N = b D' + k D (paper eq. 2)",
                "hertz": "modified Kelvin law N = q (m1 k1)^0.5 D^0.25 D' + k1 D^1.5 (paper eq. 3)"}[law]
    rigid = RP.read_traj(res, f"small_far_rigid{suf}")
    window = 1.5 * RP.pulse_duration(rigid)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=False)
    for ax, panel in zip(axes, ("a", "b")):
        if panel == "a":
            curves = [(f"small_far_rigid{suf}", "e = 0.2", "#1f77b4", "-"),
                      (f"small_far_rigid{suf}_e0.5", "e = 0.5", "#9467bd", "--"),
                      (f"small_far_rigid{suf}_e0.9", "e = 0.9", "#8c564b", "-.")]
            ax.set_title("(a) rigid fence (m2 = inf), restitution e varied")
        else:
            curves = [(f"small_far_{d}{suf}", DRIVE_LABELS[d], DRIVE_COLORS[d], ls)
                      for d, ls in (("rigid", "-"), ("flexible", "--"), ("free", "-."))]
            ax.set_title("(b) e = 0.2: rigid, flexible and free fence")
        for tname, label, color, ls in curves:
            df = RP.read_traj(res, tname)
            ev = RP.events(df)
            t = df["t"].to_numpy()
            sel = (t >= ev.A - 0.1 * window) & (t <= ev.A + window)
            x = np.r_[(t[sel] - ev.A) * 1e3]
            y = df["N_fence"].to_numpy()[sel] / 1e3
            ax.plot(x, y, ls=ls, color=color, lw=1.4, label=label)
            first = RP.first_impact(df, window)
            if law == "linear" and math.isfinite(first["N_onset"]):
                ax.plot([first["dt_onset"] * 1e3], [first["N_onset"] / 1e3], "o", ms=4, color=color)
        ff = rigid.attrs["results"]["freefall_force"] / 1e3
        ax.axhline(ff, color="0.4", lw=0.8, ls=":")
        rp = rigid.attrs["params"]
        # the legend and the free-fall level's label in a band of their own above the line and the curves
        ax.text(0.4, ff, f"free fall from H = {rp['H']:g} m (e = {rp['e']:g}): {ff:.1f} kN", ha="center",
                va="bottom", fontsize=7, color="0.3", transform=ax.get_yaxis_transform())
        ax.set_xlim(-0.1 * window * 1e3, window * 1e3)
        top = 1.6 * max(ff, ax.get_ylim()[1])
        ax.set_ylim(0, top)
        ax.set_xlabel("time since first contact A, t - t_A [ms]")
        ax.set_ylabel("normal force of the load on the fence N [kN]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", framealpha=0.95)
    extra = " Dots: the force at the first integrator step after contact (the jump of the linear law)." \
        if law == "linear" else ""
    fig.suptitle(f"Paper Fig. {'2' if law == 'linear' else '3'}: force of the first impact, {law_text}\n"
                 f"small_far load (0.2 x 0.1 m, m1 = 15 kg) in the sorting cycle, {WORKING_POINT}." + extra,
                 fontsize=9.5)
    fig.tight_layout()
    return _save(fig, out, name)


def fig2(res: Path, out: Path) -> Path:
    """Paper Fig. 2: first-impact force with the linear Kelvin law."""
    return _fig_impact(res, out, "linear")


def fig3(res: Path, out: Path) -> Path:
    """Paper Fig. 3: first-impact force with the modified (Hertz-like) Kelvin law."""
    return _fig_impact(res, out, "hertz")


# ---------------------------------------------------------------------------- Fig 4
def fig4(res: Path, out: Path) -> Path:
    """Paper Fig. 4: drive input alpha_w and the moment of the load on the fence, both cases."""
    plt = _plt()
    fig, axes = plt.subplots(3, 1, figsize=(9, 9.2), gridspec_kw={"height_ratios": [0.7, 1, 1]})
    base = RP.read_traj(res, "small_far_flexible")
    tc = base.attrs["params"]["t_c"]
    ax = axes[0]
    ax.plot(base["t"], np.degrees(base["alpha_w"]), color="k", lw=1.4)
    ax.set_ylabel("alpha_w [deg]")
    ax.set_title(f"(a) kinematic input of the crank-rocker drive, t_c = {tc:g} s, swing "
                 f"{math.degrees(base.attrs['params']['swing']):.0f} deg")
    ax.grid(alpha=0.3)
    stages = set()
    for ax, case, letter in ((axes[1], "small_far", "b"), (axes[2], "long_near", "c")):
        flex = RP.read_traj(res, f"{case}_flexible")
        rig = RP.read_traj(res, f"{case}_rigid")
        ev = RP.events(flex)
        stages |= {s for _, _, s in ev.runs}
        _shade_stages(ax, ev)
        ax.plot(rig["t"], rig["M_fence"], color=DRIVE_COLORS["rigid"], lw=0.9, ls="--", label="rigid fence")
        ax.plot(flex["t"], flex["M_fence"], color=DRIVE_COLORS["flexible"], lw=1.3,
                label="flexible fence, B2 = 72, K2 = 570")
        ax.set_ylabel("moment M [N m]")
        ax.set_xlabel("time t [s]")
        if case == "small_far":  # the impact and the brushing last 0.1 s of the cycle: zoom, log scale
            ax.set_yscale("symlog", linthresh=100.0)
            ax.set_xlim(max(0.0, ev.A - 0.03), ev.B + 0.05)
            zoom = ", zoomed on the contact (symmetric log scale above 100 N m)"
        else:
            ax.set_xlim(0, tc)
            zoom = ""
        rows = _mark_events(ax, ev)
        ax.set_title(f"({letter}) {_case_title(flex)}{zoom}", pad=6 + 10 * rows)
        ax.grid(alpha=0.3)
        mx = max(flex["M_fence"].max(), rig["M_fence"].max())
        ax.text(0.01, 0.95, f"peak {flex['M_fence'].max():.0f} N m (flexible), {rig['M_fence'].max():.0f} N m (rigid)",
                transform=ax.transAxes, va="top", fontsize=8,
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.8})
        ax.set_ylim(min(0.0, flex["M_fence"].min()) * 1.1, mx * (3.0 if case == "small_far" else 1.12))
    h, lab = axes[2].get_legend_handles_labels()
    axes[2].legend(handles=h + _stage_legend_handles(stages), loc="upper right", ncol=2,
                   title="shaded: stage (flexible run)", title_fontsize=7)
    axes[0].set_xlim(0, tc)
    axes[0].set_xlabel("time t [s]")
    fig.suptitle(f"Paper Fig. 4: fence input signals at {WORKING_POINT}, m1 = 15 kg, m2 = 5 kg\n"
                 "A first contact, B last loss of contact, C stage change (flexible run; stages S1-S4 of MODEL.md §10)")
    fig.tight_layout()
    return _save(fig, out, "fig4_fence_moment.png")


# ---------------------------------------------------------------------------- Fig 5a
def fig5a(res: Path, out: Path) -> Path:
    """Paper Fig. 5a: overload against v (t_c = 1.36 s) and t_c (v = 2 m/s); rigid, flexible, free. The named
    cases, and (when its tables are there) the worst over the load's placements, the paper's §4.1 arrangement."""
    plt = _plt()
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
    return _save(fig, out, "fig5a_overload_v_tc.png")


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
    plt = _plt()
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
    return _save(fig, out, "fig5b_quotient_m2.png")


# ---------------------------------------------------------------------------- Fig 6
def fig6(res: Path, out: Path) -> Path:
    """Paper Fig. 6: damper energy and maximal deflection against B2 at Psi = 1."""
    plt = _plt()
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
    return _save(fig, out, "fig6_psi1_b2.png")


# ---------------------------------------------------------------------------- Fig 7
def fig7(res: Path, out: Path) -> Path:
    """Paper Fig. 7: fence angle alpha and drive angle alpha_w against time, A, B, C marked."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.0), sharex="col", gridspec_kw={"height_ratios": [1.4, 1]})
    stages: set = set()
    for col, case in enumerate(RP.CASES):
        flex = RP.read_traj(res, f"{case}_flexible")
        rig = RP.read_traj(res, f"{case}_rigid")
        ev = RP.events(flex)
        evr = RP.events(rig)
        t = flex["t"].to_numpy()
        al = np.degrees(flex["alpha"].to_numpy())
        aw = np.degrees(flex["alpha_w"].to_numpy())
        ax = axes[0, col]
        ax.plot(t, aw, color="k", lw=1.1, ls="--", label="alpha_w, drive (= alpha of the rigid fence)")
        ax.plot(t, al, color=DRIVE_COLORS["flexible"], lw=1.5, label="alpha, flexible fence 72/570")
        pts = _event_points(ev)
        ymax = max(al.max(), aw.max())
        # letters below the curve (the legend is above it; near alpha = 0, where the contact bars are,
        # above it), stacked where events are close in time
        lev = _levels([tt for tt, _ in pts], 0.045 * float(flex.attrs["params"]["t_c"]))
        for (tt, letter), k in zip(pts, lev):
            y = float(np.interp(tt, t, al))
            ax.plot([tt], [y], "o", ms=5, color="k", zorder=5)
            sign = 1 if y < 0.2 * ymax else -1
            ax.annotate(letter, (tt, y), xytext=(0, sign * (14 + 11 * k)), textcoords="offset points", fontsize=8,
                        fontweight="bold", ha="center", va="center",
                        arrowprops={"arrowstyle": "-", "lw": 0.5, "color": "0.3", "shrinkB": 3})
        # contact intervals (the paper's Delta t2): rigid and flexible
        ymax = max(al.max(), aw.max())
        for k, (e, name, c) in enumerate(((evr, "contact, rigid", DRIVE_COLORS["rigid"]),
                                          (ev, "contact, flexible", DRIVE_COLORS["flexible"]))):
            yb = -0.08 * ymax - k * 0.07 * ymax
            ax.plot([e.A, e.B], [yb, yb], color=c, lw=4, solid_capstyle="butt")
            ax.text(e.B, yb, f"  {name}: {e.B - e.A:.3f} s", va="center", fontsize=7, color=c)
        ax.set_ylim(-0.3 * ymax, 1.4 * ymax)
        ax.set_ylabel("angle [deg]")
        ax.set_title(_case_title(flex))
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=7, ncol=2)
        ax = axes[1, col]
        _shade_stages(ax, ev)
        ax.plot(t, al - aw, color=DRIVE_COLORS["flexible"], lw=1.3)
        ax.axhline(0, color="k", lw=0.6)
        tc = flex.attrs["params"]["t_c"]
        ax.set_xlim(0, tc)
        _mark_events(ax, ev)
        stages |= {s for _, _, s in ev.runs}
        resid = math.degrees(flex.attrs["results"]["residual_deflection"])
        # the label in the lower right corner, away from the curve (which ends near 0), an arrow to the point
        ax.annotate(f"residual deflection at t_c: {resid:.2f} deg", (tc, float(np.interp(tc, t, al - aw))),
                    xytext=(0.97, 0.06), textcoords="axes fraction", ha="right", va="bottom", fontsize=7,
                    arrowprops={"arrowstyle": "->", "lw": 0.6, "shrinkA": 2})
        ax.set_ylabel("deflection alpha - alpha_w [deg]")
        ax.set_xlabel("time t [s]")
        ax.grid(alpha=0.3)
    fig.legend(handles=_stage_legend_handles(stages), loc="lower center", ncol=len(stages), fontsize=7,
               title="shaded: stage of the flexible run (MODEL.md §10)", title_fontsize=7,
               bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(f"Paper Fig. 7: response of the fence, flexible element B2 = 72 N m s/rad, K2 = 570 N m/rad, "
                 f"{WORKING_POINT}\nA first contact, B last loss of contact, C stage change; bars: time in contact "
                 "(rigid vs flexible)")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return _save(fig, out, "fig7_fence_response.png")


# ---------------------------------------------------------------------------- geometry helpers (drawing)
def _outline(L, A, x, y, phi):
    from fencesweep.model.params import load_corners

    cs = load_corners(L, A, phi)
    return np.array([[x + a, y + b] for a, b in cs] + [[x + cs[0][0], y + cs[0][1]]])


def _draw_scene(ax, p, xlim):
    """Belt (light), its far edge (slide), the rail upstream of the pivot, the pivot."""
    ax.axhspan(0, p["P_max"], color="#f7f7f2", zorder=0)
    ax.axhline(p["P_max"], color="0.4", lw=1.0)
    ax.plot([xlim[0], 0], [0, 0], color="k", lw=3, solid_capstyle="butt", zorder=2)
    ax.axhline(0, color="0.6", lw=0.6, zorder=1)
    ax.plot([0], [0], "ko", ms=4, zorder=6)


# ---------------------------------------------------------------------------- Fig 8
def fig8(res: Path, out: Path) -> Path:
    """Paper Fig. 8: path of the load, rigid vs flexible fence, both cases."""
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.6))
    for ax, case in zip(axes, RP.CASES):
        p = RP.read_traj(res, f"{case}_rigid").attrs["params"]
        xlim = (-0.6, 1.9)
        top = p["P_max"] + 0.1
        _draw_scene(ax, p, xlim)
        for drive, ls in (("rigid", "-"), ("flexible", "-")):
            df = RP.read_traj(res, f"{case}_{drive}")
            r = df.attrs["results"]
            live = df[df["stage"] >= 0]
            col = DRIVE_COLORS[drive]
            ax.plot(live["x"], live["y"], ls=ls, color=col, lw=1.6,
                    label=f"{drive}: centroid path,\nexit at x = {r['x_exit']:.2f} m,\ncontact {r['contact_time']:.2f} s")
            last = live.iloc[-1]
            o = _outline(p["L"], p["A"], last["x"], last["y"], last["phi"])
            ax.fill(o[:, 0], o[:, 1], color=col, alpha=0.25, lw=0)
            ax.plot(o[:, 0], o[:, 1], color=col, lw=1.0)
            # the fence at the exit
            al = float(last["alpha"])
            ax.plot([0, p["l"] * math.cos(al)], [0, p["l"] * math.sin(al)], color=col, lw=2.2, alpha=0.8)
            ax.plot([last["x"]], [last["y"]], "o", color=col, ms=4)
            top = max(top, p["l"] * math.sin(al) + 0.05, float(o[:, 1].max()) + 0.03)
        first = RP.read_traj(res, f"{case}_rigid").iloc[0]
        o = _outline(p["L"], p["A"], first["x"], first["y"], first["phi"])
        ax.fill(o[:, 0], o[:, 1], color="0.6", alpha=0.5, lw=0)
        ax.plot(o[:, 0], o[:, 1], color="0.3", lw=1.0)
        ax.text(o[:, 0].mean(), o[:, 1].max() + 0.02, "start", ha="center", fontsize=7)
        ax.plot([0, p["l"]], [0, 0], color="0.2", lw=1.5, ls=":")
        ax.text(0.02, -0.05, "rail | fence pivot O", fontsize=7, va="top")
        ax.text(xlim[1] - 0.02, p["P_max"] + 0.02, "far edge y = P_max: slide", ha="right", fontsize=7)
        ax.annotate("", (xlim[1] - 0.05, 0.05), (xlim[1] - 0.35, 0.05),
                    arrowprops={"arrowstyle": "->", "lw": 1})
        ax.text(xlim[1] - 0.2, 0.07, f"belt v = {p['v']:g} m/s", ha="center", fontsize=7)
        ax.set_xlim(*xlim)
        ax.set_ylim(-0.12, top)
        ax.set_aspect("equal")
        ax.set_xlabel("x along the belt [m]")
        ax.set_ylabel("y across the belt [m]")
        ax.set_title(f"{_case_title(RP.read_traj(res, f'{case}_rigid'))}: load and fence at the exit (shaded)")
        # outside, to the right: inside, every free spot of one case is taken by a path or a fence in the other
        ax.legend(loc="center left", fontsize=7, bbox_to_anchor=(1.01, 0.5), frameon=False)
    fig.suptitle(f"Paper Fig. 8: path of the load's centroid, rigid vs flexible fence (72/570), {WORKING_POINT}")
    fig.tight_layout()
    return _save(fig, out, "fig8_load_path.png")


# ---------------------------------------------------------------------------- design maps
def _draw_outline(ax, xe, ye, mask, **kw):
    """Outline the cells of `mask` (ny, nx) along the cell edges."""
    from matplotlib.collections import LineCollection

    ny, nx = mask.shape
    segs = []
    for i in range(ny):
        for j in range(nx):
            if not mask[i, j]:
                continue
            if j == 0 or not mask[i, j - 1]:
                segs.append([(xe[j], ye[i]), (xe[j], ye[i + 1])])
            if j == nx - 1 or not mask[i, j + 1]:
                segs.append([(xe[j + 1], ye[i]), (xe[j + 1], ye[i + 1])])
            if i == 0 or not mask[i - 1, j]:
                segs.append([(xe[j], ye[i]), (xe[j + 1], ye[i])])
            if i == ny - 1 or not mask[i + 1, j]:
                segs.append([(xe[j], ye[i + 1]), (xe[j + 1], ye[i + 1])])
    if kw.pop("halo", False):  # a dark edge under it keeps a light outline visible on any colour
        ax.add_collection(LineCollection(segs, colors="k", linewidths=kw.get("linewidths", 2.0) + 2.0,
                                         capstyle="projecting"))
    ax.add_collection(LineCollection(segs, capstyle="projecting", **kw))


def _map_marks(ax, D, show_best=True):
    ax.plot([RP.PAPER_B2], [RP.PAPER_K2], "o", ms=7, mfc="white", mec="k", mew=1.2, zorder=6)
    ax.annotate("paper 72/570", (RP.PAPER_B2, RP.PAPER_K2), xytext=(6, -10), textcoords="offset points",
                fontsize=7, color="k", bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7})
    if show_best and D.best:
        ax.plot([D.best["B2"]], [D.best["K2"]], "*", ms=13, mfc="gold", mec="k", mew=0.8, zorder=7)


def _psi_contour(ax, D, case):
    psi = D.grids[case]["Psi"]
    cs = ax.contour(D.B2, D.K2, psi, levels=[1.0], colors="0.25", linewidths=0.9, linestyles="--")
    ax.clabel(cs, fmt={1.0: "Psi = 1"}, fontsize=7)


def _map_case(res: Path, out: Path, case: str, D) -> Path:
    plt = _plt()
    from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    g = D.grids[case]
    xe, ye = RP.cell_edges(D.B2), RP.cell_edges(D.K2)
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.6), sharex=True, sharey=True)
    perm = float(np.nanmax(g["dalpha_perm"]))
    panels = [
        (axes[0, 0], "overload", "overload = peak force / free-fall peak [-]", "viridis", None, [1.0]),
        (axes[0, 1], "deflection_max_deg", "maximal deflection |alpha - alpha_w| [deg]", "magma_r", None,
         [math.degrees(perm)]),
        (axes[1, 0], "residual_deg", "residual amplitude at t_c [deg] (log scale)", "cividis_r",
         LogNorm(vmin=max(0.01, float(np.nanmin(g["residual_deg"]))), vmax=float(np.nanmax(g["residual_deg"]))),
         sorted({0.5, D.residual_max_deg, 2.0})),
    ]
    for ax, key, label, cmap, norm, levels in panels:
        z = g[key]
        m = ax.pcolormesh(xe, ye, z, cmap=cmap, norm=norm, shading="flat")
        cb = fig.colorbar(m, ax=ax, shrink=0.9)
        cb.set_label(label)
        if key == "overload":  # the landscape below 1: thin labelled contours
            fine = [v for v in (0.6, 0.65, 0.7, 0.8, 0.9) if np.nanmin(z) < v < np.nanmax(z)]
            if fine:
                cs = ax.contour(D.B2, D.K2, z, levels=fine, colors="0.85", linewidths=0.6)
                ax.clabel(cs, fmt=lambda v: f"{v:g}", fontsize=6)
        lv = [v for v in levels if np.nanmin(z) < v < np.nanmax(z)]
        if lv:
            cs = ax.contour(D.B2, D.K2, z, levels=lv, colors="w", linewidths=1.0)
            ax.clabel(cs, fmt=lambda v: f"{v:g}", fontsize=7)
            for v in lv:
                cb.ax.axhline(v, color="w", lw=1.5)
    axes[0, 0].set_title("overload (contour: 1 = a drop from H = 0.3 m)")
    axes[0, 1].set_title(f"deflection_max (contour: dalpha_perm = {math.degrees(perm):.0f} deg)")
    axes[1, 0].set_title(f"residual_amplitude at t_c (contours 0.5 / {D.residual_max_deg:g} / 2 deg)")
    ax = axes[1, 1]
    names = list(OUTCOME_COLORS)
    code = np.vectorize(lambda s: names.index(s) if s in names else 3)(g["outcome"])
    cmap = ListedColormap([OUTCOME_COLORS[n] for n in names])
    ax.pcolormesh(xe, ye, code, cmap=cmap, norm=BoundaryNorm(np.arange(-0.5, 4.5), 4), shading="flat", alpha=0.85)
    present = [n for n in names if (g["outcome"] == n).any()]
    ax.set_title("outcome of the cycle")
    for a in axes.flat:
        _draw_outline(a, xe, ye, D.feasible[case], colors="cyan" if a is not ax else "k", linewidths=2.0,
                      halo=a is not ax)
        _psi_contour(a, D, case)
        _map_marks(a, D)
        a.set_xlim(xe[0], xe[-1])
        a.set_ylim(ye[0], ye[-1])
    for a in axes[1, :]:
        a.set_xlabel("damping B2 [N m s/rad]")
    for a in axes[:, 0]:
        a.set_ylabel("stiffness K2 [N m/rad]")
    handles = [Patch(color=OUTCOME_COLORS[n], label=n) for n in present]
    handles += [Line2D([], [], color="k", lw=2.2, label="feasible region (cyan on the other maps)"),
                Line2D([], [], color="0.25", ls="--", label="Psi = 1 (critical damping)"),
                Line2D([], [], ls="", marker="o", mfc="white", mec="k", label="paper's element 72/570"),
                Line2D([], [], ls="", marker="*", ms=11, mfc="gold", mec="k", label="two-case pick (recommended for both named cases)")]
    ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.9)
    n = int(D.feasible[case].sum())
    fig.suptitle(f"Design map over B2 x K2, {RP.CASE_TEXT[case]}; {WORKING_POINT}, m2 = 5 kg\n"
                 f"feasible ({n} of {D.feasible[case].size} cells): scraped, overload <= 1, deflection_max <= "
                 f"{math.degrees(perm):.0f} deg, residual <= {D.residual_max_deg:g} deg")
    fig.tight_layout()
    return _save(fig, out, f"map_{case}.png")


def _map_both(res: Path, out: Path, D) -> Path:
    plt = _plt()
    from matplotlib.colors import BoundaryNorm, ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    xe, ye = RP.cell_edges(D.B2), RP.cell_edges(D.K2)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.9), sharey=True)
    ax = axes[0]
    z = np.where(D.both, D.worst, np.nan)
    ax.pcolormesh(xe, ye, np.where(D.both, np.nan, 1.0), cmap=ListedColormap(["#dddddd"]), shading="flat")
    m = ax.pcolormesh(xe, ye, z, cmap="viridis", shading="flat")
    cb = fig.colorbar(m, ax=ax)
    cb.set_label("worst overload over both cases [-]")
    _draw_outline(ax, xe, ye, D.both, colors="k", linewidths=1.8)
    _draw_outline(ax, xe, ye, D.robust, colors="w", linewidths=1.0, linestyles="--")
    ax.set_title("overload (larger of the two cases) where both are feasible;\ngrey: infeasible, white dashed: "
                 "feasible with all 8 neighbours")
    ax = axes[1]
    colors = ["#4daf4a", "#e41a1c", "#984ea3", "#ff7f00", "#377eb8"]
    ax.pcolormesh(xe, ye, D.first_fail, cmap=ListedColormap(colors), norm=BoundaryNorm(np.arange(-0.5, 5.5), 5),
                  shading="flat", alpha=0.85)
    _draw_outline(ax, xe, ye, D.both, colors="k", linewidths=1.8)
    ax.set_title("first constraint that fails (either case), in the order listed")
    present = sorted(set(np.unique(D.first_fail).tolist()))
    handles = [Patch(color=colors[k], label=RP.Design.FAIL_NAMES[k] if k != 4 else
                     f"residual amplitude > {D.residual_max_deg:g} deg") for k in present]
    handles += [Line2D([], [], ls="", marker="o", mfc="white", mec="k", label="paper's element 72/570"),
                Line2D([], [], ls="", marker="*", ms=11, mfc="gold", mec="k", label="two-case pick"),
                Line2D([], [], color="0.25", ls="--", label="Psi = 1")]
    ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.9)
    for a in axes:
        _psi_contour(a, D, "small_far")
        _map_marks(a, D)
        a.set_xlabel("damping B2 [N m s/rad]")
        a.set_xlim(xe[0], xe[-1])
        a.set_ylim(ye[0], ye[-1])
    axes[0].set_ylabel("stiffness K2 [N m/rad]")
    b = D.best
    rec = (f"recommended B2 = {b['B2']:g} N m s/rad, K2 = {b['K2']:g} N m/rad (Psi = {b['Psi']:.2f}), worst overload "
           f"{b['worst_overload']:.3f}" if b else "no cell is feasible for both cases with a one-step margin")
    if D.damped:
        d = D.damped
        rec += f"; well-damped (0.7 <= Psi <= 1): {d['B2']:g} / {d['K2']:g}, {d['worst_overload']:.3f}"
        axes[0].plot([d["B2"]], [d["K2"]], "D", ms=6, mfc="none", mec="w", mew=1.3, zorder=7)
    fig.suptitle(f"Design map for both named cases (small_far and long_near), {WORKING_POINT}; residual threshold "
                 f"{D.residual_max_deg:g} deg\n{rec}")
    fig.tight_layout()
    return _save(fig, out, "map_both.png")


def maps(res: Path, out: Path, residual_max_deg: float = RP.RESIDUAL_MAX_DEG) -> list:
    """Design maps over B2 x K2: one per named case and one for both."""
    D = RP.design(RP.read_table(res, "b2k2"), residual_max_deg)
    paths = [_map_case(res, out, c, D) for c in RP.CASES if c in D.grids]
    paths.append(_map_both(res, out, D))
    return paths


# ---------------------------------------------------------------------------- the recommended element
def recommended(res: Path, out: Path) -> Path:
    """Deflection and fence force over a cycle: the paper's 72/570 against the elements read off the maps."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.2), layout="constrained")
    variants = [("flexible", "paper", "#d62728", "-"), ("recommended", "two-case pick", "#1a9850", "-"),
                ("well_damped", "well-damped", "#4575b4", "--")]
    for r, case in enumerate(RP.CASES):
        shown = []
        for tag, what, color, ls in variants:
            path = RP.traj_path(res, f"{case}_{tag}")
            if tag != "flexible" and not path.exists():
                continue
            df = RP.read_traj(res, f"{case}_{tag}")
            p, rs = df.attrs["params"], df.attrs["results"]
            from fencesweep.model.params import relative_damping

            label = (f"{what}: B2 = {p['B2']:g}, K2 = {p['K2']:g} (Psi = {relative_damping(p['B2'], p['K2'], p['I2']):.2f})"
                     f"; overload {rs['overload']:.3f}, residual amplitude {math.degrees(rs['residual_amplitude']):.2f} deg")
            t = df["t"].to_numpy()
            axes[r, 0].plot(t, np.degrees(df["alpha"] - df["alpha_w"]), color=color, ls=ls, lw=1.4, label=label)
            axes[r, 1].plot(t, df["N_fence"] / rs["freefall_force"], color=color, ls=ls, lw=1.3)
            shown.append(RP.events(df))
        perm = math.degrees(float(df.attrs["params"]["dalpha_perm"]))
        ax = axes[r, 0]
        ax.axhline(0, color="k", lw=0.6)
        for sgn in (1, -1):
            ax.axhline(sgn * RP.RESIDUAL_MAX_DEG, color="0.5", lw=0.7, ls=":")
        ax.set_xlim(0, float(df.attrs["params"]["t_c"]))
        ax.set_ylabel("deflection alpha - alpha_w [deg]")
        ax.set_xlabel("time t [s]")
        ax.set_title(f"{RP.CASE_TEXT[case]}\ndeflection (dotted: +-{RP.RESIDUAL_MAX_DEG:g} deg, the 'home' "
                     f"threshold on the residual amplitude; dalpha_perm = {perm:.0f} deg)", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.2), fontsize=8, ncol=1, frameon=False)
        ax = axes[r, 1]
        a = min(e.A for e in shown)
        b = max(e.B for e in shown)
        if case == "small_far":
            ax.set_xlim(a - 0.01, b + 0.02)
            ax.set_yscale("symlog", linthresh=0.02)
        else:
            ax.set_xlim(0, float(df.attrs["params"]["t_c"]))
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_ylabel("fence force / free-fall peak [-]")
        ax.set_xlabel("time t [s]")
        ax.set_title(f"{case}: normal force of the load on the fence\n" +
                     ("zoomed on the contact, symmetric log scale above 0.02" if case == "small_far" else
                      "whole cycle"), fontsize=9)
        ax.grid(alpha=0.3)
    fig.suptitle(f"The elements read off the two named cases' design maps (two-case pick, well-damped) against the "
                 f"paper's 72/570, {WORKING_POINT}, m2 = 5 kg\n(for a whole load envelope: "
                 f"results/design/recommended.json)")
    return _save(fig, out, "recommended.png")


# ---------------------------------------------------------------------------- a stream of cycles
#: the elements of sweeps/period.yaml that have a deflection (the rigid fence has none)
STREAM_ELEMENTS = (("paper 72/570", dict(B2=72.0, K2=570.0), "#d62728", "-"),
                   ("two-case pick 15/2075", dict(B2=15.0, K2=2075.0), "#1a9850", "-"),
                   ("well-damped 140/2075", dict(B2=140.0, K2=2075.0), "#4575b4", "--"))
def stream(res: Path, out: Path) -> Path:
    """Deflection over 10 back-to-back cycles (MODEL.md §14) at T = t_c, alternating loads."""
    from fencesweep.model.simulate import simulate_resolved
    from fencesweep.model.params import resolve

    plt = _plt()
    loads = ["small_far", "long_near"] * (RP.STREAM_FIGURE_CYCLES // 2)
    fig, axes = plt.subplots(2, 1, figsize=(13, 7.5), layout="constrained")
    for ax, tc in zip(axes, RP.STREAM_FIGURE_TC):
        for label, params, color, ls in STREAM_ELEMENTS:
            r, df = simulate_resolved(resolve("stream", loads=loads, t_c=tc, period=tc, **params), trajectory=True)
            amp = math.degrees(r["worst_start_amplitude"])
            ax.plot(df["t"], np.degrees(df["alpha"] - df["alpha_w"]), color=color, ls=ls, lw=1.1,
                    label=f"{label}\nworst overload {r['worst_overload']:.3f}\nlargest start amplitude {amp:.2f} deg\n"
                          f"{r['n_scraped']}/{r['n_cycles']} scraped")
        for k in range(RP.STREAM_FIGURE_CYCLES + 1):
            ax.axvline(k * tc, color="0.6", lw=0.6, ls=":")
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.12 * (hi - lo))  # a band at the top for the loads' names, above the curves
        for k in range(RP.STREAM_FIGURE_CYCLES):
            ax.text((k + 0.5) * tc, 0.98, "small_far" if k % 2 == 0 else "long_near",
                    transform=ax.get_xaxis_transform(), ha="center", va="top", fontsize=7, color="0.35")
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xlim(0, RP.STREAM_FIGURE_CYCLES * tc)
        ax.set_xlabel("time t [s] (dotted: the start of each cycle, t_k = k T)")
        ax.set_ylabel("deflection alpha - alpha_w [deg]")
        ax.set_title(f"t_c = T = {tc:g} s ({3600 / tc:.0f} packages/h), the load of each cycle at the top",
                     fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    fig.suptitle(f"The fence over {RP.STREAM_FIGURE_CYCLES} cycles back to back, the state of the element carried over "
                 f"(scene stream), v = 2 m/s, m2 = 5 kg; the rigid fence has no deflection")
    return _save(fig, out, "stream_deflection.png")


# ---------------------------------------------------------------------------- one cycle in frames
def _instants(df, n=8) -> list:
    """~n instants of a cycle as (t, label): start, A, the peak force, the middle of every long stage,
    the stage changes, B, the exit and t_c, in that order of priority, at least 1.5 % of the cycle apart."""
    ev = RP.events(df)
    r = df.attrs["results"]
    p = df.attrs["params"]
    t = df["t"].to_numpy()
    t_end = float(p["t_c"])
    cand = [(0.0, "start", 0)]
    if math.isfinite(ev.A):
        cand.append((float(t[int(np.argmax(df["N_fence"].to_numpy()))]), "peak fence force", 1))
    cand.append((min(float(r["t_exit"]), float(t[-1])), f"exit ({r['outcome']})", 1))
    for t0, t1, s in ev.runs:
        if t1 - t0 > 0.1 * t_end and s != 1:
            cand.append((0.5 * (t0 + t1), f"middle of {RP.STAGE_NAMES[s]}", 2))
    if math.isfinite(ev.A):
        cand.append((ev.A, "A, first contact", 3))
    if math.isfinite(ev.B):
        cand.append((ev.B, "B, last contact", 3))
    cand += [(tc, f"C, {RP.STAGE_NAMES[a]} -> {RP.STAGE_NAMES[b]}", 4) for tc, a, b in ev.C]
    cand.append((t_end, "t_c, end of the cycle", 5))
    sep = 0.015 * t_end
    picked: list = []
    for tt, label, _ in sorted(cand, key=lambda c: c[2]):
        if len(picked) < n and all(abs(tt - q[0]) > sep for q in picked):
            picked.append((tt, label))
    picked.sort()
    lo = ev.A if math.isfinite(ev.A) else 0.0
    hi = min(float(r["t_exit"]), t_end)
    while len(picked) < n:  # fill the longest gap of the interaction [A, exit], else of the cycle
        ts = np.array([q[0] for q in picked])
        gaps = np.diff(ts)
        inside = (ts[:-1] >= lo - 1e-9) & (ts[1:] <= hi + 1e-9)
        i = int(np.argmax(np.where(inside, gaps, -1.0))) if (inside & (gaps > 2 * sep)).any() else int(np.argmax(gaps))
        picked.insert(i + 1, (0.5 * (picked[i][0] + picked[i + 1][0]), ""))
    return picked


def _arrow(ax, head, vec, color):
    """A force arrow whose head touches the point it acts on (tail at head - vec)."""
    from matplotlib.patches import FancyArrowPatch

    ax.add_patch(FancyArrowPatch(tuple(head - vec), tuple(head), arrowstyle="-|>", mutation_scale=10,
                                 color=color, lw=1.6, zorder=7, clip_on=False))


def _force_label(ax, tail, u, text, color):
    """A force's value just beyond its arrow's tail, on the far side along u (the unit vector from
    the head to the tail), so the text never lies on the arrow, the fence or the load."""
    x, y = tail + 0.03 * u
    ha = "left" if u[0] > 0.35 else ("right" if u[0] < -0.35 else "center")
    va = "bottom" if u[1] > 0.35 else ("top" if u[1] < -0.35 else "center")
    ax.text(x, y, text, fontsize=7, color=color, ha=ha, va=va, zorder=8,
            bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8})


def _cycle(res: Path, out: Path, case: str) -> Path:
    plt = _plt()
    df = RP.read_traj(res, f"{case}_flexible")
    p = df.attrs["params"]
    r = df.attrs["results"]
    inst = _instants(df, 8)
    t = df["t"].to_numpy()
    nmax = max(float(df["N_fence"].max()), float(df["N_rail"].max()), 1e-9)
    fig, axes = plt.subplots(4, 2, figsize=(8.6, 10.0))
    xlim = (-0.8, 1.6)
    ylim = (-0.5, p["P_max"] + 0.3)  # room under the belt for the rail's and the pivot's force labels
    for k, (ax, (tt, label)) in enumerate(zip(axes.flat, inst)):
        i = min(int(np.searchsorted(t, tt - 1e-12)), len(t) - 1)
        row = df.iloc[i]
        _draw_scene(ax, p, xlim)
        al, aw = float(row["alpha"]), float(row["alpha_w"])
        d = np.array([math.cos(al), math.sin(al)])
        nvec = np.array([-math.sin(al), math.cos(al)])
        ax.plot([0, p["l"] * math.cos(aw)], [0, p["l"] * math.sin(aw)], color="0.4", lw=1.0, ls="--", zorder=3)
        ax.plot([0, p["l"] * d[0]], [0, p["l"] * d[1]], color="#b2182b", lw=3, solid_capstyle="round", zorder=4)
        gone = int(row["stage"]) < 0
        o = _outline(p["L"], p["A"], row["x"], row["y"], row["phi"])
        ax.fill(o[:, 0], o[:, 1], color="0.8" if gone else "#8c6d31", alpha=0.6 if gone else 0.85, zorder=3)
        ax.plot(o[:, 0], o[:, 1], color="k", lw=0.8, ls="--" if gone else "-", zorder=3)
        # forces on the load, the head at the point of action: the fence's at its centre of
        # pressure s = M / N along the fence, the rail's under the load's lowest corner at x <= 0;
        # length ~ sqrt(N / N_max)
        nf, nr = float(row["N_fence"]), float(row["N_rail"])
        if nf > 0:
            s = min(max(float(row["M_fence"]) / nf, 0.0), p["l"])
            ln = 0.06 + 0.24 * math.sqrt(nf / nmax)
            _arrow(ax, s * d, ln * nvec, "#2166ac")
            _force_label(ax, s * d - ln * nvec, -nvec, f"{nf:.0f} N" if nf < 1e3 else f"{nf / 1e3:.2f} kN",
                         "#2166ac")
        if nr > 0:
            xs, ys = o[:-1, 0], o[:-1, 1]
            j = int(np.argmin(np.where(xs <= 0.0, ys, np.inf)))
            ln = 0.06 + 0.18 * math.sqrt(nr / nmax)
            _arrow(ax, np.array([xs[j], 0.0]), np.array([0.0, ln]), "#1b7837")
            _force_label(ax, np.array([xs[j], -ln]), np.array([0.0, -1.0]), f"rail {nr:.0f} N", "#1b7837")
        stage = "after the exit" if gone else f"stage {RP.STAGE_NAMES.get(int(row['stage']), '?')}"
        ax.set_title(f"{k + 1}. t = {row['t']:.3f} s" + (f", {label}" if label else "") + f"; {stage}\n"
                     f"alpha = {math.degrees(al):.1f} deg, alpha - alpha_w = {math.degrees(al - aw):+.1f} deg",
                     fontsize=8)
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(inst):]:
        ax.axis("off")
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="#b2182b", lw=3, label="fence (pivot O at the origin)"),
               Line2D([], [], color="0.4", lw=1, ls="--", label="drive lever alpha_w (the fence's equilibrium)"),
               Line2D([], [], color="k", lw=3, label="rail (x <= 0), belt edge y = 0"),
               Line2D([], [], color="#2166ac", lw=1.6, label="force of the fence on the load"),
               Line2D([], [], color="#1b7837", lw=1.6, label="force of the rail on the load"),
               Line2D([], [], color="0.4", lw=1, label="far edge y = P_max (slide)")]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8, bbox_to_anchor=(0.5, -0.005))
    fig.suptitle(f"One sorting cycle, {RP.CASE_TEXT[case]}; flexible fence 72/570, {WORKING_POINT}\n"
                 f"outcome {r['outcome']} at t = {r['t_exit']:.3f} s, overload {r['overload']:.2f}. x along the "
                 "belt, y across it [m]; arrow heads at the point of action, length ~ sqrt(force)")
    fig.tight_layout(rect=(0, 0.035, 1, 1))
    return _save(fig, out, f"cycle_{case}.png")


def cycle(res: Path, out: Path) -> list:
    """One cycle in frames (8 instants) for each named case, flexible 72/570 fence."""
    return [_cycle(res, out, c) for c in RP.CASES]


# ---------------------------------------------------------------------------- registry and CLI
FIGURES = {
    "fig2": (fig2, "paper Fig. 2: impact force, linear Kelvin law"),
    "fig3": (fig3, "paper Fig. 3: impact force, modified Kelvin law"),
    "fig4": (fig4, "paper Fig. 4: drive input and moment of the load on the fence"),
    "fig5a": (fig5a, "paper Fig. 5a: overload against v and t_c"),
    "fig5b": (fig5b, "paper Fig. 5b: quotient of peak forces against m2"),
    "fig6": (fig6, "paper Fig. 6: damper energy and maximal deflection at Psi = 1"),
    "fig7": (fig7, "paper Fig. 7: alpha, alpha_w with A, B, C"),
    "fig8": (fig8, "paper Fig. 8: load path, rigid vs flexible"),
    "maps": (maps, "design maps over B2 x K2 (per case and both)"),
    "cycle": (cycle, "one cycle in frames, per case"),
    "recommended": (recommended, "the recommended element against the paper's 72/570"),
    "stream": (stream, "deflection over 10 cycles back to back (scene stream), three elements"),
}
#: number of PNG files `plot all` writes
N_FILES = 8 + 3 + 2 + 1 + 1


def plot(names, res: Path = Path("results"), out: Path | None = None,
         residual_max_deg: float = RP.RESIDUAL_MAX_DEG) -> list:
    """Draw the named figures ('all' for every one); return the PNG paths written."""
    res = Path(res)
    out = Path(out) if out else res / "figures"
    names = list(FIGURES) if (not names or "all" in names) else list(names)
    paths = []
    for n in names:
        fn = FIGURES[n][0]
        got = fn(res, out, residual_max_deg) if n == "maps" else fn(res, out)
        paths += got if isinstance(got, list) else [got]
    return paths
