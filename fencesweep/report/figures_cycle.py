"""Cycles drawn in time: one cycle of each named case in frames (cycle_<case>.png: load, fence, drive
lever, belt and contact forces at 8 instants) and the deflection over a stream of cycles back to
back (stream_deflection.png, scene stream: the only figure that runs the engine itself). One
instant is drawn by draw_frame, which the animation (report/animation.py) draws with too.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from fencesweep.report import analysis as RP
from fencesweep.report.figures_common import WORKING_POINT, draw_scene, load_outline, pyplot, save


# ---------------------------------------------------------------------------- a stream of cycles
#: the elements of sweeps/period.yaml that have a deflection (the rigid fence has none)
STREAM_ELEMENTS = (("paper 72/570", dict(B2=72.0, K2=570.0), "#d62728", "-"),
                   ("two-case pick 15/2075", dict(B2=15.0, K2=2075.0), "#1a9850", "-"),
                   ("well-damped 140/2075", dict(B2=140.0, K2=2075.0), "#4575b4", "--"))


def stream(res: Path, out: Path) -> Path:
    """Deflection over 10 back-to-back cycles (docs/model.md §14) at T = t_c, alternating loads."""
    from fencesweep.model.simulate import simulate_resolved
    from fencesweep.model.params import resolve

    plt = pyplot()
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
    return save(fig, out, "stream_deflection.png")


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


#: the scene's extent along the belt [m] in the cycle frames and the animation
XLIM = (-0.8, 1.6)
FENCE_COLOR, LEVER_COLOR, FENCE_FORCE_COLOR, RAIL_FORCE_COLOR = "#b2182b", "0.4", "#2166ac", "#1b7837"


def row_at(t, tt: float) -> int:
    """The trajectory row drawn at time tt: the first at or after it (the last row past the end)."""
    return min(int(np.searchsorted(t, tt - 1e-12)), len(t) - 1)


def frame_title(row, head: str = "", label: str = "") -> str:
    """A frame's title: head, the row's time, label, the stage; the fence's angle and deflection."""
    al, aw = float(row["alpha"]), float(row["alpha_w"])
    gone = int(row["stage"]) < 0
    stage = "after the exit" if gone else f"stage {RP.STAGE_NAMES.get(int(row['stage']), '?')}"
    return (f"{head}t = {row['t']:.3f} s" + (f", {label}" if label else "") + f"; {stage}\n"
            f"alpha = {math.degrees(al):.1f} deg, alpha - alpha_w = {math.degrees(al - aw):+.1f} deg")


def _draw_forces(ax, p, row, o, d, nmax) -> None:
    """The forces on the load, the head at the point of action: the fence's at its centre of
    pressure s = M / N along the fence, the rail's under the load's lowest corner at x <= 0;
    length ~ sqrt(N / N_max)."""
    nvec = np.array([-d[1], d[0]])
    nf, nr = float(row["N_fence"]), float(row["N_rail"])
    if nf > 0:
        s = min(max(float(row["M_fence"]) / nf, 0.0), p["l"])
        ln = 0.06 + 0.24 * math.sqrt(nf / nmax)
        _arrow(ax, s * d, ln * nvec, FENCE_FORCE_COLOR)
        _force_label(ax, s * d - ln * nvec, -nvec, f"{nf:.0f} N" if nf < 1e3 else f"{nf / 1e3:.2f} kN",
                     FENCE_FORCE_COLOR)
    if nr > 0:
        xs, ys = o[:-1, 0], o[:-1, 1]
        j = int(np.argmin(np.where(xs <= 0.0, ys, np.inf)))
        ln = 0.06 + 0.18 * math.sqrt(nr / nmax)
        _arrow(ax, np.array([xs[j], 0.0]), np.array([0.0, ln]), RAIL_FORCE_COLOR)
        _force_label(ax, np.array([xs[j], -ln]), np.array([0.0, -1.0]), f"rail {nr:.0f} N", RAIL_FORCE_COLOR)


