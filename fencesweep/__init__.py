"""fencesweep: Numba-accelerated sweeps of an active rotary fence (docs/model.md).

One scene: simulate, simulate_resolved, resolve. Studies of many (README, Python API for
sweeps): grid, estimate, design, sensitivity, as the CLI's commands, and points (an envelope
sweep's per-design-point table); they live in fencesweep.study.api and are imported when first
used, so that `import fencesweep` loads neither pandas nor pyarrow.
"""
from fencesweep.version import __version__
from fencesweep.errors import (DesignError, EnvelopeError, ParameterError, SensitivityError, SpecError,
                               SweepInterrupted, SweepWriteError, UsageError, VerificationWarning, WriteError)
from fencesweep.model.params import CASES, resolve
from fencesweep.model.simulate import simulate, simulate_resolved

#: the studies' functions (fencesweep.study.api), imported on first use
_STUDIES = ("grid", "estimate", "design", "sensitivity", "points")

#: what a user catches: bad input (ParameterError and its kinds, UsageError), a file that could not be
#: written, an interrupted sweep, a verification that failed (fencesweep/errors.py)
__all__ = ["simulate", "simulate_resolved", "resolve", "CASES", "__version__",
           "ParameterError", "SpecError", "EnvelopeError", "DesignError", "SensitivityError", "UsageError",
           "WriteError", "SweepWriteError", "SweepInterrupted", "VerificationWarning",
           "grid", "estimate", "design", "sensitivity", "points"]


def __getattr__(name: str):
    if name in _STUDIES:
        from fencesweep.study import api

        return getattr(api, name)
    raise AttributeError(f"module 'fencesweep' has no attribute {name!r}")


def __dir__() -> list:
    return sorted(set(globals()) | set(_STUDIES))
