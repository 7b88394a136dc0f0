"""The asv suite (airspeed velocity; asv.conf.json at the repository root, benchmarks/README.md).

Every benchmark uses only what every measured revision has, back to 8a6dc2a: the public call
`fencesweep.simulate`, `fencesweep.grid` and the `fencesweep` command (`python -m fencesweep`).
The specs and the independent reference (tests/reference/) are read from this checkout, so that
every revision runs the same inputs and is judged against the same reference.
"""
from pathlib import Path

import numpy as np

#: the repository root of this checkout (the suite's inputs: sweeps/, tests/reference/)
ROOT = Path(__file__).resolve().parents[2]
CASES = ("small_far", "long_near")
DRIVES = ("flexible", "rigid", "free")


def main_job_sample(n: int = 60, seed: int = 20261123) -> list[tuple[str, float, float]]:
    """A fixed sample of the main job's scenes (sweeps/b2k2.yaml: 81 B2 x 81 K2 x the two named
    cases) as (case, B2, K2): the sample of the retired revision benchmarks and of instructions.py."""
    b2, k2 = np.linspace(0, 200, 81), np.linspace(100, 2100, 81)
    idx = np.random.default_rng(seed).choice(81 * 81 * 2, n, replace=False)
    return [(CASES[i // 6561], float(b2[i % 6561 // 81]), float(k2[i % 81])) for i in idx]
