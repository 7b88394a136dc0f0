"""What several test files share: the stand-in for the engine that the sweep tests run, and the
small specs they sweep. Plain functions and constants, so that a test module can use them at
import time (a default argument) and ship the engine to another process by value (cloudpickle);
conftest.py gives them as fixtures too (`faked_engine`, `sweep_spec_file`).

Importable as `helpers` through pyproject.toml's pytest pythonpath (tests/).
"""
from __future__ import annotations

import math
import sys
import textwrap
from pathlib import Path

import cloudpickle

from fencesweep.model import params as P
from fencesweep.model import results as R
from fencesweep.study.spec import file as specfile

#: A cycle sweep of 40 scenes and 22 distinct runs (rigid: B2 and K2 unused, one run per case;
#: flexible: 5 x 2 per case), in 6 chunks of 4.
SWEEP_SPEC = """
    scene: cycle
    params: {m1: 12.0}
    grid:
      drive: [rigid, flexible]
      B2: {linspace: [0, 100, 5]}
      K2: [200, 570]
    cases: [small_far, long_near]
    chunk_size: 4
"""

#: 3 x 3 B2 x K2 over both named cases: 18 cycles of the flexible drive (small enough for the
#: real engine).
GRID_SPEC = """
    params: {drive: flexible}
    grid:
      B2: [15, 72, 140]
      K2: [570, 1200, 2075]
    cases: [small_far, long_near]
"""


#: a design of 2 generations of 4 points over 4 loads, compared with the paper's element and a
#: rigid fence (the real engine: a few seconds)
DESIGN_SPEC = """
    params: {drive: flexible}
    envelope:
      L: [0.2, 0.7]
      m1: [5, 15]
      A: 0.1
      dP: across
      seed: 1
    design:
      variables:
        B2: {min: 10, max: 200}
        K2: {min: 500, max: 2100}
      optimizer: {seed: 2, maxiter: 2, popsize: 2, refine: 4}
      verify: {sobol: 4, seed: 9}
      compare:
        paper: {B2: 72, K2: 570}
        rigid: {drive: rigid}
    """

#: Saltelli's n = 4 over two inputs, each point over two loads
SENSITIVITY_SPEC = """
    params: {drive: flexible, B2: 140, K2: 2075}
    envelope:
      L: [0.2, 0.7]
      A: 0.1
      dP: across
      seed: 1
    sensitivity:
      inputs:
        k1: {min: 2.0e6, max: 8.0e6}
        mu2: {min: 0.15, max: 0.35}
      n: 4
      seed: 3
    """

def load_spec(text: str = SWEEP_SPEC):
    """The Spec of an indented YAML text (a spec above, or one of a test file)."""
    return specfile.loads(textwrap.dedent(text))


def write_spec(folder: Path, text: str = SWEEP_SPEC, name: str = "spec.yaml") -> Path:
    """The YAML text written, dedented, into folder/name; its path."""
    path = Path(folder) / name
    path.write_text(textwrap.dedent(text))
    return path


def fake_engine(vals, trajectory=False, drift=0.0):
    """A deterministic stand-in for fencesweep.model.simulate.simulate_resolved: every result of
    the scene from its model key without step_factor (so that a sweep's verification, which
    re-runs at tol / 10, agrees exactly), except peak_force, which moves by `drift` (relative)
    when step_factor is not 1. Outcomes, flags and step counts vary from run to run, and
    t_first_contact is NaN for some; freefall_force, where the scene has it, is 100 N."""
    key = [(n, v) for n, v in P.model_key(vals)[1:] if n != "step_factor"]
    x = sum((k + 1) * (v if isinstance(v, float) else len(v)) for k, (_, v) in enumerate(key)) / 1000
    out = {}
    for k, (name, _, _) in enumerate(R.SCENE_RESULTS[vals["scene"]]):
        if name == "outcome":
            out[name] = R.OUTCOMES[int(x * 7000) % 3]
        elif name == "status":
            out[name] = "ok"
        elif name in ("n_impacts", "n_steps", "n_rejected"):
            out[name] = int(x * 13000) % 1000
        elif name in ("safe", "deflection_ok"):
            out[name] = math.sin(x + k) > 0
        elif name == "t_first_contact":
            out[name] = math.nan if int(x * 1000) % 5 == 0 else abs(math.sin(7 * x))
        else:
            out[name] = abs(math.sin(x * (k + 11) * 1000)) * 10.0 ** (k % 3)
    if "freefall_force" in out:  # the scale of the force's floor (docs/model.md (15.15))
        out["freefall_force"] = 100.0
    if vals["step_factor"] != 1.0:
        out["peak_force"] *= 1 + drift
    return out, None


# the engine goes to loky workers and to test subprocesses pickled by value: they need not
# import this file (a subprocess has no tests/ on its path)
cloudpickle.register_pickle_by_value(sys.modules[__name__])