def draw_frame(ax, p: dict, row, nmax: float, title: str) -> None:
    """One instant of a cycle on `ax`, all from one trajectory row: the scene (belt, rail, pivot, far
    edge), the drive lever alpha_w (dashed), the fence alpha, the load at (x, y, phi) (grey and dashed
    after its exit; its polygon has gid "load") and the contact forces, scaled by nmax (the largest
    force of the run). p: the run's P_max, l and the load's L and A. The cycle frames (cycle_<case>.png)
    and the animation (report/animation.py) both draw with it."""
    draw_scene(ax, p, XLIM)
    al, aw = float(row["alpha"]), float(row["alpha_w"])
    d = np.array([math.cos(al), math.sin(al)])
    ax.plot([0, p["l"] * math.cos(aw)], [0, p["l"] * math.sin(aw)], color=LEVER_COLOR, lw=1.0, ls="--", zorder=3)
    ax.plot([0, p["l"] * d[0]], [0, p["l"] * d[1]], color=FENCE_COLOR, lw=3, solid_capstyle="round", zorder=4)
    gone = int(row["stage"]) < 0
    o = load_outline(p["L"], p["A"], row["x"], row["y"], row["phi"])
    ax.fill(o[:, 0], o[:, 1], color="0.8" if gone else "#8c6d31", alpha=0.6 if gone else 0.85, zorder=3, gid="load")
    ax.plot(o[:, 0], o[:, 1], color="k", lw=0.8, ls="--" if gone else "-", zorder=3)
    _draw_forces(ax, p, row, o, d, nmax)
    ax.set_title(title, fontsize=8)
    ax.set_xlim(*XLIM)
    ax.set_ylim(-0.5, p["P_max"] + 0.3)  # room under the belt for the rail's and the pivot's force labels
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)


def legend_handles() -> list:
    """The legend of the cycle frames and the animation: fence, lever, rail, the two forces, far edge."""
    from matplotlib.lines import Line2D

    return [Line2D([], [], color=FENCE_COLOR, lw=3, label="fence (pivot O at the origin)"),
            Line2D([], [], color=LEVER_COLOR, lw=1, ls="--", label="drive lever alpha_w (the fence's equilibrium)"),
            Line2D([], [], color="k", lw=3, label="rail (x <= 0), belt edge y = 0"),
            Line2D([], [], color=FENCE_FORCE_COLOR, lw=1.6, label="force of the fence on the load"),
            Line2D([], [], color=RAIL_FORCE_COLOR, lw=1.6, label="force of the rail on the load"),
            Line2D([], [], color="0.4", lw=1, label="far edge y = P_max (slide)")]


def largest_force(df) -> float:
    """The largest contact force of a trajectory (fence or rail), which the arrows are scaled by."""
    return max(float(df["N_fence"].max()), float(df["N_rail"].max()), 1e-9)


def _cycle(res: Path, out: Path, case: str) -> Path:
    plt = pyplot()
    df = RP.read_traj(res, f"{case}_flexible")
    p = df.attrs["params"]
    r = df.attrs["results"]
    inst = _instants(df, 8)
    t = df["t"].to_numpy()
    nmax = largest_force(df)
    fig, axes = plt.subplots(4, 2, figsize=(8.6, 10.0))
    for k, (ax, (tt, label)) in enumerate(zip(axes.flat, inst)):
        row = df.iloc[row_at(t, tt)]
        draw_frame(ax, p, row, nmax, frame_title(row, f"{k + 1}. ", label))
    for ax in axes.flat[len(inst):]:
        ax.axis("off")
    fig.legend(handles=legend_handles(), loc="lower center", ncol=3, fontsize=8, bbox_to_anchor=(0.5, -0.005))
    fig.suptitle(f"One sorting cycle, {RP.CASE_TEXT[case]}; flexible fence 72/570, {WORKING_POINT}\n"
                 f"outcome {r['outcome']} at t = {r['t_exit']:.3f} s, overload {r['overload']:.2f}. x along the "
                 "belt, y across it [m]; arrow heads at the point of action, length ~ sqrt(force)")
    fig.tight_layout(rect=(0, 0.035, 1, 1))
    return save(fig, out, f"cycle_{case}.png")


def cycle(res: Path, out: Path) -> list:
    """One cycle in frames (8 instants) for each named case, flexible 72/570 fence."""
    return [_cycle(res, out, c) for c in RP.CASES]
