"""Step-level numerics shared by the scenes: the classical RK4 combination, cubic Hermite
dense output of a step, and parabolic peak location.

RK4 (Kutta 1901; Hairer, Norsett & Wanner, Solving ODEs I, Table 1.2):
  y1 = y0 + h/6 (k1 + 2 k2 + 2 k3 + k4).
Dense output between two accepted steps uses the cubic Hermite interpolant of
(y0, f0) and (y1, f1) (Hairer et al. II.6, eq. 6.7), third order, enough to locate events
inside a step to well below the step's own error.
"""
from __future__ import annotations

from numba import njit


@njit(cache=True)
def axpy(y, h, k, out):
    """out = y + h k (a stage state of RK4)."""
    for i in range(y.shape[0]):
        out[i] = y[i] + h * k[i]


@njit(cache=True)
def rk4_combine(y, h, k1, k2, k3, k4, out):
    """out = y + h/6 (k1 + 2 k2 + 2 k3 + k4)."""
    c = h / 6.0
    for i in range(y.shape[0]):
        out[i] = y[i] + c * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True, inline="always")
def hermite_basis(s, h):
    """Weights of y0, h f0, y1, h f1 (the last two scaled by h) in the cubic Hermite
    interpolant at fraction s of a step of size h: h00 = 2s^3 - 3s^2 + 1,
    h10 = s^3 - 2s^2 + s, h01 = -2s^3 + 3s^2, h11 = s^3 - s^2."""
    s2 = s * s
    s3 = s2 * s
    return 2.0 * s3 - 3.0 * s2 + 1.0, (s3 - 2.0 * s2 + s) * h, -2.0 * s3 + 3.0 * s2, (s3 - s2) * h


@njit(cache=True)
def hermite(y0, f0, y1, f1, h, s, out):
    """Cubic Hermite interpolant at fraction s in [0, 1] of a step of size h:
    y(s) = h00 y0 + h10 h f0 + h01 y1 + h11 h f1 (hermite_basis)."""
    a, b, c, d = hermite_basis(s, h)
    for i in range(y0.shape[0]):
        out[i] = a * y0[i] + b * f0[i] + c * y1[i] + d * f1[i]


@njit(cache=True)
def parabola_peak(t0, q0, t1, q1, t2, q2):
    """Vertex (t, q) of the parabola through three samples with q1 >= q0, q2 (a local maximum)."""
    d1 = (q1 - q0) / (t1 - t0)
    d2 = (q2 - q1) / (t2 - t1)
    a = (d2 - d1) / (t2 - t0)
    if a >= 0.0:
        return t1, q1
    tm = 0.5 * (t0 + t1) - d1 / (2.0 * a)
    if tm < t0 or tm > t2:
        return t1, q1
    return tm, q1 + d1 * (tm - t1) + a * (tm - t0) * (tm - t1)
