"""Keep Numba's on-disk cache (cache=True) consistent with the kernel sources.

Numba keys a cached function on its own source file only; the cycle kernel inlines helpers
from drive.py and contact.py, so an edit there would leave a stale compiled kernel. At
import we hash every kernel source; when the hash differs from the one stored beside the
cache, the package's cache files are removed and Numba recompiles once.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

_PKG = Path(__file__).resolve().parent
_KERNEL_SOURCES = ("jit.py", "layout.py", "results.py", "numerics.py", "contact.py", "drive.py", "integrate.py",
                   "scenes/load.py", "scenes/contacts.py", "scenes/cycle.py", "scenes/stream.py", "scenes/impact.py",
                   "scenes/freefall.py")
_STAMP = _PKG / "__pycache__" / "kernels.sha256"


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
        _STAMP.parent.mkdir(exist_ok=True)
        tmp = _STAMP.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(digest)
        os.replace(tmp, _STAMP)
    except OSError:  # a read-only install: nothing to invalidate, nothing we can write
        pass
