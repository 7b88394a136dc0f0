"""The `design:` section of a spec (`fencesweep design`, sweeps/README.md), checked into a
DesignConfig: the design variables and their bounds, the constraints (envelope.Limits), the
objective, the optimiser's and the verification's settings, the elements to compare, the output.

A bad section raises DesignError naming the key, the value and what is allowed. The section
needs the spec's `envelope:` (the loads a design must handle) and scene cycle; the spec's other
axes may vary only the design variables. design/search.py runs the study.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from fencesweep.errors import DesignError
from fencesweep.model import params as P

RESIDUAL_MAX_DEFAULT = math.radians(1.0)  # rad: the fence is home (report.RESIDUAL_REASON)


@dataclass(frozen=True)
class Limits:
    """The design constraints: every load scraped; worst overload <= overload; worst
    deflection_max <= deflection_max (None: each row's dalpha_perm) [rad]; worst
    residual_amplitude <= residual_amplitude [rad] (None: not constrained)."""

    scraped: bool = True
    overload: float = 1.0
    deflection_max: float | None = None
    residual_amplitude: float | None = RESIDUAL_MAX_DEFAULT

    def as_dict(self) -> dict:
        return {"scraped": "every load" if self.scraped else "not required", "overload": self.overload,
                "deflection_max": "dalpha_perm" if self.deflection_max is None else self.deflection_max,
                "residual_amplitude": self.residual_amplitude}

OBJECTIVES = ("max_min_margin", "min_worst_overload")
SECTION_KEYS = ("variables", "constraints", "objective", "optimizer", "verify", "compare", "output", "digits",
                "prefer", "within")
OPTIMIZER_KEYS = ("seed", "maxiter", "popsize", "tol", "refine")
VERIFY_KEYS = ("sobol", "lhs", "seed")
DEFAULT_COMPARE = {"paper 72/570": {"B2": 72.0, "K2": 570.0}, "two-case 15/2075": {"B2": 15.0, "K2": 2075.0},
                   "rigid fence": {"drive": "rigid"}}


@dataclass
class DesignConfig:
    """A checked design section (its defaults where the section gives nothing)."""

    variables: dict  # name -> (lo, hi)
    limits: Limits
    objective: str = "max_min_margin"
    seed: int = 0
    maxiter: int = 30
    popsize: int = 10
    tol: float = 0.01
    refine: int = 40  # Nelder-Mead evaluations on the dense sample (0: none)
    verify_n: int = 256
    verify_seed: int = 1
    verify_method: str = "sobol"
    compare: dict = field(default_factory=lambda: dict(DEFAULT_COMPARE))
    output: str = "results/design"
    digits: int = 3
    prefer: tuple | None = None  # (variable, "min" | "max"): the second stage of max_min_margin
    within: float = 0.01  # ... among points whose smallest margin is within this of the best

    def as_dict(self) -> dict:
        return {"variables": {k: {"min": lo, "max": hi} for k, (lo, hi) in self.variables.items()},
                "constraints": self.limits.as_dict(), "objective": self.objective,
                "optimizer": {"method": "scipy.optimize.differential_evolution", "seed": self.seed,
                              "maxiter": self.maxiter, "popsize": self.popsize, "tol": self.tol,
                              "refine": self.refine},
                "verify": {self.verify_method: self.verify_n, "seed": self.verify_seed}, "digits": self.digits,
                "prefer": None if self.prefer is None else {self.prefer[0]: self.prefer[1]}, "within": self.within}


def _num(value: Any, where: str, lo: float | None = None) -> float:
    x = P.as_finite_number(value)
    if x is None:
        raise DesignError(f"{where} = {value!r}: expected a finite number")
    if lo is not None and x < lo:
        raise DesignError(f"{where} = {value!r}: must be >= {lo}")
    return x


def _int(value: Any, where: str, lo: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < lo:
        raise DesignError(f"{where} = {value!r}: expected a whole number >= {lo}")
    return value


def _keys(raw: Any, where: str, allowed: tuple) -> dict:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise DesignError(f"{where} = {raw!r}: expected a mapping with keys among {', '.join(allowed)}")
    bad = [k for k in raw if k not in allowed]
    if bad:
        raise DesignError(f"{where}: unknown key {bad[0]!r} (allowed: {', '.join(allowed)})")
    return raw


def _variables(raw: Any, spec) -> dict:
    if not isinstance(raw, dict) or not raw:
        raise DesignError(f"design.variables = {raw!r}: expected a mapping NAME: {{min: a, max: b}}, "
                          f"e.g. B2: {{min: 0, max: 200}}")
    out = {}
    for name, rng in raw.items():
        where = f"design.variables.{name}"
        if name not in P.NAMES or P.BY_NAME[name].kind == "choice":
            raise DesignError(f"{where}: {name!r} is not a numeric parameter of docs/model.md §12 "
                              f"(e.g. B2, K2, m2, t_c)")
        if name in spec.envelope.names:
            raise DesignError(f"{where}: {name} is a dimension of the envelope; a design variable is what the "
                              f"designer chooses, a load parameter is not")
        if name in spec.params:
            raise DesignError(f"{where}: {name} is also fixed in params ({name} = {spec.params[name]!r}); "
                              f"remove one of them")
        if not isinstance(rng, dict) or set(rng) != {"min", "max"}:
            raise DesignError(f"{where} = {rng!r}: expected {{min: a, max: b}}")
        lo, hi = _num(rng["min"], f"{where}.min"), _num(rng["max"], f"{where}.max")
        if not lo < hi:
            raise DesignError(f"{where}: min = {lo!r} must be < max = {hi!r}")
        for v, k in ((lo, "min"), (hi, "max")):
            try:
                P.check_value(name, v)
            except P.ParameterError as exc:
                raise DesignError(f"{where}.{k}: {exc}") from None
        out[name] = (lo, hi)
    return out


def _limits(raw: Any) -> Limits:
    raw = _keys(raw, "design.constraints", ("scraped", "overload", "deflection_max", "residual_amplitude"))
    scraped = raw.get("scraped", True)
    if not isinstance(scraped, bool):
        raise DesignError(f"design.constraints.scraped = {scraped!r}: expected true (every load scraped) or false")
    dmax = raw.get("deflection_max", "dalpha_perm")
    dmax = None if dmax == "dalpha_perm" else _num(dmax, "design.constraints.deflection_max [rad] "
                                                         "(or dalpha_perm)", 1e-12)
    res = raw.get("residual_amplitude", RESIDUAL_MAX_DEFAULT)
    res = None if res is None else _num(res, "design.constraints.residual_amplitude [rad] (or null)", 1e-12)
    return Limits(scraped, _num(raw.get("overload", 1.0), "design.constraints.overload", 1e-12), dmax, res)


def _compare(raw: Any) -> dict:
    if raw is None:
        return dict(DEFAULT_COMPARE)
    if not isinstance(raw, dict):
        raise DesignError(f"design.compare = {raw!r}: expected a mapping LABEL: {{parameter: value}}")
    out = {}
    for label, over in raw.items():
        if not isinstance(over, dict):
            raise DesignError(f"design.compare.{label} = {over!r}: expected a mapping of §12 parameters")
        for name, value in over.items():
            try:
                P.check_value(name, value)
            except P.ParameterError as exc:
                raise DesignError(f"design.compare.{label}: {exc}") from None
        out[str(label)] = dict(over)
    return out


def _check_axes(spec, variables: dict) -> None:
    for a in spec.axes:
        if a.where == "envelope":
            continue
        extra = [n for n in a.names if n not in variables]
        if extra:
            raise DesignError(f"design: {a.where} varies {', '.join(extra)}, which is neither a design variable nor "
                              f"the envelope; fix it under params, or make it a design variable")
    if len(spec.cases) > 1:
        raise DesignError("design: the spec has several cases; a design is judged over one set of fixed inputs "
                          "(the envelope gives the loads)")


def parse_section(raw: Any, spec) -> DesignConfig:
    """The spec's `design:` section, checked (DesignError names the key and what is allowed)."""
    raw = _keys(raw, "design", SECTION_KEYS)
    if spec.envelope is None:
        raise DesignError("design: needs an envelope: section (the loads a design must handle)")
    if spec.scene != "cycle":
        raise DesignError(f"design: scene = {spec.scene!r}; a design is judged on work cycles (scene: cycle)")
    variables = _variables(raw.get("variables"), spec)
    _check_axes(spec, variables)
    cfg = DesignConfig(variables=variables, limits=_limits(raw.get("constraints")))
    cfg.objective = raw.get("objective", cfg.objective)
    if cfg.objective not in OBJECTIVES:
        raise DesignError(f"design.objective = {cfg.objective!r}: expected one of {', '.join(OBJECTIVES)}")
    opt = _keys(raw.get("optimizer"), "design.optimizer", OPTIMIZER_KEYS)
    cfg.seed = _int(opt.get("seed", cfg.seed), "design.optimizer.seed", 0)
    cfg.maxiter = _int(opt.get("maxiter", cfg.maxiter), "design.optimizer.maxiter", 1)
    cfg.popsize = _int(opt.get("popsize", cfg.popsize), "design.optimizer.popsize", 2)
    cfg.tol = _num(opt.get("tol", cfg.tol), "design.optimizer.tol", 0.0)
    cfg.refine = _int(opt.get("refine", cfg.refine), "design.optimizer.refine", 0)
    ver = _keys(raw.get("verify"), "design.verify", VERIFY_KEYS)
    if "sobol" in ver and "lhs" in ver:
        raise DesignError("design.verify: give one of sobol: N and lhs: N, not both")
    cfg.verify_method = "lhs" if "lhs" in ver else "sobol"
    cfg.verify_n = _int(ver.get(cfg.verify_method, cfg.verify_n), f"design.verify.{cfg.verify_method}", 1)
    cfg.verify_seed = _int(ver.get("seed", cfg.verify_seed), "design.verify.seed", 0)
    if cfg.verify_seed == spec.envelope.seed and cfg.verify_method == spec.envelope.method:
        raise DesignError(f"design.verify.seed = {cfg.verify_seed}: the same seed as the envelope's; the check "
                          f"needs a fresh sample, give another seed")
    cfg.compare = _compare(raw.get("compare"))
    cfg.output = raw.get("output", cfg.output)
    if not isinstance(cfg.output, str) or not cfg.output:
        raise DesignError(f"design.output = {cfg.output!r}: expected a directory")
    cfg.digits = _int(raw.get("digits", cfg.digits), "design.digits", 1)
    _prefer(raw, cfg)
    return cfg


def _prefer(raw: dict, cfg: DesignConfig) -> None:
    pref = raw.get("prefer")
    if pref is None:
        return
    shape = "{VARIABLE: min} or {VARIABLE: max}, a design variable"
    if not isinstance(pref, dict) or len(pref) != 1:
        raise DesignError(f"design.prefer = {pref!r}: expected {shape}")
    (name, way), = pref.items()
    if name not in cfg.variables or way not in ("min", "max"):
        raise DesignError(f"design.prefer = {pref!r}: expected {shape} (variables: {', '.join(cfg.variables)})")
    if cfg.objective != "max_min_margin":
        raise DesignError(f"design.prefer needs objective: max_min_margin (got {cfg.objective!r})")
    cfg.prefer = (name, way)
    cfg.within = _num(raw.get("within", cfg.within), "design.within", 0.0)
