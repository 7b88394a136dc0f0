"""The kernels' compile policy (fencesweep/kernel/jit.py) and their cache (kernel/cache.py):
every kernel function compiles once, without reference counting, as IR for its callers; only
the entry points are called from Python; a first run says it compiles, and two processes
started at once on an empty cache both finish, one compiling while the other waits."""
import importlib
import json
import pkgutil
import subprocess
import sys
import textwrap

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
ALLOCATORS = {"new_work"}


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


def test_the_cache_directory_is_named_by_the_kernel_sources(tmp_path):
    """Editing any kernel source gives another directory: no stale kernel is ever loaded."""
    assert cache.DIR.name == f"fencesweep-{cache.HASH[:16]}"
    code = textwrap.dedent(f"""
        import shutil, sys
        shutil.copytree({str(cache.PKG)!r}, {str(tmp_path / "fencesweep")!r})
        with open({str(tmp_path / "fencesweep" / "model" / "contact.py")!r}, "a") as fh:
            fh.write("\\n# an edit\\n")
        sys.path.insert(0, {str(tmp_path)!r})
        from fencesweep.kernel import cache
        print(cache.HASH)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] != cache.HASH


#: a process that runs every scene variant on an empty cache and reports what it compiled
COLD_RUN = textwrap.dedent("""
    import gc, json, sys
    from numba.core.dispatcher import Dispatcher
    import fencesweep
    from fencesweep.kernel import jit

    def dispatchers():
        return [o for o in gc.get_objects() if isinstance(o, Dispatcher) and o.py_func.__module__.startswith("fencesweep")]

    def compiled():
        return sum(len(d.signatures) for d in dispatchers())

    runs = [dict(case="small_far"), dict(case="long_near", drive="rigid"), dict(case="small_far", drive="free"),
            dict(case="small_far", contact_law="linear"), dict(case="long_near", integrator="rk4", step_factor=8.0),
            dict(case="small_far", profile="harmonic")]
    res = [fencesweep.simulate("cycle", **r)["peak_force"] for r in runs]
    res.append(fencesweep.simulate("stream", case="small_far", n_cycles=2, period=1.5)["worst_overload"])
    cycle_compiled = compiled()  # before the impact scenes, which the other process may be compiling
    res += [fencesweep.simulate("impact", drive=d)["peak_force"] for d in ("rigid", "flexible", "free")]
    res.append(fencesweep.simulate("freefall")["peak_force"])
    from fencesweep.kernel import share
    from fencesweep.model.simulate import CYCLE_PLAN
    disps = dispatchers()
    steps = share.load_plan(CYCLE_PLAN)
    plan = [share.signature(args) in d.signatures for d, args in [steps.entry, *steps.kernels]]
    from fencesweep.model import drive
    print(json.dumps({"results": res, "most": max(len(d.signatures) for d in disps),
                      "compiled": compiled(), "plan": plan, "cycle_compiled": cycle_compiled,
                      "loaded": sum(sum(d._cache_hits.values()) for d in disps if isinstance(d, jit.KernelDispatcher)),
                      "rocker_loaded": sum(drive.fill_rocker_table._cache_hits.values())}))
""")


def test_two_processes_on_an_empty_cache_both_finish_and_every_function_compiles_once(tmp_path):
    """The issue's race: both start at once; one compiles (and says so) under the compile lock,
    the other waits and loads the kernels; both give the in-process results."""
    env = {**__import__("os").environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    procs = [subprocess.Popen([sys.executable, "-c", COLD_RUN], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [e[-2000:] for _, e in outs]
    reports = [json.loads(o.strip().splitlines()[-1]) for o, _ in outs]
    here = json.loads(subprocess.run([sys.executable, "-c", COLD_RUN], capture_output=True, text=True,
                                     check=True).stdout.strip().splitlines()[-1])["results"]
    assert reports[0]["results"] == reports[1]["results"] == here
    said = ["compiling the cycle kernels" in e for _, e in outs]
    assert sorted(said) == [False, True]  # one compiled and said so; the other loaded
    cold = reports[said.index(True)]
    assert cold["most"] == 1 and cold["compiled"] > 80  # every function compiled exactly once
    assert reports[said.index(False)]["cycle_compiled"] <= 3  # the cycle's entry points, loaded
    # the impact kernels, too, were compiled by one of the two (whichever got there first)
    assert sorted("compiling the impact kernels" in e for _, e in outs) == [False, True]
    # the compile plan's example arguments have the types run_cycles compiles its functions for,
    # and the helper compiled some of them (kernel/share.py); its directory is gone
    assert cold["plan"] and all(cold["plan"])
    assert cold["loaded"] > 0
    # the helper's prelude compiled the crank-rocker table's entry point, which this process,
    # having waited for the prelude after its own compile, loaded instead of compiling it again
    assert cold["rocker_loaded"] == 1
    assert list(tmp_path.glob("fencesweep-*/share-*")) == []
    # the same results with the compile all in one process
    env[share.HELPER_ENV] = "0"
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "alone")
    alone = json.loads(subprocess.run([sys.executable, "-c", COLD_RUN], env=env, capture_output=True, text=True,
                                      check=True).stdout.strip().splitlines()[-1])
    assert alone["results"] == here
    assert alone["loaded"] == 0 and alone["most"] == 1 and alone["rocker_loaded"] == 0


def test_a_warm_process_says_nothing(capfd):
    api.simulate(case="small_far")  # compiles into the cache if it is not there
    code = "import fencesweep; fencesweep.simulate(case='small_far')"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stderr == ""


def test_loading_the_kernels_imports_neither_scipy_linalg_nor_cffi_nor_coverage():
    """jit.py answers Numba's BLAS probe "no" while Numba loads its NumPy support (the probe
    imports all of scipy.linalg, 0.27 s a process) and hides cffi and coverage, which no kernel
    uses; the kernels run the same without them."""
    here = api.simulate(case="small_far")
    unused = ["scipy.linalg", "cffi", "pycparser", "coverage"]
    code = ("import sys, json\nfrom fencesweep.model import simulate as api\nr = api.simulate(case='small_far')\n"
            f"print(json.dumps([[m for m in {unused!r} if m in sys.modules], r['peak_force']]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    imported, peak = json.loads(out.stdout.strip().splitlines()[-1])
    assert imported == []
    assert peak == here["peak_force"]


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
