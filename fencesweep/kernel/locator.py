"""Where Numba keeps a kernel's compiled code: `KernelLocator`, a Numba cache locator for the
package's functions, rooted at kernel/cache.py's DIR (the entry points: kernel/jit.py's
EntryCache) or, as a subclass, at a shared compile's directory (kernel functions,
kernel/share.py). Only those caches of the package use it: Numba's caching of other functions
is left as it is."""
from __future__ import annotations

from pathlib import Path

from fencesweep.kernel.numba_setup import numba  # noqa: F401  first: Numba loaded as the kernels load it
from fencesweep.kernel import cache
from fencesweep.kernel.internals import CacheLocator


class KernelLocator(CacheLocator):
    """A function's cache files go to root(), under the path of its module, and are valid while
    the kernel hash is (kernel/cache.py)."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file  # named by Numba's warning when a compile result cannot be cached
        self._lineno = py_func.__code__.co_firstlineno
        self._path = self.root() / Path(py_file).resolve().relative_to(cache.PKG).parent

    @classmethod
    def root(cls) -> Path:
        return cache.DIR

    def get_cache_path(self):
        return str(self._path)

    def get_source_stamp(self):
        return cache.HASH

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            Path(py_file).resolve().relative_to(cache.PKG)
        except ValueError:  # not a function of this package: Numba's own locators decide
            return None
        self = cls(py_func, py_file)
        try:
            self.ensure_cache_path()
        except OSError:  # nowhere to write: Numba's own locators (or no cache) then
            return None
        return self
