"""The parameter table of docs/model.md §12: names, units, defaults, checks, named cases.

This is the one place defaults live. The CLI, the YAML sweep specs and the Parquet
columns use exactly these names; everything else only overrides them.

`resolve(scene, case, **overrides)` checks a parameter set and returns a plain dict of
every parameter (defaults filled in, derived values computed). Any bad input raises
`ParameterError` (a ValueError) naming the parameter, the value and what is allowed,
before anything runs.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from fencesweep.errors import ParameterError

SCENES = ("cycle", "impact", "freefall", "stream")


@dataclass(frozen=True)
class Param:
    """One row of docs/model.md §12 (or a numerical setting of the engine)."""

    name: str
    unit: str
    default: Any
    doc: str
    kind: str = "float"  # float | int | choice
    choices: tuple = ()
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False  # lo < x instead of lo <= x
    derived: bool = False  # default None means "derived from the others"
    numerics: bool = False  # an engine setting, not physics

    def allowed(self) -> str:
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        lo = "" if self.lo == -math.inf else (f"{self.lo:g} < " if self.lo_open else f"{self.lo:g} <= ")
        hi = "" if self.hi == math.inf else f" <= {self.hi:g}"
        what = "an integer" if self.kind == "int" else "a number"
        rng = f"{lo}{self.name}{hi}" if (lo or hi) else ""
        extra = " (or null for the derived default)" if self.derived else ""
        return f"{what}{' with ' + rng if rng else ''}{extra}"


_PI = math.pi
#: most work cycles of one stream (docs/model.md §14): 1e6 cycles hold ~0.3 GB of per-cycle results
MAX_CYCLES = 1_000_000

#: docs/model.md §12, in its order. Units in brackets in the docs.
TABLE: tuple[Param, ...] = (
    Param("v", "m/s", 2.0, "belt speed", lo=0.0, hi=50.0, lo_open=True),
    Param("P_max", "m", 0.7, "belt width", lo=0.0, hi=20.0, lo_open=True),
    Param("mu1", "-", 0.4, "load-belt friction coefficient", lo=0.0, hi=5.0),
    Param("mu2", "-", 0.25, "load-fence and load-rail friction coefficient", lo=0.0, hi=5.0),
    Param("L", "m", 0.7, "load length (along the belt at phi = 0)", lo=0.0, hi=20.0, lo_open=True),
    Param("A", "m", 0.1, "load width", lo=0.0, hi=20.0, lo_open=True),
    Param("m1", "kg", 15.0, "load mass", lo=0.0, hi=1e5, lo_open=True),
    Param("dP", "m", 0.0, "gap between the load's near side and the rail", lo=0.0, hi=20.0),
    Param("R_s", "m", 0.0, "leading edge's x at fence activation", lo=-50.0, hi=50.0),
    Param("phi0", "rad", 0.0, "initial orientation of the load", lo=-_PI, hi=_PI),
    Param("e", "-", 0.2, "restitution coefficient", lo=0.01, hi=1.0),
    Param("k1", "N/m^1.5", 4.0e6, "contact stiffness of the modified Kelvin law", lo=0.0, hi=1e13, lo_open=True),
    Param("contact_law", "-", "hertz", "hertz (paper eq. 3) or linear (eq. 2)", kind="choice",
          choices=("hertz", "linear")),
    Param("k_lin", "N/m", None, "stiffness of the linear law (derived: equal undamped peak in free fall)",
          lo=0.0, hi=1e13, lo_open=True, derived=True),
    Param("l", "m", 1.2, "fence length", lo=0.0, hi=20.0, lo_open=True),
    Param("m2", "kg", 5.0, "fence mass; I2 = m2 l^2/3", lo=0.0, hi=1e5, lo_open=True),
    Param("I2", "kg m^2", None, "fence moment of inertia about the pivot (derived: m2 l^2/3)",
          lo=0.0, hi=1e6, lo_open=True, derived=True),
    Param("B2", "N m s/rad", 72.0, "flexible element damping", lo=0.0, hi=1e6),
    Param("K2", "N m/rad", 570.0, "flexible element stiffness", lo=0.0, hi=1e7),
    Param("drive", "-", "flexible", "flexible / rigid / free fence drive", kind="choice",
          choices=("flexible", "rigid", "free")),
    Param("t_c", "s", 1.36, "work cycle time (one crank turn)", lo=0.0, hi=100.0, lo_open=True),
    Param("swing", "rad", math.radians(42.0), "drive swing psi", lo=0.0, hi=_PI / 2, lo_open=True),
    Param("profile", "-", "crank_rocker", "crank_rocker / harmonic drive profile", kind="choice",
          choices=("crank_rocker", "harmonic")),
    Param("coupler_ratio", "-", 2.5, "coupler over rocker length b/c (crank_rocker only)",
          lo=0.0, hi=100.0, lo_open=True),
    Param("H", "m", 0.3, "permitted drop height", lo=0.0, hi=100.0, lo_open=True),
    Param("dalpha_perm", "rad", math.radians(15.0), "permitted deflection", lo=0.0, hi=_PI, lo_open=True),
    Param("R", "m", 1.2, "impact scene: distance of the impact point from the pivot", lo=0.0, hi=20.0,
          lo_open=True),
    Param("w", "m/s", 2.0, "impact scene: normal approach speed", lo=0.0, hi=100.0, lo_open=True),
    Param("eps_v", "m/s", 1e-3, "friction regularisation velocity", lo=0.0, hi=1.0, lo_open=True),
    Param("t_max", "s", None, "end of a cycle without outcome (derived: t_c + 1)", lo=0.0, hi=1000.0,
          lo_open=True, derived=True),
    Param("n_cycles", "-", None, "stream scene: number of work cycles (derived: the number of loads, or 1)",
          kind="int", lo=1, hi=MAX_CYCLES, derived=True),
    Param("period", "s", None, "stream scene: time from one cycle's start to the next's, >= t_c (derived: t_c)",
          lo=0.0, hi=1000.0, lo_open=True, derived=True),
    # --- engine settings (not physics; recorded in every result table) ---
    Param("step_factor", "-", 1.0, "scales the integrator's error tolerance as TOL x step_factor^5, so its "
          "steps scale about like step_factor (0.1 = steps ~10x shorter); with integrator = rk4 it "
          "multiplies the fixed step dt", lo=1e-4, hi=10.0, numerics=True),
    Param("integrator", "-", "dopri5", "dopri5 (Dormand-Prince 5(4) with error control, the default) or rk4 "
          "(classical RK4 at the fixed step dt: the first engine's baseline)", kind="choice",
          choices=("dopri5", "rk4"), numerics=True),
    Param("dt", "s", None, "fixed step of integrator = rk4 (derived: 1e-5 s)", lo=1e-9, hi=1.0,
          derived=True, numerics=True),
)

BY_NAME: dict[str, Param] = {p.name: p for p in TABLE}
NAMES: tuple[str, ...] = tuple(p.name for p in TABLE)

#: The paper's unfavourable positions (§4.2), docs/model.md §12.
CASES: dict[str, dict[str, float]] = {
    "small_far": {"L": 0.2, "A": 0.1, "dP": 0.6},
    "long_near": {"L": 0.7, "A": 0.1, "dP": 0.0},
}

#: Which parameters each scene's model uses (the rest are carried but ignored). L and A enter
#: every scene: a penetration beyond half the load's smaller side fails the run (docs/model.md §5).
SCENE_USES: dict[str, frozenset] = {
    "freefall": frozenset({"m1", "e", "k1", "contact_law", "k_lin", "H", "L", "A"}),
    "impact": frozenset({"m1", "e", "k1", "contact_law", "k_lin", "H", "l", "m2", "I2", "B2", "K2",
                         "drive", "R", "w", "L", "A"}),
    "cycle": frozenset(set(NAMES) - {"R", "w", "n_cycles", "period"}),
    "stream": frozenset(set(NAMES) - {"R", "w"}),
}
#: Parameters that resolve() checks one by one and copies, which no derived value and no
#: combination check reads (docs/model.md §1, §3, §12): scenes that differ only in them resolve
#: alike but for their own values, so a sweep resolves their axes as whole columns
#: (study/spec/scenes.py). Not in a stream, whose loads take m1 from the scene (§14), and not
#: B2 or K2 where a spec sets Psi, which fixes K2 from B2 (§3). tests/test_scene_columns.py
#: checks the claim against resolve().
ALONE = frozenset({"v", "mu1", "mu2", "m1", "e", "k1", "B2", "K2", "H", "dalpha_perm", "R", "w", "eps_v",
                   "step_factor"})
#: the parameters of one load of a stream (docs/model.md §14), the columns of a loads table
LOAD_NAMES = ("L", "A", "m1", "dP", "R_s", "phi0")


_DEFAULTS = {p.name: p.default for p in TABLE}  # immutable values: a shallow copy is a new set


def defaults() -> dict[str, Any]:
    """Every parameter at its docs/model.md §12 default (derived ones as None)."""
    return dict(_DEFAULTS)


def _unknown(name: str, what: str = "parameter") -> ParameterError:
    lower = {n.lower(): n for n in NAMES}
    near = [lower[name.lower()]] if name.lower() in lower else difflib.get_close_matches(name, NAMES, n=1, cutoff=0.5)
    hint = f"; did you mean {near[0]!r}?" if near else ""
    return ParameterError(f"unknown {what} {name!r}{hint} (known: {', '.join(NAMES)})")


def as_finite_number(value: Any) -> float | None:
    """A spec's value as a finite float: a number, or text that reads as one (YAML 1.1 reads
    "1e-3" as text); None for anything else (a bool, nan, inf, other text). The callers say
    what was expected where."""
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value)


def check_value(name: str, value: Any) -> Any:  # noqa: C901 (11 > 10: existing code)
    """Check one value against its row of the table; return it normalised (float/str/None)."""
    if name not in BY_NAME:
        raise _unknown(name)
    p = BY_NAME[name]
    if value is None:
        if p.derived:
            return None
        raise ParameterError(f"{name} = None is not allowed: {name} must be {p.allowed()}")
    if p.kind == "choice":
        if not isinstance(value, str) or value not in p.choices:
            raise ParameterError(f"{name} = {value!r} is not allowed: {name} must be {p.allowed()}")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        try:  # numpy scalars
            import numpy as np

            if isinstance(value, np.generic) and np.issubdtype(type(value), np.number):
                value = value.item()
            else:
                raise TypeError
        except TypeError:
            raise ParameterError(
                f"{name} = {value!r} ({type(value).__name__}) is not allowed: {name} must be {p.allowed()}"
            ) from None
    x = float(value)
    if not math.isfinite(x) or (p.kind == "int" and not x.is_integer()):
        raise ParameterError(f"{name} = {value!r} is not allowed: {name} must be {p.allowed()}")
    ok_lo = x > p.lo if p.lo_open else x >= p.lo
    if not ok_lo or x > p.hi:
        raise ParameterError(f"{name} = {value!r} is out of range: {name} must be {p.allowed()}")
    return int(x) if p.kind == "int" else x


def parse_value(name: str, text: str) -> Any:
    """Turn a command-line string NAME=TEXT into a checked value."""
    if name not in BY_NAME:
        raise _unknown(name)
    p = BY_NAME[name]
    if p.kind == "choice":
        return check_value(name, text)
    if p.derived and text.lower() in ("none", "null", "derived"):
        return None
    try:
        x = float(text)
    except ValueError:
        raise ParameterError(f"{name} = {text!r} is not a number: {name} must be {p.allowed()}") from None
    return check_value(name, x)


def resolve(scene: str = "cycle", case: str | None = None, loads: Any = None,  # noqa: C901 (11)
            **overrides: Any) -> dict[str, Any]:
    """Check and complete a parameter set: defaults < named case < explicit overrides.

    Returns a dict with every name of TABLE (derived ones filled in) plus `scene`, `case` and
    `loads` (`stream` only: one load per cycle, see resolve_loads; None: the scene's load in
    every cycle). Raises ParameterError on anything wrong; nothing is computed then.
    """
    if loads is not None and scene != "stream":
        raise ParameterError(f"loads = {_short(loads)} is not allowed with scene = {scene!r}: "
                             f"a list of loads belongs to scene 'stream' only")
    if scene not in SCENES:
        raise ParameterError(f"scene = {scene!r} is not allowed: scene must be one of {', '.join(SCENES)}")
    if case is not None and case not in CASES:
        raise ParameterError(
            f"case = {case!r} is not allowed: case must be one of {', '.join(CASES)} (or omitted)"
        )
    vals = defaults()
    if case is not None:
        vals.update(CASES[case])
    for name, value in overrides.items():
        vals[name] = check_value(name, value)
    # derived values (docs/model.md §3, §4, §12)
    if vals["I2"] is None:
        vals["I2"] = fence_inertia(vals["m2"], vals["l"])
    if vals["t_max"] is None:
        vals["t_max"] = vals["t_c"] + 1.0
    if vals["profile"] == "crank_rocker" and vals["coupler_ratio"] <= math.sin(vals["swing"] / 2):
        raise ParameterError(
            f"coupler_ratio = {vals['coupler_ratio']!r} is not allowed with swing = {vals['swing']!r}: "
            f"the crank-rocker needs coupler_ratio > sin(swing/2) = {math.sin(vals['swing'] / 2):.6g}"
        )
    if scene in ("cycle", "stream"):
        _check_start(vals)
    vals["loads"] = None
    if scene == "stream":
        _check_stream(vals, loads)
    if vals["n_cycles"] is None:
        vals["n_cycles"] = 1
    if vals["period"] is None:
        vals["period"] = vals["t_c"]
    vals["scene"] = scene
    vals["case"] = case
    return vals


def _short(x: Any) -> str:
    text = repr(x)
    return text if len(text) < 80 else text[:76] + " ..."


def _check_stream(vals: dict[str, Any], loads: Any) -> None:
    """docs/model.md §14: period >= t_c, a drive that stays connected, one load per cycle."""
    if vals["drive"] == "free":
        raise ParameterError("drive = 'free' is not allowed with scene = 'stream': the free fence is released at "
                             "its first contact and never driven again (docs/model.md §14); drive must be 'flexible' "
                             "or 'rigid'")
    if vals["period"] is not None and vals["period"] < vals["t_c"]:
        raise ParameterError(f"period = {vals['period']!r} is not allowed: a cycle's drive turns for t_c, so "
                             f"period must be >= t_c = {vals['t_c']!r}")
    if loads is None:
        return
    rows = resolve_loads(loads, vals)
    if vals["n_cycles"] is not None and vals["n_cycles"] != len(rows):
        raise ParameterError(f"loads has {len(rows)} rows and n_cycles = {vals['n_cycles']!r}: give one load per "
                             f"cycle (or leave n_cycles out, it is then the number of loads)")
    vals["n_cycles"] = len(rows)
    vals["loads"] = rows


def resolve_loads(loads: Any, vals: dict[str, Any]) -> tuple:
    """A list of loads -> one tuple (L, A, m1, dP, R_s, phi0) per cycle (docs/model.md §14).

    `loads` is a pandas DataFrame, or a list whose entries are a named case or a mapping, each
    with columns / keys among LOAD_NAMES (and `case` in a mapping); what a row does not give is
    the scene's (`vals`). Every load must start on the belt (docs/model.md §1)."""
    if hasattr(loads, "to_dict") and hasattr(loads, "columns"):  # a pandas DataFrame
        bad = [c for c in loads.columns if c not in LOAD_NAMES]
        if bad:
            raise ParameterError(f"loads has the unknown column {bad[0]!r}: the columns of a loads table are "
                                 f"among {', '.join(LOAD_NAMES)}")
        loads = loads.to_dict("records")
    if isinstance(loads, (str, dict)) or not isinstance(loads, (list, tuple)) or not loads:
        raise ParameterError(f"loads = {_short(loads)} is not allowed: loads must be a non-empty table or list, "
                             f"one load per cycle (a named case, or a mapping of {', '.join(LOAD_NAMES)})")
    if len(loads) > MAX_CYCLES:
        raise ParameterError(f"loads has {len(loads)} rows: at most {MAX_CYCLES} cycles (n_cycles <= {MAX_CYCLES})")
    return tuple(_load_row(k, entry, vals) for k, entry in enumerate(loads))


