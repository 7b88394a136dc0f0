"""The paper's figures drawn from single cycles (the trajectories of analysis.TRAJECTORIES): Figs 2-3
(the force of the first impact, linear and modified Kelvin law), Fig. 4 (the drive's input and the
moment of the load on the fence), Fig. 7 (the fence's response, A, B, C) and Fig. 8 (the load's path).
Drawing only: every number comes from a Parquet file the engine wrote.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fencesweep.report import analysis as RP
from fencesweep.report.figures_common import (DRIVE_COLORS, DRIVE_LABELS, WORKING_POINT, case_title, draw_scene,
                                              event_points, load_outline, mark_events, pyplot, save, shade_stages,
                                              stack_levels, stage_legend_handles)


# ---------------------------------------------------------------------------- Figs 2-3
def _fig_impact(res: Path, out: Path, law: str) -> Path:
    plt = pyplot()
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
    return save(fig, out, name)


def fig2(res: Path, out: Path) -> Path:
    """Paper Fig. 2: first-impact force with the linear Kelvin law."""
    return _fig_impact(res, out, "linear")


def fig3(res: Path, out: Path) -> Path:
    """Paper Fig. 3: first-impact force with the modified (Hertz-like) Kelvin law."""
    return _fig_impact(res, out, "hertz")


# ---------------------------------------------------------------------------- Fig 4
def fig4(res: Path, out: Path) -> Path:
    """Paper Fig. 4: drive input alpha_w and the moment of the load on the fence, both cases."""
    plt = pyplot()
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
        shade_stages(ax, ev)
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
        rows = mark_events(ax, ev)
        ax.set_title(f"({letter}) {case_title(flex)}{zoom}", pad=6 + 10 * rows)
        ax.grid(alpha=0.3)
        mx = max(flex["M_fence"].max(), rig["M_fence"].max())
        ax.text(0.01, 0.95, f"peak {flex['M_fence'].max():.0f} N m (flexible), {rig['M_fence'].max():.0f} N m (rigid)",
                transform=ax.transAxes, va="top", fontsize=8,
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.8})
        ax.set_ylim(min(0.0, flex["M_fence"].min()) * 1.1, mx * (3.0 if case == "small_far" else 1.12))
    h, lab = axes[2].get_legend_handles_labels()
    axes[2].legend(handles=h + stage_legend_handles(stages), loc="upper right", ncol=2,
                   title="shaded: stage (flexible run)", title_fontsize=7)
    axes[0].set_xlim(0, tc)
    axes[0].set_xlabel("time t [s]")
    fig.suptitle(f"Paper Fig. 4: fence input signals at {WORKING_POINT}, m1 = 15 kg, m2 = 5 kg\n"
                 "A first contact, B last loss of contact, C stage change "
                 "(flexible run; stages S1-S4 of docs/model.md §10)")
    fig.tight_layout()
    return save(fig, out, "fig4_fence_moment.png")


# ---------------------------------------------------------------------------- Fig 7
def fig7(res: Path, out: Path) -> Path:
    """Paper Fig. 7: fence angle alpha and drive angle alpha_w against time, A, B, C marked."""
    plt = pyplot()
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
        pts = event_points(ev)
        ymax = max(al.max(), aw.max())
        # letters below the curve (the legend is above it; near alpha = 0, where the contact bars are,
        # above it), stacked where events are close in time
        lev = stack_levels([tt for tt, _ in pts], 0.045 * float(flex.attrs["params"]["t_c"]))
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
        ax.set_title(case_title(flex))
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=7, ncol=2)
        ax = axes[1, col]
        shade_stages(ax, ev)
        ax.plot(t, al - aw, color=DRIVE_COLORS["flexible"], lw=1.3)
        ax.axhline(0, color="k", lw=0.6)
        tc = flex.attrs["params"]["t_c"]
        ax.set_xlim(0, tc)
        mark_events(ax, ev)
        stages |= {s for _, _, s in ev.runs}
        resid = math.degrees(flex.attrs["results"]["residual_deflection"])
        # the label in the lower right corner, away from the curve (which ends near 0), an arrow to the point
        ax.annotate(f"residual deflection at t_c: {resid:.2f} deg", (tc, float(np.interp(tc, t, al - aw))),
                    xytext=(0.97, 0.06), textcoords="axes fraction", ha="right", va="bottom", fontsize=7,
                    arrowprops={"arrowstyle": "->", "lw": 0.6, "shrinkA": 2})
        ax.set_ylabel("deflection alpha - alpha_w [deg]")
        ax.set_xlabel("time t [s]")
        ax.grid(alpha=0.3)
    fig.legend(handles=stage_legend_handles(stages), loc="lower center", ncol=len(stages), fontsize=7,
               title="shaded: stage of the flexible run (docs/model.md §10)", title_fontsize=7,
               bbox_to_anchor=(0.5, 0.0))
    fig.suptitle(f"Paper Fig. 7: response of the fence, flexible element B2 = 72 N m s/rad, K2 = 570 N m/rad, "
                 f"{WORKING_POINT}\nA first contact, B last loss of contact, C stage change; bars: time in contact "
                 "(rigid vs flexible)")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return save(fig, out, "fig7_fence_response.png")


# ---------------------------------------------------------------------------- Fig 8
def fig8(res: Path, out: Path) -> Path:
    """Paper Fig. 8: path of the load, rigid vs flexible fence, both cases."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.6))
    for ax, case in zip(axes, RP.CASES):
        p = RP.read_traj(res, f"{case}_rigid").attrs["params"]
        xlim = (-0.6, 1.9)
        top = p["P_max"] + 0.1
        draw_scene(ax, p, xlim)
        for drive, ls in (("rigid", "-"), ("flexible", "-")):
            df = RP.read_traj(res, f"{case}_{drive}")
            r = df.attrs["results"]
            live = df[df["stage"] >= 0]
            col = DRIVE_COLORS[drive]
            ax.plot(live["x"], live["y"], ls=ls, color=col, lw=1.6,
                    label=f"{drive}: centroid path,\nexit at x = {r['x_exit']:.2f} m,\ncontact {r['contact_time']:.2f} s")
            last = live.iloc[-1]
            o = load_outline(p["L"], p["A"], last["x"], last["y"], last["phi"])
            ax.fill(o[:, 0], o[:, 1], color=col, alpha=0.25, lw=0)
            ax.plot(o[:, 0], o[:, 1], color=col, lw=1.0)
            # the fence at the exit
            al = float(last["alpha"])
            ax.plot([0, p["l"] * math.cos(al)], [0, p["l"] * math.sin(al)], color=col, lw=2.2, alpha=0.8)
            ax.plot([last["x"]], [last["y"]], "o", color=col, ms=4)
            top = max(top, p["l"] * math.sin(al) + 0.05, float(o[:, 1].max()) + 0.03)
        first = RP.read_traj(res, f"{case}_rigid").iloc[0]
        o = load_outline(p["L"], p["A"], first["x"], first["y"], first["phi"])
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
        ax.set_title(f"{case_title(RP.read_traj(res, f'{case}_rigid'))}: load and fence at the exit (shaded)")
        # outside, to the right: inside, every free spot of one case is taken by a path or a fence in the other
        ax.legend(loc="center left", fontsize=7, bbox_to_anchor=(1.01, 0.5), frameon=False)
    fig.suptitle(f"Paper Fig. 8: path of the load's centroid, rigid vs flexible fence (72/570), {WORKING_POINT}")
    fig.tight_layout()
    return save(fig, out, "fig8_load_path.png")
