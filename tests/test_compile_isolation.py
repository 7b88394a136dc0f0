"""fencesweep compiles its kernels its own way without changing how Numba compiles anything else
(fencesweep/kernel/jit.py): a user's own @njit function compiles to the same optimised LLVM IR
and machine code in a process that has loaded fencesweep and compiled its kernels as in one
that never imported it, and Numba's classes hold their own methods, its LLVM-lock callbacks
and cache locators are its own, after the import and after a kernel run."""
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import llvmlite.binding as llvm
from numba.core import caching
from numba.core.codegen import CPUCodeLibrary, JITCodeLibrary, JITCPUCodegen
from numba.core.compiler_lock import global_compiler_lock

from fencesweep.kernel import jit
from fencesweep.model import simulate as api

ROOT = Path(__file__).resolve().parent.parent

#: a user's own compiled functions, compiled in a new process; with the argument "fencesweep"
#: after loading fencesweep (first, as a user's script would) and running a cycle on an empty
#: cache, so that its kernels compile in that process. Prints their IR, machine code and
#: results, and what Numba's classes and llvmlite's lock held after the import and after the run.
USER = r"""
import json, sys
with_fencesweep = sys.argv[1] == "fencesweep"
if with_fencesweep:
    import fencesweep
import numpy as np
import llvmlite.binding as llvm
from numba import float64, njit
from numba.core import caching
from numba.core.codegen import CPUCodeLibrary, JITCPUCodegen

ATTRS = [(CPUCodeLibrary, "_optimize_functions"), (CPUCodeLibrary, "_optimize_final_module"),
         (CPUCodeLibrary, "_finalize_final_module"), (CPUCodeLibrary, "finalize"),
         (JITCPUCodegen, "set_env"), (JITCPUCodegen, "create_library")]

def numba_state():
    return {"attrs": [getattr(c, n) for c, n in ATTRS],
            "callbacks": [f for pair in llvm.ffi.lib._lock._cblist for f in pair],
            "locators": list(caching.CacheImpl._locator_classes)}

state = numba_state()
same = None
if with_fencesweep:
    fencesweep.simulate(case="small_far")
    after = numba_state()
    same = {k: len(v) == len(after[k]) and all(a is b for a, b in zip(v, after[k])) for k, v in state.items()}

@njit
def sum_sin(x):
    s = 0.0
    for v in x:
        s += np.sin(v)
    return s

@njit
def convolve(a, b):
    return np.convolve(a, b)

x = np.linspace(0.0, 3.0, 101)
out = {"numba": {"attrs": [[o.__module__, o.__qualname__, hasattr(o, "__wrapped__")] for o in state["attrs"]],
                 "callbacks": [f.__module__ for f in state["callbacks"]],
                 "locators": [c.__module__ for c in state["locators"]]},
       "same after a run": same}
for f, args in ((sum_sin, (x,)), (convolve, (x, x[:7]))):
    sig = tuple(float64[::1] for _ in args)
    f.compile(sig)
    out[f.__name__] = {"llvm": f.inspect_llvm(sig), "asm": f.inspect_asm(sig),
                       "result": np.asarray(f(*args)).tolist()}
print(json.dumps(out))
"""


def _normalised(code: str) -> str:
    """Code with the names Numba makes per process made alike: a mangled name carries the count of
    functions compiled in the process before it (B<n>v<count>B), which differs in a process that
    has compiled fencesweep's kernels first, and so does the length of the error message that
    names a function's environment; older Numba also names a constant by the address of the
    object it was made from (and prints that object's address into it), new in every process,
    to which LLVM adds a number where two such names meet in one module."""
    code = re.sub(r"B\d+v\d+B", "BvB", code)
    code = re.sub(r"\[\d+ x i8\] c\"missing Environment", "[n x i8] c\"missing Environment", code)
    code = re.sub(r"(\.size\s+\".const.missing Environment[^\"]*\"), \d+", r"\1, n", code)
    code = re.sub(r"\.const\.pickle(data|buf)\.\d+(\.sha1)?(?:\.\d+)?", r".const.pickle\1.n\2", code)
    return re.sub(r" object at 0x[0-9a-f]+", " object at 0xn", code)


