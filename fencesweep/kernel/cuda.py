"""The kernel functions compiled for a GPU by numba-cuda, from their own Python source: no physics here.

A kernel function (kernel/jit.py) is plain Python compiled by numba.njit; it allocates nothing
and calls other kernel functions by their global names (or through modules: rk.next_step).
`device(fn)` makes numba-cuda's device function of the same source: a copy of fn's code
(jit.bind) whose globals name the device functions of the kernel functions it calls (and
proxies of the package's modules whose kernel functions are device functions), made as needed
and once each. Templates bind their own names (`MEM`: jit.HEAP on the CPU, where MEM.local.array is
np.empty; numba.cuda in a GPU thread, cuda.local.array). So the GPU runs the same functions, line for line, as the CPU; what differs is
only the compiler (and that it contracts a * b + c into one fused multiply-add, as the CPU's
does not).

numba-cuda is an optional dependency (`pip install -e ".[gpu]"`): `load()` imports it or raises
GpuUnavailable saying how to install it. numba-cuda registers an overload of np.row_stack,
which NumPy 2.5 removed; where it is missing, the alias np.row_stack = np.vstack is in place
for the length of that import only (`_row_stack_alias`).

A PTX compile needs no GPU (`compile_ptx`), but numba-cuda asks the current device for its
compute capability when it compiles a device function for a kernel: without a GPU, that one
question is answered with the compute capability being compiled for (`_asked_cc`), for the
length of the compile and under Numba's compiler lock.
"""
from __future__ import annotations

import contextlib
import importlib
import threading
import types as pytypes

from fencesweep.errors import GpuUnavailable
from fencesweep.kernel.internals import NAMES  # a list of names: imports nothing of Numba itself

#: how to get the GPU path, said by every message about it missing
INSTALL = 'pip install -e ".[gpu]" (numba-cuda with the CUDA compiler and runtime as wheels; no system CUDA)'


@contextlib.contextmanager
def _row_stack_alias():
    """np.row_stack while numba-cuda registers its overload of it, where NumPy (>= 2.5) has none."""
    import numpy as np

    missing = not hasattr(np, "row_stack")
    if missing:
        np.row_stack = np.vstack
    try:
        yield
    finally:
        if missing:
            del np.row_stack


_LOADED: dict = {}


def load():
    """numba.cuda, imported (with its NumPy support, module docstring), or GpuUnavailable."""
    if "cuda" not in _LOADED:
        try:
            with _row_stack_alias():
                cuda = importlib.import_module("numba.cuda")
                importlib.import_module(NAMES["cuda_arrayobj"].module)  # the module that registers np.row_stack
        except ImportError as exc:
            raise GpuUnavailable(f"the GPU path needs numba-cuda, which is not installed here ({exc}): {INSTALL}") \
                from None
        _LOADED["cuda"] = cuda
    return _LOADED["cuda"]


def version() -> str:
    """numba-cuda's version."""
    load()
    from importlib.metadata import version as v

    return v("numba-cuda")


def gpus() -> list:
    """The GPUs numba-cuda finds: [{"id", "name", "cc", "memory"}] ([] when none is, or no driver)."""
    cuda = load()
    if cuda.config.ENABLE_CUDASIM:
        return [{"id": 0, "name": "Numba's CUDA simulator (on the CPU)", "cc": (0, 0), "memory": 0}]
    try:
        if not cuda.is_available():
            return []
        out = []
        for g in cuda.gpus:
            with g:
                free, total = cuda.current_context().get_memory_info()
                out.append({"id": g.id, "name": _name(g.name), "cc": tuple(g.compute_capability), "memory": total})
        return out
    except Exception:  # a driver that fails to start: no GPU to use
        return []


def _name(name) -> str:
    return name.decode() if isinstance(name, bytes) else str(name)


def require_gpu() -> dict:
    """The GPU a run uses (the first one), or GpuUnavailable."""
    found = gpus()
    if not found:
        raise GpuUnavailable("backend 'cuda': numba-cuda is installed but no GPU was found (no CUDA device or "
                             "driver); run on a machine with an NVIDIA GPU, or use backend 'loky'")
    return found[0]


