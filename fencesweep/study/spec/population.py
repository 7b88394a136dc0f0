"""A parcel mix: the `population:` section of a risk spec (sweeps/README.md, Risk from a parcel mix).

The parcels' sizes and masses (L, A, m1) come either from a file of measured parcels
(`parcels: FILE`, CSV or Parquet, one row per parcel, drawn with replacement) or from one
scipy.stats distribution per column, truncated to its bounds ({dist: NAME, min, max, and the
distribution's own parameters}). Where a parcel lies when the fence starts is drawn apart:
dP uniform across the part of the belt where the parcel fits (0 .. P_max minus its extent across
the belt; a distribution given for dP draws the fraction of that room, 0 <= min < max <= 1), R_s
uniform over the trigger window {min, max} (the leading edge's x when the drive starts), phi0 one
value. dP and R_s may be given a distribution of their own instead.

Draws are plain pseudo-random numbers (numpy's PCG64, seeded): sample k is the same for any
number of workers and for every element, and sample k of a longer run is sample k of a shorter
one. A parcel wider than the belt is refused (too_large: error, the default) or left out of the
population and counted (too_large: skip). Orchestration only: no physics here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fencesweep.errors import SpecError
from fencesweep.model import params as P
from fencesweep.study.spec.axes import did_you_mean

SIZES = ("L", "A", "m1")  # what a parcel is; a parcels file has these columns
PLACES = ("dP", "R_s", "phi0")  # where it lies when the fence starts
KEYS = ("parcels", *SIZES, *PLACES, "seed", "too_large")
ACROSS = "across"
R_S_WINDOW = (-0.4, 0.6)  # m: the trigger-timing window of sweeps/tolerance.yaml (REPORT.md section 7)
#: stream of each drawn column (numpy SeedSequence spawn keys): a column's draws do not move when another is added
STREAMS = {"parcel": 0, "L": 1, "A": 2, "m1": 3, "dP": 4, "R_s": 5, "phi0": 6}


@dataclass
class Column:
    """One drawn column: a truncated scipy.stats distribution, a uniform range or one value."""

    name: str
    kind: str  # "dist" | "fixed" | "across"
    dist: str = "uniform"
    args: dict = field(default_factory=dict)
    lo: float = -math.inf
    hi: float = math.inf
    value: float = 0.0

    def definition(self) -> Any:
        if self.kind == "fixed":
            return self.value
        if self.kind == "across":
            return ACROSS
        return {"dist": self.dist, **self.args, "min": self.lo, "max": self.hi}

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Values of the column from uniforms u in [0, 1): the inverse CDF on [F(lo), F(hi))."""
        if self.kind == "fixed":
            return np.full(len(u), self.value)
        d = frozen(self.dist, self.args, self.name)
        a, b = d.cdf(self.lo), d.cdf(self.hi)
        return np.clip(d.ppf(a + u * (b - a)), self.lo, self.hi)


@dataclass
class Population:
    """A checked population: parcels from a file (table) or distributions (columns), placement."""

    columns: dict  # name -> Column (sizes when no file, and the placement)
    seed: int = 0
    too_large: str = "error"
    parcels: Any = None  # {L, A, m1: arrays} of a parcels file
    source: str | None = None  # the parcels file as given
    n_file: int = 0  # rows of the file
    left_out: list = field(default_factory=list)  # rows (1-based) of the file left out: too large for the belt
    P_max: float = 0.7

    def definition(self) -> dict:
        out = {name: c.definition() for name, c in self.columns.items()}
        if self.source is not None:
            out["parcels"] = {"file": self.source, "rows": self.n_file, "left_out_too_large": len(self.left_out)}
        return out | {"seed": self.seed, "too_large": self.too_large, "draws": "numpy PCG64, plain pseudo-random"}


