"""Values solved once per input and kept beside the compiled kernels (fencesweep/kernel/cache.py solved)."""
import math

import pytest

from fencesweep.kernel import cache as _cache
from fencesweep.model.calibrate import damping_coefficient, solve_damping_coefficient
from fencesweep.model.drive import crank_rocker_geometry, solve_crank_rocker_geometry


@pytest.fixture
def store(tmp_path, monkeypatch):
    monkeypatch.setattr(_cache, "SOLVED", tmp_path / "solved.json")
    monkeypatch.setattr(_cache, "_solved", None)
    return tmp_path / "solved.json"


def test_a_value_is_solved_once_and_read_back_exactly_by_a_new_process(store):
    calls = []

    def solve():
        calls.append(1)
        return (math.pi / 7, 1e-300, -2.5)

    first = _cache.solved("f", (0.1, "x"), solve)
    _cache._solved = None  # as a new process: only the file
    again = _cache.solved("f", (0.1, "x"), solve)
    assert again == first and isinstance(again, tuple) and len(calls) == 1
    assert _cache.solved("f", (0.2, "x"), solve) == first and len(calls) == 2  # another key


def test_an_unreadable_store_only_costs_solving_again(store):
    store.write_text("{not json")
    assert _cache.solved("g", (1,), lambda: 2.0) == 2.0
    _cache._solved = None
    assert _cache.solved("g", (1,), lambda: 3.0) == 2.0  # the store was rewritten


@pytest.mark.parametrize("e, law", [(0.2, "hertz"), (0.55, "linear")])
def test_kept_damping_coefficient_is_the_solved_one(e, law):
    assert damping_coefficient(e, law) == solve_damping_coefficient(e, law)


def test_kept_crank_rocker_geometry_is_the_solved_one():
    assert crank_rocker_geometry(0.6, 2.0) == solve_crank_rocker_geometry(0.6, 2.0)
