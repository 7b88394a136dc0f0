"""fencesweep: Numba-accelerated sweeps of an active rotary fence (docs/model.md).

One scene: simulate, simulate_resolved, resolve. Studies of many (README, Python API for
sweeps): grid, estimate, design, sensitivity, as the CLI's commands, and points (an envelope
sweep's per-design-point table); they live in fencesweep.study.api and are imported when first
used, so that `import fencesweep` loads neither pandas nor pyarrow.
"""
from importlib import metadata as _metadata

try:  # the version lives in one place, pyproject.toml; the installed metadata carries it
    __version__ = _metadata.version("fencesweep")
except _metadata.PackageNotFoundError:  # a source tree on sys.path, never installed
    __version__ = "0+unknown"

from fencesweep.model.params import CASES, ParameterError, resolve
from fencesweep.model.simulate import simulate, simulate_resolved

#: the studies' functions (fencesweep.study.api), imported on first use
_STUDIES = ("grid", "estimate", "design", "sensitivity", "points")

__all__ = ["simulate", "simulate_resolved", "resolve", "CASES", "ParameterError", "__version__", *_STUDIES]


def __getattr__(name: str):
    if name in _STUDIES:
        from fencesweep.study import api

        return getattr(api, name)
    raise AttributeError(f"module 'fencesweep' has no attribute {name!r}")


def __dir__() -> list:
    return sorted(set(globals()) | set(_STUDIES))
