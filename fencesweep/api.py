"""Python API: `simulate(scene, case, **params) -> dict` (issue: the engine).

Orchestration only: checks parameters (params.resolve), prepares the derived constants
(setup.prepare), calls the compiled kernel of the scene and unpacks its result vector.
"""
from __future__ import annotations

from typing import Any

from . import params as P


def simulate(scene: str = "cycle", case: str | None = None, **params: Any) -> dict:
    """Simulate one scene; return the results of MODEL.md §11 (cycle) or §8 (impact, freefall).

    Parameters take the names and defaults of MODEL.md §12; `case` ('small_far' or
    'long_near') is applied first and explicit parameters override it. Bad input raises
    ParameterError (a ValueError) naming the parameter, the value and what is allowed.
    """
    vals = P.resolve(scene, case, **params)
    res, _ = simulate_resolved(vals)
    return res


def simulate_resolved(vals: dict, trajectory: bool = False):
    """Run an already-resolved parameter set. Returns (results dict, trajectory DataFrame or None)."""
    raise NotImplementedError("engine not yet in place")
