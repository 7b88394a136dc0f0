"""How fast is the compiled solver a Numba user would reach for first, beside the engine? The peer:
the cycle of docs/model.md (flexible drive, crank-rocker profile, Hertz law: the named cases) as one
``numba.cfunc`` right-hand side handed to ``numbalsoda.lsoda`` on a uniform output grid, the results
read off the samples; timed beside ``fencesweep.simulate`` on small_far and long_near.

    python benchmarks/lsoda_peer.py [--rtol 1e-6] [--rounds 51]    -> results/lsoda_peer.md

Time it with nothing else busy (both run in one process). Needs numbalsoda (the bench extra; it
builds from source with a Fortran compiler). Ported from docs/model.md and the reference
(tests/reference/model.py: q_from_e gives the damping); it imports nothing from ``fencesweep``
except to time the engine. State [x, y, phi, xd, yd, om, 10 alpha, alphadot] (alpha x10: LSODA's
one scalar atol is the reference's per-component one). No event restarts: the corners' side memory
sigma_j lives in ``data``, set by the right-hand side and undone when LSODA calls it again at an
earlier t (a rejected attempt: _rollback); the outcome and t_exit (cubic Hermite between samples)
and the peak force (the largest sample; refined: re-integrated around each sampled maximum) come
from the grid. Its errors on every validation scene, with the rigid and free drives, the harmonic
profile and the linear law it then had, are on the page (measured once; the full peer:
``git show 1dcab14:benchmarks/lsoda_peer.py``).
"""
from __future__ import annotations

import argparse
import functools
import math
import platform
import sys
import time
from pathlib import Path

import numba as nb
import numpy as np
from common import md_table
from numba import njit
from numbalsoda import lsoda, lsoda_sig

ROOT = Path(__file__).resolve().parents[1]
# this tree's package (main only); tests/: the independent reference (tests/reference/)
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from reference.model import q_from_e  # noqa: E402  (the reference's calibration)

G_ACC = 9.81            # [m/s^2] §6
ASCALE = 10.0           # state[6] = ASCALE * alpha (atol of alpha = atol / ASCALE)
ATOL_SCALE = 1e-3       # atol = ATOL_SCALE * rtol (reference: rtol * STATE_SCALE)
DT_EVAL = 2e-4          # [s] default output grid spacing
CHUNK = 0.25            # [s] integration chunk after t_c while no outcome
MXSTEP = 500000         # LSODA's cap on steps between two output points
REFINE_FRACTION = 0.5   # refine: sampled local maxima above this fraction of the peak
REFINE_MAX = 3          # refine: at most this many of them
REFINE_POINTS = 101     # refine: output points of each re-integration
REFINE_LEVELS = 2       # refine: re-integrations per maximum (each zooms 50x)

# ---- Parameters (docs/model.md §12)
DEFAULTS = {"v": 2.0, "P_max": 0.7, "mu1": 0.4, "mu2": 0.25, "L": 0.7, "A": 0.1, "m1": 15.0, "dP": 0.0, "R_s": 0.0,
            "phi0": 0.0, "e": 0.2, "k1": 4.0e6, "l": 1.2, "m2": 5.0, "B2": 72.0, "K2": 570.0, "t_c": 1.36,
            "swing": math.radians(42.0), "coupler_ratio": 2.5, "eps_v": 1e-3}
CASES = {"small_far": {"L": 0.2, "A": 0.1, "dP": 0.6}, "long_near": {"L": 0.7, "A": 0.1, "dP": 0.0}}


def resolve(case: str) -> dict:
    """Defaults <- named case, with I2 and t_max derived (§3, §12)."""
    p = {**DEFAULTS, **CASES[case]}
    p["I2"], p["t_max"] = p["m2"] * p["l"] ** 2 / 3.0, p["t_c"] + 1.0
    return p


# ---- data array layout (float64, shared by the cfunc and the post-processing)
(I_NFEV, I_NSTEP, I_TLAST, I_TC, I_OMEGA, I_CA, I_CB, I_CC, I_CD, I_TH0, I_BE0, I_V, I_M1, I_I1, I_L, I_A, I_LF,
 I_I2, I_B2, I_K2, I_MU2, I_EPS, I_K, I_C, I_FMAX, I_MMAX, I_RHO, I_PMAX, I_TMAX, I_NLOG, I_SIG) = range(31)
