"""fencesweep: Numba-accelerated sweeps of an active rotary fence (docs/model.md).

One scene: simulate, simulate_resolved, resolve; animate (a cycle or a stream as a GIF or an MP4).
Studies of many (README, Python API for sweeps): grid, estimate, design, sensitivity, risk, as the
CLI's commands, and points (an envelope sweep's per-design-point table); a table read back:
read_table (units and provenance in df.attrs, as plain pd.read_parquet gives them) and to_xarray
(a Dataset over the spec's axes). They are imported when first used, so that `import fencesweep`
loads neither pandas nor pyarrow (nor matplotlib).
"""
from fencesweep.version import __version__
from fencesweep.errors import (DesignError, EnvelopeError, ParameterError, SensitivityError, SpecError,
                               SweepInterrupted, SweepWriteError, UsageError, VerificationWarning, WorkerError,
                               WriteError)
from fencesweep.model.params import CASES, resolve
from fencesweep.model.simulate import simulate, simulate_resolved

#: the studies' functions and the tables' readers, each imported from its module on first use
_LAZY = {"grid": "fencesweep.study.api", "estimate": "fencesweep.study.api", "design": "fencesweep.study.api",
         "sensitivity": "fencesweep.study.api", "risk": "fencesweep.study.api", "points": "fencesweep.study.api",
         "read_table": "fencesweep.study.store.table", "to_xarray": "fencesweep.study.store.dataset",
         "animate": "fencesweep.report.animation"}

#: the exceptions are those a user catches: bad input (ParameterError and its kinds, UsageError), a
#: file that could not be written, an interrupted sweep, a verification that failed (errors.py)
__all__ = ["simulate", "simulate_resolved", "resolve", "animate", "CASES", "__version__",
           "ParameterError", "SpecError", "EnvelopeError", "DesignError", "SensitivityError", "UsageError",
           "WriteError", "SweepWriteError", "SweepInterrupted", "VerificationWarning", "WorkerError",
           "grid", "estimate", "design", "sensitivity", "risk", "points", "read_table", "to_xarray"]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'fencesweep' has no attribute {name!r}")


def __dir__() -> list:
    return sorted(set(globals()) | set(_LAZY))
