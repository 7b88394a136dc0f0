"""How the compiled kernels are compiled. Every compiled function of the package is decorated
with one of:

  kernel()  a kernel function, called only from other compiled functions: numba.njit with
            * one signature: the function is compiled for the plain types of its arguments
              (KernelDispatcher), never for the literal type of a constant argument. Numba
              would otherwise compile f(x, N_CTRL), f(x, N_STATE) and f(x, 3) as three
              functions, f(x, True) and f(x, flag) as two (measured: 1130 compilations of 79
              functions for a first cycle before; tests/test_jit.py checks one per function);
            * cache=True: compiled once into Numba's on-disk cache (kernel/cache.py keeps that
              cache in a directory of its own, named by a hash of every kernel source);
            * _nrt=False: without Numba's reference counting. A kernel function allocates
              nothing: it works on arrays its caller made. With the counting on, Numba
              increments and decrements (atomically) the reference of every array argument of
              every call: measured with perf on the long_near cycle, 28% of the kernel's time.
              Off, an allocation inside a kernel function does not compile, so "no allocation
              in the loops" is checked by the compiler;
            * no_cpython_wrapper, no_cfunc_wrapper: without the wrappers that let Python (or C)
              call the function. Nothing but a kernel calls it, and the wrappers cost more to
              compile than a small function itself (measured on this machine: 0.125 s against
              0.039 s for a one-line function, of the ~60 kernel functions' cold compile).
              `python_callable` gives a test or a Python caller its own callable copy.
  kernel(inline="always") only for the few generic functions that take other compiled
            functions as arguments (kernel/rk.py `step`, kernel/search.py, kernel/driver.py):
            Numba can cache a function that receives a function only when it is inlined,
            which makes the function argument a constant of the caller.
  entry()   an entry point, called from Python with one type signature (its caller passes
            float64 scalars and C-contiguous float64 / int64 arrays, so one compilation
            serves every call; tests/test_jit.py checks that every function has exactly one):
            with reference counting, as entry points allocate a run's work arrays once.

Loading the kernels without the imports they do not use (each measured in a fresh process
with a warm cache):
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
not imported it already. And Numba's error-message highlighting is switched off before Numba is
imported: every failed overload candidate that Numba tries while typing formats a message, and
with colorama installed each one set up and tore down colorama's terminal wrappers (5% of a
cold compile).
"""
from __future__ import annotations

import contextlib
import functools
import os
import sys

os.environ.setdefault("NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING", "1")


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
    from numba import njit, types
    from numba.core.registry import CPUDispatcher


def _import_numba_support_without_probes() -> None:
    """Import Numba's NumPy and cffi support with the BLAS probe answered "no" and cffi hidden
    (module docstring)."""
    if "numba.np.arraymath" in sys.modules:
        return  # already imported: nothing to save
    with _hidden("scipy.linalg.cython_blas", "cffi"):
        import numba.core.typing.cffi_utils  # noqa: F401
        import numba.np.arraymath  # noqa: F401


_import_numba_support_without_probes()

from fencesweep.kernel import cache  # noqa: E402  (after Numba's set-up above; it registers the cache locator)

#: True when NUMBA_DISABLE_JIT=1: the decorators return the plain Python functions
JIT_DISABLED = bool(numba.config.DISABLE_JIT)


_KERNEL = dict(nopython=True, _nrt=False, no_cpython_wrapper=True, no_cfunc_wrapper=True)


class KernelDispatcher(CPUDispatcher):
    """Numba's dispatcher for a kernel function: a call from compiled code is typed with the
    arguments' plain types (types.unliteral), so a constant argument does not make a new
    compilation (module docstring)."""

    def get_call_template(self, args, kws):
        return super().get_call_template(tuple(types.unliteral(a) for a in args),
                                         {k: types.unliteral(v) for k, v in kws.items()})


def kernel(inline=False):
    """The decorator of a kernel function (module docstring)."""
    if JIT_DISABLED:
        return lambda fn: fn
    if inline == "always":  # a generic function that takes compiled functions: inlined by Numba
        targetoptions = dict(_KERNEL, inline="always", forceinline=False)
    else:
        targetoptions = dict(_KERNEL, forceinline=bool(inline))

    def compiled(fn):
        disp = KernelDispatcher(py_func=fn, locals={}, targetoptions=targetoptions)
        disp.enable_caching()
        return disp

    return compiled


def entry(**options):
    """numba.njit for an entry point called from Python (module docstring)."""
    return njit(cache=True, _nrt=True, no_cfunc_wrapper=True, forceinline=False, **options)


@functools.lru_cache(maxsize=None)
def python_callable(fn):
    """A copy of kernel function `fn` that Python can call (tests, and Python code that needs a
    formula once): compiled on its first call, not cached on disk. `fn` itself when the JIT is off."""
    if JIT_DISABLED or not hasattr(fn, "py_func"):
        return fn
    return njit(_nrt=False)(fn.py_func)


__all__ = ["kernel", "entry", "python_callable", "cache", "JIT_DISABLED"]