I_SCR = I_SIG + 4       # scratch: 5 for the forces' info, 4 for sigma before the call
I_LOG = I_SCR + 9       # rollback log of the memory: N_LOG entries (t, corner j, sigma before)
N_LOG = 32
N_DATA = I_LOG + 3 * N_LOG
N_INFO = 9              # per sample: N fence, N rail, D max, alpha, alpha_w, sigma_0..3


# ---- Drive (§2)
@njit(cache=True)
def _rocker(th, a, b, c, d):
    """Rocker angle beta(theta) (open assembly) and d beta / d theta."""
    Ax, Ay = a * math.cos(th), a * math.sin(th)
    ex, ey = d - Ax, -Ay
    e = math.sqrt(ex * ex + ey * ey)
    ux, uy = ex / e, ey / e
    pp = (b * b - c * c + e * e) / (2.0 * e)
    h = math.sqrt(max(b * b - pp * pp, 0.0))
    Bx = Ax + pp * ux - h * uy          # B to the left of the directed line A -> (d, 0)
    By = Ay + pp * uy + h * ux
    bt = math.atan2(By, Bx - d)
    num = (Bx - Ax) * (-a * math.sin(th)) + (By - Ay) * (a * math.cos(th))
    den = c * (-(Bx - Ax) * math.sin(bt) + (By - Ay) * math.cos(bt))
    return bt, num / den


@njit(cache=True)
def _drive(t, p):
    """(alpha_w, alphadot_w) at t; at rest outside [0, t_c]."""
    if t <= 0.0 or t >= p[I_TC]:
        return 0.0, 0.0
    om = p[I_OMEGA]
    bt, db = _rocker(p[I_TH0] + om * t, p[I_CA], p[I_CB], p[I_CC], p[I_CD])
    x = bt - p[I_BE0]
    x -= 2.0 * math.pi * math.floor((x + math.pi) / (2.0 * math.pi))    # unwrap about beta0
    return x, db * om


@functools.lru_cache(maxsize=None)
def crank_rocker_theta0(swing: float, coupler_ratio: float) -> tuple:
    """Link lengths and the crank angle theta0 of minimum beta (§2), with beta(theta0)."""
    from scipy.optimize import brentq

    c = 1.0
    a = c * math.sin(swing / 2.0)
    b = coupler_ratio * c
    d = math.sqrt(b * b + c * c * math.cos(swing / 2.0) ** 2)
    ths = np.linspace(0.0, 2.0 * math.pi, 1441)
    bs = np.array([_rocker(th, a, b, c, d)[0] % (2.0 * math.pi) for th in ths])
    i = int(np.argmin(bs))
    lo, hi = ths[max(i - 1, 0)], ths[min(i + 1, len(ths) - 1)]
    if i == 0:
        lo = ths[-2] - 2.0 * math.pi
    th0 = brentq(lambda th: _rocker(th, a, b, c, d)[1], lo, hi, xtol=1e-15, rtol=1e-15)
    return a, b, c, d, th0, _rocker(th0, a, b, c, d)[0]


# ---- Forces (§3-§6): one function for the right-hand side and the post-processing
@njit(cache=True, inline="always")
def _law(D, Dd, p):
    """Unclipped normal force for D > 0 (§4): the modified Kelvin law."""
    sq = math.sqrt(D)
    return p[I_K] * D * sq + p[I_C] * math.sqrt(sq) * Dd


