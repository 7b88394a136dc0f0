"""Explicit Runge-Kutta steps: the method, its error estimate, its dense output and the step
controller (in the spirit of scipy.integrate._ivp's rk.py).

A scene supplies a right-hand side `rhs(t, y, p, iw, dy, aux)` (compiled); this module supplies
  * `stepper(rhs, name)`: one step of a method chosen by code with that right-hand side (the
    template `step` specialised, kernel/jit.py), returning the weighted error estimate (0 for
    the fixed-step RK4 baseline), the right-hand side called from one place (a stage loop);
  * `dense_coeffs` / `dense_eval`: the step's continuous extension
    y(t0 + theta h) = y0 + Q0 theta + Q1 theta^2 + Q2 theta^3 + Q3 theta^4;
  * `error_norm` and `next_step`: the standard step-size controller.

Methods (kernel/numerics.py says which is the default and why):
  METHOD_DOPRI5  Dormand-Prince 5(4), FSAL, local extrapolation (Dormand & Prince 1980;
                 Hairer, Norsett & Wanner, Solving ODEs I, Table II.5.2); 4th-order dense
                 output of Shampine (1986), the coefficients scipy's RK45 uses.
  METHOD_RK4     classical RK4 (Kutta 1901) at a fixed step, cubic Hermite dense output
                 (Hairer et al. II.6, eq. 6.7): the baseline of the first engine.
"""
from __future__ import annotations

import math

from fencesweep.kernel.jit import kernel, specialise

METHOD_DOPRI5, METHOD_RK4 = 0, 1
N_STAGES = 7  # stage vectors kept per step (DOPRI5: 6 + the FSAL stage f(t + h, y1))

# ---- Dormand-Prince 5(4): nodes c, coefficients a_ij, error weights e_j (5th minus 4th order),
# dense-output weights p_jk (scipy's RK45 `P`); scalars, so that Numba compiles them as constants ----
C2, C3, C4, C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
A21 = 1 / 5
A31, A32 = 3 / 40, 9 / 40
A41, A42, A43 = 44 / 45, -56 / 15, 32 / 9
A51, A52, A53, A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
A61, A62, A63, A64, A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
B1, B3, B4, B5, B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84  # = a7j (FSAL)
DP_E = (-71 / 57600, 0.0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40)
DP_P = (
    (1.0, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432),
    (0.0, 0.0, 0.0, 0.0),
    (0.0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799),
    (0.0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072),
    (0.0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632),
    (0.0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844),
    (0.0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423),
)
DP_ORDER_EST = 4  # order of the error estimate: the controller's exponent is 1 / (4 + 1)

# ---- classical RK4 ----
RK4_C = (0.0, 0.5, 0.5, 1.0)
RK4_B = (1 / 6, 1 / 3, 1 / 3, 1 / 6)


@kernel(inline=True)
def last_stage(method):
    """Stages evaluated in a step after K[0] = f(t, y): 6 for DOPRI5 (the 6th at the solution y1,
    its value the FSAL stage K[6]), 4 for RK4 (K[1..3], and K[6] = f(t + h, y1))."""
    return 6 if method == METHOD_DOPRI5 else 4


@kernel(inline=True)
def dopri5_stage(s, t, y, h, K, out, n):  # noqa: C901 (12: the tableau's six rows, each written out)
    """The state y + h sum_j a_sj K_j at which DOPRI5's stage s (1..6; 6: the solution y1) is
    evaluated, into out[:n]; returns the stage's time t + c_s h. The sums are written out in the
    order of the tableau's rows."""
    if s == 1:
        for m in range(n):
            out[m] = y[m] + h * A21 * K[0, m]
        return t + C2 * h
    if s == 2:
        for m in range(n):
            out[m] = y[m] + h * (A31 * K[0, m] + A32 * K[1, m])
        return t + C3 * h
    if s == 3:
        for m in range(n):
            out[m] = y[m] + h * (A41 * K[0, m] + A42 * K[1, m] + A43 * K[2, m])
        return t + C4 * h
    if s == 4:
        for m in range(n):
            out[m] = y[m] + h * (A51 * K[0, m] + A52 * K[1, m] + A53 * K[2, m] + A54 * K[3, m])
        return t + C5 * h
    if s == 5:
        for m in range(n):
            out[m] = y[m] + h * (A61 * K[0, m] + A62 * K[1, m] + A63 * K[2, m] + A64 * K[3, m] + A65 * K[4, m])
        return t + h
    for m in range(n):
        out[m] = y[m] + h * (B1 * K[0, m] + B3 * K[2, m] + B4 * K[3, m] + B5 * K[4, m] + B6 * K[5, m])
    return t + h


