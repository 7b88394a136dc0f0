"""The GPU path (kernel/cuda.py, model/scenes/gpu.py, study/sweep/gpu.py), without a GPU:

* the cycle kernel, every kernel function a numba-cuda device function of its own source,
  compiles to PTX for sm_80 and sm_90 (a typing error in any kernel function fails here);
* on Numba's CUDA simulator (NUMBA_ENABLE_CUDASIM=1) `--backend cuda` writes the CPU's table: a
  scene of each named case, outcomes and step counts equal, values within 1e-6;
* a GPU thread's parameter vector without the drive table (the four-bar solved instead) runs the
  CPU's cycle;
* the messages: no numba-cuda, no GPU, a scene the GPU does not run.
"""
import math
import os
import subprocess
import sys
import textwrap

import numpy as np
import pandas as pd
import pytest

from fencesweep.errors import UsageError
from fencesweep.kernel.jit import python_callable
from fencesweep.model import drive
from fencesweep.model import layout as Lp
from fencesweep.model import params as P
from fencesweep.model.prepare import prepare
from fencesweep.model.results import N_CYCLE_RESULTS, unpack
from fencesweep.model.scenes.stream import run_cycles
from fencesweep.study.store import table as store

cuda_module = pytest.importorskip("numba.cuda", reason="the gpu extra (numba-cuda) is part of the test extra")

SCENES = [("small_far", {}), ("long_near", {}), ("small_far", {"drive": "rigid"}),
          ("long_near", {"B2": 15.0, "K2": 2075.0}), ("small_far", {"swing": 1.0, "coupler_ratio": 2.0})]


def _cycle(p: np.ndarray) -> dict:
    """One cycle of parameter vector p on the CPU, as model/simulate.py runs it."""
    loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
    out = np.empty((1, 40))
    run_cycles(p, loads, float(p[Lp.TC]), out, np.empty((0, 19)), np.zeros(2, np.int64))
    return unpack("cycle", out[0, :N_CYCLE_RESULTS])


def test_the_four_bar_solved_gives_the_tables_drive():
    """drive_angle without the table (TAB_N = 0) solves (2.2)-(2.6) at each time; the table
    interpolates the same to ~1e-12 rad (docs/model.md (15.11))."""
    vals = P.resolve("cycle", "small_far")
    with_table, header = prepare(vals), prepare(vals, table=False)
    assert len(header) == Lp.N_P and header[Lp.TAB_N] == 0 and with_table[Lp.TAB_N] > 0
    angle = python_callable(drive.drive_angle)
    for t in np.linspace(0.0, vals["t_c"], 997):
        (a1, r1), (a2, r2) = angle(t, with_table), angle(t, header)
        assert abs(a1 - a2) < 1e-10 and abs(r1 - r2) < 1e-8 * max(1.0, abs(r1))


@pytest.mark.parametrize("case,over", SCENES)
def test_a_cycle_without_the_drive_table_is_the_cpus_cycle(case, over):
    """A GPU thread's parameter vector (the header only) runs, on the CPU, the cycle of the full one."""
    vals = P.resolve("cycle", case, **over)
    a, b = _cycle(prepare(vals)), _cycle(prepare(vals, table=False))
    for k, x in a.items():
        if isinstance(x, float) and math.isfinite(x):
            assert abs(x - b[k]) <= 1e-6 * max(1.0, abs(x)), k
        elif k != "n_steps":
            assert x == b[k] or (isinstance(x, float) and math.isnan(b[k])), k
    assert abs(a["n_steps"] - b["n_steps"]) <= 2


# ------------------------------------------------------------------ PTX, without a GPU
@pytest.fixture(scope="module")
def cycles():
    from fencesweep.model.scenes.gpu import Cycles

    return Cycles()


@pytest.mark.parametrize("cc", [(8, 0), (9, 0)])
def test_the_cycle_kernel_compiles_to_ptx_for_sm80_and_sm90(cycles, cc):
    """The whole cycle, type-checked and compiled by numba-cuda (without NVVM's optimisation, as
    `fencesweep gpu-info --ptx CC --no-optimize`), with no GPU here."""
    ptx = cycles.ptx(cc, opt=False)
    assert f".target sm_{cc[0]}{cc[1]}" in ptx
    assert ".entry" in ptx and "cycle_threads" in ptx
    assert ".f64" in ptx  # the cycle runs in double precision