@njit(cache=True)
def _evaluate(t, y, p, sig, dy, info, want_rhs):
    """Derivatives dy of the state y at t; info = [N fence, N rail, max D, alpha, alpha_w].
    sig: the corners' side memory, updated here."""
    x, yc, ph, u, w, om = y[0], y[1], y[2], y[3], y[4], y[5]
    aw, awd = _drive(t, p)
    al, ald = y[6] / ASCALE, y[7]
    c, s = math.cos(ph), math.sin(ph)
    ca, sa = math.cos(al), math.sin(al)
    hL, hA, lf = 0.5 * p[I_L], 0.5 * p[I_A], p[I_LF]
    mu2, eps2 = p[I_MU2], p[I_EPS] * p[I_EPS]
    # §6 belt friction
    ux, uy = u - p[I_V], w
    rho = p[I_RHO]
    S = math.sqrt(ux * ux + uy * uy + (rho * om) ** 2 + eps2)
    Fx = -p[I_FMAX] * ux / S
    Fy = -p[I_FMAX] * uy / S
    Mz = -p[I_MMAX] * rho * om / S
    Nf = Nr = Dmax = tau = 0.0
    # The load has left (§9: centroid at P_max, or every corner past x = l) or the run
    # timed out: no contact forces from then on, only belt friction, under which yd and
    # the load's x-velocity do not change sign, so the load stays gone; the fence runs on
    # alone.  (Freezing the load instead makes y' jump from yd > 0 to 0 at y = P_max: a
    # sliding boundary that an implicit corrector can never step across.)
    gone = yc >= p[I_PMAX] or x - abs(c) * hL - abs(s) * hA > lf or t >= p[I_TMAX]
    if not gone:
        for j in range(4):
            ox = hL if (j == 0 or j == 3) else -hL       # §1 corner j in body axes
            oy = hA if j < 2 else -hA
            rx = c * ox - s * oy
            ry = s * ox + c * oy
            gx, gy = x + rx, yc + ry
            vx, vy = u - om * ry, w + om * rx
            # §5.1 corner-fence, with the side memory sigma_j
            sj = gx * ca + gy * sa
            h = -gx * sa + gy * ca
            if sj > lf:
                sig[j] = 1.0 if h >= 0.0 else -1.0
            elif sj < 0.0:
                sig[j] = 1.0
            else:
                sg = sig[j]
                D = -sg * h
                if D > 0.0:
                    Dmax = max(Dmax, D)
                    Dd = -sg * ((-vx * sa + vy * ca) - ald * sj)
                    N = _law(D, Dd, p)
                    if N > 0.0:
                        Nf += N
                        ws = vx * ca + vy * sa
                        f = -mu2 * N * ws / math.sqrt(ws * ws + eps2)
                        fx = -sg * N * sa + f * ca
                        fy = sg * N * ca + f * sa
                        Fx, Fy, Mz = Fx + fx, Fy + fy, Mz + (rx * fy - ry * fx)
                        tau -= sg * N * sj
            # §5.3 corner-rail
            if gx <= 0.0 and gy < 0.0:
                D = -gy
                Dmax = max(Dmax, D)
                N = _law(D, -vy, p)
                if N > 0.0:
                    Nr += N
                    fx = -mu2 * N * vx / math.sqrt(vx * vx + eps2)
                    Fx += fx
                    Fy += N
                    Mz += rx * N - ry * fx
        # §5.2 tip-edge: T inside the load, edge by the separating-axis test of O-T
        Tx, Ty = lf * ca, lf * sa
        rx, ry = Tx - x, Ty - yc
        px = rx * c + ry * s
        py = -rx * s + ry * c
        if hL - px > 0.0 and hL + px > 0.0 and hA - py > 0.0 and hA + py > 0.0:
            ox = -x * c - yc * s
            oy = x * s - yc * c
            ovx = min(max(ox, px), hL) - max(min(ox, px), -hL)
            ovy = min(max(oy, py), hA) - max(min(oy, py), -hA)
            if ovx < ovy:
                sg = 1.0 if px >= 0.0 else -1.0
                D = hL - sg * px
                nx, ny = sg * c, sg * s
            else:
                sg = 1.0 if py >= 0.0 else -1.0
                D = hA - sg * py
                nx, ny = -sg * s, sg * c
            Dmax = max(Dmax, D)
            tx, ty = -ny, nx
            dvx = (u - om * ry) + lf * ald * sa        # load point at T minus the tip
            dvy = (w + om * rx) - lf * ald * ca
            N = _law(D, dvx * nx + dvy * ny, p)
            if N > 0.0:
                Nf += N
                slip = dvx * tx + dvy * ty
                f = -mu2 * N * slip / math.sqrt(slip * slip + eps2)
                fx = -N * nx + f * tx
                fy = -N * ny + f * ty
                Fx, Fy, Mz = Fx + fx, Fy + fy, Mz + (rx * fy - ry * fx)
                tau += -Tx * fy + Ty * fx                # reaction -F at T
    info[0], info[1], info[2], info[3], info[4] = Nf, Nr, Dmax, al, aw
    if not want_rhs:
        return
    dy[0], dy[1], dy[2] = u, w, om
    dy[3], dy[4], dy[5] = Fx / p[I_M1], Fy / p[I_M1], Mz / p[I_I1]
    dy[6] = ASCALE * ald
    dy[7] = (p[I_B2] * (awd - ald) + p[I_K2] * (aw - al) + tau) / p[I_I2]