# ------------------------------------------------------------------------------ parsing
def frozen(dist: str, args: dict, where: str):
    """The frozen scipy.stats distribution `dist`(**args); SpecError naming what is wrong."""
    from scipy import stats

    fn = getattr(stats, dist, None)
    if not isinstance(fn, stats.rv_continuous):
        names = [n for n in dir(stats) if isinstance(getattr(stats, n), stats.rv_continuous)]
        raise SpecError(f"{where}: unknown distribution {dist!r}{did_you_mean(dist, names)} (a continuous "
                        f"distribution of scipy.stats, e.g. uniform, norm, lognorm, gamma, truncnorm)")
    allowed = [*(fn.shapes.split(", ") if fn.shapes else []), "loc", "scale"]
    for key in args:
        if key not in allowed:
            raise SpecError(f"{where}: unknown parameter {key!r} of scipy.stats.{dist}{did_you_mean(key, allowed)} "
                            f"(its parameters: {', '.join(allowed)})")
    try:
        d = fn(**args)
        if not np.isfinite(d.ppf(0.5)):
            raise ValueError("its median is not finite")
    except (TypeError, ValueError) as exc:
        raise SpecError(f"{where}: scipy.stats.{dist}({args}) is not a valid distribution: {exc}") from None
    return d


def _number(value: Any, where: str) -> float:
    x = P.as_finite_number(value)
    if x is None:
        raise SpecError(f"{where} = {value!r}: expected a finite number")
    return x


def _bounds(name: str, raw: dict, where: str) -> tuple:
    lo, hi = _number(raw["min"], f"{where}.min"), _number(raw["max"], f"{where}.max")
    for bound, key in ((lo, "min"), (hi, "max")):
        try:
            P.check_value(name, bound)
        except P.ParameterError as exc:
            raise SpecError(f"{where}.{key}: {exc}") from None
    if name == "dP" and not 0 <= lo < hi <= 1:
        raise SpecError(f"{where} = {raw!r}: a distribution of dP draws the fraction of the room across the belt "
                        f"where the parcel fits: 0 <= min < max <= 1 ('across': uniform over all of it)")
    if name in SIZES and lo <= 0:
        raise SpecError(f"{where}.min = {lo!r}: a parcel's {name} must be > 0")
    if not lo < hi:
        raise SpecError(f"{where}: min = {lo!r} must be < max = {hi!r} (one value: give it alone)")
    return lo, hi


def _column(name: str, raw: Any, where: str) -> Column:
    if raw == ACROSS:
        if name != "dP":
            raise SpecError(f"{where} = 'across' is only for dP (anywhere across the belt where the parcel fits)")
        return Column(name, "across")
    if not isinstance(raw, dict):
        return Column(name, "fixed", value=float(P.check_value(name, _number(raw, where))))
    if "min" not in raw or "max" not in raw:
        raise SpecError(f"{where} = {raw!r}: give its bounds, {{min: a, max: b}} (uniform between them) or "
                        f"{{dist: NAME, PARAMETER: value, ..., min: a, max: b}} (a scipy.stats distribution "
                        f"truncated to them)")
    lo, hi = _bounds(name, raw, where)
    dist = raw.get("dist", "uniform")
    args = {k: _number(v, f"{where}.{k}") for k, v in raw.items() if k not in ("dist", "min", "max")}
    if dist == "uniform" and not args:
        args = {"loc": lo, "scale": hi - lo}
    frozen(str(dist), args, where)
    col = Column(name, "dist", str(dist), args, lo, hi)
    if not np.isfinite(col.from_unit(np.array([0.0, 0.5, 0.999999]))).all():
        raise SpecError(f"{where}: scipy.stats.{dist}({args}) puts no probability between min = {lo!r} and "
                        f"max = {hi!r}")
    return col


