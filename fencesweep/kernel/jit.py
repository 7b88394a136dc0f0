"""How the compiled kernels are compiled. Every compiled function of the package is decorated
with one of:

  kernel()  a kernel function, called only from other compiled functions: numba.njit with
            * one signature: the function is compiled for the plain types of its arguments
              (KernelDispatcher), never for the literal type of a constant argument. Numba
              would otherwise compile f(x, N_CTRL), f(x, N_STATE) and f(x, 3) as three
              functions, f(x, True) and f(x, flag) as two (measured: 1130 compilations of 79
              functions for a first cycle before; tests/test_jit.py checks one per function);
            * not cached itself: it is compiled into the entry points that call it, which are
              (IR_ONLY below; kernel/cache.py keeps their cache in a directory of its own, named
              by a hash of every kernel source);
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
              `python_callable` gives a test or a Python caller its own callable copy;
            * KernelCompiler: Numba's nopython pipeline without the passes for what no kernel
              function uses (KernelCompiler's docstring).
  specialise(template, name, **bindings)  for the few generic functions that call a scene's
            compiled function (kernel/rk.py's step calls the right-hand side, kernel/driver.py's
            loop calls the step and the scene's accept, kernel/search.py calls a predicate or a
            quantity): the template is a plain function that calls the scene's function by a
            global name (RHS, STEP, ...); specialise compiles a copy of it with that name bound,
            once per scene, like a C++ template instance. Passing the function as an argument
            instead would make Numba inline the generic function at every call site to be able
            to cache it (measured: 0.5-2.4 s of a cold compile per call site).
  entry()   an entry point, called from Python with one type signature (its caller passes
            float64 scalars and C-contiguous float64 / int64 arrays, so one compilation
            serves every call; tests/test_jit.py checks that every function has exactly one):
            with reference counting, as entry points allocate a run's work arrays once.
  kernel(allocates=True)  an entry point's allocations (its work arrays): a kernel function
            with reference counting, compiled as IR for the entry point like the others (so a
            first run's helper can compile it too: kernel/share.py); Python calls its plain
            function (`.py_func`) for arrays of the same types.
A first run compiles on two cores: kernel/share.py.
"""
from __future__ import annotations

import functools
import types as pytypes

from fencesweep.kernel.numba_setup import numba  # first: Numba loaded without what it does not need
from numba import njit, types
from numba.core import caching
from numba.core import typed_passes as tp, untyped_passes as up
from numba.core.codegen import CPUCodeLibrary, JITCPUCodegen
from numba.core.compiler import CompilerBase
from numba.core.compiler_machinery import PassManager
from numba.core.registry import CPUDispatcher

from fencesweep.kernel import cache, share
from fencesweep.kernel.locator import KernelLocator

# ------------------------------------------------------------------ where the entry points are cached
def _register() -> None:
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
    if KernelLocator not in impl._locator_classes:
        impl._locator_classes.insert(0, KernelLocator)


_register()


#: True when NUMBA_DISABLE_JIT=1: the decorators return the plain Python functions
JIT_DISABLED = bool(numba.config.DISABLE_JIT)


_KERNEL = dict(nopython=True, _nrt=False, no_cpython_wrapper=True, no_cfunc_wrapper=True)


#: kernel functions being compiled, innermost last (KernelDispatcher.compile)
_COMPILING: list = []


class KernelCompiler(CompilerBase):
    """Numba's nopython pipeline (numba.core.compiler.DefaultPassBuilder) for a kernel function,
    without the passes for what no kernel function uses; each of those passes walks the whole
    function, about 1 s of a first cycle's 15 s (results/startup.md):
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

    def define_pipelines(self):
        pm = PassManager("fencesweep kernel")
        for pass_class, what in (
                (up.TranslateByteCode, "analyzing bytecode"), (up.FixupArgs, "fix up args"),
                (up.IRProcessing, "processing IR"),
                (up.RewriteSemanticConstants, "rewrite semantic constants"),
                (up.DeadBranchPrune, "dead branch pruning"), (up.GenericRewrites, "nopython rewrites"),
                (up.RewriteDynamicRaises, "rewrite dynamic raises"),
                (tp.NopythonTypeInference, "nopython frontend"),
                (tp.InlineOverloads, "inline overloaded functions"),
                (tp.NoPythonSupportedFeatureValidation, "ensure features that are in use are in a valid form"),
                (tp.IRLegalization, "ensure IR is legal prior to lowering"),
                (tp.AnnotateTypes, "annotate types"), (tp.NativeLowering, "native lowering"),
                (tp.NoPythonBackend, "nopython mode backend")):
            pm.add_pass(pass_class, what)
        pm.finalize()
        return [pm]


class KernelDispatcher(CPUDispatcher):
    """Numba's dispatcher for a kernel function (module docstring): a call from compiled code is
    typed with the arguments' plain types (types.unliteral), so a constant argument does not make
    a new compilation; what it compiles is LLVM IR for its callers to link (IR_ONLY)."""

    def get_call_template(self, args, kws):
        return super().get_call_template(tuple(types.unliteral(a) for a in args),
                                         {k: types.unliteral(v) for k, v in kws.items()})

    def compile(self, sig):
        _COMPILING.append(self)
        try:
            with share.turn(self):  # a cold compile on two cores: kernel/share.py
                return super().compile(sig)
        finally:
            _COMPILING.pop()

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__qualname__} is a kernel function, called from compiled code only; "
                        f"fencesweep.kernel.jit.python_callable gives Python a callable copy")


def _ir_only(method):
    """A CPUCodeLibrary method that does nothing for a kernel function's own library (IR_ONLY)."""

    def wrapped(library):
        if not _COMPILING:
            method(library)

    wrapped.__wrapped__ = method
    return wrapped