@njit(cache=True)
def _rollback(t, p):
    """Undo the memory changes made at times later than t.

    LSODA calls the right-hand side at t_n + h for each attempt of a step; a call at a
    time earlier than a logged change means that the step that made the change was
    rejected (or is being retried with a smaller h), so the change is undone."""
    n = int(p[I_NLOG])
    while n > 0 and p[I_LOG + 3 * (n - 1)] > t:
        k = I_LOG + 3 * (n - 1)
        p[I_SIG + int(p[k + 1])] = p[k + 2]
        n -= 1
    p[I_NLOG] = n


@njit(cache=True)
def _log_sigma(t, p, sig_before):
    """Log the changes of sigma made at t (sig_before: the values before this call)."""
    for j in range(4):
        if p[I_SIG + j] != sig_before[j]:
            n = int(p[I_NLOG])
            if n == N_LOG:                       # full: forget the oldest change
                for k in range(3 * (N_LOG - 1)):
                    p[I_LOG + k] = p[I_LOG + 3 + k]
                n -= 1
            k = I_LOG + 3 * n
            p[k], p[k + 1], p[k + 2] = t, j, sig_before[j]
            p[I_NLOG] = n + 1


@nb.cfunc(lsoda_sig, cache=True)
def peer_rhs(t, u, du, data):
    p = nb.carray(data, (N_DATA,))
    y = nb.carray(u, (8,))
    dy = nb.carray(du, (8,))
    p[I_NFEV] += 1.0
    if t != p[I_TLAST]:
        p[I_NSTEP] += 1.0
        p[I_TLAST] = t
    _rollback(t, p)
    sig_before = p[I_SCR + 5:I_SCR + 9]          # views into data: no allocation per call
    for j in range(4):
        sig_before[j] = p[I_SIG + j]
    _evaluate(t, y, p, p[I_SIG:I_SIG + 4], dy, p[I_SCR:I_SCR + 5], True)
    _log_sigma(t, p, sig_before)


RHS_ADDRESS = peer_rhs.address


# ---- Post-processing on the samples
@njit(cache=True)
def _post(ts, Y, p, sig, t_max, d_fail, out, awg):
    """One pass over the samples.  Until the first outcome: out[i] = (N fence, N rail,
    D max, alpha, alpha_w, sigma_0..3 after the sample) and the outcome checks; after it only alpha and alpha_w (the
    deflection is wanted up to max(t_exit, t_c)).  Returns (index of the first sample
    with an outcome or len(ts), kind) with kind 1 scraped, 2 escaped, 3 failed
    (penetration over d_fail or a non-finite sample), 0 none.  awg: alpha_w on ts (see
    :func:`drive_on_grid`), or an empty array to compute it here."""
    n, m = Y.shape
    dy = np.empty(m)
    info = np.empty(5)
    hL, hA = 0.5 * p[I_L], 0.5 * p[I_A]
    first, kind = n, 0
    rad = math.sqrt(hL * hL + hA * hA) * (1.0 + 1e-9)   # the load's half-diagonal
    for i in range(n):
        y = Y[i]
        if kind == 0:
            for k in range(m):
                if not math.isfinite(y[k]):
                    return i, 3
            # broad phase: every corner on the fence's front side (h > 0; then the tip,
            # on the line h = 0, is outside the load too) and above the rail, with every
            # sigma_j = +1 (which the memory rule keeps): no force, no memory change
            aw = awg[i] if awg.size else _drive(ts[i], p)[0]
            al = y[6] / ASCALE
            hc = -y[0] * math.sin(al) + y[1] * math.cos(al)
            if (hc > rad and y[1] > rad and sig[0] == 1.0 and sig[1] == 1.0 and sig[2] == 1.0
                    and sig[3] == 1.0):
                info[:3] = 0.0
                info[3], info[4] = al, aw
            else:
                _evaluate(ts[i], y, p, sig, dy, info, False)
            out[i, :5] = info
            out[i, 5:] = sig
            if ts[i] <= t_max:
                c, s = math.cos(y[2]), math.sin(y[2])
                if info[2] > d_fail:
                    return i, 3
                if y[1] >= p[I_PMAX]:
                    first, kind = i, 1
                elif y[0] - abs(c) * hL - abs(s) * hA > p[I_LF]:
                    first, kind = i, 2
        else:
            aw = awg[i] if awg.size else _drive(ts[i], p)[0]
            al = y[6] / ASCALE
            out[i, :3] = 0.0
            out[i, 3], out[i, 4] = al, aw
    return first, kind


