"""Independent reference implementation of the fencesweep sorting-cycle model.

Written from the model's specification alone (sections cited as "§n": those of
docs/model.md, which keeps the specification's numbers), with a plain Python/NumPy
right-hand side integrated by :func:`scipy.integrate.solve_ivp`.  It exists to measure
the error of the fast engine, so it shares no code with it: it imports nothing from
fencesweep (tests/test_reference_model.py checks that).

Method
------
The model is piecewise smooth: contact onsets, force clipping ``N := max(N, 0)``,
the side memory of the corners, the end of the rail at ``x = 0``, the fence-load
manifold of §5.2 (its axis, the edge the under-tip point U lies on and the term of its
depth, the ends of the fence's part inside the load, the end a load edge pushes with, the
load's incident edge) and the drive's kinks at ``t = 0, t_c``
all make the right-hand side jump or kink.  The integration therefore runs in
*segments*: inside a segment every discrete choice (which contacts are engaged, clipped
or off, each corner's side sigma_j, the manifold's axis and points, the fence
kinematic or dynamic, the drive moving or at rest) is frozen, so the right-hand side
is smooth; each way that a frozen choice can become wrong is an event function of
``solve_ivp`` (terminal, with a direction).  At the event the mode
is updated and the integration restarts, so every discontinuity lies on a segment
boundary and the integrator's order is never broken inside a step.  Peaks (force,
deflection, ...) are located on the dense output of each segment.

Public entry point: :func:`simulate_reference`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

G_ACC = 9.81  # [m/s^2] §6

# ---------------------------------------------------------------------------
# Parameters (§12) and named cases
# ---------------------------------------------------------------------------

# docs/model.md §12 defaults.  The two angles are exact: swing 42 deg (the table's
# 0.7330383 rad is this value rounded) and dalpha_perm 15 deg (0.2618 rounded).
DEFAULTS = {
    "v": 2.0, "P_max": 0.7, "mu1": 0.4, "mu2": 0.25, "L": 0.7, "A": 0.1,
    "m1": 15.0, "dP": 0.0, "R_s": 0.0, "phi0": 0.0, "e": 0.2, "k1": 4.0e6,
    "contact_law": "hertz", "k_lin": None, "l": 1.2, "m2": 5.0, "I2": None,
    "B2": 72.0, "K2": 570.0, "drive": "flexible", "t_c": 1.36,
    "swing": math.radians(42.0), "profile": "crank_rocker", "coupler_ratio": 2.5,
    "H": 0.3, "dalpha_perm": math.radians(15.0), "R": 1.2, "w": 2.0, "eps_v": 1e-3,
    "t_max": None,
}

CASES = {
    "small_far": {"L": 0.2, "A": 0.1, "dP": 0.6},
    "long_near": {"L": 0.7, "A": 0.1, "dP": 0.0},
}

STRING_PARAMS = ("contact_law", "drive", "profile")


def resolve_params(params=None):
    """Defaults <- named case <- explicit parameters; derived values filled in."""
    params = dict(params or {})
    case = params.pop("case", None)
    p = dict(DEFAULTS)
    if case is not None:
        if case not in CASES:
            raise ValueError(f"case: unknown named case {case!r} (known: {sorted(CASES)})")
        p.update(CASES[case])
    for k, val in params.items():
        if k not in DEFAULTS:
            raise ValueError(f"{k}: unknown parameter")
        p[k] = val
    for k in DEFAULTS:
        if k not in STRING_PARAMS and p[k] is not None:
            p[k] = float(p[k])
    if p["contact_law"] not in ("hertz", "linear"):
        raise ValueError(f"contact_law: must be hertz or linear, got {p['contact_law']!r}")
    if p["drive"] not in ("flexible", "rigid", "free"):
        raise ValueError(f"drive: must be flexible, rigid or free, got {p['drive']!r}")
    if p["profile"] not in ("crank_rocker", "harmonic"):
        raise ValueError(f"profile: must be crank_rocker or harmonic, got {p['profile']!r}")
    for k in ("P_max", "L", "A", "m1", "k1", "l", "m2", "t_c", "H", "eps_v"):
        if not p[k] > 0:
            raise ValueError(f"{k}: must be > 0, got {p[k]}")
    for k in ("mu1", "mu2", "B2", "K2"):
        if not p[k] >= 0:
            raise ValueError(f"{k}: must be >= 0, got {p[k]}")
    if not 0.0 < p["e"] <= 1.0:
        raise ValueError(f"e: must be in (0, 1], got {p['e']}")
    if p["I2"] is None:
        p["I2"] = p["m2"] * p["l"] ** 2 / 3.0          # §3: I2 = m2 l^2 / 3
    if p["t_max"] is None:
        p["t_max"] = p["t_c"] + 1.0                    # §12
    if p["k_lin"] is None:
        p["k_lin"] = derived_k_lin(p["m1"], p["k1"], p["H"])
    return p


# ---------------------------------------------------------------------------
# Contact law calibration (§4, §7)
# ---------------------------------------------------------------------------

def hertz_undamped_peak(m1, k1, w):
    """Peak of N = k1 D^1.5 for mass m1 hitting a rigid wall at speed w [N] (§7).

    Energy: m1 w^2 / 2 = (2/5) k1 D^2.5  ->  D_max = (5 m1 w^2 / (4 k1))^0.4.
    """
    return k1 * (5.0 * m1 * w * w / (4.0 * k1)) ** 0.6


def derived_k_lin(m1, k1, H):
    """Default linear stiffness (§4): same undamped free-fall peak as the Hertz law.

    Linear undamped peak is sqrt(k_lin m1) v_H, hence k_lin = F0^2 / (m1 v_H^2).
    """
    vH = math.sqrt(2.0 * G_ACC * H)
    F0 = hertz_undamped_peak(m1, k1, vH)
    return F0 * F0 / (m1 * vH * vH)


def _rebound_hertz(q):
    """Dimensionless rebound speed e(q) of x'' = -max(x^1.5 + q x^0.25 x', 0).

    x(0) = 0, x'(0) = 1; separation when x^1.5 + q x^0.25 x' first returns to 0,
    i.e. x^1.25 + q x' = 0 (x > 0).  A short series start avoids the x^0.25 kink:
    x = tau - tau^3.5/8.75 - q tau^2.25/2.8125 + O(tau^3.5 q, q^2 tau^2.5 ...).
    """
    if q == 0.0:
        return 1.0
    t0 = 1e-6
    x0 = t0 - t0 ** 3.5 / (2.5 * 3.5) - q * t0 ** 2.25 / (1.25 * 2.25)
    v0 = 1.0 - t0 ** 2.5 / 2.5 - q * t0 ** 1.25 / 1.25

    def f(t, y):
        x, xd = y
        xp = x if x > 0.0 else 0.0
        return [xd, -(xp ** 1.5 + q * xp ** 0.25 * xd)]

    def sep(t, y):
        xp = y[0] if y[0] > 0.0 else 0.0
        return xp ** 1.25 + q * y[1]
    sep.terminal = True
    sep.direction = -1
    s = solve_ivp(f, (t0, 1e3), [x0, v0], method="DOP853", rtol=1e-13, atol=1e-16,
                  events=sep)
    return -s.y_events[0][0][1]


def _rebound_linear(zeta):
    """Dimensionless rebound speed of x'' = -max(x + zeta x', 0), x(0)=0, x'(0)=1."""
    if zeta == 0.0:
        return 1.0

    def f(t, y):
        return [y[1], -(y[0] + zeta * y[1])]

    def sep(t, y):
        return y[0] + zeta * y[1]
    sep.terminal = True
    sep.direction = -1
    s = solve_ivp(f, (0.0, 1e3), [0.0, 1.0], method="DOP853", rtol=1e-13, atol=1e-16,
                  events=sep)
    return -s.y_events[0][0][1]


@functools.lru_cache(maxsize=None)
def q_from_e(e):
    """Damping factor q of the modified Kelvin law for restitution e (§4)."""
    if e >= 1.0:
        return 0.0
    hi = 4.0
    while _rebound_hertz(hi) > e:
        hi *= 4.0
    return brentq(lambda q: _rebound_hertz(q) - e, 0.0, hi, xtol=1e-14, rtol=1e-13)


@functools.lru_cache(maxsize=None)
def zeta_from_e(e):
    """Dimensionless damping b_lin / sqrt(m1 k_lin) of the linear law for e (§4)."""
    if e >= 1.0:
        return 0.0
    hi = 4.0
    while _rebound_linear(hi) > e:
        hi *= 4.0
    return brentq(lambda z: _rebound_linear(z) - e, 0.0, hi, xtol=1e-14, rtol=1e-13)


class ContactLaw:
    """N = k1 D^1.5 + q sqrt(m1 k1) D^0.25 D'  (hertz, eq. (3)/(A2))
    or N = k_lin D + b_lin D'  (linear, eq. (2)); clipping to N >= 0 is done by the
    caller through the contact mode (active / clipped).

    For D < 0 (only ever met inside an integration step that overshoots a separation
    event) the terms are extended continuously: D^1.5 -> sign(D)|D|^1.5,
    D^0.25 -> |D|^0.25, so that N keeps falling through 0 and the event is bracketed.
    """

    def __init__(self, law, m1, k1, k_lin, e):
        self.law = law
        if law == "hertz":
            self.q = q_from_e(e)
            self.k = k1
            self.c = self.q * math.sqrt(m1 * k1)
        else:
            self.q = zeta_from_e(e)
            self.k = k_lin
            self.c = self.q * math.sqrt(m1 * k_lin)
        self.hertz = law == "hertz"

    def parts(self, D, Dd):
        """(elastic part, damping part) of the unclipped normal force [N]."""
        if self.hertz:
            aD = -D if D < 0.0 else D
            sq = math.sqrt(aD)
            el = self.k * aD * sq
            if D < 0.0:
                el = -el
            return el, self.c * math.sqrt(sq) * Dd
        return self.k * D, self.c * Dd


# ---------------------------------------------------------------------------
# Drive (§2)
# ---------------------------------------------------------------------------

class Drive:
    """Kinematic constraint alpha_w(t) of the drive lever and its rate (§2)."""

    def __init__(self, profile, swing, t_c, coupler_ratio):
        self.profile = profile
        self.psi = swing
        self.t_c = t_c
        self.omega = 2.0 * math.pi / t_c
        if profile == "crank_rocker":
            c = 1.0
            self.c = c
            self.a = c * math.sin(swing / 2.0)
            self.b = coupler_ratio * c
            if not self.b > self.a:
                raise ValueError("coupler_ratio: must exceed sin(swing/2)")
            self.d = math.sqrt(self.b ** 2 + c * c * math.cos(swing / 2.0) ** 2)
            ths = np.linspace(0.0, 2.0 * math.pi, 1441)
            bs = np.array([self._beta(th) for th in ths])
            i = int(np.argmin(bs))
            # minimum of beta: root of d beta / d theta, bracketed by the grid
            lo, hi = ths[max(i - 1, 0)], ths[min(i + 1, len(ths) - 1)]
            if i == 0:
                lo = ths[-2] - 2.0 * math.pi
            self.theta0 = brentq(self._dbeta, lo, hi, xtol=1e-15, rtol=1e-15)
            self.beta0 = self._beta(self.theta0)

    # crank-rocker geometry --------------------------------------------------
    def _pins(self, th):
        a, b, c, d = self.a, self.b, self.c, self.d
        Ax, Ay = a * math.cos(th), a * math.sin(th)
        ex, ey = d - Ax, -Ay                      # A -> rocker pivot (d, 0)
        e = math.hypot(ex, ey)
        ux, uy = ex / e, ey / e
        p = (b * b - c * c + e * e) / (2.0 * e)   # foot of B on line A->(d,0)
        h = math.sqrt(b * b - p * p)
        # open assembly: B to the LEFT of the directed line A -> (d, 0)
        Bx = Ax + p * ux - h * uy
        By = Ay + p * uy + h * ux
        return Ax, Ay, Bx, By

    def _beta(self, th):
        _, _, Bx, By = self._pins(th)
        return math.atan2(By, Bx - self.d) % (2.0 * math.pi)

    def _dbeta(self, th):
        """d beta / d theta from d/dtheta |B - A|^2 = 0 with B = (d,0) + c(cos b, sin b)."""
        Ax, Ay, Bx, By = self._pins(th)
        bt = math.atan2(By, Bx - self.d)
        dAx, dAy = -self.a * math.sin(th), self.a * math.cos(th)
        num = (Bx - Ax) * dAx + (By - Ay) * dAy
        den = self.c * (-(Bx - Ax) * math.sin(bt) + (By - Ay) * math.cos(bt))
        return num / den

    def __call__(self, t):
        """(alpha_w, d alpha_w / dt) for a moving drive, 0 <= t <= t_c [rad, rad/s]."""
        if self.profile == "harmonic":
            ph = self.omega * t
            return (0.5 * self.psi * (1.0 - math.cos(ph)),
                    0.5 * self.psi * self.omega * math.sin(ph))
        th = self.theta0 + self.omega * t
        dbeta = self._beta(th) - self.beta0
        dbeta = (dbeta + math.pi) % (2.0 * math.pi) - math.pi   # unwrap about beta(theta0)
        return dbeta, self._dbeta(th) * self.omega

    def at(self, t):
        """alpha_w(t) on the whole time axis: at rest outside [0, t_c]."""
        if t < 0.0 or t > self.t_c:
            return 0.0, 0.0
        return self(t)


# ---------------------------------------------------------------------------
# Helpers: dense-output maximisation, footprint
# ---------------------------------------------------------------------------

def rho_bar(L, A):
    """Mean distance of a uniform L x A rectangle from its centroid [m] (§6)."""
    a, b = 0.5 * L, 0.5 * A
    dl = math.hypot(a, b)
    return (2.0 * a * b * dl + a ** 3 * math.log((b + dl) / a)
            + b ** 3 * math.log((a + dl) / b)) / (6.0 * a * b)


def _maximise(fun, ts):
    """Max of a smooth scalar fun(t) over [ts[0], ts[-1]]: samples at ts and the
    step midpoints, then a bounded Brent refinement around the best sample."""
    ts = np.asarray(ts, dtype=float)
    if ts.size == 0:
        return -math.inf, math.nan
    if ts.size == 1 or ts[-1] <= ts[0]:
        return fun(float(ts[0])), float(ts[0])
    mids = 0.5 * (ts[1:] + ts[:-1])
    grid = np.empty(2 * ts.size - 1)
    grid[0::2] = ts
    grid[1::2] = mids
    vals = np.array([fun(float(t)) for t in grid])
    i = int(np.argmax(vals))
    best_v, best_t = float(vals[i]), float(grid[i])
    lo = grid[max(i - 1, 0)]
    hi = grid[min(i + 1, grid.size - 1)]
    if hi > lo:
        r = minimize_scalar(lambda t: -fun(float(t)), bounds=(lo, hi), method="bounded",
                            options={"xatol": 1e-14 * max(1.0, abs(hi)), "maxiter": 200})
        if r.success and -r.fun > best_v:
            best_v, best_t = float(-r.fun), float(r.x)
    return best_v, best_t


# ---------------------------------------------------------------------------
# Scenes "impact" and "freefall" (§7, §8)
# ---------------------------------------------------------------------------

def _impact_core(m1, w, R, I2, B2, K2, fence, law, method, rtol, atol):
    """Material point m1 against a fence point at distance R, normal speed w.

    Reading of docs/model.md: impulse = integral of N over the impact, contact_time = from
    first touch to the first return of N to 0, e_eff = -(relative normal speed of the
    point w.r.t. the fence point at separation) / w; the fence starts at rest at its
    equilibrium (flexible: B2, K2 with the drive at rest; free: B2 = K2 = 0).

    State [x_p, xd_p, impulse] (+ [theta, thetad] unless rigid). D = x_p - R theta
    (small rotation), m1 xdd_p = -N, I2 thetadd = -B2 thetad - K2 theta + N R.
    The impact ends at the first return of N to 0.
    """
    rigid = fence == "rigid"
    Dstar = (m1 * w * w / law.k) ** 0.4 if law.hertz else w * math.sqrt(m1 / law.k)
    Tstar = Dstar / w
    nfev = [0]

    def D_Dd(y):
        if rigid:
            return y[0], y[1]
        return y[0] - R * y[3], y[1] - R * y[4]

    def force(y):
        D, Dd = D_Dd(y)
        el, dm = law.parts(D, Dd)
        return el + dm

    def f(t, y):
        nfev[0] += 1
        N = force(y)
        out = [y[1], -N / m1, N]
        if not rigid:
            out += [y[4], (-B2 * y[4] - K2 * y[3] + N * R) / I2]
        return out

    def sep(t, y):
        return force(y)
    sep.terminal = True
    sep.direction = -1

    y0 = [0.0, w, 0.0] + ([] if rigid else [0.0, 0.0])
    if atol is None:
        sc = [Dstar, w, m1 * w] + ([] if rigid else [Dstar / R, w / R])
        atol_v = rtol * np.array(sc)
    else:
        atol_v = atol
    s = solve_ivp(f, (0.0, 1e4 * Tstar), y0, method=method, rtol=rtol, atol=atol_v,
                  events=sep, dense_output=True)
    if s.status != 1:
        return {"status": "failed: impact did not end (" + s.message + ")",
                "peak_force": math.nan, "impulse": math.nan, "contact_time": math.nan,
                "e_eff": math.nan, "n_rhs": nfev[0]}
    te = float(s.t_events[0][0])
    ye = s.y_events[0][0]
    peak, tpk = _maximise(lambda t: force(s.sol(t)), s.t)
    Dd_end = D_Dd(ye)[1]
    return {"peak_force": peak, "t_peak": tpk, "impulse": float(ye[2]),
            "contact_time": te, "e_eff": float(-Dd_end / w), "n_rhs": nfev[0],
            "n_steps": len(s.t) - 1, "status": "ok"}


def simulate_impact(p, method="DOP853", rtol=1e-10, atol=None):
    """Scene `impact` (§8): drive at rest, fence rigid / flexible / free throughout."""
    law = ContactLaw(p["contact_law"], p["m1"], p["k1"], p["k_lin"], p["e"])
    if p["drive"] == "free":
        B2, K2 = 0.0, 0.0
    else:
        B2, K2 = p["B2"], p["K2"]
    return _impact_core(p["m1"], p["w"], p["R"], p["I2"], B2, K2, p["drive"], law,
                        method, rtol, atol)


def simulate_freefall(p, method="DOP853", rtol=1e-10, atol=None):
    """Scene `freefall` (§7): m1 hits an undeformable surface at v_H = sqrt(2 g H)."""
    law = ContactLaw(p["contact_law"], p["m1"], p["k1"], p["k_lin"], p["e"])
    vH = math.sqrt(2.0 * G_ACC * p["H"])
    return _impact_core(p["m1"], vH, 1.0, 1.0, 0.0, 0.0, "rigid", law, method, rtol, atol)


# ---------------------------------------------------------------------------
# Scene "cycle" (§1-§6, §9-§11)
# ---------------------------------------------------------------------------

OFF, ACTIVE, CLIPPED = 0, 1, 2          # contact state inside its region
BEHIND, ON, BEYOND = -1, 0, 1           # corner region along the fence: s<0, 0<=s<=l, s>l

OUTCOME_EVENTS = ("scraped", "escaped", "fail")
EVENT_BIAS = 1e-300     # infinitesimal hysteresis of the event functions (see event_values)
# Hysteresis of the contact switches, so that neither round-off nor the integration
# error itself toggles a contact that sits at D ~ 0 (long_near starts with corners
# exactly on the fence line and on the rail, D ~ t^3 .. t^5; sustained rail contacts
# at loose tolerances).  A separation needs N_raw < -N_hyst, a re-engagement
# N_raw > +N_hyst (and D > 0), a loss of geometric contact D < -D_hyst, with
#   D_hyst = the absolute position tolerance (rtol * 1e-3 m by default),
#   N_hyst = max(N_FLOOR, N_PER_RTOL * rtol).
# At the reference tolerance (1e-10): 1e-13 m and 1e-6 N, far below any result's
# resolution; at rtol = 1e-3: 1 um and 1 N, below that tolerance's own error.
# An onset needs only D > 0 (EVENT_BIAS): its time is what the results report.
# Events that are one instant in exact arithmetic (the tip entering the load through an
# edge, the under-tip point U's depth and that edge's tip end reaching 0 with it; a corner
# reaching the fence line and the fence's crossings of its two edges' lines reaching depth
# 0) are located one by one and land within round-off of each other.  A geometric event
# function (a length) within BATCH_TOL of its crossing at the located instant is applied
# in the same batch, so that no intermediate mode (T inside the load, its edge's point
# not yet in contact) lives for a zero-length segment and the manifold is chosen from
# all of them at once (ties, (5.7)).  Only a function that moved towards its crossing
# over the last step counts (a corner resting exactly on a line, D == 0, does not).  Force
# events (N) and outcomes need a true crossing.
BATCH_TOL = 1e-14       # [m]
# The manifold's choice crossings ("ax", "fb", "ee": differences of two depths) start the
# next segment at their root, where the reverse crossing is 0 up to round-off (~1e-16 m);
# several of them can be one instant in exact arithmetic (a face flush across the tip: the
# face's bias, U's term and the axis all cross where the load is parallel to the fence),
# located one by one a few ulps apart.  A choice crossing therefore counts once it is past
# this (a round-off guard, 1e-4 eta, not part of the rule of (5.7)).
CHOICE_TOL = BATCH_TOL  # [m]
N_FLOOR = 1e-6          # [N]
N_PER_RTOL = 1e3        # [N]
IMPLICIT_METHODS = ("Radau", "BDF")
IMPLICIT_FIRST_STEP = 1e-6     # [t_c], see simulate_cycle
IMPLICIT_BOOTSTRAP = 1e-4      # [t_c], see simulate_cycle

# per-component state scales [SI] used for the default absolute tolerance
# atol_i = rtol * scale_i.  Positions are compared with contact penetrations
# (1e-4 .. 1e-2 m), angles with deflections, energies with J.
STATE_SCALE = {"x": 1e-3, "y": 1e-3, "phi": 1e-3, "xd": 1e-3, "yd": 1e-3, "om": 1e-3,
               "al": 1e-4, "ald": 1e-3, "Ec": 1e-3, "Ed": 1e-3}


# §5.2 The fence against the load: one manifold.  Its axes are the load's edges e = 0..3
# (0: x' = +L/2, 1: x' = -L/2, 2: y' = +A/2, 3: y' = -A/2) and the fence's face F.
AXIS_F = 4
AXIS_ORDER = (AXIS_F, 0, 1, 2, 3)       # exact ties of the biased measures: F, then e = 0..3
# eta of (5.7), this * l: a fixed bias, not a memory.  The face's measure is lowered by eta
# when one of its corners is its deepest point and raised by eta when U is (so flush faces
# stay on the face and U loses ties to the edges), and an edge pushes with its pivot end
# only where that end is deeper than the tip end by more than eta.  The choices are
# functions of the state alone.
MANIFOLD_HYSTERESIS = 1e-10
# the rectangle's edges as (corner, next corner) of CycleModel.cx / cy
EDGE_CORNERS = ((0, 1), (1, 2), (2, 3), (3, 0))
# the edge line e of (5.8) (0: x' = L/2, 1: x' = -L/2, 2: y' = A/2, 3: y' = -A/2) of an edge
# given by its two corners, in either order
EDGE_LINE = {frozenset((0, 1)): 2, frozenset((1, 2)): 1, frozenset((2, 3)): 3, frozenset((3, 0)): 0}
# kappa of (5.7): the face measures U as U's edge measures the fence's tip end (its depth along
# the edge's normal) unless U's own depth, shrunk by 1 - kappa, is deeper (the edge more than
# acos(1 - kappa) from the fence's line)
FACE_TOL = 0.01
# The load's four edge lines k are numbered as the edges.  A point P' of the load's frame
# has the margins (L/2 - P'_x, L/2 + P'_x, A/2 - P'_y, A/2 + P'_y): > 0 on the load's side
# of line k, and the margin of line e is the depth delta_e of (5.8).  Along the fence,
# P(u) = u T, every margin is linear in u: delta_k(P(u)) = a_k + u (b_k - a_k), with a_k,
# b_k the margins of the pivot O and of the tip T.
TINY = 1e-300
# an "einc" crossing (a difference of two cosines) holds at its located instant within this
INCIDENCE_TOL = 1e-9
#: the variant in which the load's incident edge pushes with both ends of [u_a, u_b] (tried, and not
#: docs/model.md's rule: it brought the corner-cut double count back, results/tip.md); off
INCIDENT_BOTH_ENDS = False


class _Mode:
    """The frozen discrete state of one integration segment.

    The manifold of §5.2: whether the fence's segment is inside the load (`touch`), what
    bounds the ends of the segment's part inside the load ([u_a, u_b]: O or T themselves,
    or the edge line through which it enters or leaves), the axis in use, and the states
    of that axis' points (corners in span and U for the fence's face; for a load edge one
    end of [u_a, u_b], or both ends for the load's incident edge).  The points of the
    other axes exert no force and are not tracked; they are classified when their axis is
    chosen.  The incident edge and the load's side of the fence line it is derived from
    are tracked all the time (they change only at located events).
    """

    def __init__(self):
        self.cf_region = [ON] * 4
        self.cf_sigma = [1] * 4
        self.cf_state = [OFF] * 4          # corner j as a point of the fence's face
        self.rl_region = [False] * 4       # x_G <= 0
        self.rl_state = [OFF] * 4
        # the side of each of the load's four edge lines of the pivot O (lines[0]) and the
        # tip T (lines[1]): True on the rectangle's side.  T inside <=> all four of
        # lines[1].  One event per line, so a tip that grazes a corner of the load (in and
        # out within one step) is still seen.
        self.lines = [[False] * 4, [False] * 4]
        # [u_a, u_b]: bind[0] the line through which the fence enters the load (-1: O is
        # inside, u_a = 0), bind[1] the line through which it leaves (-1: T is inside,
        # u_b = 1); touch: [u_a, u_b] is not empty, the bodies touch (§5.2)
        self.bind = [-1, -1]
        self.touch = False
        # the under-tip point U (5.16): the edge (C, C') it lies on, which term of the
        # min gives D_U (0: the depth at U, 1: the depth of C'), its state
        self.u_edge = None
        self.u_term = 0
        self.u_state = OFF
        # a load edge's points: the ends of [u_a, u_b] it pushes with (0: pivot end,
        # 1: tip end), a tuple: one end (the pivot end iff D_a > D_b + eta, else the tip
        # end: followed by its located crossings "ee" and chosen afresh where e_cands, the
        # ends not on the edge's own line, change), both ends that are points (the
        # incident edge, e_both), or none; each end's state
        self.e_ends = ()
        self.e_cands = ()
        self.e_both = False
        self.ep_state = [OFF, OFF]
        # the load's incident edge (§5.2): the edge whose outward normal is most
        # anti-parallel to sigma_L n, with sigma_L the side of the fence line the load's
        # centroid is on (+1: X.n >= 0)
        self.sigma_L = 1
        self.e_inc = 3
        self.axis = None                   # None (no contact), 0..3 (E_e) or AXIS_F
        # corners behind the fence line (-sigma_j h_j > 0), for the face's bias while it is no axis
        self.cf_behind = [False] * 4
        # the face's deepest point is U (True: its bias +eta) or a corner in span (False:
        # -eta), (5.7): a function of the state, followed by its located crossings ("fb")
        # and derived afresh where the face's points change (face_key: those it is for)
        self.face_u = False
        self.face_key = None
        self.fence_dyn = False             # fence has its own state (alpha, alphadot)
        self.drive_on = True               # t < t_c
        self.B2 = 0.0
        self.K2 = 0.0

    def copy(self):
        m = _Mode.__new__(_Mode)
        m.__dict__.update({k: ([list(x) if isinstance(x, list) else x for x in v]
                               if isinstance(v, list) else v)
                           for k, v in self.__dict__.items()})
        return m

    @property
    def tip_inside(self):
        return all(self.lines[1])

    def state(self, kind, j):
        if kind == "cf":
            return self.cf_state[j]
        if kind == "u":
            return self.u_state
        if kind == "ep":
            return self.ep_state[j % 2]
        return self.rl_state[j]

    def set_state(self, kind, j, st):
        if kind == "cf":
            self.cf_state[j] = st
        elif kind == "u":
            self.u_state = st
        elif kind == "ep":
            self.ep_state[j % 2] = st
        else:
            self.rl_state[j] = st

    def face_points(self):
        """The fence's face's points (kind, j): the corners in span and U."""
        pts = [("cf", j) for j in range(4) if self.cf_region[j] == ON]
        if self.u_edge is not None:
            pts.append(("u", 0))
        return pts

    def axis_points(self):
        """The points of the axis in use: ("ep", 2 e + end) for a load edge."""
        if self.axis == AXIS_F:
            return self.face_points()
        if self.axis is None:
            return []
        return [("ep", 2 * self.axis + end) for end in self.e_ends]

    def engaged(self):
        """The points of the axis in use that are in contact (ACTIVE or CLIPPED)."""
        return [p for p in self.axis_points() if self.state(*p) != OFF]

    # Reading of docs/model.md: "contact" for stages (§10), A/B, contact_time, n_impacts and
    # the free fence's release (§3) is a FORCE-CARRYING contact (N > 0).  A contact
    # that is geometrically penetrating but clipped (D > 0, N = 0 after a separation)
    # counts as no contact; re-engagement from there is a new onset.
    def n_fence_active(self):
        """The manifold's pushing points (§10): the ACTIVE points of the axis in use."""
        return sum(1 for p in self.axis_points() if self.state(*p) == ACTIVE)

    def n_rail_active(self):
        return sum(1 for j in range(4) if self.rl_region[j] and self.rl_state[j] == ACTIVE)

    def stage(self):
        """§10: S2 none, S1 one manifold point, S3 >= 2, S4 fence + rail, rail."""
        nf, nr = self.n_fence_active(), self.n_rail_active()
        if nf == 0:
            return "S2" if nr == 0 else "rail"
        if nr > 0:
            return "S4"
        return "S1" if nf == 1 else "S3"


class _Snap:
    """The scene at one (t, y) under a mode: the load, its corners, the fence, T and O in
    the load's frame (5.6) and their margins to the load's four edge lines."""

    def __init__(self, model, t, y, mode):
        x, yc, ph, u, w, om = (float(v) for v in y[:6])
        al, ald, aw, awd = (float(v) for v in model.fence(t, y, mode))
        self.x, self.yc, self.u, self.w, self.om = x, yc, u, w, om
        self.al, self.ald, self.aw, self.awd = al, ald, aw, awd
        c, s = math.cos(ph), math.sin(ph)
        ca, sa = math.cos(al), math.sin(al)
        self.c, self.s, self.ca, self.sa = c, s, ca, sa
        self.G = [model.corner(j, x, yc, c, s, u, w, om) for j in range(4)]
        self.sj = [g[0] * ca + g[1] * sa for g in self.G]          # (5.1)
        self.hj = [-g[0] * sa + g[1] * ca for g in self.G]
        l, hL, hA = model.l, 0.5 * model.L, 0.5 * model.A
        self.Tx, self.Ty = l * ca, l * sa                         # (5.5)
        rx, ry = self.Tx - x, self.Ty - yc
        self.Tp = (rx * c + ry * s, -rx * s + ry * c)             # T' (5.6)
        self.Op = (-x * c - yc * s, x * s - yc * c)               # O' (P = 0)
        self.g = [(hL - px, hL + px, hA - py, hA + py) for px, py in (self.Op, self.Tp)]


class CycleModel:
    """One sorting work cycle (§1-§6)."""

    def __init__(self, p):
        self.p = p
        self.v = p["v"]
        self.m1 = p["m1"]
        self.L, self.A = p["L"], p["A"]
        self.I1 = self.m1 * (self.L ** 2 + self.A ** 2) / 12.0       # §1
        self.l = p["l"]
        self.I2 = p["I2"]
        self.mu2 = p["mu2"]
        self.eps = p["eps_v"]
        self.law = ContactLaw(p["contact_law"], p["m1"], p["k1"], p["k_lin"], p["e"])
        self.drive = Drive(p["profile"], p["swing"], p["t_c"], p["coupler_ratio"])
        # §6 belt friction, ellipsoidal limit surface
        self.Fmax = p["mu1"] * self.m1 * G_ACC
        self.rho = rho_bar(self.L, self.A)          # rho = M_max / F_max = rho_bar
        self.Mmax = self.Fmax * self.rho
        # corners j = 0..3 in body frame (§1)
        hL, hA = 0.5 * self.L, 0.5 * self.A
        self.cx = (hL, -hL, -hL, hL)
        self.cy = (hA, hA, -hA, -hA)
        self.D_fail = 0.5 * min(self.L, self.A)     # §5: penetration limit
        self.D_hyst = EVENT_BIAS                    # set by simulate_cycle
        self.N_hyst = N_FLOOR
        self.eta = MANIFOLD_HYSTERESIS * self.l     # (5.7)
        self.nfev = 0

    # ---- initial state (§1) ------------------------------------------------
    def initial_state(self):
        p = self.p
        ph = p["phi0"]
        c, s = math.cos(ph), math.sin(ph)
        rx = [c * ox - s * oy for ox, oy in zip(self.cx, self.cy)]
        ry = [s * ox + c * oy for ox, oy in zip(self.cx, self.cy)]
        x = p["R_s"] - max(rx)          # foremost corner at x = R_s
        y = p["dP"] - min(ry)           # lowest corner at y = dP
        for j in range(4):
            yg = y + ry[j]
            # round-off allowance: small_far puts its far side exactly on P_max
            if yg < -1e-12 or yg > p["P_max"] + 1e-12:
                raise ValueError(
                    f"dP: start invalid, corner {j} at y = {yg:.6g} outside [0, P_max] "
                    f"(check dP, A, L, phi0, P_max)")
        if not p["R_s"] < self.l:
            raise ValueError(f"R_s: start invalid, R_s = {p['R_s']} >= l = {self.l} "
                             "(load already past the fence)")
        return np.array([x, y, ph, self.v, 0.0, 0.0])

    # ---- state layout ---------------------------------------------------------
    @staticmethod
    def names(mode):
        n = ["x", "y", "phi", "xd", "yd", "om"]
        if mode.fence_dyn:
            n += ["al", "ald"]
        return n + ["Ec", "Ed"]

    def fence(self, t, y, mode):
        """(alpha, alphadot, alpha_w, alphadot_w)."""
        aw, awd = self.drive(t) if mode.drive_on else (0.0, 0.0)
        if mode.fence_dyn:
            return y[6], y[7], aw, awd
        return aw, awd, aw, awd

    # ---- per-contact kinematics --------------------------------------------
    def corner(self, j, x, yc, c, s, u, w, om):
        ox, oy = self.cx[j], self.cy[j]
        rx = c * ox - s * oy
        ry = s * ox + c * oy
        return x + rx, yc + ry, rx, ry, u - om * ry, w + om * rx

    # A manifold point is returned as
    #   (D, Dd, nx, ny, tx, ty, slip, rx, ry, fx, fy):
    # its depth and rate, the direction of the normal force on the load (n), the friction
    # direction (t) and the slip of the load's material point relative to the fence's
    # along t, the point of application relative to the centroid (r), and the fence's
    # point (f) at which the reaction acts (its moment about the pivot is -(f x F)).
    def corner_point(self, sn, mode, j):
        """Corner j on the fence's face (5.3), (5.4)."""
        gx, gy, rx, ry, vx, vy = sn.G[j]
        ca, sa = sn.ca, sn.sa
        sg = mode.cf_sigma[j]
        sj = sn.sj[j]
        D = -sg * sn.hj[j]
        Dd = -sg * ((-vx * sa + vy * ca) - sn.ald * sj)
        # the reaction at the fence's point s d under the corner: -(s d) x (sigma N n + f d)
        # = -sigma N s, the friction along the fence passes through the pivot
        return (D, Dd, -sg * sa, sg * ca, ca, sa, vx * ca + vy * sa, rx, ry, sj * ca, sj * sa)

    def crossing_edges(self, mode):
        """The load's edges that cross the line s = l: (C, C') with C short of it and C'
        beyond the tip (5.16), from the corners' regions."""
        out = []
        for a, b in EDGE_CORNERS:
            ba, bb = mode.cf_region[a] == BEYOND, mode.cf_region[b] == BEYOND
            if ba != bb:
                out.append((b, a) if ba else (a, b))
        return out

    def other_u_edge(self, mode):
        for edge in self.crossing_edges(mode):
            if edge != mode.u_edge:
                return edge
        return None

    def u_depths(self, sn, mode, edge):
        """(lambda, -sigma_C h(U), -sigma_C h(C')) of the under-tip point on edge (C, C')."""
        jc, jc2 = edge
        sg = mode.cf_sigma[jc]
        s1, s2 = sn.sj[jc], sn.sj[jc2]
        den = s2 - s1
        if den == 0.0:
            den = TINY
        lam = (self.l - s1) / den
        hU = sn.hj[jc] + lam * (sn.hj[jc2] - sn.hj[jc])
        return lam, -sg * hU, -sg * sn.hj[jc2]

    def u_tip_depth(self, sn, mode):
        """The depth of the fence's tip end P(u_b) below U's edge (5.8): U's point on branch 0."""
        return self.depth_at(sn, EDGE_LINE[frozenset(mode.u_edge)], self.end_u(sn, mode, 1))

    def u_point(self, sn, mode):
        """The under-tip point U (5.7): the shallower of the fence's tip end below U's edge (as
        that edge's axis pushes it, (5.8)-(5.10)) and the corner C' beyond the tip behind the
        fence's line, whose depth and rate push at the tip as a corner does (5.4), with the
        in-span corner C's side."""
        jc, jc2 = mode.u_edge
        if mode.u_term == 0:
            return self.edge_point(sn, mode, EDGE_LINE[frozenset(mode.u_edge)], 1)
        sg = mode.cf_sigma[jc]
        _, _, _, _, vcx, vcy = sn.G[jc2]
        ca, sa = sn.ca, sn.sa
        D = -sg * sn.hj[jc2]                                   # C''s depth and rate ...
        Dd = -sg * ((-vcx * sa + vcy * ca) - sn.ald * sn.sj[jc2])
        rx, ry = self.l * ca - sn.x, self.l * sa - sn.yc         # ... pushed at the tip
        vx, vy = sn.u - sn.om * ry, sn.w + sn.om * rx
        return (D, Dd, -sg * sa, sg * ca, ca, sa, vx * ca + vy * sa, rx, ry, self.l * ca, self.l * sa)

    # ---- the fence's part inside the load, [u_a, u_b] of (5.7) ------------------
    @staticmethod
    def line_sets(mode):
        """From the sides of O and T: the lines that bound u_a from below (O outside, T
        inside), those that bound u_b from above (T outside, O inside), and whether a line
        has both outside (then the segment misses the load)."""
        lo, up, miss = [], [], False
        for k in range(4):
            in_o, in_t = mode.lines[0][k], mode.lines[1][k]
            if not in_o and not in_t:
                miss = True
            elif not in_o:
                lo.append(k)
            elif not in_t:
                up.append(k)
        return lo, up, miss

    @staticmethod
    def line_param(sn, k):
        """The u at which the fence crosses line k: a_k + u (b_k - a_k) = 0."""
        a, b = sn.g[0][k], sn.g[1][k]
        den = a - b
        if den == 0.0:
            den = TINY
        return a / den

    def end_u(self, sn, mode, end):
        k = mode.bind[end]
        return float(end) if k < 0 else self.line_param(sn, k)

    @staticmethod
    def depth_at(sn, e, uu):
        """delta_e (5.8) of the fence's point P(u)."""
        a = sn.g[0][e]
        return a + uu * (sn.g[1][e] - a)

    # ---- the load's incident edge (§5.2) ------------------------------------------
    @staticmethod
    def centroid_side(sn):
        """X.n: the signed distance of the load's centroid from the fence's line [m]."""
        return -sn.x * sn.sa + sn.yc * sn.ca

    @staticmethod
    def incidence(sn, sigma_L):
        """n_e.(sigma_L n) of the four edges e: with n' = R(phi)^T n =
        (-sin(alpha - phi), cos(alpha - phi)), (sigma n'_x, -sigma n'_x, sigma n'_y,
        -sigma n'_y)."""
        npx = -(sn.sa * sn.c - sn.ca * sn.s)
        npy = sn.ca * sn.c + sn.sa * sn.s
        return (sigma_L * npx, -sigma_L * npx, sigma_L * npy, -sigma_L * npy)

    def incident_edge(self, sn, sigma_L):
        """The argmin over e of n_e.(sigma_L n) (ties: the lowest e)."""
        f = self.incidence(sn, sigma_L)
        return min(range(4), key=lambda e: (f[e], e))

    def edge_point(self, sn, mode, e, end):
        """The pivot end (0) or tip end (1) of [u_a, u_b] on load edge e: depth (5.8), rate
        (5.9), force (5.10)."""
        uu = self.end_u(sn, mode, end)
        D = self.depth_at(sn, e, uu)
        c, s = sn.c, sn.s
        nx, ny = ((c, s), (-c, -s), (-s, c), (s, -c))[e]      # outward normal n_e
        Px, Py = uu * sn.Tx, uu * sn.Ty                        # P(u) = u T
        rx, ry = Px - sn.x, Py - sn.yc
        dvx = (sn.u - sn.om * ry) - (-sn.ald * Py)             # v_Q - v_P
        dvy = (sn.w + sn.om * rx) - (sn.ald * Px)
        Dd = dvx * nx + dvy * ny
        tx, ty = -ny, nx                                       # t_e = k x n_e
        return (D, Dd, -nx, -ny, tx, ty, dvx * tx + dvy * ty, rx, ry, Px, Py)

    def point(self, sn, mode, kind, j):
        if kind == "cf":
            return self.corner_point(sn, mode, j)
        if kind == "u":
            return self.u_point(sn, mode)
        return self.edge_point(sn, mode, j // 2, j % 2)

    def face_has_points(self, mode):
        return mode.u_edge is not None or any(r == ON for r in mode.cf_region)

    def measure(self, sn, mode, X):
        """m of (5.7): the face as deep as its corners in span and the depth at U (not the
        min with C'), an edge as deep as the deeper end of [u_a, u_b].  A face without a
        corner in span and without U (the load wholly behind the pivot) is no axis: +inf."""
        if X == AXIS_F:
            ds = [-mode.cf_sigma[j] * sn.hj[j] for j in range(4) if mode.cf_region[j] == ON]
            if mode.u_edge is not None:
                ds.append(self.u_measure(sn, mode))
            return max(ds) if ds else math.inf
        return max(self.depth_at(sn, X, self.end_u(sn, mode, end)) for end in (0, 1)
                   if self.end_is_point(mode, end))

    def u_measure(self, sn, mode):
        """U's part of the face's measure (5.7): the depth of the fence's tip end below U's edge,
        as that edge's axis measures it, or U's own depth times 1 - kappa if deeper; U's own
        depth where the fence leaves the load through U's edge."""
        own = self.u_depths(sn, mode, mode.u_edge)[1]
        e = EDGE_LINE[frozenset(mode.u_edge)]
        if mode.bind[1] == e:
            return own
        return max(self.depth_at(sn, e, self.end_u(sn, mode, 1)), (1.0 - FACE_TOL) * own)

    def face_corner_max(self, sn, mode):
        """The deepest of the corners in span, -sigma_j h_j (-inf if none)."""
        return max((-mode.cf_sigma[j] * sn.hj[j] for j in range(4) if mode.cf_region[j] == ON),
                   default=-math.inf)

    def face_deepest_is_u(self, sn, mode):
        """Whether the face's deepest point is U (its depth at U, -sigma_C h(U), above every
        corner in span; no corner in span: True) rather than a corner (ties: the corner;
        no U: False).  Decides the sign of the face's bias (5.7)."""
        if mode.u_edge is None:
            return False
        return self.u_depths(sn, mode, mode.u_edge)[1] > self.face_corner_max(sn, mode)

    def biased(self, sn, mode, X, m=None):
        """The biased measure b of (5.7), by which the axis is chosen: the face's
        m_F - eta while a corner of it is in contact, m_F + eta when U is its only point
        (face_corner_touches); an edge's m_e unbiased.  A fixed bias, not a memory."""
        if m is None:
            m = self.measure(sn, mode, X)
        if X != AXIS_F:
            return m
        return m - self.eta if self.face_corner_touches(sn, mode) else m + self.eta

    @staticmethod
    def face_corner_touches(sn, mode):
        """Reading of docs/model.md (5.7) as it now stands: the face's bias is -eta while one of
        its corners in span touches (in contact, ACTIVE or CLIPPED, while the face is the axis;
        behind the line, -sigma_j h_j > 0, while it is not: a corner that is no point yet),
        +eta when U is its only point.  (A bias by which of the face's points is deepest made a
        face lying flat across the tip switch axes at every crossing of its two ends' depths.)"""
        return any(mode.cf_region[j] == ON and (mode.cf_behind[j] or mode.cf_state[j] != OFF) for j in range(4))

    @staticmethod
    def end_is_point(mode, end):
        """Both ends of [u_a, u_b] are points of an edge axis (docs/model.md §5.2), the pivot O
        itself included when it lies inside the load (a ridge where the fence dips below the
        rail's line)."""
        return True

    # ---- right-hand side ------------------------------------------------------
    def evaluate(self, t, y, mode, want_rhs=True):
        """Forces of the frozen mode at (t, y).

        Returns (dy, info) where info holds the fence / rail normal-force sums and
        the largest engaged penetration (for post-processing)."""
        sn = _Snap(self, t, y, mode)
        u, w, om = sn.u, sn.w, sn.om
        al, ald, aw, awd = sn.al, sn.ald, sn.aw, sn.awd
        law, mu2, eps = self.law, self.mu2, self.eps
        # §6 belt friction (Goyal-Ruina ellipse, (A9)): slip u = (xd - v, yd), spin om
        ux, uy = u - self.v, w
        S = math.sqrt(ux * ux + uy * uy + (self.rho * om) ** 2 + eps * eps)
        Fx = -self.Fmax * ux / S
        Fy = -self.Fmax * uy / S
        Mz = -self.Mmax * self.rho * om / S
        tau = 0.0          # moment of the load's contact forces on the fence about O
        Pc = 0.0           # contact dissipation rate (N - N_el) Dd
        Nf = 0.0
        Nr = 0.0
        Dmax = -math.inf
        # §5.2 the manifold: the points of the axis in use, nothing from the others.
        # Reading of docs/model.md: the region 0 <= s <= l is closed (a corner exactly at the
        # pivot or the tip is on the fence), h = 0 is no contact (sigma h < 0 strict).
        for kind, j in mode.engaged():
            D, Dd, nx, ny, tx, ty, slip, rx, ry, px, py = self.point(sn, mode, kind, j)
            el, dm = law.parts(D, Dd)
            Dmax = max(Dmax, D)
            if mode.state(kind, j) == CLIPPED:
                Pc -= el * Dd
                continue
            N = el + dm
            Pc += dm * Dd
            Nf += N
            f = -mu2 * N * slip / math.sqrt(slip * slip + eps * eps)
            fx = N * nx + f * tx
            fy = N * ny + f * ty
            Fx += fx
            Fy += fy
            Mz += rx * fy - ry * fx
            tau -= px * fy - py * fx                         # reaction -F at the fence's point
        # §5.3 corner-rail
        # Reading of docs/model.md: x_G <= 0 is closed, y_G < 0 strict; leaving x_G = 0 with
        # D > 0 drops the rail force at once (the hand-over to the fence happens at
        # s = 0, which for alpha > 0 lies at x_G = -y_G tan(alpha) > 0: a short gap).
        for j in range(4):
            if not mode.rl_region[j] or mode.rl_state[j] == OFF:
                continue
            gx, gy, rx, ry, vx, vy = sn.G[j]
            D, Dd = -gy, -vy
            el, dm = law.parts(D, Dd)
            Dmax = max(Dmax, D)
            if mode.rl_state[j] == CLIPPED:
                Pc -= el * Dd
                continue
            N = el + dm
            Pc += dm * Dd
            Nr += N
            fx = -mu2 * N * vx / math.sqrt(vx * vx + eps * eps)
            Fx += fx
            Fy += N
            Mz += rx * N - ry * fx
        info = (Nf, Nr, Dmax, al, aw)
        if not want_rhs:
            return None, info
        dy = [u, w, om, Fx / self.m1, Fy / self.m1, Mz / self.I1]
        Pd = 0.0
        if mode.fence_dyn:
            rel_v = awd - ald
            # §3 I2 alpha'' = B2 (alpha_w' - alpha') + K2 (alpha_w - alpha) + tau
            dy += [ald, (mode.B2 * rel_v + mode.K2 * (aw - al) + tau) / self.I2]
            if mode.drive_on:
                Pd = mode.B2 * rel_v * rel_v
        dy += [Pc, Pd]
        return dy, info

    def rhs(self, t, y, mode):
        self.nfev += 1
        return self.evaluate(t, y, mode)[0]

    # ---- events -----------------------------------------------------------------
    @staticmethod
    def _state_events(ev, prefix, j, st):
        """D crossing 0, and N* crossing 0 while in contact."""
        if st == OFF:
            ev.append((prefix + "_D", j, 1))
        else:
            ev += [(prefix + "_D", j, -1), (prefix + "_N", j, -1 if st == ACTIVE else 1)]

    def event_list(self, mode):
        """(kind, index, direction) of every way the frozen mode can end."""
        ev = []
        on_F = mode.axis == AXIS_F
        for j in range(4):
            r = mode.cf_region[j]
            if r == BEHIND:
                ev.append(("cf_s0", j, 1))
            elif r == BEYOND:
                ev.append(("cf_sl", j, -1))
            else:
                ev += [("cf_s0", j, -1), ("cf_sl", j, 1)]
                if on_F:
                    self._state_events(ev, "cf", j, mode.cf_state[j])
                elif mode.axis is not None:
                    # the face's bias flips where a corner in span crosses the line (5.7)
                    ev.append(("cfz", j, -1 if mode.cf_behind[j] else 1))
        for j in range(4):
            if mode.rl_region[j]:
                ev.append(("rl_x", j, 1))
                self._state_events(ev, "rl", j, mode.rl_state[j])
            else:
                ev.append(("rl_x", j, -1))
        # the sides of O and T on the load's edge lines: T inside, what bounds [u_a, u_b]
        for k in range(8):
            ev.append(("ln", k, -1 if mode.lines[k // 4][k % 4] else 1))
        lo, up, miss = self.line_sets(mode)
        if not miss:
            # another line takes over an end of [u_a, u_b] (the fence passes a corner)
            for end, cand in ((0, lo), (1, up)):
                if mode.bind[end] >= 0:
                    ev += [("bd", 4 * end + k, 1) for k in cand if k != mode.bind[end]]
            # both ends on lines: [u_a, u_b] closes or opens (the segment cuts a corner)
            if mode.bind[0] >= 0 and mode.bind[1] >= 0:
                ev.append(("tch", 0, -1 if mode.touch else 1))
        if mode.u_edge is not None:
            if self.other_u_edge(mode) is not None:
                ev.append(("u_edge", 0, -1))
            if on_F:
                self._state_events(ev, "u", 0, mode.u_state)
                ev.append(("u_term", 0, 1 if mode.u_term == 0 else -1))
        if mode.axis is not None and not on_F:
            e = mode.axis
            for end in mode.e_ends:
                self._state_events(ev, "ep", 2 * e + end, mode.ep_state[end])
            # one end (not the incident edge): the pivot end's D_a - D_b - eta crossing 0
            if not mode.e_both and len(mode.e_ends) == 1:
                other = 1 - mode.e_ends[0]
                if mode.bind[other] != e and self.end_is_point(mode, other):
                    ev.append(("ee", e, 1))
        # the incident edge: another edge's n_e.(sigma_L n) falling below the incident
        # edge's, and the load's centroid crossing the fence line (sigma_L flips)
        ev += [("einc", k, 1) for k in range(4) if k != mode.e_inc]
        ev.append(("sgL", 0, -1))
        if mode.axis is not None:
            # (5.7): the biased argmin changing, b_axis - b_X crossing 0 upwards
            for X in AXIS_ORDER:
                if X != mode.axis and (X != AXIS_F or self.face_has_points(mode)):
                    ev.append(("ax", X, 1))
            # the face's bias flips where its deepest point changes between a corner and U
            if mode.u_edge is not None and any(r == ON for r in mode.cf_region):
                pass  # ("fb": the face's bias now flips at its corners' own contact events)
        ev.append(("scraped", 0, 1))
        ev.append(("escaped", 0, 1))
        if mode.engaged() or any(mode.rl_region[j] and mode.rl_state[j] != OFF
                                 for j in range(4)):
            ev.append(("fail", 0, 1))
        return ev

    def event_values(self, t, y, mode, evlist):
        """Values of the event functions of `evlist`, each shifted by an infinitesimal
        EVENT_BIAS against its direction, so that a function that stays exactly 0
        (a corner resting exactly on the fence line, D == 0 == N) is not taken for a
        crossing: solve_ivp reports g_old <= 0 <= g_new as an up-crossing even for 0 -> 0.
        """
        g = self._event_values(t, y, mode, evlist)
        out = []
        for gi, ev in zip(g, evlist):
            if ev[0] in ("cf_N", "rl_N", "u_N", "ep_N"):
                b = self.N_hyst
            elif ev[0] in ("cf_D", "rl_D", "u_D", "ep_D", "tch") and ev[2] < 0:
                b = self.D_hyst
            elif ev[0] in ("ax", "fb", "ee"):
                b = CHOICE_TOL
            else:
                b = EVENT_BIAS
            out.append(gi - b if ev[2] > 0 else gi + b)
        return out

    def _event_values(self, t, y, mode, evlist):
        sn = _Snap(self, t, y, mode)
        cache = {}

        def pt(kind, j):
            r = cache.get((kind, j))
            if r is None:
                r = cache[(kind, j)] = self.point(sn, mode, kind, j)
            return r
        meas = {}

        def m(X):
            if X not in meas:
                meas[X] = self.measure(sn, mode, X)
            return meas[X]
        out = []
        Dmax = None
        l = self.l
        for kind, j, direction in evlist:
            if kind == "cf_s0":
                out.append(sn.sj[j])
            elif kind == "cf_sl":
                out.append(sn.sj[j] - l)
            elif kind in ("cf_D", "u_D", "ep_D"):
                out.append(pt(kind[:-2], j)[0])
            elif kind in ("cf_N", "u_N", "ep_N"):
                r = pt(kind[:-2], j)
                out.append(self._n_event(r[0], r[1], direction))
            elif kind == "cfz":
                out.append(-mode.cf_sigma[j] * sn.hj[j])
            elif kind == "rl_x":
                out.append(sn.G[j][0])
            elif kind == "rl_D":
                out.append(-sn.G[j][1])
            elif kind == "rl_N":
                out.append(self._n_event(-sn.G[j][1], -sn.G[j][5], direction))
            elif kind == "ln":
                out.append(sn.g[j // 4][j % 4])
            elif kind == "bd":
                # u_a = max of its lower bounds, u_b = min of its upper bounds
                end, k = j // 4, j % 4
                d = self.line_param(sn, k) - self.line_param(sn, mode.bind[end])
                out.append((d if end == 0 else -d) * l)
            elif kind == "tch":
                out.append((self.end_u(sn, mode, 1) - self.end_u(sn, mode, 0)) * l)
            elif kind == "ee":
                # the end rule (5.7): the pivot end pushes iff D_a > D_b + eta; g = D_a - D_b
                # - eta crossing up from the tip end, its negative from the pivot end
                g = (self.depth_at(sn, j, self.end_u(sn, mode, 0))
                     - self.depth_at(sn, j, self.end_u(sn, mode, 1)) - self.eta)
                out.append(g if mode.e_ends[0] == 1 else -g)
            elif kind == "einc":
                # edge j's normal more anti-parallel to sigma_L n than the incident edge's
                # (times l: a length)
                f = self.incidence(sn, mode.sigma_L)
                out.append((f[mode.e_inc] - f[j]) * l)
            elif kind == "sgL":
                out.append(mode.sigma_L * self.centroid_side(sn))
            elif kind == "u_term":
                out.append(self.u_tip_depth(sn, mode) - self.u_depths(sn, mode, mode.u_edge)[2])
            elif kind == "u_edge":
                # the deeper of the two edges that cross s = l (5.16)
                out.append(self.u_depths(sn, mode, mode.u_edge)[1]
                           - self.u_depths(sn, mode, self.other_u_edge(mode))[1])
            elif kind == "ax":
                # (5.7): axis j's biased measure falling below that of the axis in use
                out.append(self.biased(sn, mode, mode.axis, m(mode.axis))
                           - self.biased(sn, mode, j, m(j)))
            elif kind == "fb":
                # the face's deepest point changing between a corner and U (its bias flips)
                d = (self.u_depths(sn, mode, mode.u_edge)[1]
                     - self.face_corner_max(sn, mode))
                out.append(-d if mode.face_u else d)
            elif kind == "scraped":
                # Reading of docs/model.md: checked all the time, also when the load no
                # longer touches the fence (it can slide off past the tip and still
                # reach P_max by its own momentum).
                out.append(sn.yc - self.p["P_max"])          # §9 centroid reaches P_max
            elif kind == "escaped":
                out.append(min(g[0] for g in sn.G) - l)      # §9 all corners x > l
            elif kind == "fail":
                # Reading of docs/model.md: the penetration limit applies to every engaged
                # contact (the manifold's points of the axis in use, the rail), clipped
                # ones included.
                if Dmax is None:
                    Dmax = self.evaluate(t, y, mode, want_rhs=False)[1][2]
                out.append(Dmax - self.D_fail)
        return out

    def _n_event(self, D, Dd, direction):
        """Unclipped normal force as an event function.  For a re-engagement
        (direction +1) a non-positive D gives -(|elastic| + |damping|) <= 0: the
        continuation of the law to D < 0 must not re-engage a contact that has not
        come back into penetration."""
        el, dm = self.law.parts(D, Dd)
        if direction > 0 and D <= 0.0:
            return -(abs(el) + abs(dm))
        return el + dm

    # ---- mode transitions ------------------------------------------------------
    def _classify(self, D, N):
        """Contact state when a contact enters its region with penetration D."""
        # Reading of docs/model.md: a corner that enters the fence region (from behind the
        # pivot, e.g. handed over from the rail) or the rail region already
        # penetrating starts with that D, the force jumping; it is clipped (N = 0) if
        # the unclipped law is <= 0 there.  The same for a manifold point that starts
        # to push at a finite depth (a change of axis, of U's edge, of an edge's end).
        if D > 0.0:
            return ACTIVE if N > 0.0 else CLIPPED
        return OFF

    def _classify_point(self, sn, mode, kind, j):
        D, Dd = self.point(sn, mode, kind, j)[:2]
        mode.set_state(kind, j, self._classify(D, sum(self.law.parts(D, Dd))))

    def contact_now(self, t, y, mode, kind, j):
        """(D, Dd, N_raw) of contact (kind, j) at (t, y) under `mode`: kind "cf" (corner j
        on the fence's face), "u" (the under-tip point), "ep" (end j % 2 of [u_a, u_b] on
        load edge j // 2) or "rl" (corner j on the rail)."""
        sn = _Snap(self, t, y, mode)
        if kind == "rl":
            D, Dd = -sn.G[j][1], -sn.G[j][5]
        else:
            D, Dd = self.point(sn, mode, kind, j)[:2]
        el, dm = self.law.parts(D, Dd)
        return D, Dd, el + dm

    def apply_event(self, t, y, mode, kind, j, direction):
        """Update the frozen mode for an event that fired at (t, y).  The manifold's
        derived choices (U's edge, [u_a, u_b], the axis, an edge's end) follow in
        refresh_manifold."""
        if kind == "cfz":
            mode.cf_behind[j] = direction > 0      # the face's bias re-read in refresh_manifold
        elif kind == "cf_s0":
            if direction < 0:                      # on -> behind the pivot
                mode.cf_region[j] = BEHIND
                mode.cf_state[j] = OFF
                mode.cf_sigma[j] = 1               # §5.1: behind the pivot sigma := +1
            else:                                  # behind -> on
                mode.cf_region[j] = ON
                mode.cf_sigma[j] = 1
                if mode.axis == AXIS_F:
                    D, Dd, N = self.contact_now(t, y, mode, "cf", j)
                    mode.cf_state[j] = self._classify(D, N)
        elif kind == "cf_sl":
            if direction > 0:                      # on -> beyond the tip
                mode.cf_region[j] = BEYOND
                mode.cf_state[j] = OFF
            else:                                  # beyond -> on: sigma := sign(h) as it was
                x, yc, ph = y[0], y[1], y[2]
                al = self.fence(t, y, mode)[0]
                gx, gy = self.corner(j, x, yc, math.cos(ph), math.sin(ph), 0, 0, 0)[:2]
                h = -gx * math.sin(al) + gy * math.cos(al)
                mode.cf_sigma[j] = 1 if h >= 0.0 else -1    # h = 0 counts as +1
                mode.cf_region[j] = ON
                if mode.axis == AXIS_F:
                    D, Dd, N = self.contact_now(t, y, mode, "cf", j)
                    mode.cf_state[j] = self._classify(D, N)
        elif kind == "rl_x":
            if direction > 0:                      # leaves the rail (x_G > 0)
                mode.rl_region[j] = False
                mode.rl_state[j] = OFF
            else:
                mode.rl_region[j] = True
                D, Dd, N = self.contact_now(t, y, mode, "rl", j)
                mode.rl_state[j] = self._classify(D, N)
        elif kind in ("cf_D", "rl_D", "u_D", "ep_D"):
            mode.set_state(kind[:-2], j, ACTIVE if direction > 0 else OFF)
        elif kind in ("cf_N", "rl_N", "u_N", "ep_N"):
            mode.set_state(kind[:-2], j, ACTIVE if direction > 0 else CLIPPED)
        elif kind == "ln":
            mode.lines[j // 4][j % 4] = direction > 0
        # Reading of docs/model.md: at a switch of a choice by a crossing (the term of the
        # min in (5.16), U's edge, the line an end of [u_a, u_b] lies on, the end an edge
        # pushes with, whether [u_a, u_b] is empty), the crossing itself decides the new
        # choice: re-evaluating at the root could pick the old one again and loop on a
        # zero-length segment.  (A region event of the same batch may have redefined U
        # already: then refresh_manifold chooses afresh.)
        elif kind == "bd":
            mode.bind[j // 4] = j % 4
        elif kind == "tch":
            mode.touch = direction > 0
        elif kind == "ee":
            # the end rule's crossing (D_a - D_b - eta through 0): the other end
            if len(mode.e_ends) == 1 and not mode.e_both:
                end = 1 - mode.e_ends[0]
                mode.e_ends = (end,)
                mode.ep_state = [OFF, OFF]
                self._classify_point(_Snap(self, t, y, mode), mode, "ep", 2 * j + end)
        elif kind == "einc":
            # edge j takes over as the incident edge (refresh_manifold re-derives the
            # points of an edge axis affected).  A sigma_L flip of the same batch has
            # chosen afresh already: then the crossing no longer holds and is dropped.
            f = self.incidence(_Snap(self, t, y, mode), mode.sigma_L)
            if f[j] <= f[mode.e_inc] + INCIDENCE_TOL:
                mode.e_inc = j
        elif kind == "sgL":
            # the load's centroid crosses the fence's line: the other side, and the
            # incident edge chosen afresh on it
            mode.sigma_L = -mode.sigma_L
            mode.e_inc = self.incident_edge(_Snap(self, t, y, mode), mode.sigma_L)
        elif kind == "u_term":
            if mode.u_edge is not None:
                mode.u_term = 1 - mode.u_term
                if mode.u_state != OFF:
                    D, Dd, N = self.contact_now(t, y, mode, "u", 0)
                    mode.u_state = ACTIVE if N > 0.0 else CLIPPED
        elif kind == "u_edge":
            other = self.other_u_edge(mode)
            if other is not None:
                mode.u_edge = other
                self._fresh_u(_Snap(self, t, y, mode), mode)
        elif kind == "fb":
            # the face's deepest point changes between a corner and U: its bias flips
            # (refresh_manifold keeps the flipped value and chooses the axis again)
            mode.face_u = not mode.face_u
        # "ax": the axis is chosen again in refresh_manifold (the one in use excluded)

    def _fresh_u(self, sn, mode):
        mode.u_term = 0 if self.u_tip_depth(sn, mode) <= self.u_depths(sn, mode, mode.u_edge)[2] else 1
        if mode.axis == AXIS_F:
            self._classify_point(sn, mode, "u", 0)
        else:
            mode.u_state = OFF

    def _pick_axis(self, bs, exclude=None):
        """The axis of (5.7): the argmin of the biased measures b (a fixed bias, not a
        memory); exact ties in AXIS_ORDER (the face, then e = 0..3).  `exclude`: an axis
        that an "ax" crossing has just left, so that round-off at the located instant does
        not choose it again (the crossing decides); None where nothing else is left."""
        cand = [(v, AXIS_ORDER.index(X), X) for X, v in bs.items()
                if v < math.inf and X != exclude]
        return min(cand)[2] if cand else exclude

    def _pick_end(self, sn, mode, e):
        """The end of [u_a, u_b] a load edge e (not the incident one under
        INCIDENT_BOTH_ENDS) pushes with, of the ends not on e's own line: the pivot end iff
        D_a > D_b + eta, else the tip end (a fixed bias, not a memory: a function of the
        state); the only such end if one lies on e's line; None if both do."""
        ends = [end for end in (1, 0) if mode.bind[end] != e and self.end_is_point(mode, end)]
        if not ends:
            return None
        if len(ends) == 1:
            return ends[0]
        Da = self.depth_at(sn, e, self.end_u(sn, mode, 0))
        Db = self.depth_at(sn, e, self.end_u(sn, mode, 1))
        return 0 if Da > Db + self.eta else 1

    def refresh_manifold(self, t, y, mode, exclude=None):
        """Re-derive the manifold's choices after events (§5.2): the edge U lies on, the
        lines that bound [u_a, u_b] and whether it is empty, the sign of the face's bias,
        the axis and an edge's end (5.7).  A fixed bias, not a memory: the axis is the
        argmin of the biased measures at this state, chosen afresh at every event, except
        that at an "ax" crossing the axis it leaves (`exclude`) is not chosen again (the
        crossing decides, so that round-off at the root does not undo it).  The face's
        bias sign and an edge's end (the pivot end iff D_a > D_b + eta) are functions of
        the state too; they are followed by their own located crossings ("fb", "ee",
        applied in apply_event) and derived afresh here where what they are chosen from
        changes (the face's points; the axis or the ends not on its line), so that an
        unrelated event at one of their roots does not re-decide them by round-off.  The
        points of a newly chosen axis or end are classified by their depth and force
        (PUSH or CLIPPED)."""
        sn = _Snap(self, t, y, mode)
        for j in range(4):  # (at a root of its own event the event's direction decides)
            dj = -mode.cf_sigma[j] * sn.hj[j]
            if abs(dj) > 1e-13:
                mode.cf_behind[j] = dj > 0.0
        lo, up, miss = self.line_sets(mode)
        old_bind = list(mode.bind)
        if miss:
            mode.touch = False
            mode.bind = [-1, -1]
        else:
            for end, cand, pick in ((0, lo, max), (1, up, min)):
                if not cand:
                    mode.bind[end] = -1
                elif mode.bind[end] not in cand:
                    mode.bind[end] = pick(cand, key=lambda k: self.line_param(sn, k))
            if mode.bind[0] < 0 or mode.bind[1] < 0:
                mode.touch = True          # O or T inside, no line outside both: [u_a, u_b] is there
            elif mode.bind != old_bind:
                # (with the ends' lines unchanged the "tch" events keep it: re-read from the state
                # at a "tch" root, within round-off of 0, the flag flipped back at the same instant)
                length = (self.end_u(sn, mode, 1) - self.end_u(sn, mode, 0)) * self.l
                mode.touch = length >= -self.D_hyst if mode.touch else length > 0.0
        # U's edge after [u_a, u_b]: U on its branch 0 is the tip end u_b below that edge
        cross = self.crossing_edges(mode)
        if mode.u_edge not in cross:
            if cross:
                mode.u_edge = max(cross, key=lambda ed: self.u_depths(sn, mode, ed)[1])
                self._fresh_u(sn, mode)
            else:
                mode.u_edge, mode.u_term, mode.u_state = None, 0, OFF
        # the face's bias: U or a corner its deepest point, from the state where the face's
        # points changed or no "fb" event followed it (no axis in use)
        old = mode.axis
        key = (tuple(mode.cf_region), tuple(mode.cf_sigma), mode.u_edge)
        if key != mode.face_key or old is None:
            mode.face_u = self.face_deepest_is_u(sn, mode)
            mode.face_key = key
        new = None
        if mode.touch:
            bs = {X: self.biased(sn, mode, X) for X in AXIS_ORDER}
            new = self._pick_axis(bs)
            if new == exclude:
                new = self._pick_axis(bs, exclude=exclude)
        if new != old:
            mode.axis = new
            mode.cf_state = [OFF] * 4
            mode.u_state = OFF
            mode.e_ends, mode.e_both, mode.ep_state = (), False, [OFF, OFF]
            if new == AXIS_F:
                for kind, j in mode.face_points():
                    if kind == "u":
                        self._fresh_u(sn, mode)
                    else:
                        self._classify_point(sn, mode, kind, j)
        if mode.axis is not None and mode.axis != AXIS_F:
            e = mode.axis
            if INCIDENT_BOTH_ENDS and e == mode.e_inc:
                # the incident edge (a face of the load flush or nearly flush on the
                # fence): both ends of [u_a, u_b] push, each but one on e's own line
                ends = tuple(end for end in (0, 1)
                             if mode.bind[end] != e and self.end_is_point(mode, end))
                if new != old or not mode.e_both:
                    # a new axis, or e has just become the incident edge: all anew
                    mode.e_both, mode.e_ends, mode.ep_state = True, ends, [OFF, OFF]
                    for end in ends:
                        self._classify_point(sn, mode, "ep", 2 * e + end)
                elif ends != mode.e_ends:
                    # an end moved onto e's line (no point) or off it (a new point)
                    for end in (0, 1):
                        if end not in ends:
                            mode.ep_state[end] = OFF
                        elif end not in mode.e_ends:
                            self._classify_point(sn, mode, "ep", 2 * e + end)
                    mode.e_ends = ends
            else:
                # one point, the end of the rule (_pick_end): chosen afresh for a new axis,
                # e no longer the incident edge, or an end gone onto e's line or off it;
                # else the end in use (as "ee" crossings have set it)
                cands = tuple(end for end in (0, 1)
                              if mode.bind[end] != e and self.end_is_point(mode, end))
                if new != old or mode.e_both or cands != mode.e_cands:
                    end = self._pick_end(sn, mode, e)
                    mode.e_both, mode.ep_state = False, [OFF, OFF]
                    mode.e_ends = () if end is None else (end,)
                    if end is not None:
                        self._classify_point(sn, mode, "ep", 2 * e + end)
                mode.e_cands = cands

    def mode_at(self, t, y, drive="rigid", drive_on=True):
        """A mode derived from the state alone (sides sigma_j := +1 in span and behind the
        pivot, sign(h) beyond the tip, (5.2)); every contact classified by D and N, the
        manifold chosen afresh.  A point exactly on a line counts as on the load's side
        of it, and a segment that only touches the load's boundary as touching it.
        y: the full state of names(mode) or just the load's six."""
        m = _Mode()
        m.drive_on = drive_on
        m.fence_dyn = drive == "flexible"
        if m.fence_dyn:
            m.B2, m.K2 = self.p["B2"], self.p["K2"]
        y = np.asarray(y, dtype=float)
        if len(y) == 6:
            y = np.concatenate([y, [0.0, 0.0] if m.fence_dyn else [], [0.0, 0.0]])
        sn = _Snap(self, t, y, m)
        for j in range(4):
            s_, h = sn.sj[j], sn.hj[j]
            m.cf_region[j] = BEHIND if s_ < 0.0 else (ON if s_ <= self.l else BEYOND)
            m.cf_sigma[j] = -1 if (s_ > self.l and h < 0.0) else 1
            gx, gy = sn.G[j][:2]
            m.rl_region[j] = gx <= 0.0
            if m.rl_region[j]:
                m.rl_state[j] = self._classify(-gy, sum(self.law.parts(-gy, -sn.G[j][5])))
        m.lines = [[gk >= 0.0 for gk in sn.g[p]] for p in (0, 1)]
        m.sigma_L = 1 if self.centroid_side(sn) >= 0.0 else -1
        m.e_inc = self.incident_edge(sn, m.sigma_L)
        m.bind = [None, None]
        m.touch = True
        self.refresh_manifold(t, y, m)
        return m

    def initial_mode(self, y0, drive):
        # Reading of docs/model.md: a valid start has no contact (D <= 0 everywhere, T
        # outside the load); the corners and the pivot O may lie exactly on a line (the
        # fence resting on the load's boundary: touching, at depth 0).
        return self.mode_at(0.0, y0, drive)


def _event_key(kind, j):
    """Events of one contact slot at one instant are applied once (the first of the batch):
    the region, D and N events of a corner, a rail contact or a manifold point, and each
    of the lines, U's term, U's edge and the axis events on their own."""
    if kind in ("u_term", "u_edge", "ax", "ln"):
        return (kind, j)
    return (kind.split("_")[0], j)


def _state_atol(names, rtol, atol):
    if atol is None:
        return rtol * np.array([STATE_SCALE[n] for n in names])
    a = np.asarray(atol, dtype=float)
    if a.ndim == 0:
        return float(a)
    # a full vector is given for the 8-component state [x y phi xd yd om al ald]
    full = dict(zip(["x", "y", "phi", "xd", "yd", "om", "al", "ald"], a))
    return np.array([full.get(n, rtol * STATE_SCALE[n]) for n in names])


def _max_step_default(p):
    # Guard against an event function crossing zero twice inside one step (a grazing
    # contact), which solve_ivp cannot see: no step longer than t_c / 100.
    return p["t_c"] / 100.0


def simulate_cycle(p, method="DOP853", rtol=1e-10, atol=None, max_step=None,
                   max_segments=20000, keep_trajectory=False):
    """Integrate one work cycle; see :func:`simulate_reference`.

    Returns (results, n_rhs).  With keep_trajectory the results also hold
    "_model" and "_segments" [(t0, t1, mode, dense output, step times)] (tests)."""
    model = CycleModel(p)
    drive_kind = p["drive"]
    t_c, t_max = p["t_c"], p["t_max"]
    if max_step is None:
        max_step = _max_step_default(p)
    y_load = model.initial_state()
    atol_x = _state_atol(["x"], rtol, atol)
    model.D_hyst = float(np.atleast_1d(atol_x)[0])
    model.N_hyst = max(N_FLOOR, N_PER_RTOL * rtol)
    mode = model.initial_mode(y_load, drive_kind)
    y = list(y_load) + ([0.0, 0.0] if mode.fence_dyn else []) + [0.0, 0.0]
    y = np.array(y, dtype=float)
    t = 0.0
    if t_c <= 0.0:
        mode.drive_on = False

    segments = []          # (t0, t1, mode, OdeSolution or None, step times)
    stage_time = {"S1": 0.0, "S2": 0.0, "S3": 0.0, "S4": 0.0, "rail": 0.0}
    stage_log = []         # (t, stage) at every change of stage (points A, B, C)
    t_first = math.nan
    t_last_loss = math.nan
    n_impacts = 0
    n_steps = 0
    n_mode_fixes = 0
    n_retries = 0
    n_scan_events = 0
    outcome, status = None, "ok"
    state_at_tc = None
    released_at = math.nan

    def make_events(evlist, cache):
        # The event values are computed once per time t and then reused for the same
        # t.  solve_ivp first evaluates the events at each step end with the solver's
        # own y, then brackets a root with brentq on the dense output sol(t_old),
        # sol(t_new); for LSODA (and in principle any method) sol(t_old) may differ
        # from y_old in the last bits, and a function sitting at 0 (a tie left for the
        # next segment) would then change sign and make brentq raise.  Reusing the
        # step-end values keeps the bracket consistent with the crossing test.
        seen = cache.setdefault("seen", {})

        def allv(t_, y_):
            val = seen.get(t_)
            if val is None:
                if len(seen) > 4096:
                    seen.clear()
                val = model.event_values(t_, y_, cache["mode"], evlist)
                seen[t_] = val
            return val
        funcs = []
        for k, (_, _, direc) in enumerate(evlist):
            def f(t_, y_, k=k):
                return allv(t_, y_)[k]
            f.terminal = True
            f.direction = direc
            funcs.append(f)
        return funcs

    # A corner lying exactly on the resting fence (D = 0, 0 <= s <= l; long_near's
    # front corner at the pivot) is in contact from t = 0+: the drive turns the fence
    # into it at once (alpha ~ t^2 > 0).  It is engaged from the start instead of
    # waiting for D to exceed the event hysteresis.
    for j in range(4):
        if mode.cf_region[j] == ON:
            D0 = model.contact_now(0.0, y, mode, "cf", j)[0]
            if abs(D0) <= model.D_hyst:
                mode.cf_state[j] = ACTIVE
    at_rest_on_fence = [j for j in range(4) if mode.cf_region[j] == ON and mode.cf_state[j] != OFF]
    model.refresh_manifold(0.0, y, mode)
    if mode.axis == AXIS_F:          # pushing from t = 0+ (its N* is 0 at t = 0)
        for j in at_rest_on_fence:
            mode.cf_state[j] = ACTIVE
    if mode.n_fence_active() > 0:
        n_impacts, t_first = 1, 0.0
        if drive_kind == "free":       # §3: such a load releases the free fence at once
            mode.fence_dyn = True
            mode.B2 = mode.K2 = 0.0
            released_at = 0.0
            y = np.concatenate([y[:6], [0.0, 0.0], y[6:]])
    stage_log.append((0.0, mode.stage()))
    nseg = 0
    while True:
        nseg += 1
        if nseg > max_segments:
            outcome, status = "failed", f"failed: more than {max_segments} events (chattering)"
            break
        t_end = t_c if (mode.drive_on and t_c < t_max) else t_max
        if t_end <= t:
            # the drive window closes exactly at an event instant, or t_max reached
            if mode.drive_on and t >= t_c and t_c < t_max:
                mode.drive_on = False
                state_at_tc = (t, y.copy(), mode.copy())
                continue
            outcome = "timeout"
            break
        evlist = model.event_list(mode)
        seg_mode = mode.copy()
        cache = {"mode": seg_mode}
        events = make_events(evlist, cache)
        names = model.names(mode)
        # Radau/BDF evaluate their Jacobian at the segment start; at a contact onset
        # (D = 0) the D^0.25 term is not differentiable and Newton can fail down to
        # "step size < spacing".  Then the segment is retried with a small first
        # step, and failing that its first IMPLICIT_BOOTSTRAP * t_c is integrated
        # with DOP853 (same tolerances and events) before the implicit method takes
        # over again.  Counted in n_retries.
        attempts = [(method, None, t_end)]
        if method in IMPLICIT_METHODS:
            attempts += [(method, IMPLICIT_FIRST_STEP * p["t_c"], t_end),
                         ("DOP853", None, min(t + IMPLICIT_BOOTSTRAP * p["t_c"], t_end))]
        for meth_, fs_, t_stop in attempts:
            kw = {} if fs_ is None else {"first_step": min(fs_, t_stop - t)}
            cache["seen"] = {}
            sol = solve_ivp(lambda tt, yy: model.rhs(tt, yy, seg_mode), (t, t_stop), y,
                            method=meth_, rtol=rtol, atol=_state_atol(names, rtol, atol),
                            events=events, dense_output=True, max_step=max_step, **kw)
            if sol.status != -1:
                break
            n_retries += 1
        n_steps += len(sol.t) - 1
        if sol.status == -1:
            segments.append((t, float(sol.t[-1]), seg_mode, sol.sol, sol.t.copy()))
            outcome, status = "failed", "failed: integrator: " + sol.message
            break
        # ---- safety net: sub-step scan for crossings solve_ivp cannot see ----------
        found = None
        if np.all(np.isfinite(sol.y[:, -1])):
            found = _scan_events(model, seg_mode, evlist, sol, t, y)
        if found is not None:
            n_scan_events += 1
            k0, te, ye, t_old, y_old = found
            ts_ = np.append(sol.t[sol.t < te], te)
        else:
            ts_ = sol.t.copy()
        t1 = float(ts_[-1])
        segments.append((t, t1, seg_mode, sol.sol, ts_))
        # Reading of docs/model.md: stage times cover [0, t_exit]; S2 ("none") includes
        # the approach before the first contact and any time after the last one.
        stage_time[seg_mode.stage()] += t1 - t
        y_new = sol.y[:, -1].copy() if found is None else ye
        if not np.all(np.isfinite(y_new)):
            outcome, status = "failed", f"failed: non-finite state at t = {t1:.6g}"
            break
        if sol.status == 0 and found is None:
            t, y = t1, y_new
            if t < t_end:                 # end of a bootstrap piece (see attempts)
                continue
            if mode.drive_on and t >= t_c and t_c < t_max:
                mode.drive_on = False
                state_at_tc = (t, y.copy(), mode.copy())
                continue
            outcome = "timeout"
            break
        # ---- a terminal event fired: which, and any tie at the same instant ----
        if found is None:
            fired = [k for k in range(len(evlist)) if len(sol.t_events[k]) > 0]
            k0 = fired[0]
            te = float(sol.t_events[k0][0])
            ye = np.asarray(sol.y_events[k0][0], dtype=float)
            t_old = float(sol.t[-2]) if len(sol.t) >= 2 else t
            y_old = sol.y[:, -2] if len(sol.t) >= 2 else y
        batch = [k0]
        if te > t_old:
            g_old = model.event_values(t_old, y_old, seg_mode, evlist)
            g_now = model.event_values(te, ye, seg_mode, evlist)
            for k, (kind, j, direc) in enumerate(evlist):
                if k == k0:
                    continue
                if (direc > 0 and g_old[k] <= 0.0 < g_now[k]) or \
                        (direc < 0 and g_old[k] >= 0.0 > g_now[k]):
                    batch.append(k)
                elif not (kind.endswith("_N") or kind in OUTCOME_EVENTS) and \
                        direc * (g_now[k] - g_old[k]) > BATCH_TOL and \
                        direc * g_old[k] <= 0.0 and direc * g_now[k] > -BATCH_TOL:
                    batch.append(k)          # on its way across, within round-off of it
        nf_before = mode.n_fence_active()
        kinds = [evlist[k][0] for k in batch]
        oc = next((kd for kd in kinds if kd in OUTCOME_EVENTS), None)
        t, y = te, ye
        if oc is not None:
            if oc == "fail":
                outcome = "failed"
                status = (f"failed: penetration exceeds half the load's smaller side "
                          f"({model.D_fail:.4g} m) at t = {te:.6g}")
            else:
                outcome = oc
            break
        touched = set()
        exclude = None
        for k in batch:
            kind, j, direc = evlist[k]
            key = _event_key(kind, j)
            if key in touched:
                continue
            touched.add(key)
            if kind == "ax":               # the axis it leaves is not chosen again at its root
                exclude = seg_mode.axis
            model.apply_event(t, y, mode, kind, j, direc)
        model.refresh_manifold(t, y, mode, exclude=exclude)
        # consistency check of the modes not touched by the events (diagnostic)
        fixes = _fix_modes(model, t, y, mode, touched)
        if fixes:
            n_mode_fixes += fixes
            model.refresh_manifold(t, y, mode, exclude=exclude)
        nf_after = mode.n_fence_active()
        if nf_before == 0 and nf_after > 0:
            n_impacts += 1
            if math.isnan(t_first):
                t_first = t
            # §3 free fence: released at the first load-fence contact
            # Reading of docs/model.md: from alpha = alpha_w, alphadot = alphadot_w of that
            # instant; B2 = K2 = 0 for the rest of the cycle, also after the load has
            # left (so its damper_energy is 0 and it coasts to t_c).
            if drive_kind == "free" and not mode.fence_dyn:
                al, ald = model.drive(t) if mode.drive_on else (0.0, 0.0)
                mode.fence_dyn = True
                mode.B2 = mode.K2 = 0.0
                released_at = t
                y = np.concatenate([y[:6], [al, ald], y[6:]])
        if nf_before > 0 and nf_after == 0:
            t_last_loss = t
        stg = mode.stage()
        if stg != stage_log[-1][1]:
            stage_log.append((t, stg))

    t_exit = t
    y_exit = y
    if outcome == "timeout":
        t_exit = t_max
    still_touching = mode.n_fence_active() > 0
    # Reading of docs/model.md: without any load-fence contact t_first_contact is NaN and
    # contact_time 0.
    if math.isnan(t_first):
        t_A, contact_time = math.nan, 0.0
    else:
        t_B = t_exit if still_touching else t_last_loss
        t_A, contact_time = t_first, t_B - t_first

    # ---- post-processing on the dense output of every segment ---------------
    peak_f = peak_r = 0.0
    t_peak = math.nan
    dmax_pen = 0.0
    defl_max = 0.0
    alpha_max = -math.inf
    for (t0, t1, md, dsol, ts) in segments:
        if t1 <= t0:
            continue
        tsg = ts[(ts >= t0) & (ts <= t1)]

        def info(tt, md=md, dsol=dsol):
            return model.evaluate(tt, dsol(tt), md, want_rhs=False)[1]
        if md.n_fence_active() > 0:
            v_, tt_ = _maximise(lambda tt: info(tt)[0], tsg)
            if v_ > peak_f:
                peak_f, t_peak = v_, tt_
        if md.n_rail_active() > 0:
            v_, _ = _maximise(lambda tt: info(tt)[1], tsg)
            peak_r = max(peak_r, v_)
        engaged = bool(md.engaged()) \
            or any(md.rl_region[j] and md.rl_state[j] != OFF for j in range(4))
        if engaged:
            v_, _ = _maximise(lambda tt: info(tt)[2], tsg)
            dmax_pen = max(dmax_pen, v_)
        if md.fence_dyn:
            def defl(tt, info=info):
                i_ = info(tt)
                return abs(i_[3] - i_[4])
            v_, _ = _maximise(defl, tsg)
            defl_max = max(defl_max, v_)
        v_, _ = _maximise(lambda tt: info(tt)[3], tsg)
        alpha_max = max(alpha_max, v_)

    names_exit = model.names(mode)
    Ec = float(y_exit[names_exit.index("Ec")])
    Ed = float(y_exit[names_exit.index("Ed")])
    residual = 0.0
    if outcome != "failed" and t_exit < t_c:
        # after the load has left only the fence's linear ODE remains, up to t_c
        # Reading of docs/model.md: also after a timeout with t_max < t_c, the load is then
        # dropped; after a failure nothing is integrated (residual = NaN).
        if mode.fence_dyn:
            B2, K2, I2 = mode.B2, mode.K2, model.I2
            drv = model.drive
            cnt = [0]

            def frhs(tt, z):
                cnt[0] += 1
                aw, awd = drv(tt)
                rv = awd - z[1]
                return [z[1], (B2 * rv + K2 * (aw - z[0])) / I2, B2 * rv * rv]
            ia = names_exit.index("al")
            z0 = [y_exit[ia], y_exit[ia + 1], Ed]
            sc = np.array([STATE_SCALE["al"], STATE_SCALE["ald"], STATE_SCALE["Ed"]])
            fs = solve_ivp(frhs, (t_exit, t_c), z0, method=method, rtol=rtol,
                           atol=rtol * sc if atol is None else (
                               float(atol) if np.ndim(atol) == 0 else rtol * sc),
                           dense_output=True, max_step=max_step)
            model.nfev += cnt[0]
            n_steps += len(fs.t) - 1
            v_, _ = _maximise(lambda tt: abs(fs.sol(tt)[0] - drv(tt)[0]), fs.t)
            defl_max = max(defl_max, v_)
            v_, _ = _maximise(lambda tt: fs.sol(tt)[0], fs.t)
            alpha_max = max(alpha_max, v_)
            zc = fs.y[:, -1]
            residual = abs(zc[0] - drv(t_c)[0])
            Ed = float(zc[2])
        else:
            grid = np.linspace(t_exit, t_c, 201)
            v_, _ = _maximise(lambda tt: model.drive(tt)[0], grid)
            alpha_max = max(alpha_max, v_)
    elif outcome != "failed" and state_at_tc is not None:
        tt, yc_, mc = state_at_tc
        nm = model.names(mc)
        if mc.fence_dyn:
            residual = abs(yc_[nm.index("al")] - 0.0)     # alpha_w(t_c) = 0
        Ed = float(yc_[nm.index("Ed")])

    # Reading of docs/model.md: x_exit, phi_exit are the centroid's x and phi at t_exit
    # (at t_max for a timeout); contact_energy sums fence, tip and rail contacts.
    ff = simulate_freefall(p)
    ffF = ff["peak_force"]
    res = {
        "outcome": outcome,
        "t_exit": t_exit,
        "peak_force": peak_f,
        "t_peak": t_peak,
        "peak_rail_force": peak_r,
        "freefall_force": ffF,
        "overload": peak_f / ffF,
        "safe": bool(peak_f / ffF <= 1.0),
        "deflection_max": defl_max,
        "deflection_ok": bool(defl_max <= p["dalpha_perm"]),
        "residual_deflection": float(residual) if outcome != "failed" else math.nan,
        "alpha_max": alpha_max,
        "damper_energy": Ed,
        "contact_energy": Ec,
        "t_first_contact": t_A,
        "t_last_contact": (t_A + contact_time) if not math.isnan(t_A) else math.nan,
        "contact_time": contact_time,
        "n_impacts": n_impacts,
        "t_S1": stage_time["S1"], "t_S2": stage_time["S2"], "t_S3": stage_time["S3"],
        "t_S4": stage_time["S4"], "t_rail": stage_time["rail"],
        "x_exit": float(y_exit[0]),
        "phi_exit": float(y_exit[2]),
        "max_penetration": dmax_pen,
        "n_steps": n_steps,
        "n_segments": len(segments),
        "n_mode_fixes": n_mode_fixes,
        "n_retries": n_retries,
        "n_scan_events": n_scan_events,
        "t_release": released_at,
        "stages": " ".join(f"{s_}@{t_:.6f}" for t_, s_ in stage_log),
        "status": status,
        "q": model.law.q,
        "k_lin": p["k_lin"],
        "I2": p["I2"],
    }
    res.update(contact_diagnostics(model, segments))
    if keep_trajectory:
        res["_model"] = model
        res["_segments"] = segments
    return res, model.nfev


SCAN_POINTS = 8     # samples per integrator step in _scan_events


def _scan_events(model, mode, evlist, sol, t0, y0):
    """Look for event crossings inside the steps of a finished segment.

    solve_ivp only compares the signs of the event functions at step ends, so a
    function that dips through zero and back within one step (the fence tip grazing
    an edge of the load while no force acts, long steps) is missed.  The dense output
    is sampled SCAN_POINTS times per step; the earliest crossing in the monitored
    direction that comes before the segment's end (or before the event solve_ivp
    reported) is located by brentq and returned as (k, te, ye, t_prev, y_prev).
    """
    t_end = float(sol.t[-1])
    if t_end <= t0:
        return None
    steps = np.asarray(sol.t)
    fr = np.arange(1, SCAN_POINTS + 1) / SCAN_POINTS
    ts = (steps[:-1, None] + np.diff(steps)[:, None] * fr[None, :]).ravel()
    ts = ts[ts <= t_end]
    Y = sol.sol(ts)
    g_prev = model.event_values(t0, y0, mode, evlist)
    t_prev, y_prev = t0, y0
    dirs = [ev[2] for ev in evlist]
    for i, tt in enumerate(ts):
        yy = Y[:, i]
        g = model.event_values(tt, yy, mode, evlist)
        hits = [k for k in range(len(evlist))
                if (dirs[k] > 0 and g_prev[k] <= 0.0 < g[k]) or
                (dirs[k] < 0 and g_prev[k] >= 0.0 > g[k])]
        if hits:
            if tt >= t_end and sol.status == 1:
                return None          # the crossing solve_ivp reported itself
            best = None
            for k in hits:
                def gk(t_, k=k):
                    if t_ == t_prev:
                        return g_prev[k]
                    return model.event_values(t_, sol.sol(t_), mode, evlist)[k]
                try:
                    r = brentq(gk, t_prev, tt, xtol=4 * np.finfo(float).eps,
                               rtol=4 * np.finfo(float).eps)
                except ValueError:
                    r = tt
                if best is None or r < best[1]:
                    best = (k, r)
            k, r = best
            return k, float(r), np.asarray(sol.sol(r), dtype=float), t_prev, y_prev
        g_prev, t_prev, y_prev = g, tt, yy
    return None


# The contact kinds of the diagnostics: "fence", the fence's face F of §5.2 (the corners of
# §5.1 and the under-tip point U); "tip", the load's edges E_e of §5.2 (the fence's tip or
# another point of it inside the load); "rail", §5.3.
CONTACT_KINDS = ("fence", "tip", "rail")


def _clearances(model, md, ts, Y):
    """Signed clearance of each contact kind of §5 at the times ts (states Y[:, i])
    under the frozen mode md: {kind: array}, +inf where no contact of that kind is
    possible (no corner in its region).  Negative means penetration.

    fence: min over the corners with 0 <= s <= l of sigma_j h_j (§5.1) and -D_U (5.16);
    tip:   distance of the tip T from the load rectangle while T is outside, minus its
           depth below the nearest edge while it is inside (the box distance, continuous);
    rail:  min over the corners with x_G <= 0 of y_G (§5.3).
    These are geometric: they do not depend on the axis in use.
    """
    n = len(ts)
    x, yc, ph = Y[0], Y[1], Y[2]
    if md.fence_dyn:
        al = Y[6]
    elif md.drive_on:
        al = np.array([model.drive(float(t))[0] for t in ts])
    else:
        al = np.zeros(n)
    c, s = np.cos(ph), np.sin(ph)
    ca, sa = np.cos(al), np.sin(al)
    out = {k: np.full(n, np.inf) for k in CONTACT_KINDS}
    G = []
    for j in range(4):
        gx = x + c * model.cx[j] - s * model.cy[j]
        gy = yc + s * model.cx[j] + c * model.cy[j]
        G.append((gx * ca + gy * sa, -gx * sa + gy * ca))
        if md.cf_region[j] == ON:
            out["fence"] = np.minimum(out["fence"], md.cf_sigma[j] * G[j][1])
        if md.rl_region[j]:
            out["rail"] = np.minimum(out["rail"], gy)
    l, hL, hA = model.l, 0.5 * model.L, 0.5 * model.A
    if md.u_edge is not None:
        jc, jc2 = md.u_edge
        sg = md.cf_sigma[jc]
        (s1, h1), (s2, h2) = G[jc], G[jc2]
        den = np.where(s2 - s1 == 0.0, TINY, s2 - s1)
        hU = h1 + (l - s1) / den * (h2 - h1)
        DU = np.minimum(-sg * hU, -sg * h2)   # the edge's depth at s = l, or C''s if shallower
        out["fence"] = np.minimum(out["fence"], -DU)
    rx, ry = l * ca - x, l * sa - yc
    px, py = rx * c + ry * s, -rx * s + ry * c            # T in load axes
    dx, dy = np.abs(px) - hL, np.abs(py) - hA
    inside = (dx < 0.0) & (dy < 0.0)
    out["tip"] = np.where(inside, np.maximum(dx, dy),
                          np.hypot(np.maximum(dx, 0.0), np.maximum(dy, 0.0)))
    return out


def contact_diagnostics(model, segments):
    """Per contact kind of §5 (fence, tip, rail): whether it touched, its maximum
    penetration and the minimum gap over the run, from the reference's own solution.

    touch_<kind>:   a force-carrying contact of that kind over a time interval of positive
                    length: fence, the fence's face is the manifold's axis and one of its
                    points is ACTIVE; tip, a load edge is the axis and one of its points is
                    ACTIVE; rail, a corner-rail contact is ACTIVE;
    max_pen_<kind>: max(0, -min clearance) [m], the deepest penetration of that kind;
    min_gap_<kind>: max(0, min clearance) [m], the closest approach without contact
                    (0 once it touches; NaN if no contact of that kind was ever possible).
    The clearance (see _clearances) is sampled SCAN_POINTS times per integrator step of
    every segment's dense output and its minimum refined by a bounded Brent search.
    """
    touch = dict.fromkeys(CONTACT_KINDS, False)
    cmin = dict.fromkeys(CONTACT_KINDS, np.inf)
    fr = np.arange(SCAN_POINTS) / SCAN_POINTS
    for (t0, t1, md, dsol, ts) in segments:
        if not t1 > t0:
            continue
        if md.n_fence_active() > 0:
            touch["fence" if md.axis == AXIS_F else "tip"] = True
        touch["rail"] |= any(md.rl_region[j] and md.rl_state[j] == ACTIVE for j in range(4))
        st = np.unique(np.concatenate([[t0], ts[(ts > t0) & (ts < t1)], [t1]]))
        grid = np.append((st[:-1, None] + np.diff(st)[:, None] * fr[None, :]).ravel(), t1)
        Y = np.asarray(dsol(grid))
        if not np.all(np.isfinite(Y)):
            continue
        cl = _clearances(model, md, grid, Y)
        for kind in CONTACT_KINDS:
            i = int(np.argmin(cl[kind]))
            best = float(cl[kind][i])
            if not math.isfinite(best):
                continue
            lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
            if hi > lo:
                def f(tt, kind=kind, md=md, dsol=dsol):
                    return float(_clearances(model, md, [tt], np.asarray(dsol(tt))[:, None])[kind][0])
                r = minimize_scalar(f, bounds=(lo, hi), method="bounded",
                                    options={"xatol": 1e-14 * max(1.0, abs(hi)), "maxiter": 200})
                if r.success and r.fun < best:
                    best = float(r.fun)
            cmin[kind] = min(cmin[kind], best)
    out = {}
    for kind in CONTACT_KINDS:
        out["touch_" + kind] = bool(touch[kind])
        m = cmin[kind]
        out["max_pen_" + kind] = max(0.0, -m) if math.isfinite(m) else 0.0
        out["min_gap_" + kind] = max(0.0, m) if math.isfinite(m) else math.nan
    return out


def _fix_modes(model, t, y, mode, touched):
    """Re-derive the mode of every contact not changed by the current events and
    repair clear inconsistencies (beyond round-off).  Returns the number of repairs;
    it should stay 0 (reported as n_mode_fixes).  The caller refreshes the manifold's
    choices after a repair."""
    tol_D = 1e-9
    fixes = 0
    sn = _Snap(model, t, y, mode)
    for j in range(4):
        gx, gy = sn.G[j][:2]
        if ("cf", j) not in touched:
            sj, h = sn.sj[j], sn.hj[j]
            reg = mode.cf_region[j]
            if (reg == ON and (sj < -tol_D or sj > model.l + tol_D)) or \
                    (reg == BEHIND and sj > tol_D) or (reg == BEYOND and sj < model.l - tol_D):
                fixes += 1
                if sj < 0.0:
                    mode.cf_region[j], mode.cf_sigma[j], mode.cf_state[j] = BEHIND, 1, OFF
                elif sj > model.l:
                    mode.cf_region[j], mode.cf_state[j] = BEYOND, OFF
                    mode.cf_sigma[j] = 1 if h >= 0.0 else -1
                else:
                    mode.cf_region[j] = ON
                    if mode.axis == AXIS_F:
                        D, Dd, N = model.contact_now(t, y, mode, "cf", j)
                        mode.cf_state[j] = model._classify(D, N)
            elif reg == ON and mode.axis == AXIS_F:     # the corners push on the face alone
                D, Dd, N = model.contact_now(t, y, mode, "cf", j)
                st = mode.cf_state[j]
                if (st == OFF and D > tol_D) or (st != OFF and D < -tol_D):
                    fixes += 1
                    mode.cf_state[j] = model._classify(D, N)
        if ("rl", j) not in touched:
            if mode.rl_region[j] != (gx <= 0.0) and abs(gx) > tol_D:
                fixes += 1
                mode.rl_region[j] = gx <= 0.0
                mode.rl_state[j] = OFF
                if mode.rl_region[j]:
                    D, Dd, N = model.contact_now(t, y, mode, "rl", j)
                    mode.rl_state[j] = model._classify(D, N)
            elif mode.rl_region[j]:
                D, Dd, N = model.contact_now(t, y, mode, "rl", j)
                st = mode.rl_state[j]
                if (st == OFF and D > tol_D) or (st != OFF and D < -tol_D):
                    fixes += 1
                    mode.rl_state[j] = model._classify(D, N)
    for k in range(8):
        gk = sn.g[k // 4][k % 4]
        if ("ln", k) not in touched and mode.lines[k // 4][k % 4] != (gk > 0.0) \
                and abs(gk) > tol_D:
            fixes += 1
            mode.lines[k // 4][k % 4] = gk > 0.0
    # the load's side of the fence line and its incident edge (§5.2)
    if ("sgL", 0) not in touched and mode.sigma_L * model.centroid_side(sn) < -tol_D:
        fixes += 1
        mode.sigma_L = -mode.sigma_L
        mode.e_inc = model.incident_edge(sn, mode.sigma_L)
    elif not any(("einc", k) in touched for k in range(4)):
        f = model.incidence(sn, mode.sigma_L)
        if f[mode.e_inc] > min(f) + INCIDENCE_TOL:
            fixes += 1
            mode.e_inc = model.incident_edge(sn, mode.sigma_L)
    # the manifold's points of the axis in use: their state against the sign of D
    for kind, j in mode.axis_points():
        if (kind, j) in touched or kind == "cf":
            continue
        D, Dd, N = model.contact_now(t, y, mode, kind, j)
        st = mode.state(kind, j)
        if (st == OFF and D > tol_D) or (st != OFF and D < -tol_D):
            fixes += 1
            mode.set_state(kind, j, model._classify(D, N))
    return fixes


def simulate_reference(params, method="DOP853", rtol=1e-10, atol=None, scene="cycle"):
    """Reference solution of one scene of docs/model.md (§8).

    Parameters
    ----------
    params : dict
        docs/model.md §12 names; missing ones take the defaults; ``case`` applies a named
        case ("small_far", "long_near") first.
    method : str
        Any solve_ivp method ("DOP853", "RK45", "LSODA", "Radau", ...).
    rtol : float
        Relative tolerance [-].
    atol : None, float or array
        None: per-component ``rtol * STATE_SCALE`` (positions 1e-3 m, angles 1e-3 rad,
        fence angle 1e-4 rad, velocities 1e-3 m/s or rad/s, energies 1e-3 J); a float
        is used for every component (solve_ivp semantics).
    scene : "cycle", "impact" or "freefall"

    Returns
    -------
    dict of the docs/model.md §11 results (cycle) or peak_force [N], impulse [N s],
    contact_time [s], e_eff [-] (impact, freefall), plus n_rhs (its cost: right-hand-side evaluations).
    """
    p = resolve_params(params)
    if scene == "cycle":
        res, nfev = simulate_cycle(p, method=method, rtol=rtol, atol=atol)
        res["n_rhs"] = nfev
    elif scene == "impact":
        res = simulate_impact(p, method=method, rtol=rtol, atol=atol)
    elif scene == "freefall":
        res = simulate_freefall(p, method=method, rtol=rtol, atol=atol)
    else:
        raise ValueError(f"scene: unknown scene {scene!r}")
    return res
