"""Resolved parameter dict -> the float64 vector `p` the kernels read (layout.py).

Everything computed once per parameter set lives here: inertias, the damping coefficient
solved from e, belt friction limits, the crank-rocker geometry, the free-fall reference
force and the integrator's settings (numerics.py). Cached where the inputs repeat.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from fencesweep.model import layout as Lp
from fencesweep.kernel import numerics as NU
from fencesweep.model.calibrate import damping_coefficient, peak_force_factor
from fencesweep.model.contact import derived_k_lin, drop_speed, mean_footprint_radius, wall_force_scale
from fencesweep.model.drive import TABLE_SIZE, crank_rocker_geometry, max_drive_rate, rocker_table
from fencesweep.kernel.rk import METHOD_DOPRI5, METHOD_RK4

_LAW = {"hertz": Lp.LAW_HERTZ, "linear": Lp.LAW_LINEAR}
_DRIVE = {"flexible": Lp.DRIVE_FLEXIBLE, "rigid": Lp.DRIVE_RIGID, "free": Lp.DRIVE_FREE}
_PROFILE = {"crank_rocker": Lp.PROFILE_CRANK_ROCKER, "harmonic": Lp.PROFILE_HARMONIC}

_METHOD = {"dopri5": METHOD_DOPRI5, "rk4": METHOD_RK4}


@lru_cache(maxsize=4096)
def freefall_force(m1: float, k1: float, e: float, law: str, k_lin: float | None, H: float) -> float:
    """Peak of N when the load falls from H onto an undeformable surface (docs/model.md (7.2)):
    the wall impact's force scale at the drop speed times the dimensionless peak solved once per
    (e, law) ((7.7); calibrate.peak_force_factor). Exact whatever a cycle's step_factor (the
    reference of its overload); the `freefall` scene integrates (7.2) itself and agrees to ~1e-9
    (tests/test_contact.py)."""
    k = k1 if law == "hertz" else (k_lin if k_lin is not None else derived_k_lin(m1, k1, H))
    return wall_force_scale(m1, k, drop_speed(H), _LAW[law]) * peak_force_factor(e, law)


def _contact_part(vals: dict) -> np.ndarray:
    """Parameter vector with the contact-law entries (KC, CD) filled in: the damping of the law
    from the restitution, c_d = q sqrt(m1 k1) or b_lin = beta sqrt(m1 k_lin) (docs/model.md (4.4))."""
    p = np.zeros(Lp.N_P)
    law = vals["contact_law"]
    p[Lp.LAW] = _LAW[law]
    p[Lp.M1] = vals["m1"]
    p[Lp.H] = vals["H"]
    p[Lp.LL] = p[Lp.AA] = math.inf
    c = damping_coefficient(float(vals["e"]), law)
    if law == "hertz":
        p[Lp.KC] = vals["k1"]
        p[Lp.CD] = c * math.sqrt(vals["m1"] * vals["k1"])  # q sqrt(m1 k1)
    else:
        k_lin = vals["k_lin"] if vals["k_lin"] is not None else derived_k_lin(vals["m1"], vals["k1"], vals["H"])
        p[Lp.KC] = k_lin
        p[Lp.CD] = c * math.sqrt(vals["m1"] * k_lin)  # b_lin = beta sqrt(m1 k_lin)
    return p


def prepare(vals: dict, table: bool = True) -> np.ndarray:
    """Fill the kernel parameter vector from a resolved parameter dict (params.resolve); without
    `table`, the header only, N_P entries, with the crank-rocker's geometry (CR_*) instead of its
    table (TAB_N = 0), as a GPU thread takes it (its drive.drive_angle solves the four-bar)."""
    p = _contact_part(vals)
    for name, idx in (("v", Lp.V), ("P_max", Lp.PMAX), ("mu2", Lp.MU2), ("L", Lp.LL),
                      ("A", Lp.AA), ("dP", Lp.DP), ("R_s", Lp.RS), ("phi0", Lp.PHI0), ("l", Lp.FL),
                      ("I2", Lp.I2), ("B2", Lp.B2), ("K2", Lp.K2), ("t_c", Lp.TC),
                      ("swing", Lp.SWING), ("dalpha_perm", Lp.DAPERM),
                      ("R", Lp.R), ("eps_v", Lp.EPSV), ("t_max", Lp.TMAX)):
        p[idx] = vals[name]
    p[Lp.DRIVE] = _DRIVE[vals["drive"]]
    p[Lp.PROFILE] = _PROFILE[vals["profile"]]
    m1, L, A = vals["m1"], vals["L"], vals["A"]
    p[Lp.I1] = load_inertia(m1, L, A)
    p[Lp.FMAX], p[Lp.MMAX], p[Lp.RHO] = belt_friction_limits(vals["mu1"], m1, L, A)
    daw = max_drive_rate(float(vals["swing"]), float(vals["t_c"]), vals["profile"], float(vals["coupler_ratio"]))
    p[Lp.DAW_MAX] = daw
    p[Lp.FFORCE] = freefall_force(float(m1), float(vals["k1"]), float(vals["e"]), vals["contact_law"],
                                  None if vals["k_lin"] is None else float(vals["k_lin"]), float(vals["H"]))
    _numerics(p, vals)
    p[Lp.OMEGA_C] = 2.0 * math.pi / float(vals["t_c"])
    p[Lp.TAB_H] = 1.0
    if vals["profile"] == "crank_rocker":
        swing, ratio = float(vals["swing"]), float(vals["coupler_ratio"])
        if table:  # the CPU's kernels read the table only (drive.DRIVE_TABLE)
            return with_drive_table(p, swing, ratio)
        p[Lp.CR_A], p[Lp.CR_B], p[Lp.CR_D], p[Lp.CR_TH0], p[Lp.CR_B0] = crank_rocker_geometry(swing, ratio)
    return p


def with_drive_table(p: np.ndarray, swing: float, coupler_ratio: float) -> np.ndarray:
    """A crank-rocker's header p (t_c set) followed by its drive table (drive.rocker_table;
    docs/model.md (15.11)), as the CPU's kernels read it."""
    p[Lp.TAB_N] = TABLE_SIZE
    p[Lp.TAB_RATE] = TABLE_SIZE / float(p[Lp.TC])
    p[Lp.TAB_H] = 2.0 * math.pi / TABLE_SIZE
    return np.concatenate((p, rocker_table(swing, coupler_ratio)))


