"""What several test files share: the stand-in for the engine that the sweep tests run, the
small specs they sweep, and the first runs on an empty cache that tests/test_jit.py and
tests/test_compile_isolation.py both read (`first_run_pair`, `first_run_here`). Plain
functions and constants, so that a test module can use them at import time (a default argument)
and ship the engine to another process by value (cloudpickle); conftest.py gives them as
fixtures too (`faked_engine`, `sweep_spec_file`, `first_runs`).

Importable as `helpers` through pyproject.toml's pytest pythonpath (tests/).
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import cloudpickle

from fencesweep.model import params as P
from fencesweep.model import results as R
from fencesweep.study.spec import file as specfile

#: A cycle sweep of 40 scenes and 22 distinct runs (rigid: B2 and K2 unused, one run per case;
#: flexible: 5 x 2 per case), in 6 chunks of 4.
SWEEP_SPEC = """
    scene: cycle
    params: {m1: 12.0}
    grid:
      drive: [rigid, flexible]
      B2: {linspace: [0, 100, 5]}
      K2: [200, 570]
    cases: [small_far, long_near]
    chunk_size: 4
"""

#: 3 x 3 B2 x K2 over both named cases: 18 cycles of the flexible drive (small enough for the
#: real engine).
GRID_SPEC = """
    params: {drive: flexible}
    grid:
      B2: [15, 72, 140]
      K2: [570, 1200, 2075]
    cases: [small_far, long_near]
"""


#: a design of 2 generations of 4 points over 4 loads, compared with the paper's element and a
#: rigid fence (the real engine: a few seconds)
DESIGN_SPEC = """
    params: {drive: flexible}
    envelope:
      L: [0.2, 0.7]
      m1: [5, 15]
      A: 0.1
      dP: across
      seed: 1
    design:
      variables:
        B2: {min: 10, max: 200}
        K2: {min: 500, max: 2100}
      optimizer: {seed: 2, maxiter: 2, popsize: 2, refine: 4}
      verify: {sobol: 4, seed: 9}
      compare:
        paper: {B2: 72, K2: 570}
        rigid: {drive: rigid}
    """

#: Saltelli's n = 4 over two inputs, each point over two loads
SENSITIVITY_SPEC = """
    params: {drive: flexible, B2: 140, K2: 2075}
    envelope:
      L: [0.2, 0.7]
      A: 0.1
      dP: across
      seed: 1
    sensitivity:
      inputs:
        k1: {min: 2.0e6, max: 8.0e6}
        mu2: {min: 0.15, max: 0.35}
      n: 4
      seed: 3
    """

def load_spec(text: str = SWEEP_SPEC):
    """The Spec of an indented YAML text (a spec above, or one of a test file)."""
    return specfile.loads(textwrap.dedent(text))


def write_spec(folder: Path, text: str = SWEEP_SPEC, name: str = "spec.yaml") -> Path:
    """The YAML text written, dedented, into folder/name; its path."""
    path = Path(folder) / name
    path.write_text(textwrap.dedent(text))
    return path


def fake_engine(vals, trajectory=False, drift=0.0):
    """A deterministic stand-in for fencesweep.model.simulate.simulate_resolved: every result of
    the scene from its model key without step_factor (so that a sweep's verification, which
    re-runs at tol / 10, agrees exactly), except peak_force, which moves by `drift` (relative)
    when step_factor is not 1. Outcomes, flags and step counts vary from run to run, and
    t_first_contact is NaN for some; freefall_force, where the scene has it, is 100 N."""
    key = [(n, v) for n, v in P.model_key(vals)[1:] if n != "step_factor"]
    x = sum((k + 1) * (v if isinstance(v, float) else len(v)) for k, (_, v) in enumerate(key)) / 1000
    out = {}
    for k, (name, _, _) in enumerate(R.SCENE_RESULTS[vals["scene"]]):
        if name == "outcome":
            out[name] = R.OUTCOMES[int(x * 7000) % 3]
        elif name == "status":
            out[name] = "ok"
        elif name in ("n_impacts", "n_steps", "n_rejected"):
            out[name] = int(x * 13000) % 1000
        elif name in ("safe", "deflection_ok"):
            out[name] = math.sin(x + k) > 0
        elif name == "t_first_contact":
            out[name] = math.nan if int(x * 1000) % 5 == 0 else abs(math.sin(7 * x))
        else:
            out[name] = abs(math.sin(x * (k + 11) * 1000)) * 10.0 ** (k % 3)
    if "freefall_force" in out:  # the scale of the force's floor (docs/model.md (15.15))
        out["freefall_force"] = 100.0
    if vals["step_factor"] != 1.0:
        out["peak_force"] *= 1 + drift
    return out, None


ROOT = Path(__file__).resolve().parent.parent

#: A new process's first run, with the argument "cold": it imports fencesweep (first, as a
#: user's script would), runs every scene variant (on an empty cache: the kernels compile) and
#: reports what it compiled (tests/test_jit.py); with "plain" it never imports fencesweep. Either
#: way it then compiles a user's own functions and reports their IR, machine code and results,
#: and what Numba's classes and llvmlite's lock held after the import and after the runs
#: (tests/test_compile_isolation.py). Prints one JSON line.
FIRST_RUN = textwrap.dedent("""
    import gc, json, sys
    cold = sys.argv[1] == "cold"
    if cold:
        import fencesweep
    import numpy as np
    import llvmlite.binding as llvm
    from numba import float64, njit
    from numba.core import caching
    from numba.core.codegen import CPUCodeLibrary, JITCPUCodegen
    from numba.core.dispatcher import Dispatcher

    ATTRS = [(CPUCodeLibrary, "_optimize_functions"), (CPUCodeLibrary, "_optimize_final_module"),
             (CPUCodeLibrary, "_finalize_final_module"), (CPUCodeLibrary, "finalize"),
             (JITCPUCodegen, "set_env"), (JITCPUCodegen, "create_library")]

    def numba_state():
        return {"attrs": [getattr(c, n) for c, n in ATTRS],
                "callbacks": [f for pair in llvm.ffi.lib._lock._cblist for f in pair],
                "locators": list(caching.CacheImpl._locator_classes)}

    state = numba_state()
    report, same = {}, None
    if cold:
        from fencesweep.kernel import jit

        def dispatchers():
            return [o for o in gc.get_objects()
                    if isinstance(o, Dispatcher) and o.py_func.__module__.startswith("fencesweep")]

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
        report.update({"results": res, "most": max(len(d.signatures) for d in disps),
                       "compiled": compiled(), "plan": plan, "cycle_compiled": cycle_compiled,
                       "loaded": sum(sum(d._cache_hits.values()) for d in disps if isinstance(d, jit.KernelDispatcher)),
                       "rocker_loaded": sum(drive.fill_rocker_table._cache_hits.values())})
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
    user = {"numba": {"attrs": [[o.__module__, o.__qualname__, hasattr(o, "__wrapped__")] for o in state["attrs"]],
                      "callbacks": [f.__module__ for f in state["callbacks"]],
                      "locators": [c.__module__ for c in state["locators"]]},
            "same after a run": same}
    for f, args in ((sum_sin, (x,)), (convolve, (x, x[:7]))):
        sig = tuple(float64[::1] for _ in args)
        f.compile(sig)
        user[f.__name__] = {"llvm": f.inspect_llvm(sig), "asm": f.inspect_asm(sig),
                            "result": np.asarray(f(*args)).tolist()}
    report["user"] = user
    print(json.dumps(report))