@pytest.fixture(scope="module")
def user_code(tmp_path_factory):
    """{"plain": the user's functions in a process without fencesweep, "fencesweep": with it}."""
    out = {}
    for mode in ("plain", "fencesweep"):
        env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
        # an empty cache (the kernels compile in the process), and one string hash for both
        # processes (Numba names a constant string by its hash)
        env.update(NUMBA_CACHE_DIR=str(tmp_path_factory.mktemp(mode)), PYTHONHASHSEED="0")
        r = subprocess.run([sys.executable, "-c", USER, mode], cwd=ROOT, env=env, capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 0, r.stderr[-3000:]
        out[mode] = json.loads(r.stdout.strip().splitlines()[-1])
    assert "compiling the cycle kernels" in r.stderr  # the kernels did compile in that process
    return out


@pytest.mark.parametrize("name", ["sum_sin", "convolve"])
def test_a_users_function_compiles_the_same_with_fencesweep_loaded(user_code, name):
    plain, with_fs = user_code["plain"][name], user_code["fencesweep"][name]
    assert _normalised(with_fs["llvm"]) == _normalised(plain["llvm"])
    assert _normalised(with_fs["asm"]) == _normalised(plain["asm"])
    assert with_fs["result"] == plain["result"]


def test_numbas_classes_hold_their_own_methods_after_import_and_after_a_kernel_run(user_code):
    plain, with_fs = user_code["plain"]["numba"], user_code["fencesweep"]["numba"]
    assert with_fs == plain  # after `import fencesweep`: Numba's own methods, callbacks and cache locators
    assert all(m == "numba.core.codegen" and not wrapped for m, _, wrapped in with_fs["attrs"])
    assert "numba.core.base" in with_fs["callbacks"]  # Numba's LLVM-lock events
    assert not any(m.startswith("fencesweep") for m in with_fs["locators"])
    # the very same objects after a cycle compiled and ran
    assert user_code["fencesweep"]["same after a run"] == {"attrs": True, "callbacks": True, "locators": True}


def _callbacks():
    return [f for pair in llvm.ffi.lib._lock._cblist for f in pair]


def test_numbas_events_are_off_while_the_package_compiles_and_back_after_even_on_an_error():
    before = _callbacks()
    assert any(f.__module__ == "numba.core.base" for f in before)
    with jit.own_compile():
        off = _callbacks()
        assert not any(f.__module__ == "numba.core.base" for f in off)
        with jit.own_compile():  # a kernel function compiled while its caller is
            assert _callbacks() == off
        assert _callbacks() == off  # still the outer compile's
    assert _callbacks() == before
    with pytest.raises(RuntimeError, match="a failed compile"), jit.own_compile():
        raise RuntimeError("a failed compile")
    assert _callbacks() == before and jit._Own.depth == 0


def test_another_threads_compile_waits_for_the_packages():
    seen = []

    def compile_elsewhere():  # what a compile in another thread does first: take the compiler lock
        with global_compiler_lock:
            seen.append(_callbacks())

    before = _callbacks()
    with jit.own_compile():
        other = threading.Thread(target=compile_elsewhere)
        other.start()
        time.sleep(0.2)
        assert seen == []  # it waits while the package compiles
    other.join(10)
    assert seen == [before]  # and then has Numba's events


def test_the_packages_code_is_in_its_own_libraries_and_numbas_classes_are_numbas():
    from numba.core.runtime import nrt
    from fencesweep.model.scenes.stream import begin_cycle, run_cycles

    api.simulate(case="small_far")  # compiled, or loaded from the cache, in this process
    assert all(isinstance(cres.library, jit.EntryLibrary) or cres.library.__class__ is JITCodeLibrary
               for cres in run_cycles.overloads.values())  # compiled here, or loaded as object code
    [cres] = begin_cycle.overloads.values() or [None]
    assert cres is None or isinstance(cres.library, jit.KernelLibrary)
    assert type(nrt.rtsys.library) is JITCodeLibrary  # Numba's runtime: Numba's library
    for cls, name in [(CPUCodeLibrary, "_optimize_functions"), (CPUCodeLibrary, "_optimize_final_module"),
                      (CPUCodeLibrary, "_finalize_final_module"), (JITCPUCodegen, "set_env")]:
        method = cls.__dict__[name]
        assert method.__module__ == "numba.core.codegen" and not hasattr(method, "__wrapped__")
    assert "_library_class" not in vars(nrt.rtsys.library.codegen)


def test_a_warm_call_changes_nothing(monkeypatch):
    """own_compile is entered per compile (or cache load), never per call of a compiled kernel."""
    api.simulate(case="small_far")  # compiled, or loaded from the cache, in this process
    entered = []
    monkeypatch.setattr(jit, "_events_off", lambda: entered.append(1))
    api.simulate(case="small_far")
    api.simulate(case="small_far", B2=80.0)
    assert entered == []


def test_numbas_cache_locators_are_its_own():
    """The entry points' cache locator is theirs (jit.EntryCache), not registered with Numba."""
    assert not any(c.__module__.startswith("fencesweep") for c in caching.CacheImpl._locator_classes)
    from fencesweep.model.scenes.stream import run_cycles

    assert isinstance(run_cycles, jit.EntryDispatcher) and isinstance(run_cycles._cache, jit.EntryCache)
