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

Loading the kernels without the imports they do not use (each measured in a fresh process
with a warm cache; benchmarks/throughput.py measures the whole kernel load):
  * Numba's BLAS probe. The first compiled function a process loads makes Numba import its
    NumPy implementations (numba.np.arraymath), and that module asks at import whether a
    BLAS is there by importing scipy.linalg.cython_blas, which imports all of scipy.linalg
    (and numpy.f2py): 0.27 s of a process's 0.6 s kernel load. No kernel uses BLAS (no
    np.dot, no linalg), so the probe is answered "no". The one effect: in this process
    Numba's np.convolve and np.correlate use Numba's own loop instead of BLAS; np.dot and
    np.linalg import scipy when they are compiled.
  * cffi (with pycparser), which Numba imports to type cffi functions, and coverage, which it
    imports to report compiled lines to a coverage run. No kernel calls a cffi function; a
    coverage run imports coverage before Numba, and then nothing is hidden. Together 0.04 s
    of the load (0.45-0.49 s -> 0.42-0.44 s to the first cycle).
Each is hidden only for the length of that import (_hidden), and only when the process has
not imported it already. tests/test_jit.py checks that loading the kernels imports none of
them and gives the same results.
"""
from __future__ import annotations

import contextlib
import sys


@contextlib.contextmanager
def _hidden(*modules: str):
    """Within the block, importing one of `modules` (not imported yet) raises ImportError at once."""
    hide = [m for m in modules if m not in sys.modules]
    for m in hide:
        sys.modules[m] = None
    try:
        yield
    finally:
        for m in hide:
            del sys.modules[m]


with _hidden("coverage"):
    from numba import njit


def _import_numba_support_without_probes() -> None:
    """Import Numba's NumPy and cffi support with the BLAS probe answered "no" and cffi hidden
    (module docstring)."""
    if "numba.np.arraymath" in sys.modules:
        return  # already imported: nothing to save
    with _hidden("scipy.linalg.cython_blas", "cffi"):
        import numba.core.typing.cffi_utils  # noqa: F401
        import numba.np.arraymath  # noqa: F401


_import_numba_support_without_probes()


def kernel(**options):
    """numba.njit for a kernel function (module docstring)."""
    return njit(cache=True, _nrt=False, **options)


def allocating(**options):
    """numba.njit for an entry point that allocates its work arrays (module docstring)."""
    return njit(cache=True, _nrt=True, **options)
