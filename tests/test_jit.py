"""The kernels' compile policy (fencesweep/kernel/jit.py) and their cache (kernel/cache.py):
every kernel function compiles once, without reference counting, as IR for its callers; only
the entry points are called from Python; a first run says it compiles, and two processes
started at once on an empty cache both finish, one compiling while the other waits."""
import ast
import contextlib
import importlib
import importlib.util
import json
import logging
import os
import pkgutil
import re
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from numba.core.dispatcher import Dispatcher
from numba.core.errors import TypingError

import fencesweep
from fencesweep.kernel import cache, share
from fencesweep.kernel.jit import KernelDispatcher, kernel, python_callable
from fencesweep.model import simulate as api
from fencesweep.model.contact import kelvin_force

ENTRY_POINTS = {"run_cycles", "impact_kernel", "fill_rocker_table"}
#: kernel functions that allocate an entry point's work arrays (kernel(allocates=True))
ALLOCATORS = {"run_on_heap"}


def _dispatchers():
    """(module.name, dispatcher) of every compiled function defined in kernel/ and model/."""
    for pkg in ("fencesweep.kernel", "fencesweep.model"):
        root = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(root.__path__, pkg + "."):
            mod = importlib.import_module(info.name)
            for attr, obj in vars(mod).items():
                if isinstance(obj, Dispatcher) and obj.py_func.__module__ in (mod.__name__, "fencesweep.kernel.rk",
                                                                              "fencesweep.kernel.search",
                                                                              "fencesweep.kernel.driver"):
                    yield f"{info.name}.{attr}", obj


def test_entry_points_count_references_and_every_other_kernel_function_does_not():
    seen = dict(_dispatchers())
    assert len(seen) > 80
    for name, disp in seen.items():
        entry = name.rsplit(".", 1)[1] in ENTRY_POINTS
        assert isinstance(disp, KernelDispatcher) is not entry, name
        assert disp.targetoptions["_nrt"] is (entry or name.rsplit(".", 1)[1] in ALLOCATORS), name
        assert disp.targetoptions.get("no_cpython_wrapper", False) is not entry, name
    assert ENTRY_POINTS <= {n.rsplit(".", 1)[1] for n in seen}


def test_a_kernel_function_that_allocates_does_not_compile():
    @kernel()
    def allocates(n):
        return np.zeros(n).sum()

    with pytest.raises(TypingError):
        python_callable(allocates)(3)  # compiled as a kernel function is: without reference counting


def test_a_kernel_function_is_not_called_from_python_but_its_copy_is():
    with pytest.raises(TypeError, match="called from compiled code only"):
        kelvin_force(1e-3, 0.0, 4e6, 1e3, 0)
    n, n_el = python_callable(kelvin_force)(1e-3, 0.0, 4e6, 1e3, 0)
    assert n == n_el == pytest.approx(4e6 * 1e-3 ** 1.5)


def _edit(path):
    with open(path, "a") as fh:
        fh.write("\n# an edit\n")


def test_the_cache_directory_is_named_by_the_kernel_sources_only(tmp_path):
    """Editing a kernel source gives another directory (no stale kernel is ever loaded); editing
    the orchestration around the kernels keeps it (the kernels stay compiled)."""
    assert cache.DIR.name == f"fencesweep-{cache.HASH[:16]}"
    pkg = tmp_path / "fencesweep"
    shutil.copytree(cache.PKG, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    hashed = [p.relative_to(pkg).as_posix() for p in cache._kernel_sources(pkg)]
    before = cache.kernel_hash(pkg)
    others = ["model/simulate.py", "model/params.py", "model/prepare.py", "model/scenes/freefall.py", "cli.py",
              sorted(pkg.glob("study/*.py"))[0], sorted(pkg.glob("report/*.py"))[0]]
    for name in others:
        assert str(name) not in hashed
        _edit(pkg / name)
        assert cache.kernel_hash(pkg) == before, name
    for name in ("kernel/numerics.py", "kernel/jit.py", "model/contact.py", "model/scenes/cycle/layout.py",
                 "model/calibrate.py"):
        _edit(pkg / name)
        after = cache.kernel_hash(pkg)
        assert after != before, name
        before = after


def _module_file(name: str) -> str:
    return Path(importlib.import_module(name).__file__).relative_to(cache.PKG).as_posix()


def _package_imports(rel: str) -> set:
    """The package's modules that module `rel` imports at its top level (what its compiled
    functions can read: functions and constants)."""
    tree = ast.parse((cache.PKG / rel).read_text())
    found = set()
    for node in tree.body:
        names = []
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("fencesweep"):
            names = [f"{node.module}.{a.name}" for a in node.names] + [node.module]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names if a.name.startswith("fencesweep")]
        for name in names:
            with contextlib.suppress(ImportError):
                if importlib.util.find_spec(name) is not None:
                    found.add(_module_file(name))
    return {f for f in found if not f.endswith("__init__.py")}


