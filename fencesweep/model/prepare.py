"""Resolved parameter dict -> the float64 vector `p` the kernels read (layout.py).

Everything computed once per parameter set lives here: inertias, the damping coefficient
solved from e, belt friction limits, the crank-rocker geometry, the free-fall reference
force and the integrator's settings (numerics.py). Cached where the inputs repeat.

One run's vector (prepare, for `simulate`) and a whole chunk's (prepare_columns, for a sweep's
workers and the GPU path) are filled by the same function (_fill) from the same formulas: on
scalars, or on columns, one entry of p at a time over all the runs. A value solved or costly to
compute (the free-fall force, the damping coefficient, the four-bar, the drive's largest rate,
the footprint radius, k_lin, the run tolerance's power) is computed once per distinct value of
its inputs (each), so the two give the same bits.
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
    k = contact_stiffness(law, m1, k1, k_lin, H)
    return wall_force_scale(m1, k, drop_speed(H), _LAW[law]) * peak_force_factor(e, law)


def contact_stiffness(law: str, m1, k1, k_lin, H):
    """The active law's stiffness: k1 (hertz), else k_lin, or when it is None the default of
    docs/model.md (4.10) (contact.derived_k_lin, once per distinct (m1, k1, H)); on a run or on
    columns (one law and one kind of k_lin)."""
    if law == "hertz":
        return k1
    return k_lin if k_lin is not None else each(derived_k_lin, m1, k1, H)


def _contact_part(p: np.ndarray, v) -> None:
    """The contact-law entries of p (LAW, KC, CD): the damping of the law from the restitution,
    c_d = q sqrt(m1 k1) or b_lin = beta sqrt(m1 k_lin) (docs/model.md (4.4)), q or beta solved once
    per (e, law) (calibrate.damping_coefficient); on a run or on columns (_fill)."""
    law, m1 = v["contact_law"], v["m1"]
    k = contact_stiffness(law, m1, v["k1"], v["k_lin"], v["H"])
    p[Lp.LAW] = _LAW[law]
    p[Lp.KC] = k
    p[Lp.CD] = each(damping_coefficient, v["e"], law) * np.sqrt(m1 * k)


#: the entries of p that are the parameters themselves
_COPIED = (("v", Lp.V), ("P_max", Lp.PMAX), ("mu2", Lp.MU2), ("L", Lp.LL), ("A", Lp.AA), ("m1", Lp.M1),
           ("dP", Lp.DP), ("R_s", Lp.RS), ("phi0", Lp.PHI0), ("l", Lp.FL), ("I2", Lp.I2), ("B2", Lp.B2),
           ("K2", Lp.K2), ("H", Lp.H), ("t_c", Lp.TC), ("swing", Lp.SWING), ("dalpha_perm", Lp.DAPERM),
           ("R", Lp.R), ("eps_v", Lp.EPSV), ("t_max", Lp.TMAX))


def _fill(p: np.ndarray, v, table: bool) -> np.ndarray:
    """Fill the header p of one run (shape (N_P,), v its resolved dict) or of a group of runs
    (shape (N_P, n), v their columns, prepare_columns: the choices and whether k_lin and dt are None
    shared); without `table`, with the crank-rocker's geometry (CR_*). Returns p."""
    _contact_part(p, v)
    for name, idx in _COPIED:
        p[idx] = v[name]
    p[Lp.DRIVE] = _DRIVE[v["drive"]]
    p[Lp.PROFILE] = _PROFILE[v["profile"]]
    m1, L, A, swing, t_c, ratio = v["m1"], v["L"], v["A"], v["swing"], v["t_c"], v["coupler_ratio"]
    p[Lp.I1] = load_inertia(m1, L, A)
    p[Lp.FMAX], p[Lp.MMAX], p[Lp.RHO] = belt_friction_limits(v["mu1"], m1, L, A)
    p[Lp.DAW_MAX] = each(max_drive_rate, swing, t_c, v["profile"], ratio)
    p[Lp.FFORCE] = each(freefall_force, m1, v["k1"], v["e"], v["contact_law"], v["k_lin"], v["H"])
    _numerics(p, v)
    p[Lp.OMEGA_C] = crank_speed(t_c)
    p[Lp.TAB_H] = 1.0
    if v["profile"] == "crank_rocker" and not table:
        p[Lp.CR_A], p[Lp.CR_B], p[Lp.CR_D], p[Lp.CR_TH0], p[Lp.CR_B0] = each(crank_rocker_geometry, swing, ratio)
    return p