def load_inertia(m1: float, L: float, A: float) -> float:
    """I1 = m1 (L^2 + A^2) / 12 [kg m^2], the load's moment of inertia about its centroid
    (docs/model.md (1.2))."""
    return m1 * (L * L + A * A) / 12.0


def belt_friction_limits(mu1: float, m1: float, L: float, A: float) -> tuple[float, float, float]:
    """(F_max, M_max, rho) of the belt friction (docs/model.md (6.1)) [N, N m, m]: F_max = mu1 m1 g,
    M_max = F_max rho_bar, rho = M_max / F_max = rho_bar, the mean footprint radius (6.2)."""
    f_max = mu1 * m1 * Lp.G
    rho_bar = mean_footprint_radius(L, A)
    return f_max, f_max * rho_bar, rho_bar


def run_tolerance(tol: float, step_factor: float) -> float:
    """TOL_run = max(tol step_factor^TOL_EXPONENT, TOL_MIN) (docs/model.md (15.1)); tol is
    numerics.TOL, or IMPACT_TOL for the impact scenes."""
    return max(tol * step_factor ** NU.TOL_EXPONENT, NU.TOL_MIN)


def largest_step(t_c: float, drive: str, K2: float, I2: float) -> float:
    """h_max = H_MAX_PER_PERIOD min(t_c, 2 pi sqrt(I2 / K2)) [s] (docs/model.md (15.5)): a fraction
    of the cycle and, for the flexible drive with K2 > 0, of the element's period."""
    period = float(t_c)
    if drive == "flexible" and K2 > 0:
        period = min(period, 2 * math.pi * math.sqrt(I2 / K2))
    return NU.H_MAX_PER_PERIOD * period


def _numerics(p: np.ndarray, vals: dict) -> None:
    """The integrator's settings (numerics.py): method, tolerance (run_tolerance), the RK4
    baseline's step, the largest step (largest_step) and the closed-form ride's slip."""
    sf = float(vals["step_factor"])
    p[Lp.METHOD] = _METHOD[vals.get("integrator", "dopri5")]
    dt = vals.get("dt")
    p[Lp.DT] = sf * (NU.DT_RK4 if dt is None else float(dt))
    if "t_c" not in vals or vals.get("scene") in ("impact", "freefall"):  # one pulse
        p[Lp.TOL] = run_tolerance(NU.IMPACT_TOL, sf)
        return
    p[Lp.TOL] = run_tolerance(NU.TOL, sf)
    p[Lp.H_MAX] = largest_step(vals["t_c"], vals["drive"], vals["K2"], vals["I2"])
    p[Lp.SNAP] = NU.SNAP_SLIP * float(vals["eps_v"])


def load_table(vals: dict) -> np.ndarray:
    """The kernel's loads table of a stream (docs/model.md §14): one row per cycle, the entries of
    the parameter vector that belong to that cycle's load (layout.LOAD_SLOTS), each distinct
    load prepared once. Without a list of loads every cycle has the scene's load."""
    from fencesweep.model.params import LOAD_NAMES

    slots = list(Lp.LOAD_SLOTS)
    n = int(vals["n_cycles"])
    if vals.get("loads") is None:
        row = prepare(vals)[slots]
        return np.tile(row, (n, 1))
    rows = {}
    for load in set(vals["loads"]):
        rows[load] = prepare(dict(vals, **dict(zip(LOAD_NAMES, load))))[slots]
    return np.array([rows[load] for load in vals["loads"]]).reshape(n, Lp.N_LOAD)