def _load_row(k: int, entry: Any, vals: dict[str, Any]) -> tuple:
    """Row k of a loads list, completed from the scene's values and checked (docs/model.md §1)."""
    row = {n: vals[n] for n in LOAD_NAMES}
    row.update(_load_entry(k, entry))
    try:
        _check_start(dict(vals, **row))
    except ParameterError as exc:
        raise ParameterError(f"loads[{k}]: {exc}") from None
    return tuple(float(row[n]) for n in LOAD_NAMES)


def _load_entry(k: int, entry: Any) -> dict[str, Any]:
    """The load values that entry k of a loads list gives: a named case's, then its own, checked."""
    if isinstance(entry, str):
        entry = {"case": entry}
    if not isinstance(entry, dict):
        raise ParameterError(f"loads[{k}] = {_short(entry)} is not allowed: a load is a named case "
                             f"({', '.join(CASES)}) or a mapping of {', '.join(LOAD_NAMES)}")
    out = {}
    if "case" in entry:
        if entry["case"] not in CASES:
            raise ParameterError(f"loads[{k}].case = {entry['case']!r} is not allowed: case must be one of "
                                 f"{', '.join(CASES)}")
        out.update(CASES[entry["case"]])
    for name, value in entry.items():
        if name == "case":
            continue
        if name not in LOAD_NAMES:
            raise ParameterError(f"loads[{k}] has the unknown key {name!r}: a load's keys are among "
                                 f"{', '.join(LOAD_NAMES)} (and case)")
        try:
            out[name] = check_value(name, value)
        except ParameterError as exc:
            raise ParameterError(f"loads[{k}]: {exc}") from None
    return out


