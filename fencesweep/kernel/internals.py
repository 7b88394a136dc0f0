"""The private and internal names of Numba, numba-cuda and llvmlite that the compile layer
(kernel/jit.py, libraries.py, locator.py, share.py, numba_setup.py, cuda.py) uses, in one list:
where each is, which modules use it, and what for. None is Numba's public API, so a Numba release
may move one; the layer takes them from here, so that a move breaks here, in one place, with a
message naming the name and the modules that use it (tests/test_internals.py checks each against
the installed versions).

  NAMES  what a module holds (the module itself, or one of its attributes): imported from here
         by its key (`from fencesweep.kernel.internals import JITCodeLibrary`), or looked up by
         where it is (`NAMES[key].module`, `.attr`) where the layer sets it or imports it by
         name. Each is imported when first asked for: this module imports nothing of Numba, so
         numba_setup.py, which loads Numba, takes its names from here too, and a module that
         uses one imports Numba through numba_setup.py first, as every kernel module does. A
         numba-cuda name is asked for only after kernel/cuda.py's load().
  ATTRS  attributes the layer reads, sets or overrides on Numba's classes and objects (a
         dispatcher's `_cache`, a cache class's `_impl_class`), with the class they are looked
         up on: "class" ones are on the class, "instance" ones are set by its __init__, a
         "parameter" is one of the callable's parameters. The code names them as attributes,
         or by ATTRS[key].name where it looks them up by name; the test also checks that the
         layer uses no private attribute that is not listed.
  REBUILD_PAYLOAD  the order of a cached compile result's parts (kernel/share.py).

Not listed: the public API (numba.njit, numba.types, numba.typeof, numba.config, numba.cuda's jit,
compile_ptx, device queries), and a dispatcher's py_func and compile().
"""
from __future__ import annotations

import importlib
from importlib.metadata import PackageNotFoundError, version
from typing import NamedTuple


class Name(NamedTuple):
    """A name a module holds: `path` is "module" or "module:attribute"."""

    path: str
    #: the kernel/ modules that use it
    users: tuple
    #: what they use it for
    why: str

    @property
    def module(self) -> str:
        return self.path.partition(":")[0]

    @property
    def attr(self) -> str:
        return self.path.partition(":")[2]


class Attr(NamedTuple):
    """An attribute `name` looked up on the class at `on` ("module:Class"), of kind "class",
    "instance" or "parameter" (module docstring)."""

    name: str
    on: str
    kind: str
    users: tuple
    why: str


_CACHE, _CODEGEN, _CUDA = "numba.core.caching", "numba.core.codegen", "numba.cuda.dispatcher"
_PASS = ("jit",), "a pass of KernelCompiler's pipeline"

