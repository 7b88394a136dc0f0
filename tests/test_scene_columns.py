"""A spec's scenes as whole columns (fencesweep/study/spec/scenes.py) against params.resolve, scene by
scene: the plan (which scenes share a model run, their numbering, the skipped ones) and the
table's parameter columns must be what resolving every scene alone gives."""
from __future__ import annotations

import math
import random

import numpy as np
import pytest

from fencesweep.model import params as P
from fencesweep.study.spec import spec as S
from fencesweep.study.spec import scenes as SC
from fencesweep.study.spec.scenes import Scenes
from fencesweep.study.store import table as store
from fencesweep.study.store.columns import numpy_column
from fencesweep.study.sweep import plan as PL
from helpers import SWEEP_SPEC, load_spec

#: starting points for the ALONE check: scenes, drives, laws, profiles, cases, one invalid start
_BASES = [
    ("cycle", None, {}),
    ("cycle", "small_far", {"drive": "rigid"}),
    ("cycle", "long_near", {"drive": "free", "contact_law": "linear", "profile": "harmonic"}),
    ("cycle", None, {"dP": 0.65, "A": 0.1, "L": 0.7}),
    ("cycle", None, {"integrator": "rk4", "I2": 3.0}),
    ("cycle", None, {"R_s": 1.3}),  # invalid: past the fence
    ("impact", None, {"drive": "rigid"}),
    ("impact", None, {}),
    ("freefall", None, {"contact_law": "linear"}),
]


def _value(p: P.Param, rng: random.Random) -> float:
    lo = p.lo if math.isfinite(p.lo) else -10.0
    hi = min(p.hi, lo + 1e4) if math.isfinite(p.hi) else lo + 10.0
    x = rng.uniform(lo, hi)
    return x if x > lo or not p.lo_open else (lo + hi) / 2


def _resolve(scene, case, over):
    try:
        return P.resolve(scene, case, **over)
    except P.ParameterError as exc:
        return str(exc)


@pytest.mark.parametrize("name", sorted(P.ALONE))
def test_alone_parameters_are_only_checked_and_copied(name):
    """params.ALONE's claim: changing one of them changes resolve's result in that value only,
    and never whether (or why) the set is refused."""
    rng = random.Random(name)
    for scene, case, over in _BASES:
        values = [_value(P.BY_NAME[name], rng) for _ in range(4)] + [P.BY_NAME[name].lo if not
                                                                     P.BY_NAME[name].lo_open else 1e-9]
        outs = [_resolve(scene, case, dict(over, **{name: x})) for x in values if math.isfinite(x)]
        for out, x in zip(outs, values):
            ref = outs[0]
            if isinstance(ref, str) or isinstance(out, str):
                assert out == ref, (scene, over, name, x)
            else:
                assert {k: v for k, v in out.items() if k != name} == {k: v for k, v in ref.items() if k != name}
                assert out[name] == x


def _scalar_plan(spec: S.Spec):
    """What planning gave scene by scene: resolve each, group by model key in order of first
    appearance; (row_model, first_row, skipped, first error)."""
    keys, row_model, first_row, error = {}, [], [], None
    for i in range(spec.n_scenes):
        try:
            vals = spec.resolve(i)
        except P.ParameterError as exc:
            row_model.append(-1)
            error = error or f"{spec.describe(i)}: {exc}"
            continue
        key = P.model_key(vals)
        if key not in keys:
            keys[key] = len(keys)
            first_row.append(i)
        row_model.append(keys[key])
    return np.array(row_model), np.array(first_row), row_model.count(-1), error


_SPECS = {
    "sweep": SWEEP_SPEC,
    "psi": """
        params: {drive: flexible}
        grid: {B2: [20, 72, 140], Psi: [0.3, 0.7]}
        cases: [small_far, long_near]
    """,
    "zip_partly_used": """
        params: {drive: rigid}
        zip: {B2: [10, 20, 30, 40], v: [1.5, 2.0, 2.5, 3.0]}
        grid: {K2: [500, 600], m2: [4, 5]}
        cases: [small_far, {drive: flexible}]
    """,
    "skipped_starts": """
        grid: {dP: [0, 0.5, 0.7], B2: [50, 60], step_factor: [1.0, 0.5]}
        invalid: skip
    """,
    "envelope_like": """
        params: {drive: flexible}
        grid: {B2: [0, 100, 200], K2: [100, 600]}
        zip: {L: [0.2, 0.5, 0.7], A: [0.1, 0.2, 0.15], m1: [5, 10, 15], dP: [0, 0.3, 0.5]}
        cases: [{drive: rigid}, {drive: flexible, contact_law: linear, k_lin: 2.0e6}]
    """,
    "impact": """
        scene: impact
        grid: {drive: [rigid, free, flexible], m2: [4, 5], w: [1, 2, 3]}
    """,
}