def fence_inertia(m2: float, l: float) -> float:
    """I2 = m2 l^2 / 3 [kg m^2], a uniform bar about its end (docs/model.md (3.1)): the fence's
    moment of inertia when I2 is not given."""
    return m2 * l ** 2 / 3.0


def relative_damping(B2: float, K2: float, I2: float) -> float:
    """Psi = B2 / (2 sqrt(K2 I2)) (paper §4.2, docs/model.md (3.5)); inf when K2 = 0 and B2 > 0."""
    if K2 <= 0.0:
        return math.inf if B2 > 0 else math.nan
    return B2 / (2.0 * math.sqrt(K2 * I2))


def load_corners(L: float, A: float, phi: float) -> list[tuple[float, float]]:
    """Corner offsets from the centroid, j = 0..3 at local (+L/2,+A/2), (-L/2,+A/2), ... (docs/model.md §1)."""
    c, s = math.cos(phi), math.sin(phi)
    loc = ((L / 2, A / 2), (-L / 2, A / 2), (-L / 2, -A / 2), (L / 2, -A / 2))
    return [(c * a - s * b, s * a + c * b) for a, b in loc]


def initial_centroid(L: float, A: float, phi0: float, R_s: float, dP: float) -> tuple[float, float]:
    """docs/model.md §1: foremost corner at x = R_s, lowest corner at y = dP."""
    cs = load_corners(L, A, phi0)
    return R_s - max(x for x, _ in cs), dP - min(y for _, y in cs)


