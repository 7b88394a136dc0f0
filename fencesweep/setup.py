"""Resolved parameter dict -> the float64 vector `p` the kernels read (layout.py).

Everything computed once per parameter set lives here: inertias, the damping coefficient
solved from e, belt friction limits, the crank-rocker geometry, the free-fall reference
force and the step sizes. Cached where the inputs repeat across a sweep.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from . import layout as Lp
from .contact import (damping_coefficient, derived_k_lin, drop_speed, hertz_contact_time,
                      mean_footprint_radius)
from .drive import TABLE_SIZE, crank_rocker_geometry, max_drive_rate, rocker_table

_LAW = {"hertz": Lp.LAW_HERTZ, "linear": Lp.LAW_LINEAR}
_DRIVE = {"flexible": Lp.DRIVE_FLEXIBLE, "rigid": Lp.DRIVE_RIGID, "free": Lp.DRIVE_FREE}
_PROFILE = {"crank_rocker": Lp.PROFILE_CRANK_ROCKER, "harmonic": Lp.PROFILE_HARMONIC}

#: RK4 steps per pulse in the impact and free-fall scenes (cheap: one or two bodies)
STEPS_PER_PULSE_IMPACT = 2000


def pulse_time(law: int, m: float, kc: float, speed: float) -> float:
    """Duration [s] of an undamped impact of mass m at the given speed (MODEL.md §7):
    Hertz 3.2181 (m^2 / (k1^2 v))^0.2; linear pi sqrt(m / k_lin)."""
    if law == Lp.LAW_HERTZ:
        return hertz_contact_time(m, kc, max(speed, 1e-6))
    return math.pi * math.sqrt(m / kc)


def run_freefall(p: np.ndarray, vals: dict, out: np.ndarray) -> None:
    """The free fall of MODEL.md §7: the load at v_H = sqrt(2 g H) on a rigid wall (IMPACT_RESULTS)."""
    from .scenes.impact import impact_kernel

    vh = drop_speed(vals["H"])
    impact_kernel(p, True, False, vh, impact_step(p, vals, True, vh), out)


@lru_cache(maxsize=4096)
def freefall_force(m1: float, k1: float, e: float, law: str, k_lin: float | None, H: float) -> float:
    """Peak of N when the load falls from H onto an undeformable surface (MODEL.md §7), at the
    default step whatever a cycle's step_factor (the reference of its overload)."""
    from .results import N_IMPACT_RESULTS, RJ

    vals = {"m1": m1, "k1": k1, "e": e, "contact_law": law, "k_lin": k_lin, "H": H, "step_factor": 1.0}
    out = np.empty(N_IMPACT_RESULTS)
    run_freefall(_contact_part(vals), vals, out)
    return float(out[RJ["peak_force"]])


def _contact_part(vals: dict) -> np.ndarray:
    """Parameter vector with the contact-law entries (KC, CD) filled in (MODEL.md §4)."""
    p = np.zeros(Lp.N_P)
    law = vals["contact_law"]
    p[Lp.LAW] = _LAW[law]
    p[Lp.M1] = vals["m1"]
    p[Lp.K1] = vals["k1"]
    p[Lp.E] = vals["e"]
    p[Lp.H] = vals["H"]
    p[Lp.LL] = p[Lp.AA] = math.inf
    c = damping_coefficient(float(vals["e"]), law)
    if law == "hertz":
        p[Lp.KC] = vals["k1"]
        p[Lp.CD] = c * math.sqrt(vals["m1"] * vals["k1"])  # q sqrt(m1 k1)
    else:
        k_lin = vals["k_lin"] if vals["k_lin"] is not None else derived_k_lin(vals["m1"], vals["k1"], vals["H"])
        p[Lp.KLIN] = k_lin
        p[Lp.KC] = k_lin
        p[Lp.CD] = c * math.sqrt(vals["m1"] * k_lin)  # b_lin = beta sqrt(m1 k_lin)
    return p


