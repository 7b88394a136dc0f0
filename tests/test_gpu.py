"""The GPU path (kernel/cuda.py, model/scenes/gpu.py, study/sweep/gpu.py), without a GPU:

* the cycle kernel, every kernel function a numba-cuda device function of its own source,
  compiles to PTX for sm_80 and sm_90 (a typing error in any kernel function fails here);
* on Numba's CUDA simulator (NUMBA_ENABLE_CUDASIM=1) `--backend cuda` writes the CPU's table: a
  scene of each named case, outcomes and step counts equal, values within 1e-6;
* a GPU thread's drive, the four-bar solved instead of the table read, is the CPU's;
* the orchestration (batches, workers, adaptive levels) with the CPU standing in for the card;
* the messages: no numba-cuda, no GPU, a scene the GPU does not run.
"""
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


def test_the_four_bar_solved_gives_the_tables_drive():
    """drive_angle compiled with DRIVE_TABLE False (a GPU thread's) solves (2.2)-(2.6) at each time
    from p's header; the CPU's table interpolates the same to ~1e-12 rad (docs/model.md (15.11))."""
    from numba import njit

    from fencesweep.kernel.jit import bind

    solved = njit(_nrt=False)(bind(drive.drive_angle.py_func, "drive_angle_solved", DRIVE_TABLE=False))
    table = python_callable(drive.drive_angle)
    for case, over in SCENES:
        vals = P.resolve("cycle", case, **over)
        with_table, header = prepare(vals), prepare(vals, table=False)
        assert len(header) == Lp.N_P and header[Lp.TAB_N] == 0 and with_table[Lp.TAB_N] > 0
        for t in np.linspace(0.0, vals["t_c"], 997):
            (a1, r1), (a2, r2) = table(t, with_table), solved(t, header)
            assert abs(a1 - a2) < 1e-10 and abs(r1 - r2) < 1e-8 * max(1.0, abs(r1))


# ------------------------------------------------------------------ PTX, without a GPU
@pytest.fixture(scope="module")
def cycles():
    from fencesweep.model.scenes.gpu import Cycles

    return Cycles()


@pytest.fixture(scope="module")
def cycle_ptx(cycles):
    """cycle_ptx(cc): the cycle kernel's PTX for cc without NVVM's optimisation, compiled once per
    cc in this module (a compile takes ~10 s; two tests read sm_90's)."""
    made = {}

    def ptx(cc):
        if cc not in made:
            made[cc] = cycles.ptx(cc, opt=False)
        return made[cc]

    return ptx


@pytest.mark.parametrize("cc", [(8, 0), (9, 0)])
def test_the_cycle_kernel_compiles_to_ptx_for_sm80_and_sm90(cycle_ptx, cc):
    """The whole cycle, type-checked and compiled by numba-cuda (without NVVM's optimisation, as
    `fencesweep gpu-info --ptx CC --no-optimize`), with no GPU here."""
    ptx = cycle_ptx(cc)
    assert f".target sm_{cc[0]}{cc[1]}" in ptx
    assert ".entry" in ptx and "cycle_threads" in ptx
    assert ".f64" in ptx  # the cycle runs in double precision


def test_the_gpu_kernel_is_cached_under_the_kernel_sources_hash(cycles):
    """numba-cuda's cache of the cycle kernel is kept in kernel/cache.py's directory, named by the
    hash of the kernel sources (its own would be keyed by model/scenes/gpu.py alone)."""
    from pathlib import Path

    from fencesweep.kernel import cache

    if os.environ.get("NUMBA_ENABLE_CUDASIM"):
        pytest.skip("the simulator compiles nothing to cache")
    path = Path(cycles.kernel._cache._cache_path)
    assert path.is_relative_to(cache.DIR) and cache.HASH[:16] in str(path)
    assert "model/scenes/gpu.py" in cache.MODEL_SOURCES or "model/scenes/gpu.py" in {
        p.relative_to(cache.PKG).as_posix() for p in cache._kernel_sources()}


def test_every_kernel_function_the_cycle_calls_is_a_device_function(cycles, cycle_ptx):
    """No CPU kernel function is left in what the GPU's copies call: each name that their code uses
    is a device function (or a proxy module of them) once the kernel has compiled."""
    from fencesweep.kernel.jit import KernelDispatcher

    assert ".entry" in cycle_ptx((9, 0))  # compiled (once in this module: the sm_90 test's PTX)
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


def test_backend_cuda_refuses_other_scenes_and_the_design_search(tmp_path):
    import fencesweep

    with pytest.raises(UsageError, match="'cuda' runs the scene 'cycle' only, not 'impact'"):
        fencesweep.grid("sweeps/impact_m2.yaml", out=tmp_path / "i.parquet", backend="cuda", progress=False)
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