#: every module, class, function and value of Numba's the layer takes from a module (module docstring)
NAMES = {
    "CacheLocator": Name(f"{_CACHE}:_CacheLocator", ("locator",), "the base of KernelLocator: where a cache's files go"),
    "CompileResultCacheImpl": Name(f"{_CACHE}:CompileResultCacheImpl", ("jit", "share"),
                                   "the base of _EntryCacheImpl and _BitcodeImpl: how a compile result is kept"),
    "FunctionCache": Name(f"{_CACHE}:FunctionCache", ("jit", "share"), "the base of EntryCache and KernelCache"),
    "NullCache": Name(f"{_CACHE}:NullCache", ("share",), "a kernel function's cache again after a shared compile"),
    "JITCodeLibrary": Name(f"{_CODEGEN}:JITCodeLibrary", ("jit", "libraries"),
                           "the base of KernelLibrary and EntryLibrary; a pipeline's library class"),
    "global_compiler_lock": Name("numba.core.compiler_lock:global_compiler_lock", ("jit", "libraries", "cuda"),
                                 "held around the package's compiles, a library's making, a GPU compile"),
    "Compiler": Name("numba.core.compiler:Compiler", ("jit",), "the base of EntryCompiler: numba.njit's pipeline"),
    "CompilerBase": Name("numba.core.compiler:CompilerBase", ("jit",), "the base of KernelCompiler"),
    "PassManager": Name("numba.core.compiler_machinery:PassManager", ("jit",), "KernelCompiler's pipeline"),
    "CPUDispatcher": Name("numba.core.registry:CPUDispatcher", ("jit",),
                          "the base of KernelDispatcher and EntryDispatcher"),
    "TranslateByteCode": Name("numba.core.untyped_passes:TranslateByteCode", *_PASS),
    "FixupArgs": Name("numba.core.untyped_passes:FixupArgs", *_PASS),
    "IRProcessing": Name("numba.core.untyped_passes:IRProcessing", *_PASS),
    "RewriteSemanticConstants": Name("numba.core.untyped_passes:RewriteSemanticConstants", *_PASS),
    "DeadBranchPrune": Name("numba.core.untyped_passes:DeadBranchPrune", *_PASS),
    "GenericRewrites": Name("numba.core.untyped_passes:GenericRewrites", *_PASS),
    "RewriteDynamicRaises": Name("numba.core.untyped_passes:RewriteDynamicRaises", *_PASS),
    "NopythonTypeInference": Name("numba.core.typed_passes:NopythonTypeInference", *_PASS),
    "InlineOverloads": Name("numba.core.typed_passes:InlineOverloads", *_PASS),
    "NoPythonSupportedFeatureValidation": Name("numba.core.typed_passes:NoPythonSupportedFeatureValidation", *_PASS),
    "IRLegalization": Name("numba.core.typed_passes:IRLegalization", *_PASS),
    "AnnotateTypes": Name("numba.core.typed_passes:AnnotateTypes", *_PASS),
    "NativeLowering": Name("numba.core.typed_passes:NativeLowering", *_PASS),
    "NoPythonBackend": Name("numba.core.typed_passes:NoPythonBackend", *_PASS),
    "llvm_lib": Name("llvmlite.binding.ffi:lib", ("jit",), "llvmlite's library, which holds its lock around LLVM calls"),
    "lock_events_module": Name("numba.core.base", ("jit",),
                               "the module of Numba's LLVM-lock callbacks, which own_compile takes off"),
    "arraymath": Name("numba.np.arraymath", ("numba_setup",), "Numba's NumPy support, imported without the BLAS probe"),
    "HAVE_BLAS": Name("numba.np.arraymath:_HAVE_BLAS", ("numba_setup",), "the BLAS answer, replaced by _BlasProbe"),
    "check_blas": Name("numba.np.arraymath:_check_blas", ("numba_setup",), "the BLAS probe _BlasProbe asks later"),
    "CUDACache": Name(f"{_CUDA}:CUDACache", ("cuda",), "the base of cache_kernel's Cache"),
    "CUDACacheImpl": Name(f"{_CUDA}:CUDACacheImpl", ("cuda",), "the base of cache_kernel's Impl"),
    "get_current_device": Name(f"{_CUDA}:get_current_device", ("cuda",),
                               "replaced by _asked_cc while a GPU-less compile asks for the device"),
    "cuda_arrayobj": Name("numba.cuda.np.arrayobj", ("cuda",), "imported by load(): it registers np.row_stack"),
    "cuda_simulator": Name("numba.cuda.simulator", ("cuda",), "the module prefix of a simulator kernel (not cached)"),
}

_LOCK, _LIB = "llvmlite.binding.ffi:_LLVMLock", f"{_CODEGEN}:JITCodeLibrary"
_LOCATOR, _IMPL = f"{_CACHE}:_CacheLocator", f"{_CACHE}:CompileResultCacheImpl"
_RESULT, _DISPATCHER = "numba.core.compiler:CompileResult", "numba.core.registry:CPUDispatcher"
_OPTIONS = "numba.core.cpu:CPUTargetOptions"