def prepare(vals: dict) -> np.ndarray:
    """Fill the kernel parameter vector from a resolved parameter dict (params.resolve)."""
    p = _contact_part(vals)
    for name, idx in (("v", Lp.V), ("P_max", Lp.PMAX), ("mu1", Lp.MU1), ("mu2", Lp.MU2), ("L", Lp.LL),
                      ("A", Lp.AA), ("dP", Lp.DP), ("R_s", Lp.RS), ("phi0", Lp.PHI0), ("l", Lp.FL),
                      ("m2", Lp.M2), ("I2", Lp.I2), ("B2", Lp.B2), ("K2", Lp.K2), ("t_c", Lp.TC),
                      ("swing", Lp.SWING), ("coupler_ratio", Lp.CRATIO), ("dalpha_perm", Lp.DAPERM),
                      ("R", Lp.R), ("w", Lp.W), ("eps_v", Lp.EPSV), ("t_max", Lp.TMAX),
                      ("step_factor", Lp.STEPF)):
        p[idx] = vals[name]
    p[Lp.DRIVE] = _DRIVE[vals["drive"]]
    p[Lp.PROFILE] = _PROFILE[vals["profile"]]
    m1, L, A = vals["m1"], vals["L"], vals["A"]
    p[Lp.I1] = m1 * (L * L + A * A) / 12.0
    p[Lp.FMAX] = vals["mu1"] * m1 * Lp.G
    rho_bar = mean_footprint_radius(L, A)
    p[Lp.MMAX] = p[Lp.FMAX] * rho_bar
    p[Lp.RHO] = rho_bar
    if vals["profile"] == "crank_rocker":
        a, b, d, th0, b0 = crank_rocker_geometry(float(vals["swing"]), float(vals["coupler_ratio"]))
        p[Lp.CRA], p[Lp.CRB], p[Lp.CRD], p[Lp.TH0], p[Lp.BETA0] = a, b, d, th0, b0
    daw = max_drive_rate(float(vals["swing"]), float(vals["t_c"]), vals["profile"], float(vals["coupler_ratio"]))
    p[Lp.DAW_MAX] = daw
    p[Lp.FFORCE] = freefall_force(float(m1), float(vals["k1"]), float(vals["e"]), vals["contact_law"],
                                  None if vals["k_lin"] is None else float(vals["k_lin"]), float(vals["H"]))
    _step_sizes(p, vals)
    if vals["profile"] == "crank_rocker":
        p[Lp.TAB_N] = TABLE_SIZE
        return np.concatenate((p, rocker_table(float(vals["swing"]), float(vals["coupler_ratio"]))))
    return p


def _step_sizes(p: np.ndarray, vals: dict) -> None:
    """Coarse and fine steps of the cycle (MODEL.md §8; issue: tie the fine step to the pulse).

    Fine: the undamped pulse time of the stiffest pairing that can occur, a corner of the
    load (effective mass >= m1/4: for any point of a rectangle m1 r^2 / I1 <= 3) against the
    fence tip (effective mass I2 / l^2), at the largest closing speed v + l max|alpha_w'|,
    divided by layout.STEPS_PER_PULSE. Coarse: the largest step that still resolves the drive and
    the fence's own linear dynamics (t_c/200, a 60th of its natural period, a quarter
    of its damping time), and never below the fine step.
    """
    sf = vals["step_factor"]
    m1 = vals["m1"]
    if vals["drive"] == "rigid":
        m_red = m1 / 4.0
    else:
        m_red = 1.0 / (4.0 / m1 + vals["l"] ** 2 / vals["I2"])
    speed = vals["v"] + vals["l"] * p[Lp.DAW_MAX]
    dt_fine = pulse_time(int(p[Lp.LAW]), m_red, p[Lp.KC], speed) / Lp.STEPS_PER_PULSE
    dt_coarse = vals["t_c"] / 200.0
    if vals["drive"] == "flexible":
        if vals["K2"] > 0:
            dt_coarse = min(dt_coarse, 2 * math.pi * math.sqrt(vals["I2"] / vals["K2"]) / 60.0)
        if vals["B2"] > 0:
            dt_coarse = min(dt_coarse, 0.25 * vals["I2"] / vals["B2"])
    p[Lp.M_RED] = m_red
    p[Lp.DT_FINE] = sf * dt_fine
    p[Lp.DT_COARSE] = sf * max(dt_coarse, dt_fine)


def impact_step(p: np.ndarray, vals: dict, rigid: bool, speed: float) -> float:
    """RK4 step [s] of the impact/free-fall scenes: STEPS_PER_PULSE_IMPACT per pulse."""
    m1 = vals["m1"]
    m_red = m1 if rigid else 1.0 / (1.0 / m1 + vals["R"] ** 2 / vals["I2"])
    return vals["step_factor"] * pulse_time(int(p[Lp.LAW]), m_red, p[Lp.KC], speed) / STEPS_PER_PULSE_IMPACT