@njit(cache=True)
def _hermite_root(t0, t1, f0, f1, d0, d1):
    """Root of the cubic Hermite interpolant of (f, f') on [t0, t1] (f0 < 0 <= f1)."""
    hdt = t1 - t0
    a, b = 0.0, 1.0
    for _ in range(55):
        s = 0.5 * (a + b)
        f = ((2 * s ** 3 - 3 * s ** 2 + 1) * f0 + (s ** 3 - 2 * s ** 2 + s) * hdt * d0
             + (-2 * s ** 3 + 3 * s ** 2) * f1 + (s ** 3 - s ** 2) * hdt * d1)
        if f < 0.0:
            a = s
        else:
            b = s
    return t0 + 0.5 * (a + b) * hdt


@njit(cache=True)
def _exit_time(kind, ta, ya, tb, yb, p):
    """t_exit between two samples: the centroid's y reaching P_max (kind 1), or the last
    corner's x passing l (kind 2), on the cubic Hermite interpolant (the state carries the
    velocities)."""
    if kind == 1:
        return _hermite_root(ta, tb, ya[1] - p[I_PMAX], yb[1] - p[I_PMAX], ya[4], yb[4])
    hL, hA, lf = 0.5 * p[I_L], 0.5 * p[I_A], p[I_LF]
    ca, sa = math.cos(ya[2]), math.sin(ya[2])
    cb, sb = math.cos(yb[2]), math.sin(yb[2])
    t_last = ta
    for j in range(4):
        ox = hL if (j == 0 or j == 3) else -hL
        oy = hA if j < 2 else -hA
        rxa, rya = ca * ox - sa * oy, sa * ox + ca * oy
        rxb, ryb = cb * ox - sb * oy, sb * ox + cb * oy
        fa, fb = ya[0] + rxa - lf, yb[0] + rxb - lf
        if fa <= 0.0 < fb:
            t_last = max(t_last, _hermite_root(ta, tb, fa, fb, ya[3] - ya[5] * rya,
                                               yb[3] - yb[5] * ryb))
    return t_last


NO_GRID = np.empty(0)


@functools.lru_cache(maxsize=64)
def drive_on_grid(swing: float, coupler_ratio: float, t_c: float, n: int) -> np.ndarray:
    """alpha_w on linspace(0, t_c, n), computed once per drive and grid (the output grid
    of [0, t_c] is the same for every cycle with the same drive)."""
    d = make_data({**DEFAULTS, "swing": swing, "coupler_ratio": coupler_ratio, "t_c": t_c, "I2": 1.0,
                   "t_max": t_c + 1.0})
    out = np.array([_drive(t, d)[0] for t in np.linspace(0.0, t_c, n)])
    out.setflags(write=False)
    return out


def make_data(p: dict) -> np.ndarray:
    """The cfunc's data array for resolved docs/model.md §12 parameters p."""
    d = np.zeros(N_DATA)
    d[I_TLAST] = math.nan
    d[I_TC], d[I_OMEGA] = p["t_c"], 2.0 * math.pi / p["t_c"]
    d[I_CA], d[I_CB], d[I_CC], d[I_CD], d[I_TH0], d[I_BE0] = crank_rocker_theta0(
        float(p["swing"]), float(p["coupler_ratio"]))
    m1, L, A = p["m1"], p["L"], p["A"]
    d[I_V], d[I_M1], d[I_I1], d[I_L], d[I_A] = p["v"], m1, m1 * (L * L + A * A) / 12.0, L, A
    d[I_LF], d[I_I2], d[I_B2], d[I_K2] = p["l"], p["I2"], p["B2"], p["K2"]
    d[I_MU2], d[I_EPS] = p["mu2"], p["eps_v"]
    d[I_K], d[I_C] = p["k1"], q_from_e(float(p["e"])) * math.sqrt(m1 * p["k1"])
    a, b = 0.5 * L, 0.5 * A                     # §6 mean footprint radius
    dl = math.hypot(a, b)
    rho = (2 * a * b * dl + a ** 3 * math.log((b + dl) / a) + b ** 3 * math.log((a + dl) / b)) / (6 * a * b)
    d[I_FMAX] = p["mu1"] * m1 * G_ACC
    d[I_MMAX], d[I_RHO] = d[I_FMAX] * rho, rho
    d[I_PMAX], d[I_TMAX] = p["P_max"], p["t_max"]
    d[I_SIG:I_SIG + 4] = 1.0
    return d


