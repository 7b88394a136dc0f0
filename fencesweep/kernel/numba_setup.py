"""Numba, loaded as the kernels need it; every kernel module imports Numba through this one.

Loaded without two imports that the kernels do not use and that would lengthen every process's
kernel load, with what Numba then knows left as it would be without fencesweep:
  * Numba's BLAS probe. The first compiled function a process loads makes Numba import its
    NumPy implementations (numba.np.arraymath), and that module asks at import whether a BLAS
    is there by importing scipy.linalg.cython_blas, which imports all of scipy.linalg (and
    numpy.f2py): about half of a warm process's kernel load. No kernel uses BLAS (no np.dot,
    no linalg), so the module is imported with the probe hidden, and its answer
    (arraymath._HAVE_BLAS, read when a compile types np.convolve or np.correlate) is then
    replaced by `_BlasProbe`, which asks the same question the first time a compile needs the
    answer: a user's own compiled np.convolve is the same with fencesweep loaded as without.
  * coverage, which Numba imports to report compiled lines to a coverage run. A coverage run
    imports coverage before Numba, and then nothing is hidden; what a process that starts
    coverage only after loading the kernels loses is the report of compiled lines, never code.
Each is hidden only for the length of that import (_hidden), and only when the process has
not imported it already. (And Numba's error-message highlighting is off: kernel/__init__.py.)
How the package's own compiles differ from Numba's: kernel/jit.py.
"""
from __future__ import annotations

import contextlib
import sys

from fencesweep.kernel.internals import NAMES, lookup  # a list of names: imports nothing of Numba itself


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


class _BlasProbe:
    """Numba's "is a BLAS there?" (numba.np.arraymath._HAVE_BLAS), asked by Numba's own probe
    the first time a compile reads it instead of when Numba loads (module docstring)."""

    def __init__(self, probe):
        self._probe, self._answer = probe, None

    def __bool__(self):
        if self._answer is None:
            self._answer = bool(self._probe())
        return self._answer


def _import_numba_support_without_probes() -> None:
    """Import Numba's NumPy support with the BLAS probe deferred (module docstring)."""
    module = NAMES["arraymath"].module
    if module in sys.modules:
        return  # already imported: nothing to save
    with _hidden("scipy.linalg.cython_blas"):
        arraymath = lookup("arraymath")
    setattr(arraymath, NAMES["HAVE_BLAS"].attr, _BlasProbe(lookup("check_blas")))


_import_numba_support_without_probes()

__all__ = ["numba"]
