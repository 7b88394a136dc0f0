"""The load's geometry (docs/model.md §1): corners, the initial state, the outcome margins (§9)."""
from __future__ import annotations

import math

from fencesweep.kernel.jit import kernel

from fencesweep.model import layout as Lp


@kernel(inline=True)
def corner_offset(j, hl, hw, cphi, sphi):
    """Offset of corner j from the centroid: local (+-L/2, +-A/2) rotated by phi (docs/model.md (1.3))."""
    lx = hl if (j == 0 or j == 3) else -hl
    ly = hw if j < 2 else -hw
    return cphi * lx - sphi * ly, sphi * lx + cphi * ly


@kernel(inline=True)
def corner_motion(j, y, hl, hw, cphi, sphi):
    """Corner j: offset (rx, ry), position (gx, gy) and velocity (gvx, gvy) (docs/model.md (1.4))."""
    rx, ry = corner_offset(j, hl, hw, cphi, sphi)
    return rx, ry, y[0] + rx, y[1] + ry, y[3] - y[5] * ry, y[4] + y[5] * rx


@kernel()
def initial_state(p, y):
    """docs/model.md (1.5): phi0; foremost corner at x = R_s, lowest at y = dP; belt velocity."""
    cphi = math.cos(p[Lp.PHI0])
    sphi = math.sin(p[Lp.PHI0])
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    xmax = -math.inf
    ymin = math.inf
    for j in range(4):
        rx, ry = corner_offset(j, hl, hw, cphi, sphi)
        xmax = max(xmax, rx)
        ymin = min(ymin, ry)
    for i in range(y.shape[0]):
        y[i] = 0.0
    y[0] = p[Lp.RS] - xmax
    y[1] = p[Lp.DP] - ymin
    y[2] = p[Lp.PHI0]
    y[3] = p[Lp.V]


@kernel()
def min_corner_x(y, p):
    """Smallest x of the load's corners [m] (for the escape event)."""
    cphi = math.cos(y[2])
    sphi = math.sin(y[2])
    hl = 0.5 * p[Lp.LL]
    hw = 0.5 * p[Lp.AA]
    xmin = math.inf
    for j in range(4):
        rx, ry = corner_offset(j, hl, hw, cphi, sphi)
        xmin = min(xmin, y[0] + rx)
    return xmin


@kernel()
def outcome_margin(kind, y, p):
    """Outcome event functions (docs/model.md (9.1), (9.2)), >= 0 once the event has happened:
    0 scraped: y - P_max; 1 escaped: min_j x_Gj - l (> 0)."""
    if kind == 0:
        return y[1] - p[Lp.PMAX]
    return min_corner_x(y, p) - p[Lp.FL]