def initial_state(p: dict) -> np.ndarray:
    """§1: foremost corner at x = R_s, lowest at y = dP, belt speed, fence at rest."""
    c, s = math.cos(p["phi0"]), math.sin(p["phi0"])
    hL, hA = 0.5 * p["L"], 0.5 * p["A"]
    cs = [(hL, hA), (-hL, hA), (-hL, -hA), (hL, -hA)]
    rx = [c * ox - s * oy for ox, oy in cs]
    ry = [s * ox + c * oy for ox, oy in cs]
    return np.array([p["R_s"] - max(rx), p["dP"] - min(ry), p["phi0"], p["v"], 0.0, 0.0, 0.0, 0.0])


def _refine_peak(data0, ts, Y, info, last, rtol, atol, nf_max):
    """Peak of the fence force between the samples: every sampled local maximum above
    REFINE_FRACTION of the sampled peak (at most REFINE_MAX of them) is re-integrated by
    LSODA from the sample before it to the sample after it on REFINE_POINTS points, and
    again around the best of those (REFINE_LEVELS zooms; no extrapolation, so a force that
    jumps at a contact onset is not overshot).  Returns (peak, t_peak, extra nfev)."""
    nf = info[: last + 1, 0]
    best, t_best, nfev = nf_max, math.nan, 0
    mid = nf[1:-1]
    cand = 1 + np.flatnonzero((mid > 0.0) & (mid >= nf[:-2]) & (mid >= nf[2:])
                              & (mid >= REFINE_FRACTION * nf_max))
    cand = cand[np.argsort(-nf[cand], kind="stable")][:REFINE_MAX]
    for k in cand:
        t0, t1, y0, sig0 = ts[k - 1], ts[k + 1], Y[k - 1], info[k - 1, 5:9]
        for _ in range(REFINE_LEVELS):
            d = data0.copy()
            d[I_SIG:I_SIG + 4] = sig0
            tf = np.linspace(t0, t1, REFINE_POINTS)
            Yf, ok = lsoda(RHS_ADDRESS, y0.copy(), tf, d, rtol, atol, MXSTEP)
            nfev += int(d[I_NFEV])
            inf = np.empty((REFINE_POINTS, N_INFO))
            _post(tf, Yf, d, sig0.copy(), math.inf, math.inf, inf, NO_GRID)
            j = int(np.argmax(inf[:, 0]))
            if inf[j, 0] > best:
                best, t_best = float(inf[j, 0]), float(tf[j])
            if not ok or j == 0 or j == REFINE_POINTS - 1:
                break
            t0, t1, y0, sig0 = tf[j - 1], tf[j + 1], Yf[j - 1], inf[j - 1, 5:9].copy()
    return best, t_best, nfev