def test_the_hash_covers_every_module_a_kernel_is_compiled_from():
    hashed = {p.relative_to(cache.PKG).as_posix() for p in cache._kernel_sources()}
    assert all((cache.PKG / name).is_file() for name in hashed)
    compiled = {_module_file(d.py_func.__module__) for _, d in _dispatchers()}
    assert compiled and compiled <= hashed  # every module that defines a compiled function
    # ... every package module those import at their top level (Numba compiles a global's value
    # into the code), and so on (the compile machinery of kernel/ is hashed whole)
    todo, seen = list(compiled), set()
    while todo:
        rel = todo.pop()
        if rel not in seen and not rel.startswith("kernel/"):
            seen.add(rel)
            todo.extend(_package_imports(rel))
    assert seen <= hashed, seen - hashed
    # ... and every module that solves a value kept beside the compiled kernels (cache.solved)
    solving = {p.relative_to(cache.PKG).as_posix() for p in cache.PKG.rglob("*.py")
               if re.search(r"\bsolved\(", p.read_text()) and not p.is_relative_to(cache.PKG / "kernel")}
    assert solving and solving <= hashed
    assert not any(name.startswith(("study/", "report/")) or "/" not in name for name in hashed)


def test_two_processes_on_an_empty_cache_both_finish_and_every_function_compiles_once(first_runs):
    """Two first runs started at once: one compiles (and says so) under the compile lock, the
    other waits and loads the kernels; both give the in-process results. (The processes:
    helpers.first_run_pair, run once per session before any test: on a new clone the pair compiles
    the kernels into the cache the tests then load, and its process that loaded them is the run
    "here"; tests/test_compile_isolation.py reads them too.)"""
    pair, here, alone = first_runs["pair"], first_runs["here"], first_runs["alone"]
    assert [p["rc"] for p in pair] == [0, 0], [p["stderr"][-2000:] for p in pair]
    assert here["rc"] == 0, here["stderr"][-2000:]
    reports = [p["report"] for p in pair]
    assert reports[0]["results"] == reports[1]["results"] == here["report"]["results"]
    said = ["compiling the cycle kernels" in p["stderr"] for p in pair]
    assert sorted(said) == [False, True]  # one compiled and said so; the other loaded
    cold = reports[said.index(True)]
    assert cold["most"] == 1 and cold["compiled"] > 80  # every function compiled exactly once
    assert reports[said.index(False)]["cycle_compiled"] <= 3  # the cycle's entry points, loaded
    # the impact kernels, too, were compiled by one of the two (whichever got there first)
    assert sorted("compiling the impact kernels" in p["stderr"] for p in pair) == [False, True]
    # the compile plan's example arguments have the types run_cycles compiles its functions for,
    # and the helper compiled some of them (kernel/share.py); its directory is gone
    assert cold["plan"] and all(cold["plan"])
    assert cold["loaded"] > 0
    # the helper's prelude compiled the crank-rocker table's entry point, which this process,
    # having waited for the prelude after its own compile, loaded instead of compiling it again
    assert cold["rocker_loaded"] == 1
    assert first_runs["left"] == []  # share-* in the pair's cache, listed right after the pair
    # the same results with the compile all in one process (the helper off, another empty cache)
    assert alone["rc"] == 0, alone["stderr"][-2000:]
    assert "compiling the cycle kernels" in alone["stderr"]
    assert alone["report"]["results"] == here["report"]["results"]
    assert alone["report"]["loaded"] == 0 and alone["report"]["most"] == 1 and alone["report"]["rocker_loaded"] == 0


def test_a_warm_process_says_nothing(capfd):
    api.simulate(case="small_far")  # compiles into the cache if it is not there
    code = "import fencesweep; fencesweep.simulate(case='small_far')"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stderr == ""


