"""How the compiled kernels are compiled. Every compiled function of the package is decorated
with one of:

  kernel()  a kernel function, called only from other compiled functions: numba.njit with
            * one signature: the function is compiled for the plain types of its arguments
              (KernelDispatcher), never for the literal type of a constant argument, which
              would make f(x, N_CTRL), f(x, N_STATE) and f(x, 3) three compilations
              (tests/test_jit.py checks one per function);
            * not cached itself, and compiled to LLVM IR only (KernelLibrary): it is compiled
              into the entry points that call it, which are cached (kernel/cache.py keeps their
              cache in a directory of its own, named by a hash of the kernel sources);
            * _nrt=False: without Numba's reference counting. A kernel function allocates
              nothing: it works on arrays its caller made, and the counting (an atomic increment
              and decrement of every array argument of every call) is a large part of a cycle's
              time. Off, an allocation inside a kernel function does not compile, so "no
              allocation in the loops" is checked by the compiler;
            * no_cpython_wrapper, no_cfunc_wrapper: without the wrappers that let Python (or C)
              call the function. Nothing but a kernel calls it, and the wrappers cost more to
              compile than a small function itself. `python_callable` gives a test or a Python
              caller its own callable copy;
            * KernelCompiler: Numba's nopython pipeline without the passes for what no kernel
              function uses (KernelCompiler's docstring).
  specialise(template, name, **bindings)  for the few generic functions that call a scene's
            compiled function (kernel/rk.py's step calls the right-hand side, kernel/driver.py's
            loop calls the step and the scene's accept, kernel/search.py calls a predicate or a
            quantity): the template is a plain function that calls the scene's function by a
            global name (RHS, STEP, ...); specialise compiles a copy of it with that name bound,
            once per scene, like a C++ template instance. Passing the function as an argument
            instead would make Numba inline the generic function at every call site to be able
            to cache it, a cold compile's cost per call site.
  entry()   an entry point, called from Python with one type signature (its caller passes
            float64 scalars and C-contiguous float64 / int64 arrays, so one compilation
            serves every call; tests/test_jit.py checks that every function has exactly one):
            with reference counting, as entry points allocate a run's work arrays once
            (EntryDispatcher, cached in kernel/cache.py's directory).
  kernel(allocates=True)  an entry point's allocations (its work arrays): a kernel function
            with reference counting, compiled as IR for the entry point like the others (so a
            first run's helper can compile it too: kernel/share.py); Python calls its plain
            function (`.py_func`) for arrays of the same types.

How the package's compiles differ from Numba's is confined to the package's own code: a kernel
function compiles into a KernelLibrary (LLVM IR only) and an entry point into an EntryLibrary,
subclasses of Numba's code library that their own pipelines (KernelCompiler, EntryCompiler)
make; Numba's classes are not changed. Numba's runtime and the helpers it compiles for an
overload during the package's compile are Numba's own libraries, so a user's own njit function
compiles to the same code in a process that has run the package's kernels as in one that has
not (tests/test_compile_isolation.py). While the package compiles (`own_compile`), Numba's
compiler lock is held and its LLVM-lock events are off. A first run compiles on two cores:
kernel/share.py.
"""
from __future__ import annotations

import contextlib
import functools
import types as pytypes

from fencesweep.kernel.numba_setup import numba  # first: Numba loaded without what it does not need
import numpy as np
from numba import njit, types

from fencesweep.kernel import cache, share
from fencesweep.kernel.internals import (  # Numba's internal names: kernel/internals.py says what each is for
    ATTRS, NAMES, AnnotateTypes, CompileResultCacheImpl, Compiler, CompilerBase, CPUDispatcher, DeadBranchPrune,
    FixupArgs, FunctionCache, GenericRewrites, InlineOverloads, IRLegalization, IRProcessing, JITCodeLibrary,
    NativeLowering, NoPythonBackend, NopythonTypeInference, NoPythonSupportedFeatureValidation, PassManager,
    RewriteDynamicRaises, RewriteSemanticConstants, TranslateByteCode, global_compiler_lock, lookup)
from fencesweep.kernel.libraries import EntryLibrary, KernelLibrary
from fencesweep.kernel.locator import KernelLocator

#: True when NUMBA_DISABLE_JIT=1: the decorators return the plain Python functions
JIT_DISABLED = bool(numba.config.DISABLE_JIT)


