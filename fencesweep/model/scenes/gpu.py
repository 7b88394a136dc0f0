"""Work cycles on a GPU, one thread per cycle (docs/model.md §8 `cycle`; the GPU path, kernel/cuda.py).

Thread i runs the cycle whose parameter vector is row i of P, as model/simulate.py runs a cycle
on the CPU: a stream of one, its load the row's own (layout.LOAD_SLOTS), its period t_c. It
calls stream.cycles_with_work, the CPU's run_cycles' own code, with its work arrays in the
thread's local memory (MEM = numba.cuda: cuda.local.array) and every kernel function a device function of
the same source (kernel/cuda.py Translation). A row has the header only (prepare.prepare with
table=False): the crank-rocker's four-bar is solved at each time instead of read from a table
that every thread would carry (drive.drive_angle, compiled with DRIVE_TABLE = False). No
trajectory is kept (a 0-row buffer).

    runner = Cycles()                 # compiles on first use (numba-cuda, ~1 min; then its cache)
    out = runner.run(P)               # P (n, N_P) float64 -> out (n, N_STREAM_CYCLE_RESULTS)
"""
from __future__ import annotations

import numpy as np

from fencesweep.model import layout as Lp
from fencesweep.model.layout import N_LOAD, N_P
from fencesweep.model import results as Rs
from fencesweep.model.scenes import stream
from fencesweep.model.scenes.cycle.layout import N_TRAJ

#: threads per block. The cycle is a large kernel (its registers spill to local memory at any
#: block size); 128 keeps four warps a block, numba-cuda's and CUDA's usual choice for such
#: kernels, and leaves the scheduler room to hide memory latency. Not tuned on a card yet.
THREADS_PER_BLOCK = 128
#: on Numba's CUDA simulator a block's threads are Python threads that run at once, taking turns
#: on the interpreter, and its blocks run one after another: one thread a block runs the cycles
#: one by one (12 cycles of tests/test_gpu.py took 306 s in one block of 128 threads)
SIMULATOR_THREADS_PER_BLOCK = 1
#: device bytes a cycle takes besides its thread's local memory: its row of P and its row of out
ROW_BYTES = 8 * (Lp.N_P + Rs.N_STREAM_CYCLE_RESULTS)
#: the signature of the kernel: P, out, the (empty) trajectory buffer
SIGNATURE = "void(float64[:, ::1], float64[:, ::1], float64[:, ::1])"

#: bound by Cycles: numba.cuda, and the cycle as a device function
CUDA = RUN = None


def cycle_threads(P, out, traj):
    """Thread i: the cycle of row i of P into row i of out (module docstring). A template:
    CUDA and RUN are numba-cuda's (Cycles)."""
    i = CUDA.grid(1)
    if i < P.shape[0]:
        p = P[i]
        pk = CUDA.local.array(N_P, np.float64)
        loads = CUDA.local.array((1, N_LOAD), np.float64)
        starts = CUDA.local.array(2, np.int64)
        for j in range(Lp.N_LOAD):
            loads[0, j] = p[Lp.LOAD_SLOTS[j]]
        RUN(p, loads, p[Lp.TC], out[i:i + 1], traj, starts, pk)


class Cycles:
    """The cycle kernel on the GPU (module docstring); `kernel` compiles it on its first launch."""

    def __init__(self):
        from fencesweep.kernel.cuda import Translation

        self.tr = Translation(DRIVE_TABLE=False)  # a thread's p has no drive table (drive.drive_angle)
        cuda = self.tr.cuda
        self.run_device = self.tr.device(stream.cycles_with_work, "cycles_with_work_gpu", MEM=cuda)
        self.bindings = dict(CUDA=cuda, RUN=self.run_device)
        self.kernel = self.tr.kernel(cycle_threads, "cycle_threads", **self.bindings)

    def ptx(self, cc: tuple, opt: bool = True) -> str:
        """The kernel's PTX for compute capability cc (no GPU needed: kernel/cuda.py compile_ptx)."""
        from fencesweep.kernel.cuda import compile_ptx

        return compile_ptx(self.kernel.py_func, SIGNATURE, cc, opt=opt)

    def free_memory(self) -> int | None:
        """The card's free bytes (None on Numba's CUDA simulator)."""
        cuda = self.tr.cuda
        if cuda.config.ENABLE_CUDASIM:
            return None
        return int(cuda.current_context().get_memory_info()[0])

    def launch(self, P: np.ndarray) -> "Launched":
        """Start the cycles of the rows of P (n, N_P) on the GPU; Launched.result() gives their
        result rows (n, N_STREAM_CYCLE_RESULTS). The launch returns before the GPU is done."""
        cuda = self.tr.cuda
        P = np.ascontiguousarray(P, dtype=np.float64)
        n = P.shape[0]
        out = np.empty((n, Rs.N_STREAM_CYCLE_RESULTS))
        if n == 0:
            return Launched(out, None)
        d_out = cuda.device_array_like(out)
        tpb = SIMULATOR_THREADS_PER_BLOCK if cuda.config.ENABLE_CUDASIM else THREADS_PER_BLOCK
        self.kernel[(n + tpb - 1) // tpb, tpb](cuda.to_device(P), d_out, cuda.device_array((0, N_TRAJ), np.float64))
        return Launched(out, d_out)

    def run(self, P: np.ndarray) -> np.ndarray:
        """The result rows of the cycles of the rows of P (launch, and wait)."""
        return self.launch(P).result()


class Launched:
    """A batch on the GPU: result() waits for it and copies its result rows back."""

    def __init__(self, out: np.ndarray, d_out):
        self.out, self.d_out = out, d_out

    def result(self) -> np.ndarray:
        if self.d_out is not None:
            self.d_out.copy_to_host(self.out)
            self.d_out = None
        return self.out