#: every attribute of Numba's objects the layer reads, sets or overrides (module docstring)
ATTRS = {
    "locator_classes": Attr("_locator_classes", _IMPL, "class", ("jit", "share"), "the locators a cache tries in turn"),
    "cuda_locator_classes": Attr("_locator_classes", f"{_CUDA}:CUDACacheImpl", "class", ("cuda",),
                                 "KernelLocator as a GPU kernel's only locator"),
    "impl_class": Attr("_impl_class", f"{_CACHE}:FunctionCache", "class", ("jit", "share"), "a cache's implementation"),
    "cuda_impl_class": Attr("_impl_class", f"{_CUDA}:CUDACache", "class", ("cuda",), "a GPU cache's implementation"),
    "save_overload": Attr("save_overload", f"{_CACHE}:FunctionCache", "class", ("share",),
                          "overridden: a shared compile's entry saved by one process"),
    "reduce": Attr("reduce", _IMPL, "class", ("share",), "overridden: a kernel function's result as bitcode"),
    "rebuild": Attr("rebuild", _IMPL, "class", ("share",), "overridden: loaded into a KernelLibrary"),
    "ensure_cache_path": Attr("ensure_cache_path", _LOCATOR, "class", ("locator",), "called: the directory is made"),
    "get_cache_path": Attr("get_cache_path", _LOCATOR, "class", ("locator",), "overridden: the cache directory"),
    "get_source_stamp": Attr("get_source_stamp", _LOCATOR, "class", ("locator",), "overridden: the kernel hash"),
    "get_disambiguator": Attr("get_disambiguator", _LOCATOR, "class", ("locator",), "overridden: the line number"),
    "from_function": Attr("from_function", _LOCATOR, "class", ("locator",), "overridden: the package's functions only"),
    "locator_py_file": Attr("_py_file", f"{_CACHE}:InTreeCacheLocator", "instance", ("locator",),
                            "kept by KernelLocator as Numba's locators keep it: a cache's check_cachable names it "
                            "in its warning"),
    "find_referenced_environments": Attr("_find_referenced_environments", _RESULT, "class", ("share",),
                                         "called by _BitcodeImpl.reduce, as CompileResult._reduce does"),
    "rebuild_result": Attr("_rebuild", _RESULT, "class", ("share",),
                           "called by Numba's rebuild with _BitcodeImpl.reduce's payload (REBUILD_PAYLOAD)"),
    "optimize_functions": Attr("_optimize_functions", _LIB, "class", ("libraries",),
                               "replaced: one function pass manager per module"),
    "optimize_final_module": Attr("_optimize_final_module", _LIB, "class", ("libraries",),
                                  "overridden: a kernel function's module is not optimized"),
    "finalize_final_module": Attr("_finalize_final_module", _LIB, "class", ("libraries",),
                                  "overridden: no machine code for a kernel function"),
    "finalize_dynamic_globals": Attr("_finalize_dynamic_globals", _LIB, "class", ("libraries",),
                                     "called by KernelLibrary._finalize_final_module"),
    "verify_declare_only_symbols": Attr("_verify_declare_only_symbols", _LIB, "class", ("libraries",),
                                        "called by KernelLibrary._finalize_final_module"),
    "finalized": Attr("_finalized", _LIB, "instance", ("libraries",), "set by KernelLibrary._finalize_final_module"),
    "library_codegen": Attr("_codegen", _LIB, "instance", ("libraries",), "a library's code generator"),
    "codegen_property": Attr("codegen", _LIB, "class", ("libraries",), "overridden: _NoEnvironment for a kernel"),
    "enable_object_caching": Attr("enable_object_caching", _LIB, "class", ("jit",), "called for a pipeline's library"),
    "serialize_using_bitcode": Attr("serialize_using_bitcode", _LIB, "class", ("share",), "a kernel's IR, cached"),
    "data_layout": Attr("_data_layout", f"{_CODEGEN}:JITCPUCodegen", "instance", ("libraries",),
                        "the data layout of a module whose functions are optimized"),
    "function_pass_manager": Attr("_function_pass_manager", f"{_CODEGEN}:JITCPUCodegen", "class", ("libraries",),
                                  "the function pass manager of _optimize_functions_once"),
    "library_class": Attr("_library_class", f"{_CODEGEN}:JITCPUCodegen", "class", ("libraries",),
                          "set on a code generator by kernel_libraries: the library class it makes"),
    "compile_extra": Attr("compile_extra", "numba.core.compiler:CompilerBase", "class", ("jit",),
                          "overridden by _OwnLibrary: the pipeline's library made first"),
    "define_pipelines": Attr("define_pipelines", "numba.core.compiler:CompilerBase", "class", ("jit",),
                             "overridden: KernelCompiler's pipeline"),
    "state_library": Attr("library", "numba.core.compiler:StateDict", "instance", ("jit",),
                          "a compile's library, made by _OwnLibrary"),
    "state_targetctx": Attr("targetctx", "numba.core.compiler:StateDict", "instance", ("jit",),
                            "a compile's target context, whose codegen() makes the library"),
    "target_codegen": Attr("codegen", "numba.core.cpu:CPUContext", "class", ("jit", "share"),
                           "the code generator a library is made with"),
    "dispatcher_cache": Attr("_cache", _DISPATCHER, "instance", ("jit", "share"),
                             "a dispatcher's cache: EntryCache, KernelCache, NullCache"),
    "get_call_template": Attr("get_call_template", _DISPATCHER, "class", ("jit",),
                              "overridden: a kernel typed with unliteral arguments"),
    "enable_caching": Attr("enable_caching", _DISPATCHER, "class", ("jit",), "overridden: an EntryCache"),
    "pipeline_class": Attr("pipeline_class", f"{_DISPATCHER}.__init__", "parameter", ("jit",),
                           "a dispatcher's compiler (KernelCompiler, EntryCompiler)"),
    "nrt": Attr("_nrt", _OPTIONS, "class", ("jit",), "a target option: reference counting off in a kernel"),
    "no_cpython_wrapper": Attr("no_cpython_wrapper", _OPTIONS, "class", ("jit",), "a target option of a kernel"),
    "no_cfunc_wrapper": Attr("no_cfunc_wrapper", _OPTIONS, "class", ("jit",), "a target option of every function"),
    "forceinline": Attr("forceinline", _OPTIONS, "class", ("jit",), "a target option: kernel(inline=True)"),
    "llvm_lock": Attr("_lock", "llvmlite.binding.ffi:_lib_wrapper", "instance", ("jit",),
                      "llvmlite's lock around every call into LLVM"),
    "lock_mutex": Attr("_lock", _LOCK, "instance", ("jit",), "held while own_compile changes the callbacks"),
    "lock_callbacks": Attr("_cblist", _LOCK, "instance", ("jit",), "the callbacks, Numba's taken off by own_compile"),
    "lock_register": Attr("register", _LOCK, "class", ("jit",), "puts a callback back"),
    "lock_unregister": Attr("unregister", _LOCK, "class", ("jit",), "takes a callback off"),
    "cuda_dispatcher_cache": Attr("_cache", f"{_CUDA}:CUDADispatcher", "instance", ("cuda",),
                                  "a GPU kernel's cache, set by cache_kernel"),
}

