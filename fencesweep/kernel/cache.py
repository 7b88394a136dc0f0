"""Keep Numba's on-disk cache (cache=True) consistent with the kernel sources, and keep the
values solved once per input (`solved`) beside it.

Numba keys a cached function on its own source file only; the cycle kernel inlines helpers
from drive.py and contact.py, so an edit there would leave a stale compiled kernel. At
import we hash every kernel source; when the hash differs from the one stored beside the
cache, the package's cache files are removed and Numba recompiles once; the solved values
(which the kernels compute) are removed with them.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

_PKG = Path(__file__).resolve().parents[1]  # the package
_KERNEL_SOURCES = ("kernel/jit.py", "model/layout.py", "model/results.py", "kernel/numerics.py", "model/contact.py",
                   "model/drive.py", "kernel/integrate.py", "model/scenes/load.py", "model/scenes/contacts.py",
                   "model/scenes/cycle.py", "model/scenes/stream.py", "model/scenes/impact.py",
                   "model/scenes/freefall.py")
_STAMP = _PKG / "__pycache__" / "kernels.sha256"
#: values solved once per input by root finding (calibrate.damping_coefficient,
#: drive.crank_rocker_geometry): without them a process imports scipy.optimize (0.3 s) and runs
#: the calibration's impacts before its first cycle, once in every sweep worker
SOLVED = _PKG / "__pycache__" / "solved.json"
_solved: dict | None = None


def kernel_hash() -> str:
    h = hashlib.sha256()
    for name in _KERNEL_SOURCES:
        h.update(name.encode())
        h.update((_PKG / name).read_bytes())
    return h.hexdigest()


def invalidate_stale_kernels() -> None:
    """Remove cached kernels compiled from other sources than the present ones."""
    try:
        digest = kernel_hash()
        if _STAMP.exists() and _STAMP.read_text().strip() == digest:
            return
        for pattern in ("*.nbi", "*.nbc"):
            for f in _PKG.rglob(pattern):
                f.unlink(missing_ok=True)
        SOLVED.unlink(missing_ok=True)
        _STAMP.parent.mkdir(exist_ok=True)
        tmp = _STAMP.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(digest)
        os.replace(tmp, _STAMP)
    except OSError:  # a read-only install: nothing to invalidate, nothing we can write
        pass


def solved(name: str, key: tuple, solve):
    """solve() for (name, key), kept in SOLVED across processes: a float or a tuple of floats,
    exact (JSON writes a float's shortest repr, which reads back to the same float). A file
    that cannot be read or written (a read-only install, a race between two workers: the
    last writer wins) only costs solving again."""
    global _solved
    if _solved is None:
        try:
            _solved = json.loads(SOLVED.read_text())
        except (OSError, ValueError):
            _solved = {}
    k = f"{name}{key!r}"
    if k in _solved:
        v = _solved[k]
        return tuple(v) if isinstance(v, list) else v
    v = solve()
    _solved[k] = list(v) if isinstance(v, tuple) else v
    try:
        SOLVED.parent.mkdir(exist_ok=True)
        tmp = SOLVED.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(_solved))
        os.replace(tmp, SOLVED)
    except OSError:
        pass
    return v