def test_every_kernel_function_the_cycle_calls_is_a_device_function(cycles):
    """No CPU kernel function is left in what the GPU's copies call: each name that their code uses
    is a device function (or a proxy module of them) once the kernel has compiled."""
    from fencesweep.kernel.jit import KernelDispatcher

    cycles.ptx((9, 0), opt=False)
    made = [dev for _, dev in cycles.tr._made.values() if hasattr(dev, "py_func")]
    assert len(made) > 100  # the cycle's ~150 kernel functions
    for dev in made:
        g = dev.py_func.__globals__
        used = [g[n] for n in dev.py_func.__code__.co_names if n in g]
        assert not any(isinstance(v, KernelDispatcher) for v in used), dev.py_func.__name__


def test_a_typing_error_in_a_kernel_function_fails_the_ptx_compile():
    """A kernel function that allocates (np.empty) does not compile for the GPU: what CI catches."""
    from numba.core.errors import TypingError as CoreTypingError

    from fencesweep.kernel import cuda
    from fencesweep.kernel.jit import kernel

    @kernel()
    def allocates(x):
        a = np.empty(3)
        a[0] = x
        return a[0]

    def threads(out):
        out[0] = F(1.0)  # noqa: F821  (F: bound below)

    tr = cuda.Translation()
    k = tr.kernel(threads, "threads", F=tr.device(allocates))
    errors = (CoreTypingError,) + tuple(e for e in [getattr(sys.modules.get("numba.cuda.core.errors"), "TypingError",
                                                            None)] if e is not None)
    with pytest.raises(errors, match="empty"):
        cuda.compile_ptx(k.py_func, "void(float64[::1])", (9, 0), opt=False)


def test_numpys_row_stack_is_aliased_only_while_numba_cuda_registers_it(monkeypatch):
    from fencesweep.kernel import cuda

    monkeypatch.delattr(np, "row_stack", raising=False)
    with cuda._row_stack_alias():
        assert np.row_stack is np.vstack
    assert not hasattr(np, "row_stack")


# ------------------------------------------------------------------ the command line
def _fencesweep(*args, env=None, code=None):
    cmd = [sys.executable, "-c", code] if code else [sys.executable, "-m", "fencesweep", *args]
    return subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **(env or {})}, timeout=900)


def test_gpu_info_names_numba_cuda_and_the_gpus():
    r = _fencesweep("gpu-info")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("numba-cuda ")
    assert "GPUs: none found" in r.stdout or "GPU 0: " in r.stdout


def test_without_numba_cuda_gpu_info_and_backend_cuda_say_how_to_install_it(tmp_path):
    for args in (["gpu-info"], ["grid", "sweeps/b2k2.yaml", "--backend", "cuda", "--out", str(tmp_path / "t.parquet")]):
        code = ("import sys; sys.modules['numba.cuda'] = None\n"
                f"from fencesweep.cli import main; sys.argv = ['fencesweep', *{args!r}]; sys.exit(main())")
        r = _fencesweep(code=code)
        assert r.returncode == 2, r.stderr
        assert 'pip install -e ".[gpu]"' in r.stderr
    assert not (tmp_path / "t.parquet").exists()


@pytest.mark.skipif(bool(os.environ.get("NUMBA_ENABLE_CUDASIM")), reason="the simulator is a GPU")
def test_backend_cuda_without_a_gpu_says_none_was_found(tmp_path):
    from fencesweep.kernel import cuda

    if cuda.gpus():
        pytest.skip("this machine has a GPU")
    r = _fencesweep("grid", "sweeps/b2k2.yaml", "--backend", "cuda", "--out", str(tmp_path / "t.parquet"))
    assert r.returncode == 2 and "no GPU was found" in r.stderr
    assert not list(tmp_path.iterdir())