#: `fencesweep ARGS...` on the simulator, whose block waits for its threads by polling them without a
#: pause: the poll holds the interpreter's lock half the time, which the one thread that runs the
#: kernel waits for (the run twice as long). Here each poll sleeps 0.5 ms first; the threads and
#: what they compute are the simulator's own.
ON_THE_SIMULATOR = textwrap.dedent("""\
    import sys, threading, time
    from numba.cuda.simulator import kernel as simulated

    if hasattr(simulated, "BlockThread"):
        def is_alive(thread, _is_alive=threading.Thread.is_alive):
            time.sleep(0.0005)
            return _is_alive(thread)

        simulated.BlockThread.is_alive = is_alive
    from fencesweep.cli import main

    sys.argv = ["fencesweep", *sys.argv[1:]]
    sys.exit(main())
    """)


def test_backend_cuda_on_the_simulator_writes_the_cpus_table(tmp_path):
    """`fencesweep grid --backend cuda` on Numba's CUDA simulator (every GPU thread run in Python,
    a few seconds a cycle): the CPU's table, row by row, and the device in its metadata."""
    spec = tmp_path / "sim.yaml"
    spec.write_text(SIM_SPEC.replace("B2: [0.0, 72.0, 300.0]", "B2: [0.0, 300.0]"))  # 8 rows: the simulator is slow
    gpu, cpu = tmp_path / "gpu.parquet", tmp_path / "cpu.parquet"
    r = subprocess.run([sys.executable, "-c", ON_THE_SIMULATOR, "grid", str(spec), "--backend", "cuda", "--out",
                        str(gpu), "--jobs", "1", "--quiet"], capture_output=True, text=True,
                       env={**os.environ, "NUMBA_ENABLE_CUDASIM": "1"}, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    r = _fencesweep("grid", str(spec), "--out", str(cpu), "--jobs", "1", "--quiet")
    assert r.returncode == 0, r.stderr[-3000:]
    a, b = pd.read_parquet(cpu), pd.read_parquet(gpu)
    assert list(a.columns) == list(b.columns) and a.dtypes.equals(b.dtypes) and len(a) == 8
    for c in a.columns:
        if c == "n_steps":
            assert (abs(a[c] - b[c]) <= 2).all()
        elif a[c].dtype.kind == "f":
            x, y = a[c].to_numpy(), b[c].to_numpy()
            both_nan = np.isnan(x) & np.isnan(y)
            # the simulator's libm is Python's, whose last bits can tip a step's tolerance switch
            # (run.set_tolerance) the other way (n_steps above): the energies, integrals over the
            # cycle, then move by their own integration error (1e-5 to 1.4e-4 of small_far's
            # contact_energy at the default setting against step_factor 0.1), the rest by < 1e-6
            rel = 1e-4 if c in ("contact_energy", "damper_energy") else 1e-6
            assert (both_nan | (np.abs(x - y) <= rel * np.maximum(1.0, np.abs(x)))).all(), c
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


# ------------------------------------------------------------------ the orchestration, with the CPU as the card
class CpuCard:
    """A stand-in for the GPU that runs each row of P (a GPU thread's parameter vector) with the
    CPU's kernel, its drive table put back: the GPU path's orchestration (batches, workers,
    chunks, adaptive levels) checked at the CPU's speed."""

    def __init__(self):
        self.launches = []

    def free_memory(self):
        return None

    def launch(self, P):
        from fencesweep.model.results import N_STREAM_CYCLE_RESULTS

        from fencesweep.model.prepare import with_drive_table

        self.launches.append(P.shape[0])
        out = np.empty((P.shape[0], N_STREAM_CYCLE_RESULTS))
        for k, header in enumerate(P):
            p = with_drive_table(header.copy(), header[Lp.SWING], header[Lp.CR_B]) \
                if header[Lp.PROFILE] == Lp.PROFILE_CRANK_ROCKER else header  # b = r_b (docs/model.md (2.1))
            loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
            run_cycles(np.ascontiguousarray(p), loads, float(p[Lp.TC]), out[k:k + 1], np.empty((0, 19)),
                       np.zeros(2, np.int64))
        card = self

        class Done:
            def result(self):
                return out

        card.last = Done()
        return card.last


@pytest.fixture
def cpu_card(monkeypatch):
    from fencesweep.study.sweep import gpu, pipeline

    card = CpuCard()
    monkeypatch.setattr(pipeline, "gpu_device", lambda spec: gpu.check_scene(spec) or {"backend": "cuda",
                                                                                      "name": "the CPU, standing in"})
    monkeypatch.setattr(gpu, "runner", lambda: card)
    return card


def _within(a: pd.DataFrame, b: pd.DataFrame) -> None:
    """The tables agree as the GPU's must agree with the CPU's: outcomes, counts and labels equal,
    values within 1e-6 (floored at 1), n_steps within a few."""
    assert list(a.columns) == list(b.columns) and len(a) == len(b)
    for c in a.columns:
        if c == "n_steps":
            assert (abs(a[c] - b[c]) <= 2).all()
        elif a[c].dtype.kind == "f":
            x, y = a[c].to_numpy(), b[c].to_numpy()
            assert ((np.isnan(x) & np.isnan(y)) | (np.abs(x - y) <= 1e-6 * np.maximum(1.0, np.abs(x)))).all(), c
        else:
            assert a[c].reset_index(drop=True).equals(b[c].reset_index(drop=True)), c


def test_a_sweep_in_batches_on_workers_writes_the_cpus_table(cpu_card, monkeypatch, tmp_path):
    """Batches of at most 5 runs, the parameter vectors and the chunks made on 2 workers (and in
    this process with 1 job): the CPU's table, and the same table either way."""
    import fencesweep
    from fencesweep.study.sweep import gpu

    monkeypatch.setattr(gpu, "BATCH_RUNS", 5)
    spec = tmp_path / "s.yaml"
    spec.write_text(SIM_SPEC)
    two = fencesweep.grid(str(spec), out=tmp_path / "two.parquet", backend="cuda", jobs=2, progress=False)
    assert max(cpu_card.launches) <= 5 and sum(cpu_card.launches) == 12
    one = fencesweep.grid(str(spec), out=tmp_path / "one.parquet", backend="cuda", jobs=1, progress=False)
    cpu = fencesweep.grid(str(spec), out=tmp_path / "cpu.parquet", jobs=1, progress=False)
    pd.testing.assert_frame_equal(one, two)
    _within(cpu, two)
    assert two.attrs["fencesweep"]["device"]["name"] == "the CPU, standing in" and two.attrs["fencesweep"]["verify"]["ok"]


def test_an_adaptive_map_on_the_gpu_path_keeps_the_cpus_rows(cpu_card, tmp_path):
    """An adaptive map's levels on the GPU path run every load of an element at once, then keep
    the loads the CPU runs (each element to its first broken constraint): the same rows."""
    import fencesweep
    from test_adaptive import SMALL

    gpu_t = fencesweep.grid(SMALL, out=tmp_path / "g.parquet", backend="cuda", jobs=1, verify=False, adaptive=True)
    cpu_t = fencesweep.grid(SMALL, out=tmp_path / "c.parquet", jobs=1, verify=False, adaptive=True)
    _within(cpu_t, gpu_t)
    assert sum(cpu_card.launches) > len(gpu_t)  # the loads after a stop ran, and were not kept
    assert gpu_t.attrs["fencesweep"]["device"]["name"] == "the CPU, standing in"


def test_a_run_that_cannot_be_prepared_is_a_failed_row_and_its_thread_runs_a_valid_cycle(monkeypatch):
    """As on the CPU (runs.run_one), a run whose parameters raise is a failed row naming the
    exception; its GPU thread gets the default cycle's vector, never one of zeros."""
    from fencesweep.model import params
    from fencesweep.model import prepare as prep
    from fencesweep.study.spec import file as specfile
    from fencesweep.study.sweep import gpu

    spec = specfile.loads(SIM_SPEC)  # scene = 6 case + 2 (B2 index) + (K2 index)
    real, real_columns = prep.prepare, prep.prepare_columns

    def fails_for_b2_300(vals, table=True):
        if vals["B2"] == 300.0:
            raise ValueError("no")
        return real(vals, table)

    def columns_fail_with_it(columns, n, table=True):  # the chunk's columns hold B2 = 300: run by run
        if 300.0 in np.atleast_1d(columns["B2"]):
            raise ValueError("no")
        return real_columns(columns, n, table)

    monkeypatch.setattr(prep, "prepare", fails_for_b2_300)
    monkeypatch.setattr(prep, "prepare_columns", columns_fail_with_it)
    _, P, failed = gpu._prepare(0, np.arange(4), (spec, None))  # B2 0 and 72: on columns, none failed
    assert failed == {} and all(np.array_equal(P[k], real(v, table=False))
                                for k, v in enumerate(spec.resolve(i) for i in range(4)))
    _, P, failed = gpu._prepare(0, np.arange(12), (spec, None))
    assert sorted(failed) == [4, 5, 10, 11] and set(failed.values()) == {"failed: exception ValueError: no"}
    default = real(params.resolve("cycle"), table=False)
    assert all(np.array_equal(P[k], default) for k in failed) and (P[:, Lp.TC] > 0).all()
