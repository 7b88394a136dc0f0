"""Adaptive maps: the maps of a spec, and the scenes of their elements.

Two kinds of spec make maps:

* an envelope study (an `envelope:` section): an element is a design point, judged over the
  envelope's loads (its scenes), feasible when it keeps every constraint of the spec's design
  section (envelope.spec_limits) for every load;
* a grid with cases (a `cases:` list, or one named `case:`), scene cycle, no envelope: an
  element is one scene, "ok" when its load is scraped with overload <= 1 and deflection_max
  within dalpha_perm (CASE_LIMITS), one map per case.

The spec's other axes are the maps' axes when their values are numbers and they have two or
more (an axis of choices, e.g. drive, or of one value makes a map per value instead); each entry
of cases makes its own maps. Elements are numbered as adaptive.Grid numbers them: map x size +
the raveled index over the numeric axes; a map is (case, values of the other axes).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fencesweep.errors import UsageError
from fencesweep.study.adaptive import refine as A
from fencesweep.study.design import judge as J
from fencesweep.study.spec import design as DS
from fencesweep.study.spec import spec as S

#: the verdict of a grid with cases: scraped, overload <= 1, deflection_max <= dalpha_perm
CASE_LIMITS = DS.Limits(scraped=True, overload=1.0, deflection_max=None, residual_amplitude=None)


def _numeric(axis) -> bool:
    return len(axis) >= 2 and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                                  for vals in axis.values for v in vals)


@dataclass
class Layout:
    """The maps of a spec: which axes are refined, which make maps, the scenes of an element."""

    spec: S.Spec
    mode: str  # "envelope" | "cases"
    limits: DS.Limits
    refined: list  # positions in spec.axes of the maps' axes (numeric, >= 2 values)
    splitting: list  # positions in spec.axes of the other non-envelope axes (a map per value)
    grid: A.Grid = field(init=False)
    n_loads: int = field(init=False)

    def __post_init__(self):
        self.n_loads = len(self.spec.envelope.loads) if self.mode == "envelope" else 1
        self._map_shape = (len(self.spec.cases),) + tuple(len(self.spec.axes[p]) for p in self.splitting)
        self.grid = A.Grid(int(np.prod(self._map_shape)), tuple(len(self.spec.axes[p]) for p in self.refined))

    @property
    def n_full(self) -> int:
        """Cycles of the full grid (every element, every load)."""
        return self.grid.n_elements * self.n_loads

    def scenes(self, elements: np.ndarray, loads: np.ndarray | None = None) -> np.ndarray:
        """Scene numbers of (element, load) pairs (loads None: load 0, a grid with cases)."""
        elements = np.asarray(elements, dtype=np.int64)
        maps, idx = self.grid.index(elements)
        mi = np.unravel_index(maps, self._map_shape)
        full = [None] * (1 + len(self.spec.axes))
        full[0] = mi[0]
        for k, p in enumerate(self.splitting):
            full[1 + p] = mi[1 + k]
        for k, p in enumerate(self.refined):
            full[1 + p] = idx[:, k]
        if self.mode == "envelope":
            full[-1] = np.zeros(len(elements), dtype=np.int64) if loads is None else np.asarray(loads, dtype=np.int64)
        return np.ravel_multi_index(tuple(full), self.spec._shape).astype(np.int64)

    def element_of(self, scenes: np.ndarray) -> tuple:
        """(element, load) of scene numbers."""
        full = np.unravel_index(np.asarray(scenes, dtype=np.int64), self.spec._shape)
        maps = np.ravel_multi_index((full[0],) + tuple(full[1 + p] for p in self.splitting), self._map_shape)
        idx = np.stack([full[1 + p] for p in self.refined], axis=1)
        loads = full[-1] if self.mode == "envelope" else np.zeros(len(maps), dtype=np.int64)
        return self.grid.ids(maps, idx), np.asarray(loads, dtype=np.int64)

    def columns(self) -> dict:
        """The columns that name every element (in element order): the case (its name and the
        parameters its entry sets, when the spec has several) and the values of every other axis."""
        spec = self.spec
        cases = []
        for c in spec.cases:
            row = {"case": c["case"] or spec.case} if (len(spec.cases) > 1 or self.mode == "cases") else {}
            cases.append(row)
        params = list(dict.fromkeys(n for c in spec.cases for n in c["params"])) if len(spec.cases) > 1 else []
        cols: dict = {k: [] for k in list(cases[0]) + params}
        axes = [a for a in spec.axes if a.where != "envelope"]
        for a in axes:
            for n in a.names:
                cols[n] = []
        for e in range(self.grid.n_elements):
            scene = int(self.scenes(np.array([e]))[0])
            ci, picks = spec.decode(scene)
            for k, v in cases[ci].items():
                cols[k].append(v)
            for n in params:
                cols[n].append(spec.cases[ci]["params"].get(n))
            for a, pick in zip(spec.axes, picks):
                if a.where != "envelope":
                    for n, v in zip(a.names, a.values[pick]):
                        cols[n].append(v)
        return cols


def layout(spec: S.Spec) -> Layout:
    """The maps of `spec`; UsageError (one line: the value and what is allowed) when the spec
    makes none."""
    name = spec.path or "the spec"
    if spec.envelope is not None:
        mode, limits = "envelope", J.spec_limits(spec)
    elif spec.scene == "cycle" and (len(spec.cases) > 1 or spec.cases[0]["case"] or spec.case):
        mode, limits = "cases", CASE_LIMITS
    else:
        has = f"scene = {spec.scene!r}, " + ("no envelope" if spec.scene != "cycle" else "no envelope and no cases")
        raise UsageError(f"--adaptive needs an envelope study (an envelope: section) or a grid of scene: cycle with "
                         f"cases (cases: [...] or case: NAME); {name} has {has}")
    if spec.invalid != "error":
        raise UsageError(f"invalid = {spec.invalid!r} in {name}: --adaptive needs every scene of the grid "
                         f"(invalid: error); a map with holes has no neighbours to infer from")
    axes = [p for p, a in enumerate(spec.axes) if a.where != "envelope"]
    refined = [p for p in axes if _numeric(spec.axes[p])]
    if not refined:
        raise UsageError(f"--adaptive needs at least one axis of two or more numbers to refine (e.g. grid: B2, K2); "
                         f"{name} has {', '.join(spec.axes[p].where for p in axes) or 'none'}")
    return Layout(spec, mode, limits, refined, [p for p in axes if p not in refined])