@kernel(inline=True)
def rk4_stage(s, t, y, h, K, out, n):
    """The state at which classical RK4's stage s (1..3; 4: the solution y1) is evaluated, into
    out[:n]; returns its time."""
    if s < 4:
        c = RK4_C[s]
        for m in range(n):
            out[m] = y[m] + c * h * K[s - 1, m]
        return t + c * h
    for m in range(n):
        out[m] = y[m] + h * (RK4_B[0] * K[0, m] + RK4_B[1] * K[1, m] + RK4_B[2] * K[2, m] + RK4_B[3] * K[3, m])
    return t + h


#: the scene's right-hand side in the template `step`, and the leading components of the state it
#: reads (0: all), bound by `stepper`
RHS = None
N_READ = 0


def stepper(rhs, name: str, n_read: int = 0):
    """`step` with the right-hand side `rhs`, compiled as the kernel function `name`; `n_read`: the
    leading components of the state that `rhs` reads (0: all). The others (quadratures, such as
    the cycle's energies) enter no stage: only the solution y1 is formed for them."""
    return specialise(step, name, RHS=rhs, N_READ=n_read)


def step(method, t, y, h, p, iw, K, tmp, y1, aux, atol, rtol, n_ctrl):
    """One step of `method` from (t, y) with K[0] = f(t, y) given: fills K[1..] (K[6] = f(t + h,
    y1), the FSAL stage) and y1; returns the error norm of the step (acceptable when <= 1; 0 for
    the fixed-step RK4, which has no estimate). A template: RHS is the scene's (`stepper`)."""
    last = last_stage(method)
    n_all = y.shape[0]
    n_read = N_READ if N_READ > 0 else n_all
    for s in range(1, last + 1):
        out = y1 if s == last else tmp
        n = n_all if s == last else n_read  # a stage's state: what the right-hand side reads
        if method == METHOD_RK4:
            ts = rk4_stage(s, t, y, h, K, out, n)
        else:
            ts = dopri5_stage(s, t, y, h, K, out, n)
        RHS(ts, out, p, iw, K[s if s < last else 6], aux)
    if method == METHOD_RK4:
        return 0.0
    return error_norm(K, h, y, y1, atol, rtol, n_ctrl)


@kernel(inline=True)
def error_norm(K, h, y0, y1, atol, rtol, n_ctrl):
    """RMS over the first n_ctrl components of e_i / sc_i, with e = h sum_k E_k K_k the
    difference of the 5th- and 4th-order solutions and sc_i = atol_i + rtol max(|y0_i|, |y1_i|)
    (Hairer et al. II.4, eq. 4.11; docs/model.md (15.3)). A component with atol_i = inf is not
    controlled."""
    acc = 0.0
    for m in range(n_ctrl):
        e = 0.0
        for k in range(N_STAGES):
            if k != 1:  # DP_E[1] = 0: the second stage enters neither solution
                e += DP_E[k] * K[k, m]
        r = h * e / (atol[m] + rtol * max(abs(y0[m]), abs(y1[m])))
        acc += r * r
    return math.sqrt(acc / n_ctrl)


@kernel(inline=True)
def dense_coeffs(method, K, h, y0, y1, Q, n):
    """Coefficients Q[0..3] of the step's continuous extension (module docstring)."""
    dense_coeffs_of(method, K, h, y0, y1, Q, 0, n)


@kernel(inline=True)
def dense_coeffs_of(method, K, h, y0, y1, Q, m0, n):
    """dense_coeffs for the components m0 <= m < n alone (each component's are its own)."""
    if method == METHOD_RK4:
        for m in range(m0, n):  # cubic Hermite of (y0, f0, y1, f1) in powers of theta
            d = y1[m] - y0[m]
            Q[0, m] = h * K[0, m]
            Q[1, m] = 3.0 * d - h * (2.0 * K[0, m] + K[6, m])
            Q[2, m] = -2.0 * d + h * (K[0, m] + K[6, m])
            Q[3, m] = 0.0
        return
    for j in range(4):
        for m in range(m0, n):
            acc = 0.0
            for k in range(N_STAGES):
                if k != 1 and (j > 0 or k == 0):  # DP_P's zeros: the row of K[1], the column of Q[0] past K[0]
                    acc += K[k, m] * DP_P[k][j]
            Q[j, m] = h * acc


@kernel(inline=True)
def dense_eval(y0, Q, theta, out, n):
    """y(t0 + theta h) on the first n components (Horner in theta; docs/model.md (15.6))."""
    for m in range(n):
        out[m] = y0[m] + theta * (Q[0, m] + theta * (Q[1, m] + theta * (Q[2, m] + theta * Q[3, m])))


@kernel(inline=True)
def next_step(h, err, safety, fac_min, fac_max):
    """Step after one with error norm err (II.4, eq. 4.13; docs/model.md (15.4)): h (1/err)^(1/5),
    damped by a safety factor and kept within [fac_min, fac_max] times h."""
    if err == 0.0:
        return h * fac_max
    fac = safety * err ** (-1.0 / (DP_ORDER_EST + 1))
    return h * min(fac_max, max(fac_min, fac))
