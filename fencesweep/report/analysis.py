"""Tables computed from results, for the report and the figures: the runs they need (which spec
makes which table, which single cycles are kept as trajectories), reading them back, the
stages and events of a trajectory, the B2 x K2 design maps. No markdown, no matplotlib.

Layout of a results directory (default `results/`):

    <res>/<table>.parquet      sweep tables (TABLES: which spec makes which)
    <res>/traj/<name>.parquet  trajectories of single cycles (TRAJECTORIES)
    <res>/figures/*.png        figures (fencesweep.report.figures)
    <res>/REPORT.md            fencesweep.report.document.write_report
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fencesweep.errors import MissingInput

# pandas is imported inside the functions that use it: the CLI's parser imports this module (for
# `plot`'s options), and every command paid pandas' import (0.2 s) before it did anything.

#: sweep tables the figures and the report read: name -> the spec that makes it
TABLES = {
    "b2k2": "sweeps/b2k2.yaml",          # design maps
    "psi_b2": "sweeps/psi_b2.yaml",      # Fig. 6
    "fig5a": "sweeps/fig5a.yaml",        # Fig. 5a
    "fig5b": "sweeps/fig5b.yaml",        # Fig. 5b
    "freefall_H": "sweeps/freefall_H.yaml",  # the drop-height lines of Fig. 5a
    "period": "sweeps/period.yaml",      # streams: the shortest safe period (section 6)
    "fig5a_worst_v": "sweeps/fig5a_worst_v.yaml",    # Fig. 5a, the worst over load placements, along v
    "fig5a_worst_tc": "sweeps/fig5a_worst_tc.yaml",  # ... along t_c
}

PAPER_B2, PAPER_K2 = 72.0, 570.0  # the paper's flexible element (§3, §4.2)
_FLEX = {"drive": "flexible", "B2": PAPER_B2, "K2": PAPER_K2}

#: single cycles at the paper's working point (t_c = 1.36 s, v = 2 m/s, R_s = 0):
#: name -> (named case, overrides). Figs 2-3 are the first impact of small_far.
TRAJECTORIES = {
    "small_far_rigid": ("small_far", {"drive": "rigid"}),
    "small_far_flexible": ("small_far", dict(_FLEX)),
    "small_far_free": ("small_far", {"drive": "free"}),
    "small_far_rigid_linear": ("small_far", {"drive": "rigid", "contact_law": "linear"}),
    "small_far_flexible_linear": ("small_far", dict(_FLEX, contact_law="linear")),
    "small_far_free_linear": ("small_far", {"drive": "free", "contact_law": "linear"}),
    "small_far_rigid_e0.5": ("small_far", {"drive": "rigid", "e": 0.5}),
    "small_far_rigid_e0.9": ("small_far", {"drive": "rigid", "e": 0.9}),
    "small_far_rigid_linear_e0.5": ("small_far", {"drive": "rigid", "contact_law": "linear", "e": 0.5}),
    "small_far_rigid_linear_e0.9": ("small_far", {"drive": "rigid", "contact_law": "linear", "e": 0.9}),
    "long_near_rigid": ("long_near", {"drive": "rigid"}),
    "long_near_flexible": ("long_near", dict(_FLEX)),
}

CASES = ("small_far", "long_near")


def case_text(case: str) -> str:
    """'small_far: 0.2 x 0.1 m load, 0.6 m from the rail', from the named case's parameters."""
    from fencesweep.model.params import resolve

    p = resolve("cycle", case)
    return (f"{case}: {p['L']:g} x {p['A']:g} m load"
            + (f", {p['dP']:g} m from the rail" if p["dP"] > 0 else " against the rail"))


CASE_TEXT = {c: case_text(c) for c in CASES}
STAGE_NAMES = {0: "S1", 1: "S2", 2: "S3", 3: "S4", 4: "rail", -1: "exit"}

#: default threshold of the "fence is home" constraint on residual_amplitude (see residual_reason)
RESIDUAL_MAX_DEG = 1.0


# ---------------------------------------------------------------------------- inputs
def table_path(res: Path, name: str) -> Path:
    return Path(res) / f"{name}.parquet"


def traj_path(res: Path, name: str) -> Path:
    return Path(res) / "traj" / f"{name}.parquet"


def read_table(res: Path, name: str):
    """A sweep table of TABLES (pandas, with attrs from store.read_table)."""
    from fencesweep.study.store import table as store

    path = table_path(res, name)
    if not path.exists():
        spec = TABLES.get(name, "?")
        raise MissingInput(f"{path} is missing: make it with `fencesweep grid {spec} --out {path}`")
    return store.read_table(path)


