"""fencesweep: Numba-accelerated sweeps of an active rotary fence (MODEL.md)."""
from .params import CASES, ParameterError, resolve
from .api import simulate, simulate_resolved

__version__ = "0.1.0"
__all__ = ["simulate", "simulate_resolved", "resolve", "CASES", "ParameterError", "__version__"]
