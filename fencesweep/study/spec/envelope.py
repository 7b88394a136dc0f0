"""Load envelopes: every package a sorter may see, as one axis of a sweep.

A spec's `envelope:` section gives, for parameters of docs/model.md §12 (normally the load's L, A,
m1, dP, R_s, phi0), a range {min, max}, a list of choices or one value, and `dP: across` for
"anywhere across the belt" (dP from 0 to P_max minus the load's extent across the belt). The
loads are the corners of that box (every combination of each range's ends and of the choices)
plus a scrambled Sobol or Latin-hypercube set of n points (scipy.stats.qmc, seeded), so that
every design point of the sweep meets the same loads. They become the spec's innermost axis
(a zip group named `envelope`): a design point's loads are contiguous in the table.

`summarize` judges each design point over its loads: the worst overload, deflection_max and
residual_amplitude, which load is worst for each, the share scraped, and the margin to each
constraint (1 - worst / limit; negative when the constraint is broken). `fencesweep grid`
and `fencesweep design` both judge through it. Orchestration only: no physics here.
"""
from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fencesweep.errors import EnvelopeError
from fencesweep.model import params as P

SAMPLE_KEYS = ("corners", "sobol", "lhs", "seed", "invalid")
ACROSS = "across"
_SIG = 6  # sampled load values: 6 significant digits (micrometres, milligrams)


def _round(x: float) -> float:
    return float(f"{x:.{_SIG}g}")


@dataclass
class Envelope:
    """The checked definition of an envelope and its sampled loads."""

    dims: dict  # name -> ("range", lo, hi) | ("choice", [values]) | ("fixed", value) | ("across",)
    corners: bool = True
    method: str = "sobol"  # sobol | lhs
    n: int = 0
    seed: int = 0
    invalid: str = "error"
    names: tuple = ()
    loads: list = field(default_factory=list)  # tuples of values, one per name
    skipped: list = field(default_factory=list)  # (load values, reason)

    def definition(self) -> dict:
        """JSON-able definition: how the loads were made (the loads themselves enter the spec's
        hash as its `envelope` axis)."""
        dims = {}
        for name, d in self.dims.items():
            kind = d[0]
            dims[name] = ({"min": d[1], "max": d[2]} if kind == "range" else list(d[1]) if kind == "choice"
                          else d[1] if kind == "fixed" else ACROSS)
        return {"dims": dims, "corners": self.corners, self.method: self.n, "seed": self.seed,
                "invalid": self.invalid, "n_loads": len(self.loads), "n_skipped": len(self.skipped)}

    def load_dicts(self) -> list:
        return [dict(zip(self.names, v)) for v in self.loads]


# ------------------------------------------------------------------------------ parsing
def _number(name: str, value: Any, where: str) -> float:
    x = P.as_finite_number(value)
    if x is None:
        raise EnvelopeError(f"{where} = {value!r}: expected a finite number")
    try:
        return float(P.check_value(name, x))
    except P.ParameterError as exc:
        raise EnvelopeError(f"{where}: {exc}") from None


def _dim(name: str, raw: Any, where: str) -> tuple:
    allowed = ("{min: a, max: b} (a range), a list of values (choices), one value, or 'across' "
               "(dP only: anywhere across the belt)")
    if name not in P.NAMES:
        raise EnvelopeError(f"{where}: unknown parameter {name!r} (parameters of docs/model.md §12: "
                            f"{', '.join(P.NAMES)}; sampling keys: {', '.join(SAMPLE_KEYS)})")
    if raw == ACROSS:
        if name != "dP":
            raise EnvelopeError(f"{where} = 'across' is only for dP (the gap to the rail); {name} takes {allowed}")
        return ("across",)
    if isinstance(raw, dict):
        if set(raw) != {"min", "max"}:
            raise EnvelopeError(f"{where} = {raw!r}: a range is {{min: a, max: b}}; an entry is {allowed}")
        lo, hi = _number(name, raw["min"], f"{where}.min"), _number(name, raw["max"], f"{where}.max")
        if not lo < hi:
            raise EnvelopeError(f"{where}: min = {lo!r} must be < max = {hi!r} (one value: give it alone)")
        return ("range", lo, hi)
    if isinstance(raw, list):
        return _choices(name, raw, where, allowed)
    if P.BY_NAME[name].kind == "choice":
        return ("fixed", P.check_value(name, raw))
    return ("fixed", _number(name, raw, where))


