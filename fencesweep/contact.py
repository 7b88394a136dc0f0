"""Contact and friction laws (MODEL.md §4, §5, §6) and the calibration of damping from e.

Compiled pieces (one formula each) are used inside the kernels; the calibration of q(e)
and b_lin(e) runs once per restitution value in plain Python with SciPy and is cached.
"""
from __future__ import annotations

import math
from functools import lru_cache

from numba import njit

from . import layout as Lp


@njit(cache=True, inline="always")
def normal_force(D, Dd, kc, cd, law):
    """Normal force N and its elastic part N_el [N] for penetration D [m] and rate Dd [m/s].

    hertz (paper eq. 3, MODEL.md §4): N = k1 D^1.5 + q sqrt(m1 k1) D^0.25 Dd, cd = q sqrt(m1 k1);
    linear (paper eq. 2): N = k_lin D + b_lin Dd, cd = b_lin. Then N := max(N, 0) (no adhesion).
    """
    if law == Lp.LAW_HERTZ:
        rd = math.sqrt(D)
        n_el = kc * D * rd  # k1 D^1.5
        n = n_el + cd * math.sqrt(rd) * Dd  # + q sqrt(m1 k1) D^0.25 Dd
    else:
        n_el = kc * D
        n = n_el + cd * Dd
    if n < 0.0:
        n = 0.0
    return n, n_el


@njit(cache=True, inline="always")
def coulomb(N, w, mu, eps):
    """Regularised Coulomb friction force [N] against the slip w [m/s] (MODEL.md §5):
    -mu N w / sqrt(w^2 + eps^2)."""
    return -mu * N * w / math.sqrt(w * w + eps * eps)


@njit(cache=True, inline="always")
def belt_friction(ux, uy, om, fmax, mmax, rho, eps):
    """Goyal-Ruina ellipse (paper eq. A9, MODEL.md §6): slip u = (ux, uy) [m/s], spin om [rad/s].

    F = -F_max u / S, M = -M_max rho om / S, S = sqrt(|u|^2 + rho^2 om^2 + eps^2).
    Returns (F_x, F_y, M) [N, N, N m].
    """
    s = math.sqrt(ux * ux + uy * uy + rho * rho * om * om + eps * eps)
    return -fmax * ux / s, -fmax * uy / s, -mmax * rho * om / s


def mean_footprint_radius(L: float, A: float) -> float:
    """rho_bar [m]: mean distance of a uniform L x A rectangle from its centroid (MODEL.md §6).

    For half-sides a, b and delta = sqrt(a^2 + b^2):
    rho_bar = [2 a b delta + a^3 ln((b + delta)/a) + b^3 ln((a + delta)/b)] / (6 a b).
    """
    a, b = L / 2, A / 2
    dl = math.hypot(a, b)
    return (2 * a * b * dl + a**3 * math.log((b + dl) / a) + b**3 * math.log((a + dl) / b)) / (6 * a * b)


def _restitution(c: float, law: str) -> float:
    """e of the dimensionless rigid-wall impact x'' = -max(x^1.5 + c x^0.25 x', 0) (hertz) or
    x'' = -max(x + c x', 0) (linear), x(0) = 0, x'(0) = 1: the rebound speed at the first
    return of the clipped force to 0 (MODEL.md §4). Integrated by the compiled impact
    kernel with m1 = k = w = 1 (2000 RK4 steps per pulse, graded start; ~1 ms)."""
    import numpy as np

    from .results import N_IMPACT_RESULTS, RJ_E_EFF
    from .scenes.impact import impact_kernel

    p = np.zeros(Lp.N_P)
    p[Lp.LAW] = Lp.LAW_HERTZ if law == "hertz" else Lp.LAW_LINEAR
    p[Lp.M1] = p[Lp.KC] = 1.0
    p[Lp.CD] = c
    p[Lp.LL] = p[Lp.AA] = np.inf
    out = np.empty(N_IMPACT_RESULTS)
    t_pulse = 3.2181 if law == "hertz" else np.pi  # undamped pulse of the scaled problem
    impact_kernel(p, True, False, 1.0, t_pulse / 2000.0, out)
    return float(out[RJ_E_EFF])


@lru_cache(maxsize=None)
def damping_coefficient(e: float, law: str = "hertz") -> float:
    """Dimensionless damping q (hertz) or beta (linear) that gives restitution e (MODEL.md §4).

    hertz: x'' = -max(x^1.5 + q x^0.25 x', 0); linear: x'' = -max(x + beta x', 0), with
    b_lin = beta sqrt(m1 k_lin). Solved by Brent's method on e(q) (monotone decreasing).
    """
    from scipy.optimize import brentq

    if e >= 1.0:
        return 0.0
    hi = 1.0
    while _restitution(hi, law) > e:
        hi *= 2.0
        if hi > 1e4:
            raise ValueError(f"e = {e!r} is too small to calibrate the damping")
    return brentq(lambda c: _restitution(c, law) - e, 0.0, hi, xtol=1e-12, rtol=1e-12)


def hertz_peak(m1: float, k1: float, v0: float) -> float:
    """Undamped Hertz peak force [N]: k1 (5 m1 v0^2 / (4 k1))^0.6 (MODEL.md §7)."""
    return k1 * (5.0 * m1 * v0**2 / (4.0 * k1)) ** 0.6


def hertz_contact_time(m1: float, k1: float, v0: float) -> float:
    """Undamped Hertz contact duration [s]: 3.2181 (m1^2 / (k1^2 v0))^0.2 (MODEL.md §7)."""
    return 3.2181 * (m1**2 / (k1**2 * v0)) ** 0.2


def drop_speed(H: float) -> float:
    """v_H = sqrt(2 g H) [m/s] (MODEL.md §7)."""
    return math.sqrt(2.0 * Lp.G * H)


def derived_k_lin(m1: float, k1: float, H: float) -> float:
    """Default k_lin [N/m] (MODEL.md §4): F0^2 / (m1 v_H^2), F0 the undamped Hertz peak of §7."""
    vh = drop_speed(H)
    return hertz_peak(m1, k1, vh) ** 2 / (m1 * vh**2)
