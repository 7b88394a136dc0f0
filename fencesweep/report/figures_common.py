"""What the figures share: pyplot on the Agg backend with the figures' font sizes, saving a PNG, the
colours and labels of the drives, stages and outcomes, the stage shading and the A / B / C marks
of a trajectory's events, and the scene (belt, rail, pivot, the load's outline) that the load-path
figure and the cycle frames draw.

matplotlib is imported inside the functions (Agg backend), so this module imports without it.
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


def pyplot():
    """matplotlib.pyplot on the Agg backend, with the figures' font sizes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 9, "axes.titlesize": 10, "axes.labelsize": 9, "legend.fontsize": 8,
                         "figure.titlesize": 11})
    return plt


def save(fig, out: Path, name: str) -> Path:
    """Write `fig` to out/name (PNG, DPI, tight bounding box) and close it."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / name
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path


def case_title(df) -> str:
    """'small_far: 0.2 x 0.1 m load, dP = 0.6 m', from a trajectory's parameters."""
    p = df.attrs.get("params") or {}
    return f"{p.get('case')}: {p.get('L'):g} x {p.get('A'):g} m load, dP = {p.get('dP'):g} m"


def stack_levels(xs, min_sep: float) -> list:
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


# ---------------------------------------------------------------------------- events and stages
def event_points(ev) -> list:
    """[(t, letter)] of A, B and the C's (C1, C2, ... when there are several), sorted by time."""
    cs = [(t, f"C{k + 1}" if len(ev.C) > 1 else "C") for k, (t, _, _) in enumerate(ev.C)]
    return sorted(p for p in [(ev.A, "A"), (ev.B, "B")] + cs if math.isfinite(p[0]))


def mark_events(ax, ev, t_scale=1.0, label=True, color="k") -> int:
    """Vertical lines at A, B and the C's; letters above the axes, stacked where they are close
    (call after the x limits are set). Returns the number of letter rows, for the title's pad."""
    pts = event_points(ev)
    lo, hi = ax.get_xlim()
    for t, _ in pts:
        ax.axvline(t * t_scale, color=color, lw=0.7, ls=":", zorder=1)
    shown = [(t, s) for t, s in pts if lo <= t * t_scale <= hi]
    if not label or not shown:
        return 0
    lev = stack_levels([t * t_scale for t, _ in shown], 0.035 * (hi - lo))
    for (t, letter), k in zip(shown, lev):
        ax.annotate(letter, (t * t_scale, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 2 + 10 * k),
                    textcoords="offset points", ha="center", va="bottom", fontsize=8, fontweight="bold",
                    color=color)
    return max(lev) + 1


def shade_stages(ax, ev, alpha=0.6):
    for t0, t1, s in ev.runs:
        if s != 1:  # S2 (no contact) stays white
            ax.axvspan(t0, t1, color=STAGE_COLORS.get(s, "#dddddd"), alpha=alpha, lw=0, zorder=0)


def stage_legend_handles(stages):
    from matplotlib.patches import Patch

    return [Patch(color=STAGE_COLORS[s], label=RP.STAGE_NAMES[s]) for s in sorted(stages) if s != 1]


# ---------------------------------------------------------------------------- geometry helpers (drawing)
def load_outline(L, A, x, y, phi):
    from fencesweep.model.params import load_corners

    cs = load_corners(L, A, phi)
    return np.array([[x + a, y + b] for a, b in cs] + [[x + cs[0][0], y + cs[0][1]]])


def draw_scene(ax, p, xlim):
    """Belt (light), its far edge (slide), the rail upstream of the pivot, the pivot."""
    ax.axhspan(0, p["P_max"], color="#f7f7f2", zorder=0)
    ax.axhline(p["P_max"], color="0.4", lw=1.0)
    ax.plot([xlim[0], 0], [0, 0], color="k", lw=3, solid_capstyle="butt", zorder=2)
    ax.axhline(0, color="0.6", lw=0.6, zorder=1)
    ax.plot([0], [0], "ko", ms=4, zorder=6)