def prepare(vals: dict, table: bool = True) -> np.ndarray:
    """Fill the kernel parameter vector from a resolved parameter dict (params.resolve); without
    `table`, the header only, N_P entries, with the crank-rocker's geometry (CR_*) instead of its
    table (TAB_N = 0), as a GPU thread takes it (its drive.drive_angle solves the four-bar)."""
    p = _fill(np.zeros(Lp.N_P), vals, table)
    if table and vals["profile"] == "crank_rocker":  # the CPU's kernels read the table only (drive.DRIVE_TABLE)
        return with_drive_table(p, float(vals["swing"]), float(vals["coupler_ratio"]))
    return p


def crank_speed(t_c):
    """omega_c = 2 pi / t_c [rad/s], the crank's angular speed (docs/model.md (2.6))."""
    return 2.0 * math.pi / t_c


def _table_header(p: np.ndarray, t_c) -> None:
    """The drive table's entries of a header (TAB_N, TAB_RATE, TAB_H: docs/model.md (15.11))."""
    p[Lp.TAB_N] = TABLE_SIZE
    p[Lp.TAB_RATE] = TABLE_SIZE / t_c
    p[Lp.TAB_H] = 2.0 * math.pi / TABLE_SIZE


def with_drive_table(p: np.ndarray, swing: float, coupler_ratio: float) -> np.ndarray:
    """A crank-rocker's header p (t_c set) followed by its drive table (drive.rocker_table;
    docs/model.md (15.11)), as the CPU's kernels read it."""
    _table_header(p, float(p[Lp.TC]))
    return np.concatenate((p, rocker_table(swing, coupler_ratio)))


def load_inertia(m1, L, A):
    """I1 = m1 (L^2 + A^2) / 12 [kg m^2], the load's moment of inertia about its centroid
    (docs/model.md (1.2)); on numbers or columns."""
    return m1 * (L * L + A * A) / 12.0


def belt_friction_limits(mu1, m1, L, A) -> tuple:
    """(F_max, M_max, rho) of the belt friction (docs/model.md (6.1)) [N, N m, m]: F_max = mu1 m1 g,
    M_max = F_max rho_bar, rho = M_max / F_max = rho_bar, the mean footprint radius (6.2) (once per
    distinct (L, A)); on numbers or columns."""
    f_max = mu1 * m1 * Lp.G
    rho_bar = each(mean_footprint_radius, L, A)
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


def _numerics(p: np.ndarray, v) -> None:
    """The integrator's settings (numerics.py): method, tolerance (run_tolerance), the RK4
    baseline's step, the largest step (largest_step) and the closed-form ride's slip; on a run
    or on columns (_fill: those two once per distinct step_factor, and (t_c, K2, I2))."""
    sf = _number(v["step_factor"])
    p[Lp.METHOD] = _METHOD[v.get("integrator", "dopri5")]
    dt = v.get("dt")
    p[Lp.DT] = sf * (NU.DT_RK4 if dt is None else _number(dt))
    if "t_c" not in v or v.get("scene") in ("impact", "freefall"):  # one pulse
        p[Lp.TOL] = each(run_tolerance, NU.IMPACT_TOL, sf)
        return
    p[Lp.TOL] = each(run_tolerance, NU.TOL, sf)
    p[Lp.H_MAX] = each(largest_step, v["t_c"], v["drive"], v["K2"], v["I2"])
    p[Lp.SNAP] = NU.SNAP_SLIP * _number(v["eps_v"])


def _number(x):
    """x as a float, or the column x as it is."""
    return x if type(x) is np.ndarray else float(x)


# ---- a chunk of runs at once --------------------------------------------------------------
#: the parameters prepare reads (the columns prepare_columns takes)
COLUMNS = ("v", "P_max", "mu1", "mu2", "L", "A", "m1", "dP", "R_s", "phi0", "e", "k1", "contact_law", "k_lin",
           "l", "I2", "B2", "K2", "drive", "t_c", "swing", "profile", "coupler_ratio", "H", "dalpha_perm", "R",
           "eps_v", "t_max", "step_factor", "integrator", "dt", "scene")
#: the columns whose value selects a branch of _fill (a string, or a number that may be None)
_BRANCHES = ("contact_law", "drive", "profile", "integrator", "scene", "k_lin", "dt")


def each(fn, *args):
    """fn(*args) where any argument may be a column (a NumPy array): fn called once per distinct
    combination of the columns' values (bit for bit), on Python floats, its results laid out as
    columns (a tuple of columns where fn returns a tuple). Without a column, fn(*args)."""
    if np.ndarray not in map(type, args):
        return fn(*args)
    combos, inverse = _distinct(args)
    out = np.array([fn(*c) for c in combos])
    return tuple(out.T[:, inverse]) if out.ndim == 2 else out[inverse]