def _check_start(vals: dict[str, Any]) -> None:
    """docs/model.md §1: every corner within 0 <= y <= P_max and the load not past the fence."""
    problem = _start_problem(*(vals[n] for n in _START_NAMES))
    if problem:
        raise ParameterError(problem)


_START_NAMES = ("R_s", "l", "L", "A", "phi0", "dP", "P_max")


@lru_cache(maxsize=4096)  # a sweep repeats the load's placing in most of its scenes
def _start_problem(R_s: float, l: float, L: float, A: float, phi0: float, dP: float, P_max: float) -> str | None:
    """Why the load cannot start there (_check_start's message), or None: it must start upstream
    of the tip, R_s < l, and entirely on the belt, max_j y_Gj(0) <= P_max (docs/model.md (1.6))."""
    if R_s >= l:
        return f"R_s = {R_s!r} is not allowed: the load would start past the fence; R_s must be < l = {l!r}"
    xc, yc = initial_centroid(L, A, phi0, R_s, dP)
    top = max(yc + y for _, y in load_corners(L, A, phi0))
    if top > P_max * (1 + 1e-12):
        return (f"dP = {dP!r} is not allowed with L = {L!r}, A = {A!r}, phi0 = {phi0!r}: "
                f"the load's far corner would be at y = {top:.6g} > P_max = {P_max!r}; "
                f"dP must be <= {dP + P_max - top:.6g}")
    return None


