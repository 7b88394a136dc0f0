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

Loading the kernels without Numba's BLAS probe: the first compiled function a process loads
makes Numba import its NumPy implementations (numba.np.arraymath), and that module asks at
import whether a BLAS is there by importing scipy.linalg.cython_blas, which imports all of
scipy.linalg (and numpy.f2py): measured 0.27 s of a process's 0.6 s kernel load. No kernel
uses BLAS (no np.dot, no linalg), so this module imports numba.np.arraymath once with that
probe answered "no" (the module hidden for the length of the import, then restored). The
one effect: in this process Numba's np.convolve and np.correlate use Numba's own loop instead
of BLAS. np.dot and np.linalg are unaffected: they import scipy when they are compiled.
benchmarks/throughput.py measures the kernel load; tests/test_jit.py checks that loading the
kernels does not import scipy.linalg.
"""
from __future__ import annotations

import sys

from numba import njit

_BLAS_PROBE = "scipy.linalg.cython_blas"


def _import_numpy_support_without_blas_probe() -> None:
    """Import numba.np.arraymath with its BLAS probe answered "no" (module docstring)."""
    if "numba.np.arraymath" in sys.modules or _BLAS_PROBE in sys.modules:
        return  # already imported, or BLAS is loaded anyway: nothing to save
    sys.modules[_BLAS_PROBE] = None  # an import of a None entry raises ImportError at once
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        del sys.modules[_BLAS_PROBE]


_import_numpy_support_without_blas_probe()


def kernel(**options):
    """numba.njit for a kernel function (module docstring)."""
    return njit(cache=True, _nrt=False, **options)


def allocating(**options):
    """numba.njit for an entry point that allocates its work arrays (module docstring)."""
    return njit(cache=True, _nrt=True, **options)
