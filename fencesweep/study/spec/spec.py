"""Sweep specifications: YAML -> a checked, hashable list of scenes (sweeps/README.md).

A spec names one `scene`, a base parameter set (a named `case` and/or `params`), and the
axes that vary: `grid` (Cartesian product), `zip` (axes that vary together) and `cases`
(named or explicit parameter sets crossed with the rest). Scene number i is decoded from
i by mixed radix (cases outermost, then the axes in the order written, the last fastest),
so no list of scenes is ever held in memory. An axis's values are expanded and checked by
spec/axes.py; `parse` reads the spec's sections but `design:` and `sensitivity:` (spec/file.py reads
a whole spec from YAML).

Everything wrong in a spec raises `SpecError` (a params.ParameterError) naming the key,
the value and what is allowed. Values are checked one by one when the spec is read;
combinations (an invalid start, docs/model.md §1) when every scene is resolved, before any
run (see plan.make_plan).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from typing import Any

from fencesweep.model import params as P
from fencesweep.study.spec import envelope as E
from fencesweep.study.spec.axes import Axis, SpecError, axis_values, check_input, did_you_mean, round_value

TOP_KEYS = ("scene", "case", "params", "grid", "zip", "cases", "output", "invalid", "chunk_size",
            "description", "loads", "envelope", "design", "sensitivity")
INVALID_POLICIES = ("error", "skip")


@dataclass
class Spec:
    """A checked sweep spec: its scene, base parameters, axes and cases (and its sections)."""

    scene: str
    case: str | None
    params: dict
    axes: list
    cases: list  # each {"case": name or None, "params": {...}, "where": "cases[k]"}
    output: str | None = None
    invalid: str = "error"
    chunk_size: int | None = None
    description: str = ""
    source: str = ""
    path: str | None = None
    loads: list | None = None  # scene stream: one load per cycle (params.resolve_loads), for every scene
    envelope: Any = None  # envelope.Envelope: its loads are the innermost axis
    design: Any = None  # design.DesignConfig: constraints, objective, variables (fencesweep design)
    sensitivity: Any = None  # sensitivity.parse_section: assumed inputs' ranges (fencesweep sensitivity)
    whole: Any = None  # a piece of a larger spec (spec/pieces.py): that spec
    offset: int = 0  # a piece's first scene, numbered in `whole`
    _shape: tuple = field(default=(), repr=False)

    def __post_init__(self):
        self._shape = (len(self.cases),) + tuple(len(a) for a in self.axes)

    # ---- size and decoding -----------------------------------------------------------
    @property
    def n_scenes(self) -> int:
        return math.prod(self._shape)

    def shape_text(self) -> str:
        parts = [f"{len(self.cases)} case{'s' if len(self.cases) != 1 else ''}"] if len(self.cases) > 1 else []
        for a in self.axes:
            parts.append(f"{'+'.join(a.names)} {len(a)}")
        return " x ".join(parts) if parts else "1 scene"

    def decode(self, i: int) -> tuple:
        """Scene number -> (case index, value index per axis); the last axis varies fastest."""
        if not 0 <= i < self.n_scenes:
            raise IndexError(i)
        idx = []
        for n in reversed(self._shape):
            i, r = divmod(i, n)
            idx.append(r)
        idx.reverse()
        return idx[0], tuple(idx[1:])

    def inputs(self, i: int) -> tuple:
        """Scene number -> (named case or None, explicit inputs incl. derived ones like Psi)."""
        ci, picks = self.decode(i)
        entry = self.cases[ci]
        over = dict(self.params)
        over.update(entry["params"])
        for axis, k in zip(self.axes, picks):
            over.update(zip(axis.names, axis.values[k]))
        return entry["case"] if entry["case"] is not None else self.case, over

    def describe(self, i: int) -> str:
        """A short label of scene i for messages: its case and axis values (numbered in the
        whole spec, for a piece)."""
        ci, picks = self.decode(i)
        entry = self.cases[ci]
        bits = []
        case = entry["case"] if entry["case"] is not None else self.case
        if len((self.whole or self).cases) > 1:
            bits.append(entry["where"] + (f" ({case})" if case else ""))
        elif case:
            bits.append(f"case {case}")
        for axis, k in zip(self.axes, picks):
            bits += [f"{n} = {v!r}" for n, v in zip(axis.names, axis.values[k])]
        return f"scene #{self.offset + i}" + (f" ({', '.join(bits)})" if bits else "")

    def resolve(self, i: int) -> dict:
        """Scene number -> the resolved parameter set of params.resolve (raises ParameterError)."""
        case, over = self.inputs(i)
        return resolve_inputs(self.scene, case, over, self.loads)

    def load_base(self) -> dict:
        """The envelope's placing and checking of loads for this spec (spec.load_base)."""
        return load_base(self.scene, self.case, self.params, self.cases)

    # ---- identity ----------------------------------------------------------------------
    def normalized(self) -> dict:
        """The resolved spec: every axis as its explicit list of values (JSON-able)."""
        return {
            "scene": self.scene,
            "case": self.case,
            "params": dict(self.params),
            "axes": [{"names": list(a.names), "values": [list(v) for v in a.values], "from": a.where}
                     for a in self.axes],
            "cases": [{"case": c["case"], "params": dict(c["params"])} for c in self.cases],
            "invalid": self.invalid,
            "chunk_size": self.chunk_size,
        } | ({"loads": self.loads} if self.loads is not None else {})

    @property
    def hash(self) -> str:
        """sha256 of the resolved spec (not of `output`, `description` or YAML formatting)."""
        text = json.dumps(self.normalized(), sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()


def resolve_inputs(scene: str, case: str | None, over: dict, loads: list | None = None) -> dict:
    """params.resolve, plus the derived input Psi (docs/model.md §3): K2 = (B2 / (2 Psi))^2 / I2."""
    if loads is not None:
        over = dict(over, loads=loads)
    if "Psi" not in over:
        return P.resolve(scene, case, **over)
    over = dict(over)
    psi = over.pop("Psi")
    if "K2" in over:  # caught when the spec is read; kept for direct callers
        raise SpecError(f"K2 = {over['K2']!r} and Psi = {psi!r} are both set: Psi fixes K2; set one of them")
    base = P.resolve(scene, case, **over)
    K2 = round_value((base["B2"] / (2.0 * psi)) ** 2 / base["I2"])  # Psi = B2 / (2 sqrt(K2 I2)), docs/model.md §3
    try:
        return P.resolve(scene, case, **over, K2=K2)
    except P.ParameterError as exc:
        raise P.ParameterError(f"Psi = {psi!r} with B2 = {base['B2']!r}, I2 = {base['I2']:.6g} gives "
                               f"K2 = {K2:.6g}: {exc}") from None


def psi_of(vals: dict) -> float:
    """Relative damping Psi = B2 / (2 sqrt(K2 I2)) of a resolved set (NaN when K2 I2 = 0)."""
    k = vals["K2"] * vals["I2"]
    return vals["B2"] / (2.0 * math.sqrt(k)) if k > 0 else math.nan


def _mapping(raw: Any, where: str, what: str) -> dict:
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise SpecError(f"{where} = {raw!r}: expected a mapping of {what}")
    return raw


def _check_case_name(name: Any, where: str) -> str:
    if not isinstance(name, str) or name not in P.CASES:
        raise SpecError(f"{where} = {name!r} is not a named case{did_you_mean(name, P.CASES)} "
                        f"(named cases: {', '.join(P.CASES)})")
    return name


def parse(data: Any, source: str = "", path: str | None = None) -> Spec:
    """A spec from its parsed YAML (a dict), all but its `design:` and `sensitivity:` sections,
    which their modules parse (specfile.parse reads a whole spec). Raises SpecError on anything
    wrong."""
    scene, case = _scene_and_case(data)
    base = {}
    for name, value in _mapping(data.get("params"), "params", "parameter: value").items():
        base[name] = check_input(name, value, f"params.{name}")
    origin: dict[str, str] = {}  # parameter -> where it varies
    axes = _grid_axes(data, base, origin) + _zip_axes(data, base, origin)
    cases = _cases(data.get("cases"), case, origin)
    _check_k2_or_psi(base, cases, origin)
    output, invalid, chunk, desc = _options(data)
    env = _envelope(data.get("envelope"), scene, case, base, cases, origin)
    if env is not None:
        axes.append(Axis(env.names, tuple(env.loads), "envelope"))  # innermost: a point's loads together
    sp = Spec(scene=scene, case=case, params=base, axes=axes, cases=cases, output=output,
              invalid=invalid, chunk_size=chunk, description=desc, source=source, path=path,
              loads=_loads(data.get("loads"), scene), envelope=env)
    return sp


def _scene_and_case(data: Any) -> tuple:
    """The spec's top level: its keys, its scene and its named case (or None)."""
    if not isinstance(data, dict):
        raise SpecError(f"a spec is a mapping with keys {', '.join(TOP_KEYS)}; got {type(data).__name__}")
    for key in data:
        if key not in TOP_KEYS:
            raise SpecError(f"unknown key {key!r} at the top of the spec{did_you_mean(key, TOP_KEYS)} "
                            f"(allowed: {', '.join(TOP_KEYS)})")
    scene = data.get("scene", "cycle")
    if scene not in P.SCENES:
        raise SpecError(f"scene = {scene!r} is not allowed{did_you_mean(scene, P.SCENES)} (scene must be one "
                        f"of {', '.join(P.SCENES)})")
    case = data.get("case")
    if case is not None:
        case = _check_case_name(case, "case")
    return scene, case


def _claim(name: str, where: str, base: dict, origin: dict) -> None:
    """Parameter `name` varies at `where`: it may vary on one axis only and not also be fixed."""
    if name in origin:
        raise SpecError(f"{where}: {name} already varies in {origin[name]}; a parameter can be on one "
                        f"axis only (use zip to vary parameters together)")
    if name in base:
        raise SpecError(f"{where}: {name} is also fixed in params ({name} = {base[name]!r}); "
                        f"remove one of them")
    origin[name] = where


def _grid_axes(data: dict, base: dict, origin: dict) -> list:
    """`grid:`, one axis per parameter."""
    axes = []
    for name, raw in _mapping(data.get("grid"), "grid", "parameter: axis").items():
        where = f"grid.{name}"
        values = axis_values(name, raw, where)
        _claim(name, where, base, origin)
        axes.append(Axis((name,), tuple((v,) for v in values), where))
    return axes


def _zip_axes(data: dict, base: dict, origin: dict) -> list:
    """`zip:`, one axis per group of parameters that vary together."""
    zraw = data.get("zip")
    groups = [] if zraw is None else ([zraw] if isinstance(zraw, dict) else zraw)
    if not isinstance(groups, list):
        raise SpecError(f"zip = {zraw!r}: expected a mapping parameter: axis (or a list of such mappings)")
    axes = []
    for g, group in enumerate(groups):
        gwhere = "zip" if isinstance(zraw, dict) else f"zip[{g}]"
        group = _mapping(group, gwhere, "parameter: axis")
        if not group:
            raise SpecError(f"{gwhere} is empty: a zip group needs at least one parameter: axis")
        cols = {}
        for name, raw in group.items():
            where = f"{gwhere}.{name}"
            cols[name] = axis_values(name, raw, where)
            _claim(name, where, base, origin)
        lengths = {n: len(v) for n, v in cols.items()}
        if len(set(lengths.values())) > 1:
            raise SpecError(f"{gwhere}: axes that vary together must have the same length; got "
                            + ", ".join(f"{n}: {k}" for n, k in lengths.items()))
        names = tuple(cols)
        values = tuple(zip(*(cols[n] for n in names)))
        if len(set(values)) != len(values):
            raise SpecError(f"{gwhere}: two positions repeat the same values; every position must differ")
        axes.append(Axis(names, values, gwhere))
    return axes


def _cases(craw: Any, case: str | None, origin: dict) -> list:
    """`cases:`, each a named case or a mapping of parameters; one base entry without it."""
    if craw is None:
        return [{"case": None, "params": {}, "where": "base"}]
    if not isinstance(craw, list) or not craw:
        raise SpecError(f"cases = {craw!r}: expected a non-empty list of named cases "
                        f"({', '.join(P.CASES)}) or mappings of parameters")
    cases = [_case_entry(entry, f"cases[{k}]", case, origin) for k, entry in enumerate(craw)]
    seen = {}
    for c in cases:
        ident = json.dumps([c["case"], c["params"]], sort_keys=True)
        if ident in seen:
            raise SpecError(f"{c['where']} repeats {seen[ident]}; every entry of cases must differ")
        seen[ident] = c["where"]
    return cases


def _case_entry(entry: Any, where: str, case: str | None, origin: dict) -> dict:
    """One entry of `cases:`."""
    if isinstance(entry, str):
        entry = {"case": entry}
    if not isinstance(entry, dict):
        raise SpecError(f"{where} = {entry!r}: expected a named case ({', '.join(P.CASES)}) or a "
                        f"mapping of parameters (optionally with case: NAME)")
    ecase = entry.get("case")
    if ecase is not None:
        ecase = _check_case_name(ecase, f"{where}.case")
        if case is not None:
            raise SpecError(f"{where}.case = {ecase!r} conflicts with the top-level case = {case!r}: "
                            f"name the case in one place")
    eparams = {}
    for name, value in entry.items():
        if name == "case":
            continue
        if name in origin:
            raise SpecError(f"{where}.{name}: {name} also varies in {origin[name]}; remove one of them")
        eparams[name] = check_input(name, value, f"{where}.{name}")
    return {"case": ecase, "params": eparams, "where": where}


def _check_k2_or_psi(base: dict, cases: list, origin: dict) -> None:
    """K2 and Psi both given for the same scenes is an error."""
    for c in cases:
        where_of = {n: f"params.{n}" for n in base}
        where_of.update({n: f"{c['where']}.{n}" for n in c["params"]})
        where_of.update(origin)
        if "K2" in where_of and "Psi" in where_of:
            raise SpecError(f"K2 (in {where_of['K2']}) and Psi (in {where_of['Psi']}) are both set: "
                            f"Psi fixes K2 = (B2 / (2 Psi))^2 / I2; set one of them")


def _options(data: dict) -> tuple:
    """(output, invalid, chunk_size, description), checked."""
    output = data.get("output")
    if output is not None and (not isinstance(output, str) or not output.endswith(".parquet")):
        raise SpecError(f"output = {output!r}: expected a path ending in .parquet")
    invalid = data.get("invalid", "error")
    if invalid not in INVALID_POLICIES:
        raise SpecError(f"invalid = {invalid!r} is not allowed{did_you_mean(invalid, INVALID_POLICIES)} "
                        f"(one of {', '.join(INVALID_POLICIES)}; skip drops the scenes that params.resolve "
                        f"rejects as a combination, e.g. an invalid start, and reports them)")
    chunk = data.get("chunk_size")
    if chunk is not None and (isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1):
        raise SpecError(f"chunk_size = {chunk!r}: expected a whole number >= 1 (model runs per chunk)")
    desc = data.get("description") or ""
    if not isinstance(desc, str):
        raise SpecError(f"description = {desc!r}: expected text")
    return output, invalid, chunk, desc


def _envelope(raw: Any, scene: str, case: str | None, base: dict, cases: list, origin: dict):
    """The spec's `envelope:` (fencesweep.study.spec.envelope), its loads checked against every entry of cases."""
    if raw is None:
        return None
    if scene != "cycle":  # a stream's table has a row per cycle: its per-design-point judge is not written yet
        raise SpecError(f"envelope is given with scene = {scene!r}: an envelope of loads needs scene: cycle "
                        f"(for loads back to back, fencesweep design runs each element's loads as a stream)")
    taken = dict(origin)
    taken.update({n: f"params.{n}" for n in base})
    for c in cases:
        taken.update({n: f"{c['where']}.{n}" for n in c["params"]})
    if "P_max" in origin and isinstance(raw, dict) and raw.get("dP") == E.ACROSS:
        raise SpecError(f"envelope.dP = across needs one belt width, but P_max varies in {origin['P_max']}")
    try:
        return E.parse(raw, load_base(scene, case, base, cases), taken)
    except P.ParameterError as exc:
        raise SpecError(str(exc)) from None


def load_base(scene: str, case: str | None, base: dict, cases: list) -> dict:
    """What an envelope's loads are placed and checked against: "defaults", the fixed inputs of
    the first entry of cases on the §12 defaults (P_max, L, A, phi0 for dP: across), and "check",
    a function of a load that raises ParameterError when it cannot start in some entry of cases."""
    first = cases[0]
    defaults = {**P.defaults(), **P.CASES.get(first["case"] or case or "", {}), **base, **first["params"]}

    def check(load: dict) -> None:
        for c in cases:
            resolve_inputs(scene, c["case"] or case, {**base, **c["params"], **load})

    return {"defaults": defaults, "check": check}


def _loads(raw: Any, scene: str) -> list | None:
    """The spec's `loads` (scene stream, docs/model.md §14): a list, one load per cycle, each a named
    case or a mapping of the load's parameters; checked entry by entry here, against each
    scene's parameters when the scenes are resolved."""
    if raw is None:
        return None
    if scene != "stream":
        raise SpecError(f"loads is given with scene = {scene!r}: a list of loads belongs to scene: stream only")
    if not isinstance(raw, list) or not raw:
        raise SpecError(f"loads = {raw!r}: expected a non-empty list, one load per cycle, each a named case "
                        f"({', '.join(P.CASES)}) or a mapping of {', '.join(P.LOAD_NAMES)}")
    try:
        for k, entry in enumerate(raw):
            P._load_entry(k, entry)
    except P.ParameterError as exc:
        raise SpecError(str(exc)) from None
    return [dict(e) if isinstance(e, dict) else e for e in raw]