# ------------------------------------------------------------------ kernel functions as device functions
class Translation:
    """The device functions of the package's kernel functions (module docstring), made once each."""

    def __init__(self, **constants):
        """`constants`: global names set in every copy whose code uses them (model/scenes/gpu.py:
        DRIVE_TABLE=False)."""
        self.cuda = load()
        self.constants = constants
        self._made: dict = {}

    def device(self, fn, name: str | None = None, **bindings):
        """numba-cuda's device function of kernel function (or plain template) `fn`, with the global
        names in `bindings` bound as given and every kernel function it calls a device function."""
        key = (id(fn), name, tuple(sorted((k, id(v)) for k, v in bindings.items())))
        if key not in self._made:
            py, copy = self._copy(fn, name)
            self._made[key] = (fn, self.cuda.jit(device=True)(copy))  # fn kept: its id stays its own
            self._fill(py, copy, bindings)  # after: what it calls may call it back through a module
        return self._made[key][1]

    def kernel(self, template, name: str, **bindings):
        """numba-cuda's kernel of the plain function `template` (bound as device does), cached on
        disk beside the CPU's kernels (cache_kernel)."""
        py, copy = self._copy(template, name)
        self._fill(py, copy, bindings)
        made = self.cuda.jit(copy)
        cache_kernel(made)
        return made

    @staticmethod
    def _copy(fn, name: str | None) -> tuple:
        from fencesweep.kernel.jit import bind

        py = getattr(fn, "py_func", fn)
        return py, bind(py, name or py.__name__)

    def _fill(self, py, copy, bindings: dict) -> None:
        """The copy's globals: those its code names translated, the constants it uses, then `bindings`."""
        g = copy.__globals__
        names = set(py.__code__.co_names)
        for k in names & set(g):
            g[k] = self._translated(g[k])
        g.update({k: v for k, v in self.constants.items() if k in names})
        g.update(bindings)

    def _translated(self, value):
        from fencesweep.kernel.jit import KernelDispatcher

        if isinstance(value, KernelDispatcher):
            return self.device(value)
        if isinstance(value, pytypes.ModuleType) and value.__name__.startswith("fencesweep."):
            return self._module(value)
        return value

    def _module(self, module):
        key = ("module", module.__name__)
        if key not in self._made:
            proxy = pytypes.ModuleType(module.__name__)
            self._made[key] = (module, proxy)  # before its attributes: modules may name each other
            for k, v in vars(module).items():
                setattr(proxy, k, self.constants[k] if k in self.constants else self._translated(v))
        return self._made[key][1]


def cache_kernel(kernel) -> bool:
    """Keep `kernel`'s compiled code in kernel/cache.py's directory, under the hash of the kernel
    sources (kernel/locator.py KernelLocator): numba-cuda's own cache would key it by the kernel's
    file alone, and keep a stale kernel after an edit of a function it calls. Without a place to
    write it (or on the simulator) the kernel is compiled in every process. Whether it is cached."""
    if kernel.__class__.__module__.startswith(NAMES["cuda_simulator"].module):
        return False
    from fencesweep.kernel.internals import CUDACache, CUDACacheImpl
    from fencesweep.kernel.locator import KernelLocator

    class Impl(CUDACacheImpl):
        _locator_classes = [KernelLocator]

    class Cache(CUDACache):
        _impl_class = Impl

    try:
        kernel._cache = Cache(kernel.py_func)
    except RuntimeError:  # no locator: nowhere to write
        return False
    return True


_LOCK = threading.Lock()


class _AskedDevice:
    """The answer to numba-cuda's "which device?" while compiling for `cc` without one."""

    def __init__(self, cc: tuple):
        self.compute_capability = tuple(cc)


@contextlib.contextmanager
def _asked_cc(cc: tuple):
    """numba.cuda.dispatcher.get_current_device answering `cc` (module docstring), unless a GPU is
    there; put back afterwards."""
    cuda = load()
    from fencesweep.kernel.internals import global_compiler_lock, lookup

    where = NAMES["get_current_device"]
    dispatcher = importlib.import_module(where.module)
    with _LOCK, global_compiler_lock:
        real = lookup("get_current_device")
        if cuda.is_available():
            yield
            return
        setattr(dispatcher, where.attr, lambda: _AskedDevice(cc))
        try:
            yield
        finally:
            setattr(dispatcher, where.attr, real)


def compile_ptx(kernel_fn, signature: str, cc: tuple, opt: bool = True) -> str:
    """PTX of the plain kernel function `kernel_fn` (Translation.kernel's py_func) for compute
    capability `cc`, with or without a GPU (module docstring)."""
    cuda = load()
    with _asked_cc(cc):
        ptx, _ = cuda.compile_ptx(kernel_fn, signature, cc=tuple(cc), opt=opt)
    return ptx


__all__ = ["GpuUnavailable", "INSTALL", "Translation", "cache_kernel", "compile_ptx", "gpus", "load", "require_gpu", "version"]