def peer_cycle(params: dict, rtol: float = 1e-6, dt_eval: float = DT_EVAL, refine: bool = False) -> dict:
    """One work cycle of the reference model with compiled LSODA: params fully resolved (resolve), rtol
    LSODA's (atol = 1e-3 rtol, on alpha 1e-4 rtol), dt_eval the output grid's spacing [s], refine: the
    peak force re-integrated around each sampled maximum (_refine_peak). The results (the dict's keys)
    as the engine's, with nfev, n_steps (step attempts) and n_samples."""
    p = params
    t_c, t_max = float(p["t_c"]), float(p["t_max"])
    data = make_data(p)
    data0 = data.copy() if refine else data
    y0 = initial_state(p)
    atol = ATOL_SCALE * rtol
    d_fail = 0.5 * min(p["L"], p["A"])
    sig = np.ones(4)
    tss, Ys, infos = [], [], []
    t0, n0, ok = 0.0, 0, True
    kind, i = 0, 0
    while True:
        # first [0, t_c] (the fence's interval, whatever the outcome), then on in chunks
        # while there is no outcome
        t1 = t_c if t0 == 0.0 else min(t0 + CHUNK, t_max)
        m = max(int(math.ceil((t1 - t0) / dt_eval)), 1) + 1
        ts = np.linspace(t0, t1, m)
        Y, ok = lsoda(RHS_ADDRESS, y0, ts, data, rtol, atol, MXSTEP)
        info = np.empty((m, N_INFO))
        awg = drive_on_grid(float(p["swing"]), float(p["coupler_ratio"]), t_c, m) if t0 == 0.0 else NO_GRID
        i, kind = _post(ts, Y, data, sig, t_max, d_fail, info, awg)
        if not ok and kind == 0:
            kind, i = 4, m - 1
        skip = 0 if t0 == 0.0 else 1             # the chunk's first sample repeats the last
        tss.append(ts[skip:])
        Ys.append(Y[skip:])
        infos.append(info[skip:])
        i += n0 - skip
        n0 += m - skip
        t0 = t1
        if kind != 0 or t0 >= t_max:
            break
        y0 = Y[-1].copy()
    ts = np.concatenate(tss) if len(tss) > 1 else tss[0]
    Y = np.concatenate(Ys) if len(Ys) > 1 else Ys[0]
    info = np.concatenate(infos) if len(infos) > 1 else infos[0]
    status = "ok"
    if kind in (1, 2):
        outcome = "scraped" if kind == 1 else "escaped"
        t_exit = _exit_time(kind, ts[i - 1], Y[i - 1], ts[i], Y[i], data) if i > 0 else 0.0
        last = i
        upto = max(i, int(np.searchsorted(ts, t_c)))   # [0, max(t_exit, t_c)]
    elif kind == 0:
        outcome, t_exit = "timeout", t_max
        last = int(np.searchsorted(ts, t_max, side="right")) - 1
        upto = len(ts) - 1
    else:
        outcome, t_exit, last, upto = "failed", float(ts[i]), i, i
        status = ("failed: LSODA did not succeed" if kind == 4 else
                  f"failed: penetration over {d_fail:.4g} m or non-finite state at t = {ts[i]:.6g}")
    nf = info[: last + 1, 0]
    k_peak = int(np.argmax(nf))
    peak, t_peak, nfev_refine = float(nf[k_peak]), float(ts[k_peak]), 0
    if refine and peak > 0.0 and kind != 4:
        v, tv, nfev_refine = _refine_peak(data0, ts, Y, info, last, rtol, atol, peak)
        if v > peak:
            peak, t_peak = v, tv
    defl = np.abs(info[: upto + 1, 3] - info[: upto + 1, 4])
    return {"outcome": outcome, "t_exit": float(t_exit), "peak_force": peak, "t_peak": t_peak,
            "deflection_max": float(defl.max()), "nfev": int(data[I_NFEV]) + nfev_refine,
            "n_steps": int(data[I_NSTEP]), "status": status}


# ---- main: the peer beside the engine on the named cases
def _cpu(f):
    """(CPU seconds of one call of f, its result)."""
    t = time.process_time()
    res = f()
    return time.process_time() - t, res


PEER_CONFIGS = [("samples", DT_EVAL, False), ("refined", DT_EVAL, True)]
KEPT = "## The peer's errors against the reference"   # the page's sections from here on stay as measured


def _machine() -> str:
    import os
    from importlib.metadata import version

    with open("/proc/cpuinfo") as f:
        cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), platform.machine())
    return (f"{cpu}, {os.cpu_count()} logical cores; Python {platform.python_version()}, "
            f"numpy {version('numpy')}, numba {version('numba')}, numbalsoda {version('numbalsoda')}")


