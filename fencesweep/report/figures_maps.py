"""The B2 x K2 design maps of the two named cases (b2k2 table: one map per case and one for both, with
the feasible region and the two-case pick) and recommended.png: deflection and fence force over a
cycle of the element to build (the load envelope's design) against the paper's 72/570 and the two
picks of the maps.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fencesweep.errors import MissingInput
from fencesweep.report import analysis as RP
from fencesweep.report.figures_common import OUTCOME_COLORS, WORKING_POINT, pyplot, save


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
    plt = pyplot()
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
                Line2D([], [], ls="", marker="*", ms=11, mfc="gold", mec="k", label="two-case pick (least overload, both named cases)")]
    ax.legend(handles=handles, loc="upper right", fontsize=7, framealpha=0.9)
    n = int(D.feasible[case].sum())
    fig.suptitle(f"Design map over B2 x K2, {RP.CASE_TEXT[case]}; {WORKING_POINT}, m2 = 5 kg\n"
                 f"feasible ({n} of {D.feasible[case].size} cells): scraped, overload <= 1, deflection_max <= "
                 f"{math.degrees(perm):.0f} deg, residual <= {D.residual_max_deg:g} deg")
    fig.tight_layout()
    return save(fig, out, f"map_{case}.png")


def _map_both(res: Path, out: Path, D) -> Path:
    plt = pyplot()
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
    rec = (f"two-case pick B2 = {b['B2']:g} N m s/rad, K2 = {b['K2']:g} N m/rad (Psi = {b['Psi']:.2f}), worst overload "
           f"{b['worst_overload']:.3f}" if b else "no cell is feasible for both cases with a one-step margin")
    if D.damped:
        d = D.damped
        rec += f"; well-damped pick (0.7 <= Psi <= 1): {d['B2']:g} / {d['K2']:g}, {d['worst_overload']:.3f}"
        axes[0].plot([d["B2"]], [d["K2"]], "D", ms=6, mfc="none", mec="w", mew=1.3, zorder=7)
    fig.suptitle(f"Design map for both named cases (small_far and long_near), {WORKING_POINT}; residual threshold "
                 f"{D.residual_max_deg:g} deg\n{rec}")
    fig.tight_layout()
    return save(fig, out, "map_both.png")


def maps(res: Path, out: Path, residual_max_deg: float = RP.RESIDUAL_MAX_DEG) -> list:
    """Design maps over B2 x K2: one per named case and one for both."""
    D = RP.design(RP.read_table(res, "b2k2"), residual_max_deg)
    paths = [_map_case(res, out, c, D) for c in RP.CASES if c in D.grids]
    paths.append(_map_both(res, out, D))
    return paths


# ---------------------------------------------------------------------------- the element to build
#: the curves of recommended.png: trajectory tag (analysis.design_runs), name, colour, line style, width
RECOMMENDED_CURVES = (("envelope", "to build (load envelope)", "#762a83", "-", 2.4),
                      ("flexible", "paper", "#d62728", "-", 1.3),
                      ("recommended", "two-case pick", "#1a9850", "-", 1.3),
                      ("well_damped", "well-damped pick", "#4575b4", "--", 1.3))


def _envelope_trajectories(res: Path) -> dict | None:
    """The element to build (analysis.envelope_element), after checking that its trajectories are
    its own: a trajectory left from an earlier design would draw another element under its name."""
    env = RP.envelope_element(res)
    if not env:
        return None
    for case in RP.CASES:
        name = f"{case}_envelope"
        p = RP.read_traj(res, name).attrs["params"] if RP.traj_path(res, name).exists() else None
        if p is None or not all(math.isclose(float(p[k]), float(env[k])) for k in ("B2", "K2")):
            raise MissingInput(f"{RP.traj_path(res, name)} is missing or is not the element of "
                                  f"{Path(res) / 'design' / 'recommended.json'} (B2 = {env['B2']:g}, K2 = "
                                  f"{env['K2']:g}): run `fencesweep plot trajectories --results {res}`")
    return env


def _deflection_panel(ax, case: str, df) -> None:
    perm = math.degrees(float(df.attrs["params"]["dalpha_perm"]))
    ax.axhline(0, color="k", lw=0.6)
    for sgn in (1, -1):
        ax.axhline(sgn * RP.RESIDUAL_MAX_DEG, color="0.5", lw=0.7, ls=":")
    ax.set_xlim(0, float(df.attrs["params"]["t_c"]))
    ax.set_ylabel("deflection alpha - alpha_w [deg]")
    ax.set_xlabel("time t [s]")
    ax.set_title(f"{RP.CASE_TEXT[case]}\ndeflection (dotted: +-{RP.RESIDUAL_MAX_DEG:g} deg, the 'home' "
                 f"threshold on the residual amplitude; dalpha_perm = {perm:.0f} deg)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.2), fontsize=7.5, ncol=1, frameon=False)


def _force_panel(ax, case: str, df, shown: list) -> None:
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


def recommended(res: Path, out: Path) -> Path:
    """Deflection and fence force over a cycle of each named case: the element to build (the load
    envelope's design, results/design/recommended.json, drawn thick) against the paper's 72/570 and
    the two picks of the named cases' maps. Before the design has run: the last three only."""
    from fencesweep.model.params import relative_damping

    plt = pyplot()
    env = _envelope_trajectories(res)
    fig, axes = plt.subplots(2, 2, figsize=(12, 9.2), layout="constrained")
    for r, case in enumerate(RP.CASES):
        shown = []
        for tag, what, color, ls, lw in RECOMMENDED_CURVES:
            if tag != "flexible" and not RP.traj_path(res, f"{case}_{tag}").exists():
                continue
            df = RP.read_traj(res, f"{case}_{tag}")
            p, rs = df.attrs["params"], df.attrs["results"]
            label = (f"{what}: B2 = {p['B2']:g}, K2 = {p['K2']:g} (Psi = {relative_damping(p['B2'], p['K2'], p['I2']):.2f})"
                     f"\noverload {rs['overload']:.3f}, residual amplitude {math.degrees(rs['residual_amplitude']):.2f} deg")
            t = df["t"].to_numpy()
            z = 1.5 if tag == "envelope" else 2  # thick and underneath: the thin curves stay visible on it
            axes[r, 0].plot(t, np.degrees(df["alpha"] - df["alpha_w"]), color=color, ls=ls, lw=lw, label=label, zorder=z)
            axes[r, 1].plot(t, df["N_fence"] / rs["freefall_force"], color=color, ls=ls, lw=lw, zorder=z)
            shown.append(RP.events(df))
        _deflection_panel(axes[r, 0], case, df)
        _force_panel(axes[r, 1], case, df, shown)
    head = (f"The element to build, B2 = {env['B2']:g} N m s/rad, K2 = {env['K2']:g} N m/rad (the load envelope's "
            "design, results/design/recommended.json), on the two named cases,\nagainst the paper's 72/570 and the "
            "named cases' two-case and well-damped picks" if env else
            "The elements read off the two named cases' design maps (two-case pick, well-damped pick) against the "
            "paper's 72/570")
    fig.suptitle(f"{head}; {WORKING_POINT}, m2 = 5 kg")
    return save(fig, out, "recommended.png")
