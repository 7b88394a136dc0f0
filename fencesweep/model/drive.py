"""The drive's kinematic constraint alpha_w(t) (docs/model.md §2).

crank_rocker: a four-bar with time ratio 1 (rocker c = 1, crank a = sin(psi/2),
coupler b = r_b, ground d = sqrt(b^2 + cos^2(psi/2))), open assembly; harmonic:
alpha_w = psi/2 (1 - cos(2 pi t / t_c)). The drive rests outside [0, t_c].
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from fencesweep.kernel.jit import entry, kernel, python_callable

from fencesweep.model import layout as Lp
from fencesweep.kernel.cache import solved


#: the crank-rocker's alpha_w from the table that follows p's header (15.11): the CPU's kernels. A
#: GPU thread's copy of drive_angle is compiled with DRIVE_TABLE = False (model/scenes/gpu.py): its p
#: has no table (each thread would carry its own 49 KB), and it solves (2.2)-(2.6) at each time.
#: A constant, so that the choice is made when the kernel is compiled: the CPU's code has no branch.
DRIVE_TABLE = True


@kernel()
def rocker_angle(theta, a, b, d):
    """Rocker angle beta(theta) and d beta/d theta of the open crank-rocker (docs/model.md (2.2), (2.3),
    (2.4)).

    Crank pivot at the origin, rocker pivot at (d, 0), rocker c = 1. The rocker pin B is
    the intersection of |B - A| = b and |B - (d,0)| = 1 left of the directed line A -> (d,0).
    Velocity: differentiating A + b e(gamma) = (d,0) + e(beta) and dotting with e(gamma)
    gives a sin(gamma - theta) = sin(gamma - beta) dbeta/dtheta.
    """
    ax = a * math.cos(theta)
    ay = a * math.sin(theta)
    ux = d - ax
    uy = -ay
    r = math.sqrt(ux * ux + uy * uy)
    ux /= r
    uy /= r
    x0 = (b * b - 1.0 + r * r) / (2.0 * r)  # distance from A along A->(d,0) to the chord
    hh = math.sqrt(max(b * b - x0 * x0, 0.0))
    bx = ax + x0 * ux - hh * uy  # left normal of u is (-uy, ux)
    by = ay + x0 * uy + hh * ux
    beta = math.atan2(by, bx - d)
    gamma = math.atan2(by - ay, bx - ax)
    dbeta = a * math.sin(gamma - theta) / math.sin(gamma - beta)
    return beta, dbeta


@kernel(inline=True)
def hermite_basis(s, h):
    """Weights of y0, h f0, y1, h f1 (the last two scaled by h) in the cubic Hermite
    interpolant at fraction s of an interval of size h: h00 = 2s^3 - 3s^2 + 1,
    h10 = s^3 - 2s^2 + s, h01 = -2s^3 + 3s^2, h11 = s^3 - s^2 (the drive table's interpolant,
    docs/model.md (15.11))."""
    s2 = s * s
    s3 = s2 * s
    return 2.0 * s3 - 3.0 * s2 + 1.0, (s3 - 2.0 * s2 + s) * h, -2.0 * s3 + 3.0 * s2, (s3 - s2) * h


@kernel(inline=True)
def drive_angle(t, p):
    """alpha_w(t) [rad] and its rate [rad/s] (docs/model.md (2.6), (2.7)); at rest for t < 0 and t > t_c
    (2.8): (2.7) here, (2.6) from the table (15.11) or rocker_offset.

    crank_rocker reads the table of beta(theta) - beta0, beta', beta'' over one crank turn
    that follows the header of p (fill_rocker_table): cubic Hermite interpolation of beta
    with beta' and of beta' with beta'' (error ~1e-12 rad at 2048 intervals). Compiled with
    DRIVE_TABLE False (a GPU thread's copy), it solves the four-bar at theta0 + omega_c t instead
    (rocker_offset), from the geometry in p's header.
    """
    tc = p[Lp.TC]
    if t <= 0.0 or t >= tc:
        return 0.0, 0.0
    om = p[Lp.OMEGA_C]
    if p[Lp.PROFILE] == Lp.PROFILE_HARMONIC:
        half = 0.5 * p[Lp.SWING]
        return half * (1.0 - math.cos(om * t)), half * om * math.sin(om * t)
    if not DRIVE_TABLE:
        aw, db = rocker_offset(p[Lp.CR_TH0] + om * t, p[Lp.CR_A], p[Lp.CR_B], p[Lp.CR_D], p[Lp.CR_B0])
        return aw, db * om
    n = int(p[Lp.TAB_N])
    u = t * p[Lp.TAB_RATE]
    i = int(u)
    if i >= n:
        i = n - 1
    s = u - i
    h = p[Lp.TAB_H]
    a0 = Lp.N_P + i  # beta - beta0 at nodes i, i + 1
    b0 = a0 + (n + 1)  # beta'
    c0 = b0 + (n + 1)  # beta''
    h00, h10, h01, h11 = hermite_basis(s, h)
    aw = h00 * p[a0] + h10 * p[b0] + h01 * p[a0 + 1] + h11 * p[b0 + 1]
    db = h00 * p[b0] + h10 * p[c0] + h01 * p[b0 + 1] + h11 * p[c0 + 1]
    return aw, db * om


@kernel()
def rocker_offset(theta, a, b, d, beta0):
    """alpha_w = beta(theta) - beta0 and d beta / d theta at crank angle theta (docs/model.md (2.6)
    with (2.2)-(2.4)): beta is unwrapped, the swing being below pi, so the difference lies in
    (-pi, pi]."""
    beta, dbeta = rocker_angle(theta, a, b, d)
    x = beta - beta0
    if x > math.pi:
        x -= 2.0 * math.pi
    elif x <= -math.pi:
        x += 2.0 * math.pi
    return x, dbeta


@entry()
def fill_rocker_table(a, b, d, theta0, beta0, out):
    """Tabulate beta(theta) - beta0, beta', beta'' at theta0 + 2 pi i / n, i = 0..n
    (out has 3 (n + 1) entries; beta'' by a central difference of the exact beta')."""
    n = out.shape[0] // 3 - 1
    dl = 1e-5
    for i in range(n + 1):
        th = theta0 + 2.0 * math.pi * i / n
        out[i], out[n + 1 + i] = rocker_offset(th, a, b, d, beta0)
        out[2 * (n + 1) + i] = (rocker_angle(th + dl, a, b, d)[1] - rocker_angle(th - dl, a, b, d)[1]) / (2.0 * dl)


#: intervals of the crank-rocker table over one crank turn
TABLE_SIZE = 2048


@lru_cache(maxsize=256)
def rocker_table(swing: float, coupler_ratio: float) -> np.ndarray:
    """The drive table for one (swing, coupler_ratio) (independent of t_c), cached."""
    a, b, d, th0, b0 = crank_rocker_geometry(swing, coupler_ratio)
    out = np.empty(3 * (TABLE_SIZE + 1))
    fill_rocker_table(a, b, d, th0, b0, out)
    out.setflags(write=False)
    return out


def _beta_unwrapped(theta: float, a: float, b: float, d: float, ref: float) -> float:
    beta = python_callable(rocker_angle)(theta, a, b, d)[0]
    return ref + math.remainder(beta - ref, 2 * math.pi)


@lru_cache(maxsize=256)
def crank_rocker_geometry(swing: float, coupler_ratio: float) -> tuple[float, float, float, float, float]:
    """(a, b, d, theta0, beta0): link lengths and the crank angle of minimum rocker angle, solved
    once per (swing, coupler_ratio) and kept beside the compiled kernels (kernel/cache.py solved)."""
    key = (float(swing), float(coupler_ratio))
    return solved("crank_rocker_geometry", key, lambda: solve_crank_rocker_geometry(*key))


def solve_crank_rocker_geometry(swing: float, coupler_ratio: float) -> tuple[float, float, float, float, float]:
    """crank_rocker_geometry: the link lengths (docs/model.md (2.1)) and the minimum of the rocker angle
    (2.5) by Brent's method on its derivative."""
    from scipy.optimize import brentq

    angle = python_callable(rocker_angle)
    a = math.sin(swing / 2)
    b = coupler_ratio
    d = math.sqrt(b * b + math.cos(swing / 2) ** 2)
    ref = angle(0.0, a, b, d)[0]
    n = 720
    thetas = [2 * math.pi * i / n for i in range(n)]
    vals = [_beta_unwrapped(th, a, b, d, ref) for th in thetas]
    i = min(range(n), key=vals.__getitem__)
    h = 2 * math.pi / n
    # the minimum is the root of d beta / d theta bracketed by the grid neighbours
    theta0 = brentq(lambda th: angle(th, a, b, d)[1], thetas[i] - h, thetas[i] + h,
                    xtol=1e-15, rtol=1e-15)
    beta0 = angle(theta0, a, b, d)[0]
    return a, b, d, theta0, beta0


@lru_cache(maxsize=4096)
def max_drive_rate(swing: float, t_c: float, profile: str, coupler_ratio: float) -> float:
    """max |d alpha_w/dt| [rad/s] over the cycle (used for proximity bounds only)."""
    om = 2 * math.pi / t_c
    if profile == "harmonic":
        return 0.5 * swing * om
    n = TABLE_SIZE + 1
    return float(np.abs(rocker_table(swing, coupler_ratio)[n:2 * n]).max()) * om