def parse(raw: Any, base: dict, spec_dir: Path | None = None) -> Population:
    """The population of a risk spec from its `population:` mapping; `base` the fixed inputs
    (resolved: P_max, phi0's default); a parcels file is read relative to the current directory,
    else to `spec_dir`."""
    if not isinstance(raw, dict) or not raw:
        raise SpecError(f"population = {raw!r}: expected a mapping: parcels: FILE, or a distribution per column "
                        f"({', '.join(SIZES)}), and the placement ({', '.join(PLACES)})")
    for key in raw:
        if key not in KEYS:
            raise SpecError(f"population.{key}: unknown key{did_you_mean(key, KEYS)} (allowed: {', '.join(KEYS)})")
    pop = _options(raw, float(base["P_max"]))
    if "parcels" in raw:
        given = [k for k in SIZES if k in raw]
        if given:
            raise SpecError(f"population: parcels: FILE gives {', '.join(SIZES)}; {', '.join(given)} cannot also "
                            f"be given a distribution")
        _read_parcels(pop, raw["parcels"], spec_dir)
    else:
        missing = [k for k in SIZES if k not in raw]
        if missing:
            raise SpecError(f"population: no parcels: FILE and no distribution for {', '.join(missing)}; give each "
                            f"of {', '.join(SIZES)} as {{dist: NAME, ..., min: a, max: b}}")
        for k in SIZES:
            pop.columns[k] = _column(k, raw[k], f"population.{k}")
    defaults = {"dP": ACROSS, "R_s": {"min": R_S_WINDOW[0], "max": R_S_WINDOW[1]}, "phi0": base["phi0"]}
    for k in PLACES:
        pop.columns[k] = _column(k, raw.get(k, defaults[k]), f"population.{k}")
    if pop.columns["phi0"].kind != "fixed":
        raise SpecError("population.phi0: one value (the parcels' orientation on the belt); a spread of phi0 is "
                        "not drawn yet")
    _check_fit(pop)
    return pop


def _options(raw: dict, P_max: float) -> Population:
    pop = Population(columns={}, P_max=P_max)
    pop.seed = raw.get("seed", 0)
    if isinstance(pop.seed, bool) or not isinstance(pop.seed, int) or pop.seed < 0:
        raise SpecError(f"population.seed = {pop.seed!r}: expected a whole number >= 0")
    pop.too_large = raw.get("too_large", "error")
    if pop.too_large not in ("error", "skip"):
        raise SpecError(f"population.too_large = {pop.too_large!r}: expected error (refuse a parcel wider than the "
                        f"belt) or skip (leave it out of the population and count it)")
    return pop


def _read_parcels(pop: Population, given: Any, spec_dir: Path | None) -> None:
    import pandas as pd

    path = Path(str(given))
    if not path.exists() and spec_dir is not None and (spec_dir / path).exists():
        path = spec_dir / path
    where = f"population.parcels {str(given)!r}"
    try:
        df = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path, dtype=str)
    except (OSError, ValueError) as exc:
        raise SpecError(f"{where}: cannot read it as {'Parquet' if path.suffix == '.parquet' else 'CSV'}: "
                        f"{exc}") from None
    missing = [c for c in SIZES if c not in df.columns]
    if missing:
        raise SpecError(f"{where}: missing column{'s' if len(missing) > 1 else ''} {', '.join(missing)} "
                        f"(a parcels file has the columns {', '.join(SIZES)}: one row per parcel; found "
                        f"{', '.join(map(str, df.columns)) or 'none'})")
    if not len(df):
        raise SpecError(f"{where}: no parcel in it (one row per parcel)")
    cols = {}
    for c in SIZES:
        vals = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(vals) | (vals <= 0))
        if len(bad):
            r = int(bad[0])
            raise SpecError(f"{where}: row {r + 1} (of {len(df)}, counting parcels from 1): {c} = {df[c].iloc[r]!r} "
                            f"is not allowed: a parcel's {c} must be a number > 0 [{P.BY_NAME[c].unit}]"
                            + (f" ({len(bad)} rows are wrong)" if len(bad) > 1 else ""))
        cols[c] = vals
    pop.source, pop.n_file, pop.parcels = str(given), len(df), cols


def extent_factors(phi0: float) -> tuple:
    """(e_L, e_A): a parcel's extent across the belt at phi0 is L e_L + A e_A (docs/model.md §1:
    the span of its corners' y, params.load_corners)."""
    def span(L, A):
        ys = [y for _, y in P.load_corners(L, A, phi0)]
        return max(ys) - min(ys)

    return span(1.0, 0.0), span(0.0, 1.0)


