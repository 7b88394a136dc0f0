"""The plain-Python path: the kernels' tests (marked plain_python) also pass with Numba's JIT
off (NUMBA_DISABLE_JIT=1), as pvlib runs its Numba and plain paths through one suite.

Without the JIT the kernels are ordinary Python functions, so the run also measures how much
of the compiled code the tests execute: at least KERNEL_COVERAGE of the statements of the
kernel sources (fencesweep.kernel.cache's list of them: kernel/ and model/) must run, leaving
out the modules of how Numba compiles them (COMPILE_MACHINERY), which a run without the JIT
does not use by design.
"""
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

from fencesweep.kernel import cache

ROOT = Path(__file__).resolve().parent.parent
#: measured 90.7 % when this test was written (the kernels of 0.1.0 + kernel v2)
KERNEL_COVERAGE = 0.85
#: Numba's set-up, the compile policy, the cache, the two-core compile, the list of Numba's internal
#: names and the GPU's compile (which a run without the JIT cannot reach): no kernel code
COMPILE_MACHINERY = {"kernel/numba_setup.py", "kernel/jit.py", "kernel/cache.py", "kernel/share.py",
                     "kernel/internals.py", "kernel/cuda.py"}


def test_kernel_tests_pass_without_the_jit_and_cover_the_kernels(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("COV_CORE_")}  # not the parent's coverage
    env.update(NUMBA_DISABLE_JIT="1", COVERAGE_FILE=str(tmp_path / ".coverage"))
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "plain_python", "tests"]
    measured = importlib.util.find_spec("pytest_cov") is not None  # the test extra has it
    if measured:
        cmd += ["--cov=fencesweep", f"--cov-report=json:{tmp_path / 'coverage.json'}"]
    r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-5000:] + r.stderr[-2000:]
    assert " passed" in r.stdout and " failed" not in r.stdout
    if not measured:
        return
    files = json.loads((tmp_path / "coverage.json").read_text())["files"]
    names = [n for n in (p.relative_to(cache.PKG).as_posix() for p in cache._kernel_sources())
             if n not in COMPILE_MACHINERY]
    kernels = {name: files[f"fencesweep/{name}"]["summary"] for name in names if f"fencesweep/{name}" in files}
    run = sum(s["covered_lines"] for s in kernels.values())
    total = sum(s["num_statements"] for s in kernels.values())
    per_file = ", ".join(f"{n} {s['percent_covered']:.0f}%" for n, s in kernels.items())
    print(f"kernel statements run without the JIT: {run}/{total} = {run / total:.1%} ({per_file})")
    assert run / total >= KERNEL_COVERAGE, per_file