def model_key(vals: dict[str, Any]) -> tuple:
    """The values a scene's model actually uses, as a hashable key.

    Two resolved parameter sets with the same key give the same results, bit for bit, so a
    sweep simulates each key once (docs/model.md §8: model only what a scene needs); the engine
    is the judge (tests/test_model_key.py). Unused parameters: R and w outside `impact`;
    B2, K2 under `drive = rigid` in a cycle (the drive is kinematic; I2 stays, as the error
    control scales the energy integrals by the fence's kinetic energy); B2, K2 under
    `drive = free`; k_lin under the Hertz law; coupler_ratio under the harmonic profile.
    """
    names = _used_names(vals["scene"], vals["drive"], vals["contact_law"], vals["profile"], vals["integrator"])
    key = (vals["scene"],) + tuple((n, vals[n]) for n in names)
    return key + (("loads", vals["loads"]),) if vals.get("loads") is not None else key


@lru_cache(maxsize=None)
def _used_names(scene: str, drive: str, contact_law: str, profile: str, integrator: str) -> tuple:
    """The names of model_key's values, in the order of NAMES, for one variant."""
    used = set(SCENE_USES[scene])
    if scene in ("cycle", "stream") and drive == "rigid":
        used -= {"B2", "K2"}
    if scene in ("cycle", "impact") and drive == "free":
        used -= {"B2", "K2"}
    if scene == "impact" and drive == "rigid":
        used -= {"B2", "K2", "m2", "I2", "l"}
    if contact_law == "hertz":
        used -= {"k_lin"}
    if profile == "harmonic":
        used -= {"coupler_ratio"}
    if "m2" in used and "I2" in used:
        used -= {"m2"}  # only I2 = m2 l^2/3 (or its override) enters the dynamics
    used.add("step_factor")
    if scene in ("cycle", "stream"):
        used.add("integrator")
        if integrator == "rk4":
            used.add("dt")
        else:
            used.discard("dt")
    else:
        used -= {"integrator", "dt"}
    return tuple(n for n in NAMES if n in used)