_KERNEL = dict(nopython=True, _nrt=False, no_cpython_wrapper=True, no_cfunc_wrapper=True)
#: an entry point's options: numba.njit's (nopython, boundscheck as njit leaves it) with
#: reference counting, no C callback wrapper (nothing calls it from C), and not inlined
_ENTRY = dict(nopython=True, boundscheck=None, _nrt=True, no_cfunc_wrapper=True, forceinline=False)


class _OwnLibrary:
    """A compiler pipeline (mixin) whose function gets a library of class `library_class`, made
    as Numba's lowering makes one (named by the function, object code kept for its cache)."""

    library_class = JITCodeLibrary

    def compile_extra(self, func):
        if self.state.library is None:
            self.state.library = self.library_class(self.state.targetctx.codegen(), func.__qualname__)
            self.state.library.enable_object_caching()
        return super().compile_extra(func)


class KernelCompiler(_OwnLibrary, CompilerBase):
    """Numba's nopython pipeline (numba.core.compiler.DefaultPassBuilder) for a kernel function,
    into a KernelLibrary, without the passes for what no kernel function uses; each of those
    passes walks the whole function, for ~140 functions in a first cycle:
      * with-contexts (objmode, parallel chunks), closures and functions made inside a kernel,
        Numba-level inlining (inline="always"; kernel(inline=True) asks LLVM instead),
        literally() and literal_unroll: not used by any kernel function;
      * the rewrites after typing: array expressions (a kernel allocates nothing, so it has none)
        and string getitems;
      * SSA form: a kernel variable keeps one type (the test suite and the tables tell if not:
        typing fails, or a result changes);
      * parfor diagnostics (no parallel=True).
    Kept: bytecode to IR, the constant rewrites (static getitem, constant raises), dead-branch
    pruning of constant conditions, typing, overload inlining, IR legalization, lowering."""

    library_class = KernelLibrary

    def define_pipelines(self):
        pm = PassManager("fencesweep kernel")
        for pass_class, what in (
                (TranslateByteCode, "analyzing bytecode"), (FixupArgs, "fix up args"),
                (IRProcessing, "processing IR"),
                (RewriteSemanticConstants, "rewrite semantic constants"),
                (DeadBranchPrune, "dead branch pruning"), (GenericRewrites, "nopython rewrites"),
                (RewriteDynamicRaises, "rewrite dynamic raises"),
                (NopythonTypeInference, "nopython frontend"),
                (InlineOverloads, "inline overloaded functions"),
                (NoPythonSupportedFeatureValidation, "ensure features that are in use are in a valid form"),
                (IRLegalization, "ensure IR is legal prior to lowering"),
                (AnnotateTypes, "annotate types"), (NativeLowering, "native lowering"),
                (NoPythonBackend, "nopython mode backend")):
            pm.add_pass(pass_class, what)
        pm.finalize()
        return [pm]


class EntryCompiler(_OwnLibrary, Compiler):
    """Numba's default pipeline (numba.njit's) for an entry point, into an EntryLibrary."""

    library_class = EntryLibrary


# ------------------------------------------------------------------ while the package compiles
def _llvm_lock():
    """llvmlite's lock around every call into LLVM (None if llvmlite has none)."""
    try:
        lib = lookup("llvm_lib")
    except ImportError:
        return None
    return getattr(lib, ATTRS["llvm_lock"].name, None)


class _Own:
    """The state of `own_compile`: how deep the package's compiles are nested, and the Numba
    LLVM-lock callbacks the outermost one took off."""

    depth = 0
    events: list = []


def _events_off() -> None:
    lock = _llvm_lock()
    if lock is not None:
        with lock._lock:  # no thread between an acquire callback and its release
            for pair in list(getattr(lock, ATTRS["lock_callbacks"].name, ())):
                if getattr(pair[0], "__module__", "") == NAMES["lock_events_module"].module:
                    lock.unregister(*pair)
                    _Own.events.append(pair)


def _events_on() -> None:
    lock = _llvm_lock()
    if lock is not None:
        with lock._lock:
            while _Own.events:
                lock.register(*_Own.events.pop(0))


@contextlib.contextmanager
def own_compile():
    """Around a compile (or cache load) of the package's: Numba's compiler lock held (a re-entrant
    lock every Numba compile takes, so no other thread's compile runs meanwhile), and without
    Numba's callbacks on llvmlite's lock. Those broadcast an event on every call into LLVM
    (thousands in a cold compile) only to add up each compiled function's time in LLVM (its
    metadata "timers"), which nothing here reads; the outermost block takes them off and puts
    them back. Entered once per compile, never per call of a compiled function."""
    with global_compiler_lock:
        if _Own.depth == 0:
            _events_off()
        _Own.depth += 1
        try:
            yield
        finally:
            _Own.depth -= 1
            if _Own.depth == 0:
                _events_on()