def _ir_only_finalize(method):
    """CPUCodeLibrary._finalize_final_module that, for a kernel function's own library, only
    checks its IR and marks it final: no machine code (IR_ONLY)."""

    def wrapped(library):
        if not _COMPILING:
            return method(library)
        library._finalize_dynamic_globals()
        library._verify_declare_only_symbols()
        library._finalized = True

    wrapped.__wrapped__ = method
    return wrapped


#: IR_ONLY: a kernel function's own library is LLVM IR that its callers link and optimize with
#: their own code (Numba links every callee's IR into its caller's module); the library is not
#: optimized as a module nor turned into machine code, which only an entry point's is (measured:
#: its module passes and its machine code were ~2/3 of a cold compile's LLVM time, all of it
#: redone in every caller). Nothing runs a kernel function's own machine code: only entry points
#: are called from Python, and only they are cached.
IR_ONLY = not hasattr(CPUCodeLibrary._finalize_final_module, "__wrapped__")
def _ir_only_env(method):
    """JITCPUCodegen.set_env that leaves alone the environment of a kernel function's own library,
    which has no machine code to hold it (IR_ONLY)."""

    def wrapped(codegen, env_name, env):
        if not _COMPILING:
            method(codegen, env_name, env)

    wrapped.__wrapped__ = method
    return wrapped


def _optimize_functions(library, ll_module):
    """CPUCodeLibrary._optimize_functions with one function pass manager for the module: Numba
    builds a new pass builder and pass manager for every function of every module it adds
    (declarations included), ~1000 of them for a first cycle; the passes run, and the code they
    give, are the same (tables identical; measured: a first cycle ~1 s less of its ~15 s)."""
    ll_module.data_layout = library._codegen._data_layout
    fpm, pb = library._codegen._function_pass_manager()
    for func in ll_module.functions:
        if not func.is_declaration:
            fpm.run(func, pb)


if IR_ONLY:
    if hasattr(numba.core.codegen, "create_pass_builder"):  # Numba on LLVM's new pass manager
        _optimize_functions.__wrapped__ = CPUCodeLibrary._optimize_functions
        CPUCodeLibrary._optimize_functions = _optimize_functions
    CPUCodeLibrary._optimize_final_module = _ir_only(CPUCodeLibrary._optimize_final_module)
    CPUCodeLibrary._finalize_final_module = _ir_only_finalize(CPUCodeLibrary._finalize_final_module)
    JITCPUCodegen.set_env = _ir_only_env(JITCPUCodegen.set_env)


def kernel(inline=False, allocates=False):
    """The decorator of a kernel function (module docstring)."""
    if JIT_DISABLED:
        return lambda fn: fn
    targetoptions = dict(_KERNEL, forceinline=bool(inline), _nrt=bool(allocates))

    def compiled(fn):
        return KernelDispatcher(py_func=fn, locals={}, targetoptions=targetoptions, pipeline_class=KernelCompiler)

    return compiled


def entry(**options):
    """numba.njit for an entry point called from Python (module docstring)."""
    return njit(cache=True, _nrt=True, no_cfunc_wrapper=True, forceinline=False, **options)


def specialise(template, name: str, **bindings):
    """A kernel function compiled from the plain function `template` with the global names in
    `bindings` bound to other kernel functions (module docstring). `name` names it in the cache
    and in profiles (it must be unique in the package)."""
    fn = pytypes.FunctionType(template.__code__, {**template.__globals__, **bindings}, name,
                              template.__defaults__, template.__closure__)
    fn.__qualname__ = name
    fn.__doc__ = template.__doc__
    return kernel()(fn)


@functools.lru_cache(maxsize=None)
def python_callable(fn):
    """A copy of kernel function `fn` that Python can call (tests, and Python code that needs a
    formula once): compiled on its first call, not cached on disk. `fn` itself when the JIT is off."""
    if JIT_DISABLED or not hasattr(fn, "py_func"):
        return fn
    return njit(_nrt=False)(fn.py_func)


__all__ = ["kernel", "entry", "specialise", "python_callable", "cache", "JIT_DISABLED"]
