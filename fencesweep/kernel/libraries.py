"""The package's own code libraries (kernel/jit.py's module docstring): a kernel function's
(KernelLibrary, LLVM IR only) and an entry point's (EntryLibrary), subclasses of Numba's code
library, so that how the package's compiles differ from Numba's stays in the package's own code.
A leaf of kernel/: jit.py compiles into them, share.py loads a shared compile's bitcode into them.
"""
from __future__ import annotations

import contextlib

from fencesweep.kernel.numba_setup import numba  # noqa: F401  (first: Numba loaded as the kernels need it)
from fencesweep.kernel.internals import ATTRS, JITCodeLibrary, global_compiler_lock


def _optimize_functions_once(library, ll_module) -> None:
    """CPUCodeLibrary._optimize_functions with one function pass manager for the module: Numba
    builds a new pass builder and pass manager for every function of every module it adds
    (declarations included), ~1000 of them for a first cycle."""
    ll_module.data_layout = library._codegen._data_layout
    fpm, pb = library._codegen._function_pass_manager()
    for func in ll_module.functions:
        if not func.is_declaration:
            fpm.run(func, pb)


class _NoEnvironment:
    """The code generator as a kernel function's library shows it: setting a function's
    environment does nothing, as no machine code of the library holds one (KernelLibrary)."""

    def __init__(self, codegen):
        self._codegen = codegen

    def set_env(self, env_name, env) -> None:
        pass

    def __getattr__(self, name):
        return getattr(self._codegen, name)


class KernelLibrary(JITCodeLibrary):
    """A kernel function's own code library: LLVM IR that its callers link and
    optimize with their own code (Numba links every callee's IR into its caller's module). The
    library is not optimized as a module nor turned into machine code, which only an entry
    point's is: that work would be most of a cold compile's LLVM time, all of it redone in every
    caller. Nothing runs a kernel function's own machine code: only entry points are called from
    Python, and only they are cached. Numba's own libraries (its runtime, the helpers it compiles
    for an overload), made during the same compile, are Numba's and compiled as Numba compiles
    them: a later compile of a user's function links the same code as without fencesweep."""

    _optimize_functions = _optimize_functions_once

    def _optimize_final_module(self) -> None:
        pass

    def _finalize_final_module(self) -> None:
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True

    @property
    def codegen(self):
        return _NoEnvironment(self._codegen)


class EntryLibrary(JITCodeLibrary):
    """An entry point's own code library: Numba's, with one function pass manager per module."""

    _optimize_functions = _optimize_functions_once


@contextlib.contextmanager
def kernel_libraries(codegen):
    """Within the block, a library Numba makes or loads with `codegen` is a KernelLibrary: for a
    kernel function loaded from a shared compile's bitcode (kernel/share.py), where Numba makes
    the library itself. Holds Numba's compiler lock, as every library is made under it."""
    library_class = ATTRS["library_class"].name
    with global_compiler_lock:
        setattr(codegen, library_class, KernelLibrary)  # the instance's, over its class's
        try:
            yield
        finally:
            delattr(codegen, library_class)
