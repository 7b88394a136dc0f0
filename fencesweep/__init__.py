"""fencesweep: Numba-accelerated sweeps of an active rotary fence (MODEL.md)."""
from importlib import metadata as _metadata

try:  # the version lives in one place, pyproject.toml; the installed metadata carries it
    __version__ = _metadata.version("fencesweep")
except _metadata.PackageNotFoundError:  # a source tree on sys.path, never installed
    __version__ = "0+unknown"

from fencesweep.model.params import CASES, ParameterError, resolve
from fencesweep.model.simulate import simulate, simulate_resolved

__all__ = ["simulate", "simulate_resolved", "resolve", "CASES", "ParameterError", "__version__"]