def read_traj(res: Path, name: str):
    """A trajectory of TRAJECTORIES; df.attrs['params'] and ['results'] hold the run's inputs and results."""
    from fencesweep.study.store import table as store

    path = traj_path(res, name)
    if not path.exists():
        raise MissingInput(f"{path} is missing: make the trajectories with `fencesweep plot trajectories "
                           f"--results {res}`")
    return store.read_trajectory(path)


def envelope_element(res: Path) -> dict | None:
    """The element to build: the design over the load envelope (<res>/design/recommended.json of
    `fencesweep design`), as the parameters of a cycle, {**fixed, **design variables}
    ({'drive': 'flexible', 't_c': 1.36, 'v': 2.0, 'B2': 231.0, 'K2': 925.0}); None before the
    design has run or when no element keeps every constraint (a status that is not 'feasible', with
    or without the search's note after it)."""
    import json

    path = Path(res) / "design" / "recommended.json"
    if not path.exists():
        return None
    rec = json.loads(path.read_text())
    if not str(rec.get("status", "")).startswith("feasible"):
        return None
    return {**rec.get("fixed", {}), **rec["design_variables"]}


def design_runs(res: Path, residual_max_deg: float = RESIDUAL_MAX_DEG) -> dict:
    """Cycles of the elements the report compares, each for both named cases: name -> (case, overrides).

    `<case>_recommended` is the two-case pick (Design.best of the b2k2 maps), `<case>_well_damped`
    the well-damped pick (Design.damped), `<case>_envelope` the element to build (envelope_element);
    each only when its table is there."""
    picks = []
    if table_path(res, "b2k2").exists():
        D = design(read_table(res, "b2k2"), residual_max_deg)
        picks += [(tag, {"drive": "flexible", "B2": pick["B2"], "K2": pick["K2"]})
                  for tag, pick in (("recommended", D.best), ("well_damped", D.damped)) if pick]
    env = envelope_element(res)
    if env:
        picks.append(("envelope", env))
    return {f"{c}_{tag}": (c, dict(over)) for tag, over in picks for c in CASES}


def worst_runs(res: Path) -> dict:
    """The worst placement of each drive at the working point (needs fig5a_worst_v): `worst_<drive>` ->
    (case, overrides)."""
    if not table_path(res, "fig5a_worst_v").exists():
        return {}
    from fencesweep.model.params import resolve

    p = resolve("cycle", "small_far")
    w = worst_over_placements(read_table(res, "fig5a_worst_v"))
    w = w[np.isclose(w["t_c"], p["t_c"]) & np.isclose(w["v"], p["v"])]
    return {f"worst_{r.drive}": ("small_far", {"drive": r.drive, "dP": float(r.dP), "R_s": float(r.R_s)})
            for r in w.itertuples()}


def make_trajectories(res: Path, names=None, residual_max_deg: float = RESIDUAL_MAX_DEG, log=print) -> list[Path]:
    """Run the cycles of TRAJECTORIES (and of design_runs and worst_runs, when their tables are there)
    through the engine and write <res>/traj/<name>.parquet."""
    from fencesweep.model import simulate as api, params
    from fencesweep.study.store import table as store

    out = []
    runs = {**TRAJECTORIES, **design_runs(res, residual_max_deg), **worst_runs(res)}
    (Path(res) / "traj").mkdir(parents=True, exist_ok=True)
    for name in names or runs:
        case, over = runs[name]
        vals = params.resolve("cycle", case, **over)
        results, df = api.simulate_resolved(vals, trajectory=True)
        path = traj_path(res, name)
        store.write_trajectory(df, path, vals, results)
        log(f"{path}: {results['outcome']}, overload {results['overload']:.3f}, {len(df)} rows")
        out.append(path)
    return out


# ---------------------------------------------------------------------------- trajectory reading
@dataclass
class Events:
    """docs/model.md §10: A first contact, B last loss of contact, C the stage changes between them."""

    A: float
    B: float
    C: list            # [(t, stage_before, stage_after)]
    runs: list         # [(t0, t1, stage)] after merging runs shorter than min_dur, stage >= 0 only


