"""Adaptive maps: the refinement on maps whose answer is known in closed
form, the load order and stop, and a small envelope study against its full grid."""
from __future__ import annotations

import numpy as np
import pytest

from fencesweep.errors import UsageError
from fencesweep.study.adaptive import refine as A
from fencesweep.study.adaptive import loads as AL
from fencesweep.study.spec import design as DS


def _drive(grid: A.Grid, margins_of, rule: A.Rule | None = None) -> A.Refiner:
    """Run a Refiner to the end on a map given in closed form: margins_of(map, idx [N, d]) -> [N, 4]."""
    ref = A.Refiner(grid, rule or A.Rule())
    while True:
        ids, _ = ref.ask()
        if not len(ids):
            return ref
        maps, idx = grid.index(ids)
        m = margins_of(maps, idx)
        ref.tell(ids, m.min(axis=1) >= 0, m.argmin(axis=1), m)


def _disc(maps, idx):
    """A feasible disc of radius 18 (map 0) or 12 (map 1) in a 65 x 49 grid; two constraints:
    the distance to the rim, and a plane that binds on the left."""
    r = np.where(maps == 0, 18.0, 12.0)
    d = np.hypot(idx[:, 0] - 30.0, idx[:, 1] - 24.0)
    m = np.full((len(maps), 4), np.inf)
    m[:, 1] = (r - d) / 20.0
    m[:, 2] = (idx[:, 0] - 20.0) / 40.0 + 0.2
    return m


def test_refiner_finds_a_smooth_boundary_from_a_fraction_of_the_points():
    grid = A.Grid(2, (65, 49))
    ref = _drive(grid, _disc)
    status, feas, bind, marg, mm = ref.result()
    assert (status != A.UNKNOWN).all()
    maps, idx = grid.index(np.arange(grid.n_elements))
    m = _disc(maps, idx)
    truth = m.min(axis=1) >= 0
    sampled = status == A.SAMPLED
    assert (feas[sampled] == truth[sampled]).all()  # a simulated element is never re-judged
    assert np.mean(feas != truth) <= 0.005
    assert sampled.mean() <= 0.35  # most of the map is inferred
    both = feas & truth
    assert np.mean(bind[both] != m[both].argmin(axis=1)) <= 0.02


def test_refiner_on_a_constant_map_simulates_only_the_coarse_lattice():
    grid = A.Grid(1, (33, 33))
    ref = _drive(grid, lambda maps, idx: np.tile([np.inf, 0.5, 0.8, 0.9], (len(maps), 1)))
    status, feas, *_ = ref.result()
    h = A.coarse_step(grid.shape)
    assert h == 4
    assert (status == A.SAMPLED).sum() == len(A.lattice(33, h)) ** 2
    assert feas.all()


def test_refiner_is_deterministic():
    grid = A.Grid(2, (65, 49))
    a, b = _drive(grid, _disc), _drive(grid, _disc)
    assert np.array_equal(a.status, b.status) and a.levels == b.levels


def test_interpolate_passes_over_infinite_corners():
    w = A.weights(np.array([[0.5, 0.5]]))
    assert np.allclose(w, 0.25)
    assert A.interpolate(np.array([[1.0, 2.0, 3.0, 4.0]]), w)[0] == pytest.approx(2.5)
    assert A.interpolate(np.array([[np.inf, 2.0, 3.0, 4.0]]), w)[0] == 2.0
    assert A.interpolate(np.array([[np.inf] * 4]), w)[0] == np.inf


def test_loads_run_worst_first_and_stop_at_the_first_broken_constraint():
    refs = np.array([[0.5, -0.2, 0.3], [0.6, 0.1, 0.2]])
    pred, low, key = AL.predictions(refs, kappa=1.0)
    assert np.allclose(pred, [0.4, -0.5, 0.1]) and np.array_equal(pred, key)
    assert list(AL.order(key, low, np.zeros(3, dtype=np.int64))) == [1, 2, 0]
    # a neighbour that stopped at the load it broke (NaN: loads it did not run): that load first;
    # nothing is predicted safe from a neighbour that did not run the load
    refs = np.array([[np.nan, -0.3, np.nan], [0.6, 0.4, 0.2]])
    pred, low, key = AL.predictions(refs, kappa=1.0)
    assert AL.order(key, low, np.zeros(3, dtype=np.int64))[0] == 1
    assert np.isneginf(pred[[0, 2]]).all() and pred[1] == pytest.approx(-1.0)
    assert list(AL.following(np.array([0.5, 0.1, 0.3]))) == [0.1, 0.3, np.inf]
    rule = AL.LoadRule()
    assert AL.stop(-0.01, -0.01, 0.9, rule) == "broken"
    assert AL.stop(0.3, 0.3, 0.9, rule) == "predicted"
    assert AL.stop(0.3, 0.3, 0.31, rule) is None  # the next load may bind: run it
    assert AL.stop(0.3, 0.3, 0.9, AL.LoadRule(predict=False)) is None


