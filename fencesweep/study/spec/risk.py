"""A risk spec (`fencesweep risk SPEC`; sweeps/README.md, Risk from a parcel mix): a parcel mix
(`population:`, spec/population.py), the elements (a grid of design parameters, e.g. B2 x K2,
or a list; `compare:` adds named ones), the operating points (t_c, v), fixed inputs (`params:`)
and the sampling (`risk:` p_max, the rounds, the cap, the limits). Every element meets every
operating point; a "unit" is one of those pairs. Orchestration only: no physics here.
"""
from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fencesweep.errors import SpecError
from fencesweep.model import params as P
from fencesweep.study.spec import population as PO
from fencesweep.study.spec.axes import axis_values, check_input, did_you_mean
from fencesweep.study.spec.design import RESIDUAL_MAX_DEFAULT, Limits

TOP_KEYS = ("description", "params", "elements", "compare", "operating", "population", "risk", "output")
RISK_KEYS = ("p_max", "confidence", "first", "growth", "cap", "limits", "samples")
LIMIT_KEYS = ("overload", "deflection_max", "residual_amplitude")
#: the parameters a risk spec may not fix or vary outside population: (a parcel's and its placement)
DRAWN = PO.SIZES + PO.PLACES


#: the share of alpha spent at the screening look (the plan's first): a unit far above p_max is
#: decided there even at this level (e.g. 9 breaks in 40 parcels against p_max = 0.01), and the
#: looks after it keep 95 % of alpha; 0.02 to 0.1 spend within 2 % of the same cycles on the
#: example map (benchmarks/risk.py)
SCREEN = 0.05


def zero_break_size(p_max: float, alpha: float) -> int:
    """The least n at which a unit with no failure in n samples is decided below p_max at level
    1 - alpha: its Clopper-Pearson upper end 1 - (alpha / 2)^(1/n) < p_max, n > ln(alpha / 2) / ln(1 - p_max)."""
    if p_max >= 1.0:
        return 1
    return math.floor(math.log(alpha / 2) / math.log1p(-p_max)) + 1


def look_plan(first: int, growth: float, cap: int, p_max: float, alpha: float) -> tuple:
    """(sizes, alphas): the looks n_1 < ... < n_K = cap and the level alpha_k spent at each (module
    docstring), summing to alpha. n_1 = first, the screening look, at SCREEN x alpha; then from
    n_2 = zero_break_size(p_max, alpha_2), or first x growth if that is larger, each size growth
    times the last (rounded up), and cap; alpha_k = (1 - SCREEN) alpha / 2^(k-1) for k >= 2, the
    last taking what is left."""
    if first >= cap:
        return [cap], [alpha]
    rest = (1 - SCREEN) * alpha
    sizes = [first, max(zero_break_size(p_max, rest / 2), math.ceil(first * growth))]
    while sizes[-1] < cap:
        sizes.append(math.ceil(sizes[-1] * growth))
    sizes = [n for n in sizes if n < cap] + [cap]
    alphas = [SCREEN * alpha] + [rest / 2 ** k for k in range(1, len(sizes) - 1)]
    return sizes, alphas + [rest - sum(alphas[1:])]


@dataclass
class RiskSpec:
    """A checked risk spec."""

    params: dict  # fixed inputs
    elements: list  # [{name: value}] of the grid or list, then of compare
    element_names: tuple  # the parameters an element sets
    grid: dict | None  # {name: [values]} when the elements are a grid (for the map)
    labels: list  # per element: its compare label, or None
    operating: list  # [{t_c: .., v: ..}]
    population: PO.Population
    p_max: float = 1e-3
    confidence: float = 0.95
    first: int = 40
    growth: float = 1.5
    cap: int = 4096
    limits: Limits = field(default_factory=Limits)
    samples: bool = False
    output: str | None = None
    description: str = ""
    path: str | None = None
    source: str = ""

    @property
    def units(self) -> list:
        """(element index, operating point index) of every unit, elements outermost."""
        return list(itertools.product(range(len(self.elements)), range(len(self.operating))))

    def plan(self, p_max: float | None = None) -> tuple:
        """(sizes, alphas): the looks at each unit and the level spent at each (look_plan): first,
        then from the size at which a unit without a failure can be decided below p_max (the
        spec's unless given), growth times the last, ..., cap."""
        return look_plan(self.first, self.growth, self.cap, self.p_max if p_max is None else p_max,
                         1 - self.confidence)

    def schedule(self) -> list:
        """The sample sizes at which each unit is looked at (plan)."""
        return self.plan()[0]

    def inputs(self, unit: int) -> dict:
        """The fixed inputs of a unit (params < element < operating point), without the parcel."""
        e, o = self.units[unit]
        return {**self.params, **self.elements[e], **self.operating[o]}

    def normalized(self) -> dict:
        lim = self.limits
        return {"params": self.params, "elements": self.elements, "labels": self.labels, "grid": self.grid,
                "operating": self.operating, "population": self.population.definition(),
                "risk": {"p_max": self.p_max, "confidence": self.confidence, "first": self.first,
                         "growth": self.growth, "cap": self.cap, "samples": self.samples,
                         "limits": {"overload": lim.overload, "deflection_max": lim.deflection_max or "dalpha_perm",
                                    "residual_amplitude": lim.residual_amplitude}}}

    @property
    def hash(self) -> str:
        return hashlib.sha256(json.dumps(self.normalized(), sort_keys=True, default=str).encode()).hexdigest()


