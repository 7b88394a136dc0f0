"""fencesweep: Numba-accelerated sweeps of an active rotary fence (MODEL.md)."""
from ._cache import invalidate_stale_kernels

invalidate_stale_kernels()  # before any kernel module is imported

from .params import CASES, ParameterError, resolve
from .api import simulate, simulate_resolved

__version__ = "0.1.0"
__all__ = ["simulate", "simulate_resolved", "resolve", "CASES", "ParameterError", "__version__"]
