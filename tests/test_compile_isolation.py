"""fencesweep compiles its kernels its own way without changing how Numba compiles anything else
(fencesweep/kernel/jit.py): a user's own @njit function compiles to the same optimised LLVM IR
and machine code in a process that has loaded fencesweep and compiled its kernels as in one
that never imported it, and Numba's classes hold their own methods, its LLVM-lock callbacks
and cache locators are its own, after the import and after a kernel run.

The processes with fencesweep are tests/test_jit.py's first runs on an empty cache
(helpers.FIRST_RUN, run once per session through conftest.py's `first_runs`): the kernels compile
in them, with the compile helper and without it, before the user's functions do."""
import re
import threading
import time

import pytest
import llvmlite.binding as llvm
from numba.core import caching
from numba.core.codegen import CPUCodeLibrary, JITCodeLibrary, JITCPUCodegen
from numba.core.compiler_lock import global_compiler_lock
from helpers import first_run

from fencesweep.kernel import jit
from fencesweep.model import simulate as api


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
def user_code(first_runs):
    """{"plain": the user's functions in a process without fencesweep, "fencesweep": [the same in
    each process that loaded fencesweep and ran every scene on an empty cache: the two started at
    once (one compiling, the other loading what it compiled) and the one that compiled alone]}
    (helpers.FIRST_RUN; the cold processes are tests/test_jit.py's, run once per session)."""
    plain = first_run("plain", None)
    assert plain["rc"] == 0, plain["stderr"][-3000:]
    cold = [*first_runs["pair"], first_runs["alone"]]
    assert [r["rc"] for r in cold] == [0, 0, 0], [r["stderr"][-3000:] for r in cold]
    # the kernels did compile in those processes: in one of the two, and in the one alone
    assert ["compiling the cycle kernels" in r["stderr"] for r in cold].count(True) == 2
    return {"plain": plain["report"]["user"], "fencesweep": [r["report"]["user"] for r in cold]}


@pytest.mark.parametrize("name", ["sum_sin", "convolve"])
def test_a_users_function_compiles_the_same_with_fencesweep_loaded(user_code, name):
    plain = user_code["plain"][name]
    for with_fs in (run[name] for run in user_code["fencesweep"]):
        assert _normalised(with_fs["llvm"]) == _normalised(plain["llvm"])
        assert _normalised(with_fs["asm"]) == _normalised(plain["asm"])
        assert with_fs["result"] == plain["result"]


def test_numbas_classes_hold_their_own_methods_after_import_and_after_a_kernel_run(user_code):
    plain = user_code["plain"]["numba"]
    for run in user_code["fencesweep"]:
        with_fs = run["numba"]
        assert with_fs == plain  # after `import fencesweep`: Numba's own methods, callbacks and cache locators
        assert all(m == "numba.core.codegen" and not wrapped for m, _, wrapped in with_fs["attrs"])
        assert "numba.core.base" in with_fs["callbacks"]  # Numba's LLVM-lock events
        assert not any(m.startswith("fencesweep") for m in with_fs["locators"])
        # the very same objects after every scene compiled (or loaded) and ran
        assert run["same after a run"] == {"attrs": True, "callbacks": True, "locators": True}


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