#: the parameters of CompileResult._rebuild after the target context, in order: the payload of a
#: kernel function's cached result (kernel/share.py _BitcodeImpl.reduce, as CompileResult._reduce)
REBUILD_PAYLOAD = ("libdata", "fndesc", "env", "signature", "objectmode", "lifted", "typeann", "reload_init",
                   "referenced_envs")


def resolve(path: str):
    """The object at `path`: "module", "module:attribute" or "module:Class.attribute"."""
    module, _, attrs = path.partition(":")
    obj = importlib.import_module(module)
    for a in filter(None, attrs.split(".")):
        obj = getattr(obj, a)
    return obj


def installed(path: str) -> str:
    """The installed package that `path` is in, with its version ("numba 0.61.0")."""
    package = "llvmlite" if path.startswith("llvmlite") else "numba-cuda" if path.startswith("numba.cuda") else "numba"
    try:
        return f"{package} {version(package)}"
    except PackageNotFoundError:
        return f"{package} (not installed)"


def moved(what: str, users: tuple, why: str, reason) -> str:
    """The message for a listed name that the installed packages do not have."""
    where = ", ".join(f"fencesweep/kernel/{u}.py" for u in users)
    return (f"{what} is not in the installed {installed(what)} ({reason}); {where} uses it ({why}): "
            f"see its entry in fencesweep/kernel/internals.py")


def lookup(key: str):
    """The object NAMES[key] names; ImportError naming it and its users where it is not there."""
    name = NAMES[key]
    try:
        return resolve(name.path)
    except (ImportError, AttributeError) as exc:
        raise ImportError(moved(name.path, name.users, name.why, f"{type(exc).__name__}: {exc}")) from None


def __getattr__(key: str):
    """`from fencesweep.kernel.internals import X`: NAMES[X], looked up once."""
    if key not in NAMES:
        raise AttributeError(f"module {__name__!r} has no attribute {key!r}")
    value = globals()[key] = lookup(key)
    return value


__all__ = ["ATTRS", "NAMES", "REBUILD_PAYLOAD", "Attr", "Name", "installed", "lookup", "moved", "resolve"]