def test_load_margin_is_the_envelope_judge_on_one_load():
    lim = DS.Limits(scraped=True, overload=1.0, deflection_max=None, residual_amplitude=0.02)
    res = {"outcome": "scraped", "overload": 0.8, "deflection_max": 0.1, "residual_amplitude": 0.005}
    assert AL.load_margin(res, 0.25, lim) == pytest.approx(min(0.2, 0.6, 0.75))
    assert AL.load_margin(dict(res, outcome="escaped"), 0.25, lim) == -1.0


SMALL = {
    "description": "adaptive test", "scene": "cycle",
    "params": {"drive": "flexible", "t_c": 1.36, "v": 2.0},
    "grid": {"B2": {"linspace": [0, 400, 17]}, "K2": {"linspace": [100, 2100, 17]}},
    "envelope": {"L": {"min": 0.2, "max": 0.7}, "A": {"min": 0.1, "max": 0.2}, "m1": {"min": 5, "max": 15},
                 "dP": "across", "R_s": 0.0, "phi0": 0.0, "corners": False, "sobol": 4, "seed": 3},
    "design": {"variables": {"B2": {"min": 0, "max": 400}, "K2": {"min": 100, "max": 2100}},
               "constraints": {"scraped": True, "overload": 1.0, "deflection_max": "dalpha_perm",
                               "residual_amplitude": 0.0174533}},
}


@pytest.fixture(scope="module")
def small_runs(tmp_path_factory):
    import fencesweep

    tmp = tmp_path_factory.mktemp("adaptive")
    full = fencesweep.grid(SMALL, out=tmp / "full.parquet", jobs=1, verify=False)
    ad = fencesweep.grid(SMALL, out=tmp / "ad.parquet", jobs=1, verify=False, adaptive=True)
    return tmp, full, ad


def test_adaptive_envelope_agrees_with_its_full_grid(small_runs):
    import fencesweep
    from fencesweep.study.adaptive import maps as AM
    from fencesweep.study.adaptive import points as APT
    from fencesweep.study.api import load_spec

    _, full, ad = small_runs
    lay = AM.layout(load_spec(SMALL))
    ref = APT.full_points(lay, full)
    pts = fencesweep.points(ad)
    rec = ad.attrs["run"]["adaptive"]
    assert len(pts) == 17 * 17 and pts["sampled"].any() and not pts["sampled"].all()
    assert rec["cycles"] == len(ad) < len(full) == rec["full_grid_cycles"]
    sampled = pts["sampled"].to_numpy()
    assert (pts["feasible"].to_numpy()[sampled] == ref["feasible"].to_numpy()[sampled]).all()
    assert np.mean(pts["feasible"].to_numpy() != ref["feasible"].to_numpy()) <= 0.02
    # every row of T is the full grid's row of the same scene
    key = ["B2", "K2", "L", "A", "m1", "dP"]
    m = ad[key + ["peak_force", "deflection_max"]].merge(full[key + ["peak_force", "deflection_max"]], on=key,
                                                         suffixes=("", "_f"))
    assert len(m) == len(ad)
    assert np.array_equal(m["peak_force"].to_numpy(float), m["peak_force_f"].to_numpy(float), equal_nan=True)


def test_adaptive_is_the_same_on_two_jobs_and_after_a_rerun(small_runs):
    import fencesweep

    tmp, _, ad = small_runs
    ad2 = fencesweep.grid(SMALL, out=tmp / "ad2.parquet", jobs=2, verify=False, adaptive=True)
    assert ad2.equals(ad)
    assert fencesweep.points(ad2).equals(fencesweep.points(ad))


def test_adaptive_needs_a_map(tmp_path):
    import fencesweep

    spec = {"scene": "cycle", "params": {"drive": "flexible", "m1": 10.0, "L": 0.4, "A": 0.15, "dP": 0.1},
            "grid": {"B2": {"linspace": [0, 100, 3]}}}
    with pytest.raises(UsageError, match="--adaptive needs an envelope study"):
        fencesweep.grid(spec, out=tmp_path / "x.parquet", adaptive=True)
    assert not (tmp_path / "x.parquet").exists()


def test_the_cli_writes_what_the_api_returns(small_runs, capsys):
    import yaml

    from fencesweep import cli
    from fencesweep.study.store import table as store

    tmp, _, ad = small_runs
    spec = tmp / "small.yaml"
    spec.write_text(yaml.safe_dump(SMALL, sort_keys=False))
    out = tmp / "cli.parquet"
    assert cli.main(["grid", str(spec), "--adaptive", "--out", str(out), "--jobs", "1", "--no-verify"]) == 0
    assert "adaptive map:" in capsys.readouterr().err
    assert store.read_table(out).equals(ad)