def _check_fit(pop: Population) -> None:
    """Parcels wider than the belt: refused (too_large: error) or left out and counted (skip)."""
    e_L, e_A = extent_factors(pop.columns["phi0"].value)
    if pop.parcels is not None:
        ext = pop.parcels["L"] * e_L + pop.parcels["A"] * e_A
        over = np.flatnonzero(ext + _fixed_dP(pop) > pop.P_max * (1 + 1e-12))  # a fixed dP: from there
        if len(over) and pop.too_large == "error":
            r = int(over[0])
            raise SpecError(f"population.parcels {pop.source!r}: {len(over)} of {pop.n_file} parcels are wider than "
                            f"the belt and are refused, e.g. row {r + 1}: L = {pop.parcels['L'][r]:g}, A = "
                            f"{pop.parcels['A'][r]:g} spans {ext[r]:.4g} m across it"
                            + (f" from dP = {_fixed_dP(pop):g} m" if _fixed_dP(pop) else "")
                            + f" > P_max = {pop.P_max:g} m; set "
                            f"population.too_large: skip to leave them out (they are counted in the table)")
        keep = np.ones(pop.n_file, bool)
        keep[over] = False
        pop.left_out = (over + 1).tolist()
        pop.parcels = {c: v[keep] for c, v in pop.parcels.items()}
        if not keep.any():
            raise SpecError(f"population.parcels {pop.source!r}: every parcel is wider than the belt")
        return
    L, A = pop.columns["L"], pop.columns["A"]
    widest = L.hi * e_L + A.hi * e_A + _fixed_dP(pop)
    if widest > pop.P_max and pop.too_large == "error":
        raise SpecError(f"population: a parcel of L = {L.hi:g}, A = {A.hi:g} (the bounds' largest) spans {widest:.4g} "
                        f"m across the belt > P_max = {pop.P_max:g} m and would be refused; lower A.max (and L.max), "
                        f"or set population.too_large: skip to leave such parcels out (they are counted)")
    if L.lo * e_L + A.lo * e_A > pop.P_max:
        raise SpecError(f"population: even the smallest parcel (L = {L.lo:g}, A = {A.lo:g}) is wider than the belt")


# ------------------------------------------------------------------------------ drawing
def _uniforms(seed: int, stream: str, n: int, start: int = 0) -> np.ndarray:
    """Uniforms [start, start + n) of a column's own stream."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(STREAMS[stream],))))
    if start:
        rng.bit_generator.advance(start)
    return rng.random(n)


def _sizes(pop: Population, n: int, start: int) -> dict:
    if pop.parcels is not None:
        k = len(pop.parcels["L"])
        idx = np.minimum((_uniforms(pop.seed, "parcel", n, start) * k).astype(np.int64), k - 1)
        return {c: pop.parcels[c][idx] for c in SIZES} | {"parcel": idx}
    return {c: pop.columns[c].from_unit(_uniforms(pop.seed, c, n, start)) for c in SIZES}


def _fixed_dP(pop: Population) -> float:
    col = pop.columns["dP"]
    return col.value if col.kind == "fixed" else 0.0


def draw(pop: Population, n: int) -> dict:
    """The first n parcels of the population, placed: {L, A, m1, dP, R_s, phi0: arrays} (and
    `parcel`, the row of the file left after too-large rows are left out, for a parcels file).
    With too_large: skip and distributions, a draw wider than the belt is left out and the next
    one taken: `drawn` counts the draws and `too_large` those left out."""
    e_L, e_A = extent_factors(pop.columns["phi0"].value)
    got, start, out = 0, 0, []
    while got < n:
        m = max(n - got, 64) if start else n
        s = _sizes(pop, m, start) | {"_draw": np.arange(start, start + m)}
        fit = s["L"] * e_L + s["A"] * e_A + _fixed_dP(pop) <= pop.P_max * (1 + 1e-12)
        out.append({c: v[fit] for c, v in s.items()})
        got += int(fit.sum())
        start += m
    s = {c: np.concatenate([o[c] for o in out])[:n] for c in out[0]}
    draws = s.pop("_draw")
    room = np.maximum(pop.P_max - (s["L"] * e_L + s["A"] * e_A), 0.0)  # where it fits: dP in [0, room]
    for c in PLACES:
        col = pop.columns[c]
        u = _uniforms(pop.seed, c, int(draws[-1]) + 1)[draws] if n else np.empty(0)
        s[c] = u * room if col.kind == "across" else col.from_unit(u) * room if c == "dP" and col.kind == "dist" \
            else col.from_unit(u)
    drawn = int(draws[-1]) + 1 if n else 0
    return s | {"drawn": drawn, "too_large": drawn - n}