# ------------------------------------------------------------------ the dispatchers
class KernelDispatcher(CPUDispatcher):
    """Numba's dispatcher for a kernel function (module docstring): a call from compiled code is
    typed with the arguments' plain types (types.unliteral), so a constant argument does not make
    a new compilation; what it compiles is LLVM IR for its callers to link (KernelLibrary)."""

    def get_call_template(self, args, kws):
        return super().get_call_template(tuple(types.unliteral(a) for a in args),
                                         {k: types.unliteral(v) for k, v in kws.items()})

    def compile(self, sig):
        with own_compile(), share.turn(self):  # a cold compile on two cores: kernel/share.py
            return super().compile(sig)

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__qualname__} is a kernel function, called from compiled code only; "
                        f"fencesweep.kernel.jit.python_callable gives Python a callable copy")


class _EntryCacheImpl(CompileResultCacheImpl):
    """Numba's cache of an entry point's compile result, kept where KernelLocator says (kernel/cache.py's
    directory); Numba's own locators when it cannot (nowhere to write)."""

    _locator_classes = [KernelLocator, *CompileResultCacheImpl._locator_classes]


class EntryCache(FunctionCache):
    _impl_class = _EntryCacheImpl


class EntryDispatcher(CPUDispatcher):
    """Numba's dispatcher for an entry point, as numba.njit(cache=True) makes it, with its compile
    (or its load from the cache) under own_compile, into an EntryLibrary, and its cache in
    kernel/cache.py's directory."""

    def enable_caching(self):
        self._cache = EntryCache(self.py_func)

    def compile(self, sig):
        with own_compile():
            return super().compile(sig)


def kernel(inline=False, allocates=False):
    """The decorator of a kernel function (module docstring)."""
    if JIT_DISABLED:
        return lambda fn: fn
    targetoptions = dict(_KERNEL, forceinline=bool(inline), _nrt=bool(allocates))

    def compiled(fn):
        return KernelDispatcher(py_func=fn, locals={}, targetoptions=targetoptions, pipeline_class=KernelCompiler)

    return compiled


def entry(**options):
    """The decorator of an entry point called from Python (module docstring)."""
    if JIT_DISABLED:
        return lambda fn: fn
    targetoptions = dict(_ENTRY, **options)

    def compiled(fn):
        disp = EntryDispatcher(py_func=fn, locals={}, targetoptions=targetoptions, pipeline_class=EntryCompiler)
        disp.enable_caching()
        return disp

    return compiled


#: where a template allocates on the CPU: HEAP.local.array(shape, dtype) is np.empty. A GPU
#: thread's copy of the template binds numba.cuda itself, whose local.array (the thread's local
#: memory) takes the same arguments (kernel/cuda.py; scenes/stream.py cycles_with_work)
HEAP = pytypes.ModuleType("fencesweep.kernel.jit.HEAP")
HEAP.local = pytypes.ModuleType("fencesweep.kernel.jit.HEAP.local")
HEAP.local.array = np.empty


def bind(template, name: str, **bindings):
    """The plain function `template` with the global names in `bindings` bound (to kernel
    functions, or to how a target allocates), named `name`: a copy of its code with its own
    globals, which a decorator then compiles (specialise; scenes/stream.py run_on_heap; a GPU
    thread's device functions, kernel/cuda.py)."""
    fn = pytypes.FunctionType(template.__code__, {**template.__globals__, **bindings}, name,
                              template.__defaults__, template.__closure__)
    fn.__qualname__ = name
    fn.__doc__ = template.__doc__
    return fn


def specialise(template, name: str, **bindings):
    """A kernel function compiled from the plain function `template` with the global names in
    `bindings` bound to other kernel functions (module docstring). `name` names it in the cache
    and in profiles (it must be unique in the package)."""
    return kernel()(bind(template, name, **bindings))


@functools.lru_cache(maxsize=None)
def python_callable(fn):
    """A copy of kernel function `fn` that Python can call (tests, and Python code that needs a
    formula once): compiled on its first call, not cached on disk. `fn` itself when the JIT is off."""
    if JIT_DISABLED or not hasattr(fn, "py_func"):
        return fn
    return njit(_nrt=False)(fn.py_func)


__all__ = ["kernel", "entry", "HEAP", "bind", "specialise", "python_callable", "own_compile", "cache", "JIT_DISABLED"]