""")


def _first_run_env(cache_dir: Path | None, **more) -> dict:
    """The environment of a FIRST_RUN process: no NUMBA_ settings but the cache directory (an empty
    one: the kernels compile in the process), one string hash for every process (Numba names a
    constant string by its hash: the user's functions compare across processes)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = str(cache_dir)
    return {**env, "PYTHONHASHSEED": "0", **more}


def _finished(proc_out: tuple, returncode: int) -> dict:
    """{"rc", "stderr", "report": the JSON line printed (None if none)} of a FIRST_RUN process."""
    out, err = proc_out
    lines = out.strip().splitlines()
    report = None
    if returncode == 0 and lines:
        report = json.loads(lines[-1])
    return {"rc": returncode, "stderr": err, "report": report}


def first_run(mode: str, cache_dir: Path | None, **env) -> dict:
    """FIRST_RUN in a new process (mode "cold" or "plain"); `_finished`'s dict."""
    r = subprocess.run([sys.executable, "-c", FIRST_RUN, mode], cwd=ROOT, env=_first_run_env(cache_dir, **env),
                       capture_output=True, text=True, timeout=600)
    return _finished((r.stdout, r.stderr), r.returncode)


def kernels_compiled_in(directory: Path) -> bool:
    """Has anything been kept in the kernels' cache directory `directory` (kernel/cache.py DIR: a
    compiled kernel, a compiled-* marker, a solved value)? A new clone's has nothing (a test
    session's collection makes its folders only)."""
    return directory.is_dir() and any(p.is_file() for p in directory.rglob("*"))


#: FIRST_RUN "cold" (argv[2]) in a new process at the lowest priority (it takes the CPU the tests
#: leave), in the folder argv[3]; when it ends, {"rc", "stdout", "stderr"} written whole to the
#: file argv[1] (a reader sees it complete or not at all)
IN_BACKGROUND = textwrap.dedent("""
    import json, os, subprocess, sys, traceback
    out, code, cwd = sys.argv[1:4]
    if hasattr(os, "nice"):
        os.nice(19)
    try:
        r = subprocess.run([sys.executable, "-c", code, "cold"], cwd=cwd, capture_output=True, text=True, timeout=600)
        done = {"rc": r.returncode, "stdout": r.stdout, "stderr": r.stderr}
    except Exception:
        done = {"rc": None, "stdout": "", "stderr": traceback.format_exc()}
    with open(out + ".tmp", "w") as fh:
        json.dump(done, fh)
    os.replace(out + ".tmp", out)
""")
#: the IN_BACKGROUND processes this process started (`wait_for_background`)
_BACKGROUND: list = []


def background_result(path: Path, timeout: float = 900.0) -> dict:
    """`_finished`'s dict of the IN_BACKGROUND run that writes `path`, once written (from any process)."""
    deadline = time.monotonic() + timeout
    while not path.exists():
        if time.monotonic() > deadline:
            return {"rc": None, "stderr": f"no result in {path} after {timeout:g} s", "report": None}
        time.sleep(0.1)
    r = json.loads(path.read_text())
    return _finished((r["stdout"], r["stderr"]), r["rc"])


def wait_for_background(timeout: float = 900.0) -> None:
    """Wait for the IN_BACKGROUND processes this process started (another may still read their
    results), stopping any still running after `timeout`."""
    while _BACKGROUND:
        proc = _BACKGROUND.pop()
        try:
            proc.wait(timeout)
        except BaseException:
            proc.kill()
            proc.wait()
            raise


def first_run_pair(root: Path) -> dict:
    """The first runs on empty caches that tests/test_jit.py and tests/test_compile_isolation.py
    read:

    * "pair": two FIRST_RUN processes started at once on one empty cache, the compile helper on
      where it can be (kernel/share.py): one compiles, the other waits and loads;
    * "alone_file": where one process on another empty cache (root/alone), the helper off, every
      kernel compiled in it, writes its result (`background_result`). It is started with the
      pair, in the background at the lowest priority: it takes the second core while the pair's
      compile has one process only (before the helper starts and once it is done), and what the
      tests leave after;
    * "here": FIRST_RUN on this checkout's cache, compiled already (nothing compiles): the pair's
      process that loaded the kernels when the pair ran on that cache (below), else None (the
      caller runs `first_run_here`).

    The pair's empty cache is the one the tests' own processes use (kernel/cache.py DIR, under
    NUMBA_CACHE_DIR or the package's __pycache__) when nothing is kept there yet, as in a new
    clone: the kernels compile once for the whole session, in the pair, and the tests load them
    (conftest.py runs the pair before any test of a session that reads it). Else (a checkout whose
    kernels are compiled already) a new one, root/pair. Any share-* directory the pair left is
    listed right after it ("left"), before a test process can start a compile of its own there;
    "cache" is the pair's cache directory (NUMBA_CACHE_DIR), "shared" whether it is the tests' own.
    """
    from fencesweep.kernel import cache, share

    shared = not kernels_compiled_in(cache.DIR)
    base = cache.DIR.parent if shared else root / "pair"
    alone = root / "alone.json"
    _BACKGROUND.append(subprocess.Popen([sys.executable, "-c", IN_BACKGROUND, str(alone), FIRST_RUN, str(ROOT)],
                                        env=_first_run_env(root / "alone", **{share.HELPER_ENV: "0"}),
                                        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                        stderr=subprocess.DEVNULL))
    env = _first_run_env(base)
    procs = [subprocess.Popen([sys.executable, "-c", FIRST_RUN, "cold"], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    pair = [_finished(p.communicate(timeout=600), p.returncode) for p in procs]
    left = sorted(str(p) for p in base.glob("fencesweep-*/share-*"))
    loaded = [p for p in pair if "compiling the cycle kernels" not in p["stderr"]]
    return {"pair": pair, "alone_file": str(alone), "here": loaded[0] if shared and loaded else None,
            "cache": str(base), "shared": shared, "left": left}


def first_run_here(root: Path) -> dict:
    """FIRST_RUN on this checkout's cache (compiled already, by the pair or before the session:
    nothing compiles), which tests/test_jit.py compares with the runs on empty caches:
    `_finished`'s dict."""
    r = subprocess.run([sys.executable, "-c", FIRST_RUN, "cold"], cwd=ROOT, capture_output=True, text=True,
                       timeout=600)
    return _finished((r.stdout, r.stderr), r.returncode)


# the engine goes to loky workers and to test subprocesses pickled by value: they need not
# import this file (a subprocess has no tests/ on its path)
cloudpickle.register_pickle_by_value(sys.modules[__name__])