def _num(value: Any, where: str, lo: float | None = None, hi: float | None = None) -> float:
    x = P.as_finite_number(value)
    if x is None or (lo is not None and x <= lo) or (hi is not None and x >= hi):
        rng = f" in ({lo}, {hi})" if hi is not None else f" > {lo}" if lo is not None else ""
        raise SpecError(f"{where} = {value!r}: expected a finite number{rng}")
    return x


def _whole(value: Any, where: str, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise SpecError(f"{where} = {value!r}: expected a whole number >= {least}")
    return value


def _mapping(raw: Any, where: str, allowed: tuple) -> dict:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise SpecError(f"{where} = {raw!r}: expected a mapping with keys among {', '.join(allowed)}")
    for k in raw:
        if k not in allowed:
            raise SpecError(f"{where}.{k}: unknown key{did_you_mean(k, allowed)} (allowed: {', '.join(allowed)})")
    return raw


def _setting(name: str, value: Any, where: str) -> Any:
    if name in DRAWN:
        raise SpecError(f"{where}: {name} is drawn from the population (population.{name}); it cannot be set here")
    if name not in P.NAMES:
        raise SpecError(f"{where}: unknown parameter {name!r}{did_you_mean(name, P.NAMES)} (parameters of "
                        f"docs/model.md §12)")
    return check_input(name, value, where)


def _elements(raw: Any, params: dict) -> tuple:
    """(elements, names, grid) from `elements:` ({NAME: axis} crossed, or a list of {NAME: value})."""
    if isinstance(raw, list) and raw:
        out = []
        for k, entry in enumerate(raw):
            if not isinstance(entry, dict) or not entry:
                raise SpecError(f"elements[{k}] = {entry!r}: expected a mapping of parameters, e.g. {{B2: 72, K2: 570}}")
            out.append({n: _setting(n, v, f"elements[{k}].{n}") for n, v in entry.items()})
        names = tuple(dict.fromkeys(n for e in out for n in e))
        return out, names, None
    if not isinstance(raw, dict) or not raw:
        raise SpecError(f"elements = {raw!r}: expected a grid {{B2: axis, K2: axis}} (axes as in a sweep spec) or a "
                        f"list of elements [{{B2: 72, K2: 570}}, ...]")
    grid = {}
    for name, axis in raw.items():
        if name in DRAWN or name not in P.NAMES:
            _setting(name, None, f"elements.{name}")  # names what is wrong
        if name in params:
            raise SpecError(f"elements.{name}: {name} is also fixed in params; set it in one place")
        grid[name] = axis_values(name, axis if isinstance(axis, (dict, list)) else [axis], f"elements.{name}")
    names = tuple(grid)
    return [dict(zip(names, vals)) for vals in itertools.product(*grid.values())], names, grid


def _compare(raw: Any, names: tuple) -> tuple:
    if raw is None:
        return [], []
    if not isinstance(raw, dict):
        raise SpecError(f"compare = {raw!r}: expected a mapping LABEL: {{B2: .., K2: ..}} (elements to mark and report)")
    out, labels = [], []
    for label, entry in raw.items():
        if not isinstance(entry, dict) or set(entry) - set(names) or not entry:
            raise SpecError(f"compare.{label} = {entry!r}: expected a mapping of the elements' parameters "
                            f"({', '.join(names)})")
        out.append({n: _setting(n, v, f"compare.{label}.{n}") for n, v in entry.items()})
        labels.append(str(label))
    return out, labels


def _operating(raw: Any) -> list:
    if raw is None:
        return [{}]
    entries = [raw] if isinstance(raw, dict) else raw
    if not isinstance(entries, list) or not entries:
        raise SpecError(f"operating = {raw!r}: expected an operating point {{t_c: 1.36, v: 2.0}} or a list of them")
    out = []
    for k, entry in enumerate(entries):
        if not isinstance(entry, dict) or set(entry) - {"t_c", "v"}:
            raise SpecError(f"operating[{k}] = {entry!r}: expected a mapping of t_c [s] and v [m/s]")
        out.append({n: check_input(n, v, f"operating[{k}].{n}") for n, v in entry.items()})
    return out


def _limits(raw: Any) -> Limits:
    raw = _mapping(raw, "risk.limits", LIMIT_KEYS)
    dmax = raw.get("deflection_max", "dalpha_perm")
    dmax = None if dmax == "dalpha_perm" else _num(dmax, "risk.limits.deflection_max [rad] (or dalpha_perm)", 0.0)
    res = _num(raw.get("residual_amplitude", RESIDUAL_MAX_DEFAULT), "risk.limits.residual_amplitude [rad]", 0.0)
    return Limits(True, _num(raw.get("overload", 1.0), "risk.limits.overload", 0.0), dmax, res)


def _risk(raw: Any, sp: RiskSpec) -> None:
    raw = _mapping(raw, "risk", RISK_KEYS)
    sp.p_max = _num(raw.get("p_max", 1e-3), "risk.p_max", 0.0, 1.0)
    sp.confidence = _num(raw.get("confidence", 0.95), "risk.confidence", 0.0, 1.0)
    sp.first = _whole(raw.get("first", 40), "risk.first", 1)
    sp.growth = _num(raw.get("growth", 1.5), "risk.growth", 1.0)
    sp.cap = _whole(raw.get("cap", 4096), "risk.cap", 1)
    if sp.cap < sp.first:
        raise SpecError(f"risk.cap = {sp.cap}: must be >= risk.first = {sp.first}")
    if len(sp.schedule()) > 40:
        raise SpecError(f"risk: {len(sp.schedule())} looks from first = {sp.first} to cap = {sp.cap}; at most 40 "
                        f"(raise first or growth)")
    sp.limits = _limits(raw.get("limits"))
    sp.samples = raw.get("samples", False)
    if not isinstance(sp.samples, bool):
        raise SpecError(f"risk.samples = {sp.samples!r}: expected true (also write every cycle) or false")


def parse(data: Any, source: str = "", path: str | None = None) -> RiskSpec:
    """A risk spec from its parsed YAML; SpecError naming the key, the value and what is allowed."""
    data = _mapping(data, "the risk spec", TOP_KEYS) if isinstance(data, dict) else data
    if not isinstance(data, dict):
        raise SpecError(f"a risk spec is a mapping with keys {', '.join(TOP_KEYS)}; got {type(data).__name__}")
    for key in ("elements", "population"):
        if key not in data:
            raise SpecError(f"the risk spec has no {key}: section (sweeps/risk.yaml is an example)")
    params = {n: _setting(n, v, f"params.{n}") for n, v in _mapping(data.get("params"), "params", P.NAMES).items()}
    elements, names, grid = _elements(data["elements"], params)
    extra, labels = _compare(data.get("compare"), names)
    operating = _operating(data.get("operating"))
    for o in operating:
        for n in o:
            if n in params or n in names:
                raise SpecError(f"operating: {n} is also set in params or elements; set it in one place")
    try:
        base = P.resolve("cycle", **params)
    except P.ParameterError as exc:
        raise SpecError(f"params: {exc}") from None
    pop = PO.parse(data["population"], base, Path(path).parent if path else None)
    sp = RiskSpec(params, elements + extra, names, grid, [None] * len(elements) + labels, operating, pop,
                  output=data.get("output"), description=str(data.get("description", "")), path=path, source=source)
    _risk(data.get("risk"), sp)
    for u in range(len(sp.units)):
        _check_unit(sp, u)
    return sp


def _check_unit(sp: RiskSpec, u: int) -> None:
    try:
        P.resolve("cycle", **sp.inputs(u))
    except P.ParameterError as exc:
        e, o = sp.units[u]
        raise SpecError(f"element {sp.elements[e]} at {sp.operating[o] or 'the params'}: {exc}") from None


def loads(text: str, path: str | None = None) -> RiskSpec:
    import yaml

    from fencesweep.study.spec.file import YamlLoader

    try:
        data = yaml.load(text, Loader=YamlLoader)
    except yaml.YAMLError as exc:
        raise SpecError(f"{path or 'spec'}: not valid YAML: {exc}") from None
    return parse(data, source=text, path=path)


def load(path: Any) -> RiskSpec:
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise SpecError(f"cannot read spec {str(path)!r}: {exc.strerror}") from None
    return loads(text, path=str(path))
