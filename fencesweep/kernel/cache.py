"""Where the compiled kernels are kept, and what a first run on a machine must know about them.

Numba caches a compiled function (cache=True) beside its source file and checks it against that
one file only: a kernel that calls a helper of another file stays stale when only the helper
changed. Here every kernel function of the package is cached in one directory of its own,

    <base>/fencesweep-<hash>/<sub-package path>/...

with <hash> a digest of the sources the kernels are compiled from (every module of kernel/, and
the model modules with a compiled function, a constant one reads or a value kept in `solved`:
MODEL_SOURCES; not the orchestration around them) and <base> Numba's NUMBA_CACHE_DIR when it is
set, else the package's __pycache__ when it is writable, else the user's cache directory. An
edited kernel source gives a new directory: nothing stale is ever loaded, and nothing needs
deleting (an old directory is left for another checkout that may still use it).
kernel/locator.py's `KernelLocator` tells Numba so. This module itself does not import Numba: a command can ask whether the
kernels are compiled (`is_warm`) before it loads them.

The same directory keeps
  * the values solved once per input by root finding (`solved`: the contact damping from e,
    the crank-rocker geometry), which without it every process would solve again;
  * a marker per entry point compiled (`is_warm` / `mark_warm`), so that a first run can say
    that it compiles before it does (`compiling`);
  * the compile lock (`compiling`): one process compiles a cold kernel, another started at the
    same time waits for it and loads the result (two processes writing one cache at once can
    crash Numba).
"""
from __future__ import annotations

import contextlib
import logging
import hashlib
import json
import os
import tempfile
from pathlib import Path


PKG = Path(__file__).resolve().parents[1]  # the package
#: the sub-package whose every module is a kernel source: the compile policy, the integrator, the
#: event search, the step loop and the tolerances the kernels are built with
KERNEL_PACKAGE = "kernel"
#: the model modules the kernels are compiled from: those that define a compiled function, those
#: whose constants a compiled function reads (Numba compiles a global's value into the code), and
#: those that solve a value kept in `solved`. The rest of model/ (parameters, preparation of the
#: parameter vector, the Python API) and every other sub-package are not: an edit there keeps the
#: compiled kernels. tests/test_jit.py checks that every module that defines a compiled function,
#: or that one of these imports from the package, is listed.
MODEL_SOURCES = (
    "model/calibrate.py", "model/contact.py", "model/drive.py", "model/layout.py", "model/results.py",
    "model/scenes/contacts.py", "model/scenes/gpu.py", "model/scenes/impact.py", "model/scenes/load.py", "model/scenes/stream.py",
    "model/scenes/cycle/books.py", "model/scenes/cycle/events.py", "model/scenes/cycle/layout.py",
    "model/scenes/cycle/peaks.py", "model/scenes/cycle/rhs.py", "model/scenes/cycle/run.py",
    "model/scenes/cycle/slots.py",
)


def _kernel_sources(pkg: Path = PKG) -> list[Path]:
    """The sources the kernel hash covers, in the package at `pkg`."""
    return sorted([*(pkg / KERNEL_PACKAGE).rglob("*.py"), *(pkg / name for name in MODEL_SOURCES)])


def kernel_hash(pkg: Path = PKG) -> str:
    """sha256 over the kernel sources (their paths and bytes)."""
    h = hashlib.sha256()
    for path in _kernel_sources(pkg):
        h.update(path.relative_to(pkg).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


HASH = kernel_hash()


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
        return True
    except OSError:
        return False


def _base() -> Path:
    """NUMBA_CACHE_DIR, else the package's __pycache__ if writable, else the user's cache directory."""
    if os.environ.get("NUMBA_CACHE_DIR"):  # Numba's own setting, read as Numba reads it
        return Path(os.environ["NUMBA_CACHE_DIR"])
    here = PKG / "__pycache__"
    if _writable(here):
        return here
    return Path(os.environ.get("XDG_CACHE_HOME") or "~/.cache").expanduser() / "fencesweep"


DIR = _base() / f"fencesweep-{HASH[:16]}"


# ------------------------------------------------------------------ values solved once
SOLVED = DIR / "solved.json"
_solved: dict | None = None


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
        SOLVED.parent.mkdir(parents=True, exist_ok=True)
        tmp = SOLVED.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(_solved))
        os.replace(tmp, SOLVED)
    except OSError:
        pass
    return v


# ------------------------------------------------------------------ first runs
#: entry points known to be compiled in this process (checked on disk once per process)
_warm: set = set()
#: seconds a cold compile of each group of entry points takes on a 2-core machine, the cycle's
#: with its helper process (kernel/share.py; results/kernel_cuts.md: a first cycle took 15.2-16.5 s
#: there, its imports and run included): what the first run announces
COMPILE_SECONDS = {"cycle": 15, "impact": 5}
#: the groups a group's compile makes warm too (none now: the contact law's calibration, which
#: every cycle's parameters need, no longer runs the impact scene; model/calibrate.py)
IMPLIES = {"cycle": ("cycle",), "impact": ("impact",)}


def _marker(name: str) -> Path:
    return DIR / f"compiled-{name}"


def is_warm(name: str) -> bool:
    """Are the entry points of `name` in the cache (a process loads them instead of compiling)?"""
    if name not in _warm and _marker(name).exists():
        _warm.add(name)
    return name in _warm


def mark_warm(name: str) -> None:
    for group in IMPLIES.get(name, (name,)):
        _warm.add(group)
        with contextlib.suppress(OSError):
            _marker(group).touch()


@contextlib.contextmanager
def compiling(name: str, say=None, cold=contextlib.nullcontext):
    """Around the first call of the entry points of `name` in a process: when they are not in
    the cache yet, say so (to `say`, by default a WARNING of the "fencesweep" logger: shown on
    stderr unless a user routes or silences it), and compile under a lock so that a process
    started at the same time waits and then loads them, inside the context `cold()` (a helper
    process on the second core: kernel/share.py); when they are, nothing."""
    if is_warm(name):
        yield
        return
    say = say or logging.getLogger("fencesweep").warning
    lock = None
    with contextlib.suppress(ImportError, OSError):
        from filelock import FileLock

        DIR.mkdir(parents=True, exist_ok=True)
        lock = FileLock(str(DIR / "compile.lock"))
        lock.acquire()
    try:
        if is_warm(name):  # another process compiled them while this one waited
            yield
            return
        say(f"fencesweep: compiling the {name} kernels (first run on this machine, about "
            f"{COMPILE_SECONDS.get(name, 10)} s; later runs load them from {DIR})")
        with cold():
            yield
        mark_warm(name)
    finally:
        if lock is not None:
            lock.release()