@pytest.mark.parametrize("name", sorted(_SPECS))
def test_plan_on_columns_equals_planning_scene_by_scene(name):
    spec = load_spec(_SPECS[name])
    row_model, first_row, skipped, _ = _scalar_plan(spec)
    plan = PL.make_plan(spec)
    assert np.array_equal(plan.row_model, row_model)
    assert np.array_equal(plan.first_row, first_row)
    assert plan.skipped == skipped
    for key, m in plan.variants.items():  # each variant's first scene
        first = next(i for i in range(spec.n_scenes) if row_model[i] >= 0 and
                     (spec.scene,) + tuple(spec.resolve(i)[c] for c in SC._CHOICES) == key)
        assert m == row_model[first]


@pytest.mark.parametrize("name", sorted(_SPECS))
def test_parameter_columns_equal_resolving_each_scene(name):
    spec = load_spec(_SPECS[name])
    rows = np.flatnonzero(_scalar_plan(spec)[0] >= 0)
    cols = Scenes(spec).columns(rows[::-1])  # any order
    for col, typ in store.param_columns():
        got = cols[col].to_pylist()
        want = [S.psi_of(v) if col == "Psi" else v[col] for v in (spec.resolve(int(i)) for i in rows[::-1])]
        same = [(a == b) or (a is None and b is None) or (isinstance(a, float) and math.isnan(a) and math.isnan(b))
                for a, b in zip(got, want)]
        assert all(same), (col, got, want)
        assert cols[col].type == typ
    assert np.array_equal(numpy_column(cols["step_factor"]), [spec.resolve(int(i))["step_factor"] for i in rows[::-1]])


def test_first_bad_scene_is_named_as_scene_by_scene():
    text = _SPECS["skipped_starts"].replace("invalid: skip", "invalid: error")
    spec = load_spec(text)
    with pytest.raises(S.SpecError) as err:
        PL.make_plan(spec)
    assert str(err.value) == _scalar_plan(spec)[3]


def test_free_axes_resolve_once_per_core_combination():
    """The envelope's shape: B2 x K2 free, the loads core: one resolve per load, not per scene."""
    spec = load_spec(_SPECS["envelope_like"])
    scenes = Scenes(spec)
    assert [spec.axes[d - 1].where for d in scenes.free] == ["grid.B2", "grid.K2"]
    slots, local = scenes.slots(scenes.decode(np.arange(spec.n_scenes)))
    assert len(slots) == len(spec.cases) * 3 and local.max() == len(slots) - 1  # cases x loads


def test_psi_makes_b2_a_core_axis():
    scenes = Scenes(load_spec(_SPECS["psi"]))
    assert scenes.free == ()


@pytest.mark.parametrize("name", sorted(_SPECS))
def test_resolved_on_columns_equals_resolve(name):
    """What the workers run: Scenes.resolved(rows) is spec.resolve of each row, key for key."""
    spec = load_spec(_SPECS[name])
    rows = np.flatnonzero(_scalar_plan(spec)[0] >= 0)[::-1]
    assert Scenes(spec).resolved(rows) == [spec.resolve(int(i)) for i in rows]


def test_an_all_core_spec_holds_a_bounded_number_of_slots(monkeypatch):
    """A spec whose every scene is its own slot (every axis enters a combination check) is planned
    as scene by scene, and no more than HELD slots are kept resolved."""
    monkeypatch.setattr(SC, "HELD", 7)
    monkeypatch.setattr(PL, "PLAN_BLOCK", 5)
    spec = load_spec("""
        grid: {t_c: [1.2, 1.36, 1.5], L: [0.2, 0.4, 0.7], dP: [0, 0.3, 0.62]}
        invalid: skip
    """)
    scenes = Scenes(spec)
    assert scenes.free == () and scenes.free_size == 1
    row_model, first_row, skipped, _ = _scalar_plan(spec)
    plan = PL.make_plan(spec)
    assert np.array_equal(plan.row_model, row_model) and np.array_equal(plan.first_row, first_row)
    assert plan.skipped == skipped > 0
    assert len(plan.columns()._held) <= 7