def stage_runs(df, min_dur: float = 2e-3) -> list:
    """Runs of constant stage (trajectory column `stage`) before the exit; runs shorter than
    `min_dur` (chatter at an onset) are merged into the run before them."""
    t = df["t"].to_numpy()
    s = df["stage"].to_numpy().astype(int)
    live = s >= 0
    if not live.any():
        return []
    t_end = t[~live][0] if (~live).any() else t[-1]
    t, s = t[live], s[live]
    cut = np.flatnonzero(np.diff(s) != 0) + 1
    starts = np.r_[0, cut]
    runs = []
    for k, i in enumerate(starts):
        t1 = t[starts[k + 1]] if k + 1 < len(starts) else t_end
        runs.append([float(t[i]), float(t1), int(s[i])])
    merged: list = []
    for r in runs:
        if merged and (r[1] - r[0] < min_dur or merged[-1][2] == r[2]):
            merged[-1][1] = r[1]
        else:
            merged.append(r)
    if len(merged) > 1 and merged[0][1] - merged[0][0] < min_dur:  # chatter at t = 0
        merged[1][0] = merged[0][0]
        merged.pop(0)
    out: list = []
    for r in merged:  # merge equal neighbours left by the removal of short runs
        if out and out[-1][2] == r[2]:
            out[-1][1] = r[1]
        else:
            out.append(r)
    return [tuple(r) for r in out]


def events(df, min_dur: float = 2e-3) -> Events:
    res = df.attrs.get("results") or {}
    A = float(res.get("t_first_contact", math.nan) or math.nan)
    B = A + float(res.get("contact_time", math.nan) or math.nan)
    runs = stage_runs(df, min_dur)
    C = []
    for (_t0, _, s0), (t1, _, s1) in zip(runs[:-1], runs[1:]):
        if math.isfinite(A) and A + min_dur < t1 < B - min_dur:
            C.append((t1, s0, s1))
    return Events(A, B, C, runs)


def first_impact(df, window: float) -> dict:
    """Force of the first load-fence contact: onset value, peak and its time, over [A, A + window]."""
    ev = events(df)
    t = df["t"].to_numpy()
    n = df["N_fence"].to_numpy()
    sel = (t > ev.A) & (t <= ev.A + window)
    if not sel.any():
        return {"A": ev.A, "N_onset": math.nan, "dt_onset": math.nan, "peak": math.nan, "t_peak": math.nan}
    i0 = np.flatnonzero(sel)[0]
    k = np.argmax(np.where(sel, n, -np.inf))
    return {"A": ev.A, "N_onset": float(n[i0]), "dt_onset": float(t[i0] - ev.A),
            "peak": float(n[k]), "t_peak": float(t[k])}


def pulse_duration(df) -> float:
    """Time from the first contact to the first return of N_fence to 0."""
    ev = events(df)
    t = df["t"].to_numpy()
    n = df["N_fence"].to_numpy()
    after = np.flatnonzero((t > ev.A) & (n <= 0.0))
    return float(t[after[0]] - ev.A) if len(after) else float(ev.B - ev.A)


# ---------------------------------------------------------------------------- design maps
@dataclass
class Design:
    """The B2 x K2 design maps of one b2k2 table and the choice read off them."""

    B2: np.ndarray            # (nx,) ascending
    K2: np.ndarray            # (ny,) ascending
    grids: dict               # case -> {column: (ny, nx) array}; deflections in degrees
    feasible: dict            # case -> (ny, nx) bool
    both: np.ndarray          # feasible for both cases
    robust: np.ndarray        # feasible for both with all 8 neighbours feasible (inside the grid)
    worst: np.ndarray         # max overload over the cases
    first_fail: np.ndarray    # 0 ok, 1 not scraped, 2 overload > 1, 3 deflection, 4 residual (either case)
    residual_max_deg: float
    best: dict | None         # lowest worst-overload among robust cells
    best_raw: dict | None     # ... among all feasible cells
    damped: dict | None       # ... among robust cells with 0.7 <= Psi <= 1 (paper §4.2)

    FAIL_NAMES = ("every constraint kept", "not scraped", "overload > 1",
                  "deflection_max > dalpha_perm", "residual amplitude too large")


def _pivot(d, col):
    return d.pivot(index="K2", columns="B2", values=col).sort_index().sort_index(axis=1)