def test_backend_cuda_refuses_other_scenes_and_adaptive_maps(tmp_path):
    import fencesweep

    with pytest.raises(UsageError, match="'cuda' runs the scene 'cycle' only, not 'impact'"):
        fencesweep.grid("sweeps/impact_m2.yaml", out=tmp_path / "i.parquet", backend="cuda", progress=False)
    with pytest.raises(UsageError, match="adaptive"):
        fencesweep.grid("sweeps/envelope.yaml", out=tmp_path / "e.parquet", backend="cuda", adaptive=True)
    with pytest.raises(UsageError, match="backend = 'cuda' is not allowed"):
        fencesweep.design("sweeps/envelope.yaml", backend="cuda")
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------ semantics, on the simulator
SIM_SPEC = textwrap.dedent("""\
    description: a few scenes of each named case through the GPU path
    scene: cycle
    cases: [small_far, long_near]
    grid:
      B2: [0.0, 72.0, 300.0]
      K2: [570.0, 2075.0]
    output: sim.parquet
    """)


def test_backend_cuda_on_the_simulator_writes_the_cpus_table(tmp_path):
    """`fencesweep grid --backend cuda` on Numba's CUDA simulator (every GPU thread run in Python,
    a few seconds a cycle): the CPU's table, row by row, and the device in its metadata."""
    spec = tmp_path / "sim.yaml"
    spec.write_text(SIM_SPEC)
    gpu, cpu = tmp_path / "gpu.parquet", tmp_path / "cpu.parquet"
    r = _fencesweep("grid", str(spec), "--backend", "cuda", "--out", str(gpu), "--jobs", "1", "--quiet",
                    env={"NUMBA_ENABLE_CUDASIM": "1"})
    assert r.returncode == 0, r.stderr[-3000:]
    r = _fencesweep("grid", str(spec), "--out", str(cpu), "--jobs", "1", "--quiet")
    assert r.returncode == 0, r.stderr[-3000:]
    a, b = pd.read_parquet(cpu), pd.read_parquet(gpu)
    assert list(a.columns) == list(b.columns) and a.dtypes.equals(b.dtypes) and len(a) == 12
    for c in a.columns:
        if c == "n_steps":
            assert (abs(a[c] - b[c]) <= 2).all()
        elif a[c].dtype.kind == "f":
            x, y = a[c].to_numpy(), b[c].to_numpy()
            both_nan = np.isnan(x) & np.isnan(y)
            assert (both_nan | (np.abs(x - y) <= 1e-6 * np.maximum(1.0, np.abs(x)))).all(), c
        else:
            assert (a[c] == b[c]).all(), c
    meta = store.read_metadata(gpu)
    assert meta["device"]["backend"] == "cuda" and "simulator" in meta["device"]["name"]
    assert meta["verify"]["ok"] is True  # re-run on the CPU at tol / 10
    assert "device" not in store.read_metadata(cpu)


def test_a_chunk_written_from_columns_is_the_chunk_written_from_rows():
    """The GPU path writes its chunks from whole result columns (results.unpack_columns,
    store.columns_table): the same table as the CPU's rows of result dicts, failed rows included."""
    from fencesweep.model.results import CYCLE_RESULTS, N_STREAM_CYCLE_RESULTS, OUTCOMES, STATUS_MESSAGES
    from fencesweep.model.results import unpack_columns

    names = [n for n, _, _ in CYCLE_RESULTS]
    rng = np.random.default_rng(7)
    out = rng.normal(size=(300, N_STREAM_CYCLE_RESULTS))
    out[:, names.index("outcome")] = rng.integers(0, len(OUTCOMES) - 1, 300)
    out[:, names.index("status")] = rng.integers(0, len(STATUS_MESSAGES), 300)
    for n in ("n_impacts", "n_steps", "n_rejected"):
        out[:, names.index(n)] = rng.integers(0, 5000, 300)
    out[::5, names.index("safe")] = 0.0
    out[::7, names.index("safe")] = np.nan
    out[::3, names.index("overload")] = np.nan
    rows = [unpack("cycle", o[:N_CYCLE_RESULTS]) for o in out]
    cols = unpack_columns(CYCLE_RESULTS, out[:, :N_CYCLE_RESULTS])
    rows[4] = store.failed_result("cycle", "failed: exception ValueError: x")
    for name, value in rows[4].items():
        cols[name][4] = value
    a = store.results_table("cycle", rows, range(300)).to_pandas()
    b = store.columns_table("cycle", cols, range(300)).to_pandas()
    pd.testing.assert_frame_equal(a, b)
    assert b["outcome"].iloc[4] == "failed" and np.isnan(b["peak_force"].iloc[4])
