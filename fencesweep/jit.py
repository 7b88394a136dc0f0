"""How the compiled kernels are compiled: every kernel module decorates with `kernel`.

kernel(**options) is numba.njit with
  * cache=True: compiled once into Numba's on-disk cache (_cache.py keeps it in step with
    the sources), so tests and sweep workers load it instead of compiling;
  * _nrt=False: without Numba's reference counting. A kernel function allocates nothing: it
    works on arrays its caller made. With the counting on, Numba increments and decrements
    (atomically) the reference of every array argument of every call it makes, and of every
    row view: measured with perf on the long_near cycle, NRT_incref and NRT_decref took 28% of
    the kernel's time, more than the right-hand side itself. Off, an allocation inside a
    kernel function does not compile: "no allocation in the loops" is checked by the compiler.

allocating(**options) is njit(cache=True) with the counting on (said explicitly: a callee
otherwise inherits its caller's setting) for the three entry points that allocate a run's
work arrays once (stream_kernel, cycle_kernel, impact_kernel).
"""
from __future__ import annotations

from numba import njit


def kernel(**options):
    """numba.njit for a kernel function (module docstring)."""
    return njit(cache=True, _nrt=False, **options)


def allocating(**options):
    """numba.njit for an entry point that allocates its work arrays (module docstring)."""
    return njit(cache=True, _nrt=True, **options)