def _choices(name: str, raw: list, where: str, allowed: str) -> tuple:
    if not raw:
        raise EnvelopeError(f"{where} = []: give at least one choice ({allowed})")
    vals = [P.check_value(name, v) if P.BY_NAME[name].kind == "choice" else _number(name, v, f"{where}[{k}]")
            for k, v in enumerate(raw)]
    if len(set(vals)) != len(vals):
        raise EnvelopeError(f"{where} = {raw!r}: a choice appears twice")
    return ("choice", vals)


def _whole(value: Any, where: str, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise EnvelopeError(f"{where} = {value!r}: expected a whole number >= {least}")
    return value


def parse(raw: Any, base: dict, taken: dict) -> Envelope:
    """The envelope of a spec from its `envelope:` mapping. `base` resolves each load (the spec's
    fixed inputs: scene, case, params) to check that it can start on the belt; `taken` maps the
    parameters that already vary elsewhere to where."""
    if not isinstance(raw, dict) or not raw:
        raise EnvelopeError(f"envelope = {raw!r}: expected a mapping of parameter: range | choices | value "
                            f"(and {', '.join(SAMPLE_KEYS)})")
    env = Envelope(dims={})
    for key, value in raw.items():
        if key in SAMPLE_KEYS:
            continue
        if key in taken:
            raise EnvelopeError(f"envelope.{key}: {key} is also set in {taken[key]}; a parameter is either in "
                                f"the envelope or elsewhere")
        env.dims[key] = _dim(key, value, f"envelope.{key}")
    if not env.dims:
        raise EnvelopeError("envelope: no parameter given; e.g. L: {min: 0.2, max: 0.7}")
    env.corners = raw.get("corners", True)
    if not isinstance(env.corners, bool):
        raise EnvelopeError(f"envelope.corners = {env.corners!r}: expected true or false")
    if "sobol" in raw and "lhs" in raw:
        raise EnvelopeError("envelope: give one of sobol: N and lhs: N, not both")
    env.method = "lhs" if "lhs" in raw else "sobol"
    env.n = _whole(raw.get(env.method, 0), f"envelope.{env.method}", 0)
    env.seed = _whole(raw.get("seed", 0), "envelope.seed", 0)
    env.invalid = raw.get("invalid", "error")
    if env.invalid not in ("error", "skip"):
        raise EnvelopeError(f"envelope.invalid = {env.invalid!r}: expected error (stop and name the loads that "
                            f"cannot start) or skip (drop them and say so)")
    if not env.corners and env.n == 0:
        raise EnvelopeError("envelope: corners: false and no sobol: N / lhs: N: the envelope has no load")
    sample(env, base)
    return env


# ------------------------------------------------------------------------------ sampling
def _extent(L: float, A: float, phi0: float) -> float:
    """The load's extent across the belt at phi0 (docs/model.md §1: lowest corner at y = dP)."""
    ys = [y for _, y in P.load_corners(L, A, phi0)]
    return max(ys) - min(ys)


def _unit_points(env: Envelope, n: int, seed: int, corners: bool) -> np.ndarray:
    """Points in [0, 1]^d, d = the non-fixed dimensions: the box's corners, then n qmc points."""
    free = [n_ for n_, d in env.dims.items() if d[0] != "fixed"]
    d = len(free)
    pts = []
    if corners and d:
        levels = [[0.0, 1.0] if env.dims[n_][0] != "choice" else
                  [(k + 0.5) / len(env.dims[n_][1]) for k in range(len(env.dims[n_][1]))] for n_ in free]
        pts += [list(c) for c in itertools.product(*levels)]
    elif corners:
        pts.append([])
    if n and d:
        from scipy.stats import qmc

        eng = qmc.Sobol(d, scramble=True, seed=seed) if env.method == "sobol" else qmc.LatinHypercube(d, seed=seed)
        with warnings.catch_warnings():  # Sobol's balance needs n = 2^m; any n is a valid sample
            warnings.simplefilter("ignore", UserWarning)
            pts += eng.random(n).tolist()
    return np.asarray(pts, dtype=float).reshape(len(pts), d)


def _round_within(x: float, most: float) -> float:
    """x to _SIG significant digits, but never above `most` (a load at the far edge stays on the
    belt; params checks the start with a relative tolerance of 1e-12, taken here as 1e-13)."""
    r = _round(x)
    while r > most + 1e-13 and r > 0:
        r = _round(r - 10.0 ** (math.floor(math.log10(r)) - _SIG + 1))
    return r


def _load_of(env: Envelope, u: np.ndarray, base: dict) -> dict:
    free = [n_ for n_, d in env.dims.items() if d[0] != "fixed"]
    load = {n_: d[1] for n_, d in env.dims.items() if d[0] == "fixed"}
    for n_, x in zip(free, u):
        d = env.dims[n_]
        if d[0] == "range":
            load[n_] = _round(d[1] + x * (d[2] - d[1]))
        elif d[0] == "choice":
            load[n_] = d[1][min(int(x * len(d[1])), len(d[1]) - 1)]
        else:
            load[n_] = x  # across: a fraction of the accessible width, made a dP below
    if "dP" in free and env.dims["dP"][0] == "across":
        v = dict(base, **load)
        room = max(v["P_max"] - _extent(v["L"], v["A"], v["phi0"]), 0.0)
        load["dP"] = _round_within(room * load["dP"], room)
    return load


def loads_of(env: Envelope, base: dict, n: int, seed: int, corners: bool) -> list:
    """The loads (dicts in the order of env.dims' names) of a sample of the envelope."""
    return [_load_of(env, u, base) for u in _unit_points(env, n, seed, corners)]


def valid_loads(env: Envelope, base: dict, n: int, seed: int, corners: bool) -> tuple:
    """(loads, skipped) of a sample of the envelope: loads as tuples in the order of env.names,
    duplicates dropped; skipped = (load, reason) for each load that cannot start on the belt
    (docs/model.md §1), as base["check"] (spec.load_base) judges it."""
    loads, skipped, seen = [], [], set()
    for load in loads_of(env, base["defaults"], n, seed, corners):
        key = tuple(load[n_] for n_ in env.names)
        if key in seen:
            continue
        seen.add(key)
        try:
            base["check"](load)
        except P.ParameterError as exc:
            skipped.append((key, str(exc)))
            continue
        loads.append(key)
    return loads, skipped


def sample(env: Envelope, base: dict) -> None:
    """Fill env.names, env.loads, env.skipped from the envelope's own sample; with invalid: error,
    a load that cannot start on the belt raises EnvelopeError naming it and why."""
    env.names = tuple(env.dims)
    env.loads, env.skipped = valid_loads(env, base, env.n, env.seed, env.corners)
    if env.skipped and env.invalid == "error":
        raise EnvelopeError(_skip_text(env, "cannot start on the belt") + "; set envelope.invalid: skip to drop "
                            "them (they are then listed in the sweep's log), or narrow the ranges")
    if not env.loads:
        raise EnvelopeError(_skip_text(env, "cannot start on the belt") + ": no load of the envelope is left")


def _skip_text(env: Envelope, what: str) -> str:
    ex = "; ".join(f"load {dict(zip(env.names, k))}: {why}" for k, why in env.skipped[:3])
    more = f" (and {len(env.skipped) - 3} more)" if len(env.skipped) > 3 else ""
    return f"envelope: {len(env.skipped)} of {len(env.skipped) + len(env.loads)} loads {what}: {ex}{more}"