def test_loading_the_kernels_imports_neither_scipy_linalg_nor_coverage():
    """numba_setup.py defers Numba's BLAS probe (it imports all of scipy.linalg) to the first
    compile that asks, and hides coverage while Numba loads; the kernels run the same without
    them, and Numba's answer to the probe, once asked, is its own."""
    here = api.simulate(case="small_far")
    unused = ["scipy.linalg", "coverage"]
    code = ("import sys, json\nfrom fencesweep.model import simulate as api\nr = api.simulate(case='small_far')\n"
            f"imported = [m for m in {unused!r} if m in sys.modules]\n"
            "from numba.np import arraymath, linalg\n"
            "print(json.dumps([imported, r['peak_force'], bool(arraymath._HAVE_BLAS)]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    imported, peak, blas = json.loads(out.stdout.strip().splitlines()[-1])
    assert imported == []
    assert peak == here["peak_force"]
    assert blas is (importlib.util.find_spec("scipy") is not None)


def test_a_module_imported_already_is_not_hidden():
    from fencesweep.kernel.numba_setup import _hidden

    with _hidden("json", "fencesweep_no_such_module"):
        assert sys.modules["json"] is json
        with pytest.raises(ImportError):
            import fencesweep_no_such_module  # noqa: F401
    assert "fencesweep_no_such_module" not in sys.modules


def test_import_fencesweep_loads_no_numba():
    code = "import sys, fencesweep; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False" and fencesweep.__version__


def test_a_kernel_function_shared_by_both_processes_is_saved_by_one(tmp_path, monkeypatch):
    """During a shared compile both processes may compile one kernel function; its cache entry is
    written by whichever saves it first, never by both (kernel/share.py KernelCache)."""
    from numba.core import caching
    from numba import float64

    saved = []
    monkeypatch.setattr(caching.FunctionCache, "save_overload", lambda self, sig, data: saved.append(sig))
    (tmp_path / "entries").mkdir()
    monkeypatch.setattr(share, "_session", share._Session(tmp_path, share.Plan(None, [], None), None))
    sig = (float64, float64)
    for _ in range(2):  # this process's and the helper's cache of the function
        share.KernelCache(kelvin_force.py_func).save_overload(sig, object())
    share.KernelCache(kelvin_force.py_func).save_overload((float64,), object())  # another signature
    assert saved == [sig, (float64,)]


#: a compile plan of one entry point (which calls a kernel function), with a prelude that fails or hangs
PLAN = textwrap.dedent("""
    import time
    from fencesweep.kernel.jit import entry, kernel
    from fencesweep.kernel.share import Plan

    @kernel()
    def twice(x):
        return 2.0 * x

    @entry()
    def run(x):
        return twice(x)

    def prelude(vals):
        if vals["how"] == "fails":
            raise ValueError("the prelude failed on purpose")
        time.sleep(60)

    def plan():
        return Plan((run, (1.0,)), [], prelude)
""")


@pytest.mark.skipif(not share._helper_enabled(), reason="the compile helper needs two usable cores")
@pytest.mark.parametrize("how, limit, said", [("fails", 60.0, "ValueError: the prelude failed on purpose"),
                                              ("hangs", 2.0, "had not finished prelude after 2 s")])
def test_a_failing_or_stuck_helper_is_logged_and_stopped(tmp_path, monkeypatch, caplog, how, limit, said):
    """What the helper writes on stderr is logged, and a wait for it ends after WAIT_LIMIT; its
    directory (a new one, tempfile.mkdtemp) is removed either way."""
    (tmp_path / "fencesweep_test_plan.py").write_text(PLAN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), str(cache.PKG.parent)]))
    monkeypatch.setattr(share, "WAIT_LIMIT", limit)
    before = set(cache.DIR.glob("share-*"))
    t = time.monotonic()
    with caplog.at_level(logging.WARNING, logger="fencesweep"):
        with share.shared_compile("fencesweep_test_plan:plan", {"how": how}):
            from fencesweep_test_plan import run

            assert run(1.5) == 3.0
    assert time.monotonic() - t < 40
    assert said in caplog.text
    assert set(cache.DIR.glob("share-*")) == before and share._session is None


def test_a_result_that_cannot_be_cached_is_warned_of_not_a_crash():
    """Numba names the source file of a compile result it cannot cache (one with dynamic globals,
    as a cold compile at NUMBA_OPT=0 makes) from the cache's locator: a KernelLocator must hold it."""
    from types import SimpleNamespace

    from numba.core.errors import NumbaWarning

    from fencesweep.kernel.jit import _EntryCacheImpl
    from fencesweep.kernel.locator import KernelLocator
    from fencesweep.model.drive import fill_rocker_table

    impl = _EntryCacheImpl(fill_rocker_table.py_func)
    assert isinstance(impl.locator, KernelLocator)
    cres = SimpleNamespace(lifted=(), library=SimpleNamespace(has_dynamic_globals=True),
                           fndesc=SimpleNamespace(qualname="fill_rocker_table"))
    with pytest.warns(NumbaWarning, match="Cannot cache compiled function"):
        assert impl.check_cachable(cres) is False
