"""Numba, loaded as the kernels need it; every kernel module imports Numba through this one.

Loaded without the imports the kernels do not use (each measured in a fresh process with a
warm cache):
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
    of the load.
Each is hidden only for the length of that import (_hidden), and only when the process has
not imported it already. (And Numba's error-message highlighting is off: kernel/__init__.py.)

And without Numba's LLVM-lock events (_drop_llvm_lock_events): Numba registers callbacks on
llvmlite's lock that broadcast an event on every call into LLVM (~11,000 in the last 2.7 s of a
first cycle's compile), only to add up the time spent in LLVM for each compiled function's
statistics (its metadata "timers"), which nothing here reads. Without them a cold first cycle
takes ~0.25 s less (3 pairs, one process compiling: 12.46/12.22, 12.73/12.50, 13.41/13.14 s).
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
    import numba


def _import_numba_support_without_probes() -> None:
    """Import Numba's NumPy and cffi support with the BLAS probe answered "no" and cffi hidden
    (module docstring)."""
    if "numba.np.arraymath" in sys.modules:
        return  # already imported: nothing to save
    with _hidden("scipy.linalg.cython_blas", "cffi"):
        import numba.core.typing.cffi_utils  # noqa: F401
        import numba.np.arraymath  # noqa: F401


_import_numba_support_without_probes()


def _drop_llvm_lock_events() -> None:
    """Unregister Numba's callbacks on llvmlite's lock (module docstring)."""
    import llvmlite.binding as ll

    lock = getattr(getattr(ll.ffi, "lib", None), "_lock", None)
    for acquire, release in list(getattr(lock, "_cblist", ())):
        if getattr(acquire, "__module__", "") == "numba.core.base":
            lock.unregister(acquire, release)


_drop_llvm_lock_events()

__all__ = ["numba"]
