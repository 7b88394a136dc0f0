"""`fencesweep gpu-info`: what the GPU path (kernel/cuda.py, model/scenes/gpu.py) has here: numba-cuda's
version, the GPUs found and, with --ptx CC, the cycle kernel compiled to PTX for that compute
capability, which needs no GPU (a typing error in any kernel function shows here)."""
from __future__ import annotations

import argparse
import re
import time

from fencesweep.errors import UsageError


def add_gpu_info_parser(sub) -> argparse.ArgumentParser:
    g = sub.add_parser("gpu-info", help="the GPU path: numba-cuda's version, the GPUs found; --ptx compiles the cycle "
                                        "kernel for a compute capability (no GPU needed)")
    g.add_argument("--ptx", metavar="CC", default=None,
                   help="compile the cycle kernel to PTX for compute capability CC (e.g. 9.0 for an H100/H200, "
                        "8.0 for an A100) and print its size")
    g.add_argument("--no-optimize", action="store_true",
                   help="with --ptx: without NVVM's optimisation (type-checks and compiles in about a third of "
                        "the time; the tests use it)")
    g.set_defaults(func=cmd_gpu_info)
    return g


def compute_capability(text: str) -> tuple:
    """'9.0' -> (9, 0); anything else is a usage error naming it."""
    m = re.fullmatch(r"\s*(\d+)\.(\d+)\s*", str(text))
    if not m or int(m.group(1)) < 5:
        raise UsageError(f"--ptx {text!r} is not a compute capability: MAJOR.MINOR, 5.0 or above (e.g. 8.0, 9.0)")
    return int(m.group(1)), int(m.group(2))


def ptx(cc: tuple, optimize: bool = True) -> tuple:
    """(the cycle kernel's PTX for compute capability cc, seconds the compile took)."""
    from fencesweep.model.scenes.gpu import Cycles

    t = time.perf_counter()
    text = Cycles().ptx(cc, opt=optimize)
    return text, time.perf_counter() - t


def lines() -> list:
    """numba-cuda's version and the GPUs found (kernel/cuda.py: GpuUnavailable without numba-cuda)."""
    import numba
    import numpy

    from fencesweep.kernel import cuda

    out = [f"numba-cuda {cuda.version()} (numba {numba.__version__}, numpy {numpy.__version__})"]
    found = cuda.gpus()
    if not found:
        out.append("GPUs: none found (no CUDA device or driver here): --backend cuda cannot run; --ptx still compiles")
    for g in found:
        mem = f", {g['memory'] / 2**30:.1f} GiB" if g["memory"] else ""
        out.append(f"GPU {g['id']}: {g['name']}, compute capability {g['cc'][0]}.{g['cc'][1]}{mem}")
    return out


def cmd_gpu_info(args: argparse.Namespace) -> int:
    cc = compute_capability(args.ptx) if args.ptx is not None else None
    for line in lines():
        print(line)
    if cc is not None:
        text, seconds = ptx(cc, optimize=not args.no_optimize)
        print(f"cycle kernel for sm_{cc[0]}{cc[1]}: PTX of {len(text.encode()):,} bytes, compiled in {seconds:.1f} s"
              + ("" if not args.no_optimize else " (not optimised)"))
    return 0