def time_named_cases(rtol: float, rounds: int) -> tuple[dict, dict]:
    """CPU time per cycle of the engine and the peer on small_far and long_near (flexible drive, §12
    defaults), warm, interleaved round by round: medians, and each job's result."""
    import fencesweep   # the engine, for the timing only

    jobs = {}
    for case in ("small_far", "long_near"):
        p = resolve(case)
        grid = np.linspace(0.0, p["t_c"], max(int(math.ceil(p["t_c"] / DT_EVAL)), 1) + 1)
        jobs[(case, "fencesweep", "default")] = lambda case=case: fencesweep.simulate("cycle", case=case)
        for name, dt, ref in PEER_CONFIGS:
            jobs[(case, "peer", name)] = lambda p=p, dt=dt, ref=ref: peer_cycle(p, rtol, dt, ref)
        y0, data = initial_state(p), make_data(p)
        jobs[(case, "peer", "lsoda alone")] = lambda y0=y0, grid=grid, data=data: lsoda(
            RHS_ADDRESS, y0, grid, data.copy(), rtol, ATOL_SCALE * rtol, MXSTEP)
    results = {k: f() for k, f in jobs.items()}        # warm (JIT, caches)
    times = {k: [] for k in jobs}
    for _ in range(rounds):
        for k, f in jobs.items():
            times[k].append(_cpu(f)[0])
    return {k: float(np.median(v)) for k, v in times.items()}, results


def timing_rows(med: dict, res: dict, rtol: float) -> list[list]:
    """The named cases' table: the engine, the peer's configurations, the lsoda call alone."""
    rows = []
    for case in ("small_far", "long_near"):
        eng = med[(case, "fencesweep", "default")]
        for key, solver, setting in [((case, "fencesweep", "default"), "fencesweep (engine)", "default step")] + [
                ((case, "peer", name), f"peer: numbalsoda LSODA ({name})",
                 f"rtol {rtol:g}, dt_eval {dt:g} s" + (", peak refined" if ref else "")) for name, dt, ref in PEER_CONFIGS]:
            r = res[key]
            rows.append([case, solver, setting, f"{med[key] * 1e3:.3f}", f"{med[key] / eng:.2f}",
                         r.get("nfev", "–"), r["n_steps"], r["outcome"], f"{r['peak_force']:.2f}",
                         f"{r['deflection_max']:.6f}", f"{r['t_exit']:.6f}"])
        t = med[(case, "peer", "lsoda alone")]
        rows.append([case, "peer: the lsoda call alone", f"rtol {rtol:g}, same grid", f"{t * 1e3:.3f}", f"{t / eng:.2f}",
                     "", "", "", "", "", ""])
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--rounds", type=int, default=51, help="timed calls per case and solver")
    args = ap.parse_args()
    table = md_table(["case", "solver", "setting", "CPU ms per cycle", "÷ engine's time", "RHS calls (nfev)", "steps",
                      "outcome", "peak_force [N]", "deflection_max [rad]", "t_exit [s]"],
                     timing_rows(*time_named_cases(args.rtol, args.rounds), args.rtol))
    print("\n".join(table), flush=True)
    text = [
        "# The peer in the table: compiled LSODA (numbalsoda) beside the engine", "",
        "Regenerate: `python benchmarks/lsoda_peer.py` (needs the `bench` extra: "
        "`pip install -e \".[bench]\"`, which builds numbalsoda from source with a Fortran "
        "compiler). The peer is `benchmarks/lsoda_peer.py`: the cycle model of docs/model.md as one "
        "`numba.cfunc` right-hand side integrated by `numbalsoda.lsoda` on a uniform output "
        "grid, results scraped from the samples (its docstring lists what it cannot do that the "
        "event-driven reference does).", "",
        f"Machine: {_machine()}.", "",
        "## Time per cycle, the named cases", "",
        f"Flexible drive, docs/model.md §12 defaults otherwise; CPU time per cycle, warm (JIT and caches "
        f"excluded), median of {args.rounds} calls interleaved round by round with the engine in "
        "the same process. *samples*: the peak force is the largest sampled value; *refined*: every sampled local "
        "maximum above half the peak is re-integrated on a 50x finer grid, twice. *the lsoda call alone*: the "
        "integration on the same grid without any post-processing. Steps: the engine's integrator steps; "
        "for the peer, LSODA's step attempts (numbalsoda reports no counters: counted as the "
        "changes of t between right-hand-side calls, rejected attempts included).", "",
        *table, ""]
    out = ROOT / "results" / "lsoda_peer.md"
    old = out.read_text() if out.exists() else ""  # the errors and the notes, measured once: kept as they are
    out.write_text("\n".join(text) + "\n" + (old[old.index(KEPT):] if KEPT in old else ""))
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
