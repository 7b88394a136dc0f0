"""The plain-Python path: the kernels' tests (marked plain_python) also pass with Numba's JIT
off (NUMBA_DISABLE_JIT=1), as pvlib runs its Numba and plain paths through one suite.

Without the JIT the kernels are ordinary Python functions, so the run also measures how much
of the compiled code the tests execute: at least KERNEL_COVERAGE of the statements of the
kernel sources (fencesweep.kernel.cache's list of them: kernel/ and model/) must run, leaving
out the modules of how Numba compiles them (COMPILE_MACHINERY), which a run without the JIT
does not use by design.

Without the JIT a cycle runs ~100 times slower, so the run leaves out COVERED_ELSEWHERE: kernel
tests slow without the JIT (0.3-4.4 s each) whose kernel statements the other tests of the run
all run too, as coverage's per-test contexts measured (the run covers the same statements with
them as without). They still run compiled in the suite. The run collects only the test files
that mark a test plain_python.
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

#: the plain_python tests the run leaves out: without the JIT each took 0.3-4.4 s (44 s of the run's
#: 55 s of tests), and the run's other tests ran every kernel statement they ran (measured with
#: `--cov-context=test` on the tree of this list: 2,162 of 2,380 statements, 90.8 %, with or
#: without them); each still runs compiled in the suite
COVERED_ELSEWHERE = [
    "test_api.py::test_a_kernel_that_needs_more_rows_on_its_rerun_is_an_error",
    "test_api.py::test_kernel_reports_the_rows_a_short_buffer_could_not_hold",
    "test_api.py::test_short_trajectory_buffer_is_grown_not_cut",
    "test_api.py::test_trajectory_holds_the_located_maxima[long_near-rigid]",
    "test_api.py::test_trajectory_holds_the_located_maxima[small_far-flexible]",
    "test_cycle.py::test_default_step_agrees_with_ten_times_finer[long_near]",
    "test_cycle.py::test_default_step_agrees_with_ten_times_finer[small_far]",
    "test_cycle.py::test_fence_without_load_matches_exact_linear_response[150.0-300.0-0.2]",
    "test_cycle.py::test_fence_without_load_matches_exact_linear_response[20.0-1500.0-0.2]",
    "test_cycle.py::test_fence_without_load_matches_exact_linear_response[72.0-570.0-0.2]",
    "test_cycle.py::test_long_near_slides_with_fence_and_rail_S4",
    "test_cycle.py::test_named_cases_scraped_rigid_and_flexible_paper_4_2[long_near]",
    "test_cycle.py::test_named_cases_scraped_rigid_and_flexible_paper_4_2[small_far]",
    "test_cycle.py::test_results_converge_as_friction_regularisation_vanishes",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[K2=0, B2=72]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[Psi=0.05]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[Psi=5]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[eps_v=1e-5]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[face flush along the fence]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[free fence]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[hit by the tip]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[jammed at the pivot, mu2=1]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[k1=1e5]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[k1=1e9]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[m1=0.1]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[m1=100]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[phi0=+pi/4]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[rigid fence]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[v=0.1]",
    "test_hard_cases.py::test_hard_case_is_stable_and_converges[v=5]",
    "test_hard_cases.py::test_hard_cases_exercise_what_they_claim",
    "test_impact.py::test_fig5a_flexible_element_only_slightly_above_free",
    "test_stream.py::test_a_stream_of_one_is_the_cycle_bit_for_bit",
]


def _marking_files() -> list[str]:
    """The test files that mark a test plain_python (the only ones the run needs to collect)."""
    here = Path(__file__)
    return sorted(f"tests/{p.name}" for p in here.parent.glob("test_*.py")
                  if p != here and "plain_python" in p.read_text())


def test_kernel_tests_pass_without_the_jit_and_cover_the_kernels(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("COV_CORE_")}  # not the parent's coverage
    env.update(NUMBA_DISABLE_JIT="1", COVERAGE_FILE=str(tmp_path / ".coverage"))
    files = _marking_files()
    assert "tests/test_cycle.py" in files and "tests/test_hard_cases.py" in files
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "plain_python", *files,
           *(f"--deselect=tests/{t}" for t in COVERED_ELSEWHERE)]
    measured = importlib.util.find_spec("pytest_cov") is not None  # the test extra has it
    if measured:  # the kernel sources' folders only (kernel/, model/), not the rest of the package, which the
        # run would trace and report for nothing (~3 s of its ~19 s)
        folders = sorted({p.relative_to(cache.PKG).parts[0] for p in cache._kernel_sources()})
        cmd += [*(f"--cov=fencesweep/{f}" for f in folders), f"--cov-report=json:{tmp_path / 'coverage.json'}"]
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
