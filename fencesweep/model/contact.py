"""Contact and friction laws (docs/model.md §4, §5, §6) and their closed forms (§7).

Compiled pieces (one formula each) are used inside the kernels. The damping coefficient
solved from e lives in calibrate.py.
"""
from __future__ import annotations

import math
from fencesweep.kernel.jit import kernel, python_callable

from fencesweep.model import layout as Lp


@kernel(inline=True)
def kelvin_force(D, Dd, kc, cd, law):
    """Unclipped normal force N and its elastic part N_el [N] for penetration D >= 0 [m] and
    rate Dd [m/s] (the sign of N says whether the contact pushes, docs/model.md (4.1), (4.2)).

    hertz (paper eq. 3): N = k1 D^1.5 + q sqrt(m1 k1) D^0.25 Dd, cd = q sqrt(m1 k1);
    linear (paper eq. 2): N = k_lin D + b_lin Dd, cd = b_lin.
    """
    if law == Lp.LAW_HERTZ:
        rd = math.sqrt(D)
        n_el = kc * D * rd  # k1 D^1.5
        return n_el + cd * math.sqrt(rd) * Dd, n_el  # + q sqrt(m1 k1) D^0.25 Dd
    n_el = kc * D
    return n_el + cd * Dd, n_el


@kernel(inline=True)
def normal_force(D, Dd, kc, cd, law):
    """Normal force N := max(kelvin_force, 0) (no adhesion, docs/model.md (4.3)) and N_el [N]."""
    n, n_el = kelvin_force(D, Dd, kc, cd, law)
    return max(n, 0.0), n_el


@kernel(inline=True)
def coulomb(N, w, mu, eps):
    """Regularised Coulomb friction force [N] against the slip w [m/s] (docs/model.md (5.13)):
    -mu N w / sqrt(w^2 + eps^2)."""
    return -mu * N * w / math.sqrt(w * w + eps * eps)


@kernel(inline=True)
def belt_friction(ux, uy, om, fmax, mmax, rho, eps):
    """Goyal-Ruina ellipse (paper eq. A9, docs/model.md (6.3), (6.4)): slip u = (ux, uy) [m/s], spin om [rad/s].

    F = -F_max u / S, M = -M_max rho om / S, S = sqrt(|u|^2 + rho^2 om^2 + eps^2).
    Returns (F_x, F_y, M) [N, N, N m].
    """
    s = math.sqrt(ux * ux + uy * uy + rho * rho * om * om + eps * eps)
    return -fmax * ux / s, -fmax * uy / s, -mmax * rho * om / s


def mean_footprint_radius(L: float, A: float) -> float:
    """rho_bar [m]: mean distance of a uniform L x A rectangle from its centroid (docs/model.md (6.2)).

    For half-sides a, b and delta = sqrt(a^2 + b^2):
    rho_bar = [2 a b delta + a^3 ln((b + delta)/a) + b^3 ln((a + delta)/b)] / (6 a b).
    """
    a, b = L / 2, A / 2
    dl = math.hypot(a, b)
    return (2 * a * b * dl + a**3 * math.log((b + dl) / a) + b**3 * math.log((a + dl) / b)) / (6 * a * b)


def hertz_peak(m1: float, k1: float, v0: float) -> float:
    """Undamped Hertz peak force [N]: k1 (5 m1 v0^2 / (4 k1))^0.6 (docs/model.md (7.4))."""
    return k1 * (5.0 * m1 * v0**2 / (4.0 * k1)) ** 0.6


def hertz_contact_time(m1: float, k1: float, v0: float) -> float:
    """Undamped Hertz contact duration [s]: 3.2181 (m1^2 / (k1^2 v0))^0.2 (docs/model.md §7)."""
    return float(python_callable(pulse_time)(Lp.LAW_HERTZ, m1, k1, v0))


@kernel()
def pulse_time(law, m, kc, speed):
    """Duration [s] of an undamped impact of mass m at the given speed (docs/model.md (7.5), (7.6)): Hertz
    3.2181 (m^2 / (k1^2 v))^0.2; linear pi sqrt(m / k_lin). The time scale of an impact."""
    if law == Lp.LAW_HERTZ:
        return 3.2181 * (m * m / (kc * kc * max(speed, 1e-9))) ** 0.2
    return math.pi * math.sqrt(m / kc)


def wall_force_scale(m1: float, k: float, v0: float, law: int) -> float:
    """The force scale [N] of a rigid-wall impact of mass m1 at speed v0 (docs/model.md (7.7)), in
    which the dimensionless impact (4.5) / (4.6) is written: k1 D*^1.5 with D* = (m1 v0^2 / k1)^0.4
    (hertz), k_lin D* with D* = v0 sqrt(m1 / k_lin) (linear)."""
    if law == Lp.LAW_HERTZ:
        d = (m1 * v0 * v0 / k) ** 0.4
        return k * d * math.sqrt(d)
    return k * v0 * math.sqrt(m1 / k)


def drop_speed(H: float) -> float:
    """v_H = sqrt(2 g H) [m/s] (docs/model.md (7.1))."""
    return math.sqrt(2.0 * Lp.G * H)


def derived_k_lin(m1: float, k1: float, H: float) -> float:
    """Default k_lin [N/m] (docs/model.md (4.10)): F0^2 / (m1 v_H^2), F0 the undamped Hertz peak of §7."""
    vh = drop_speed(H)
    return hertz_peak(m1, k1, vh) ** 2 / (m1 * vh**2)