def _distinct(args) -> tuple:
    """(the distinct combinations of the values of args (numbers as floats; a column's values
    compared bit for bit), as argument lists; each run's combination, None without a column)."""
    at = [k for k, a in enumerate(args) if type(a) is np.ndarray]
    plain = [float(a) if isinstance(a, (int, float)) and not isinstance(a, bool) else a for a in args]
    if not at:
        return [plain], None
    code = np.zeros(len(args[at[0]]), dtype=np.int64)
    for k in at:  # the combination's number so far, renumbered densely after each column
        values, inverse = np.unique(np.asarray(args[k], dtype=np.float64).view(np.int64), return_inverse=True)
        _, code = np.unique(code * len(values) + inverse.ravel(), return_inverse=True)
    _, first = np.unique(code, return_index=True)
    columns = [np.asarray(args[k], dtype=np.float64)[first].tolist() for k in at]
    combos = []
    for i in range(len(first)):
        for k, col in zip(at, columns):
            plain[k] = col[i]
        combos.append(list(plain))
    return combos, code.ravel()


class Vectors:
    """A chunk's parameter vectors (prepare_columns): `header` (n, N_P) and, with the table, each
    crank-rocker run's drive table (drive.rocker_table, shared by the runs of one (swing,
    coupler_ratio)); vectors[k] is run k's vector as prepare gives it."""

    def __init__(self, header: np.ndarray, tables: list, which: np.ndarray):
        self.header, self.tables, self.which = header, tables, which

    def __len__(self) -> int:
        return self.header.shape[0]

    def __getitem__(self, k: int) -> np.ndarray:
        t = int(self.which[k])
        if t < 0:
            return self.header[k].copy()
        table = self.tables[t]
        p = np.empty(Lp.N_P + len(table))
        p[:Lp.N_P], p[Lp.N_P:] = self.header[k], table
        return p


def prepare_columns(columns: dict, n: int, table: bool = True) -> Vectors:
    """The parameter vectors of n runs from their columns ({name: a value all share, or an array
    of n}, the names of COLUMNS; spec/scenes.py Scenes.value_columns) at once, as prepare gives
    them one by one (the same bits): the runs grouped by their branches (law, drive, profile,
    integrator, scene, k_lin and dt given or None), each group filled by _fill on its columns;
    a crank-rocker's table (with `table`) once per distinct (swing, coupler_ratio)."""
    P = np.zeros((Lp.N_P, n))  # entry by entry: each a row here, the vectors its transpose
    which = np.full(n, -1, dtype=np.int64)
    tables: list = []
    for rows, v in _groups(columns, n):
        part = _fill(P if rows is None else np.zeros((Lp.N_P, len(rows))), v, table)
        if table and v["profile"] == "crank_rocker":
            _table_header(part, v["t_c"])
            combos, inverse = _distinct((v["swing"], v["coupler_ratio"]))
            which[slice(None) if rows is None else rows] = len(tables) + (0 if inverse is None else inverse)
            tables += [rocker_table(*c) for c in combos]
        if rows is not None:
            P[:, rows] = part
    return Vectors(np.ascontiguousarray(P.T), tables, which)


def _groups(columns: dict, n: int):
    """(the runs of each combination of the branches' values (_BRANCHES), None for all of them;
    their columns, the branches as single values, numbers as float64 columns), for prepare_columns."""
    varying = [name for name in _BRANCHES if isinstance(columns.get(name), np.ndarray)]
    if not varying:
        yield None, _part(columns, None)
        return
    keys = zip(*([x is None for x in columns[name]] if name in ("k_lin", "dt") else columns[name].tolist()
                 for name in varying))
    ids: dict = {}
    code = np.array([ids.setdefault(k, len(ids)) for k in keys], dtype=np.int64)
    for g in range(len(ids)):
        rows = np.flatnonzero(code == g)
        yield rows, _part(columns, rows)


def _part(columns: dict, rows) -> dict:
    """The columns of the runs `rows` (None: all) of one group: a branch's single value, a number
    column as float64."""
    out = {}
    for name, col in columns.items():
        if isinstance(col, np.ndarray):
            col = col if rows is None else col[rows]
            if name in _BRANCHES and (name not in ("k_lin", "dt") or col[0] is None):
                col = str(col[0]) if isinstance(col[0], str) else col[0]
            else:
                col = col.astype(np.float64)
        out[name] = col
    return out


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