def design(df, residual_max_deg: float = RESIDUAL_MAX_DEG) -> Design:
    """Feasibility over B2 x K2 for each case of the table and the recommended element.

    Constraints (every one must hold for a cell to be feasible): outcome scraped,
    overload <= 1 (`safe`), deflection_max <= dalpha_perm (`deflection_ok`), and
    residual_amplitude <= residual_max_deg (residual_deflection in a table without it). The
    recommendation minimises the larger of the
    two cases' overloads over the cells that are feasible together with their 8 neighbours
    (a tolerance of one grid step on B2 and K2, and nothing read off the grid's edge).
    """
    grids, feas = {}, {}
    cases = [c for c in CASES if c in set(df["case"])]
    B2 = K2 = None
    fail = None
    for c in cases:
        d = df[df["case"] == c]
        g = {}
        for col in ("overload", "deflection_max", "residual_deflection", "Psi", "dalpha_perm",
                    "damper_energy", "x_exit", "contact_time", "residual_amplitude"):
            g[col] = _pivot(d, col if col in d else "residual_deflection").to_numpy(dtype=float)
        out = _pivot(d, "outcome")
        B2 = out.columns.to_numpy(dtype=float)
        K2 = out.index.to_numpy(dtype=float)
        g["outcome"] = out.to_numpy(dtype=object)
        g["deflection_max_deg"] = np.degrees(g["deflection_max"])
        g["residual_deg"] = np.degrees(g["residual_amplitude"])  # the "home" criterion (residual_reason)
        scraped = g["outcome"] == "scraped"
        safe = g["overload"] <= 1.0
        defl = g["deflection_max"] <= g["dalpha_perm"]
        home = g["residual_deg"] <= residual_max_deg
        code = np.where(~scraped, 1, np.where(~safe, 2, np.where(~defl, 3, np.where(~home, 4, 0))))
        fail = code if fail is None else np.where(fail == 0, code, np.where(code == 0, fail, np.minimum(fail, code)))
        grids[c] = g
        feas[c] = scraped & safe & defl & home
    both = np.logical_and.reduce([feas[c] for c in cases])
    ny, nx = both.shape
    robust = np.zeros_like(both)
    for i in range(1, ny - 1):
        for j in range(1, nx - 1):
            robust[i, j] = both[i - 1:i + 2, j - 1:j + 2].all()
    worst = np.max([grids[c]["overload"] for c in cases], axis=0)
    psi = grids[cases[0]]["Psi"]

    def pick(mask):
        if not mask.any():
            return None
        w = np.where(mask, worst, np.inf)
        i, j = np.unravel_index(np.argmin(w), w.shape)
        return {"B2": float(B2[j]), "K2": float(K2[i]), "worst_overload": float(worst[i, j]),
                "Psi": float(psi[i, j]),
                **{f"{c}.{k}": (float(grids[c][k][i, j]) if k != "outcome" else grids[c][k][i, j])
                   for c in cases for k in ("overload", "deflection_max_deg", "residual_deg", "outcome",
                                            "contact_time", "x_exit")}}

    return Design(B2, K2, grids, feas, both, robust, worst, fail, residual_max_deg,
                  pick(robust), pick(both), pick(robust & (psi >= 0.7) & (psi <= 1.0)))


def cell_edges(v: np.ndarray) -> np.ndarray:
    """Edges of cells centred on the (ascending) values v."""
    v = np.asarray(v, float)
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.r_[v[0] - (mid[0] - v[0]), mid, v[-1] + (v[-1] - mid[-1])]


#: docs/model.md §13.3: the quotient of Fig. 5b this model gives (m2 [kg] -> rigid / free peak force)
MODEL_5B = {5.0: 1.74, 1.0: 2.37, 50.0: 1.20}
PAPER_5B = 1.7          # the paper's quotient at m2 = 5 kg (§4.1)
PAPER_FREE_H = 0.1      # [m] the paper: the free fence brings the overload down to a drop from about this height
FREEFALL_LEVELS_H = (0.1, 0.2, 0.3)  # [m] the dashed free-fall levels of Fig. 5a
REAL_IMPACT = 0.3       # a free-fence overload of at least this is an impact worth the name (Fig. 5a row)
SLIGHT = 0.2            # "only slightly more": the flexible fence within this fraction of the free one
RISE_SAMPLES = (1e-5, 1e-4)  # [s] after the first contact: where the rise of the Figs 2-3 force is read
MIN_STAGE = 2e-3        # [s] runs of one stage shorter than this are merged (stage_runs)
#: sweep tables of the paper's worst-case arrangement of Fig. 5a (§4.1): one per cut of the figure
WORST_TABLES = {"fig5a_worst_v": "v", "fig5a_worst_tc": "t_c"}

#: the stream figure (fencesweep.report.figures_cycle.stream) and the report's reading of it
STREAM_FIGURE_CYCLES = 10
STREAM_FIGURE_TC = (1.36, 1.0)  # [s] the work cycle times of the figure's two panels (T = t_c)


def worst_over_placements(df):
    """Per drive, t_c and v of a placement table (sweeps/fig5a_worst_*.yaml): the row of the placement
    with the largest overload, with n_placements and two_points (its contact had two fence contact
    points at once for a while: t_S3 > 0)."""
    keys = ["drive", "t_c", "v"]
    w = df.loc[df.groupby(keys)["overload"].idxmax()].copy()
    w["n_placements"] = df.groupby(keys)["overload"].transform("size").loc[w.index]
    w["two_points"] = w["t_S3"] > 0
    return w.sort_values(keys).reset_index(drop=True)
