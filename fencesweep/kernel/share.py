"""A cold compile on two cores: a helper process compiles part of the kernel functions while this
one compiles the rest, and each loads what the other has finished.

Numba compiles one process's functions one at a time (it holds a global lock), in the order its
typing meets them: for a first cycle, ~140 kernel functions, then the entry point's module
(kernel/libraries.py KernelLibrary). While a first run compiles (kernel/cache.py `compiling`):

  * every kernel function this process or the helper compiles is kept on disk as LLVM bitcode
    (`KernelCache`: Numba's cache of a compiled function, with the IR a caller links instead of
    machine code, which a kernel function does not have) in a directory of this compile, made
    anew for it (tempfile.mkdtemp in kernel/cache.py's directory), and a kernel function found
    there is loaded instead of compiled. An entry there is written by whichever process saves
    it first (a file created exclusively); the other's copy, the same IR, is not saved;
  * the scene gives a plan (`Plan`, scenes/stream.py `compile_plan`): its entry point and a
    list of its large kernel functions, each with example arguments of the types they are
    called with, and a prelude: what a run does before it calls the entry point and the helper
    can do for it (solve the values kept in kernel/cache.py `solved`, compile the small entry
    points these need). This process compiles the list from the front, then the entry point
    (whose compile then finds its kernel functions compiled), before its run's own
    preparation, which then finds the prelude's results. The helper (`python -m
    fencesweep.kernel.share DIR PLAN`) compiles the list from the back, stops where this
    process has arrived, then runs the prelude for the run's parameters while this process
    compiles the entry point alone (the entry point's compile is the serial part: the helper
    has nothing of the plan left to do then). This process waits for the prelude after the
    entry point if the helper is still at it, so that the two never compile one entry point
    of the cache at once. A plan function is claimed by whichever process starts it first (a
    file created exclusively); one that reaches a function the other has claimed waits for it
    (this process, while the helper runs) or compiles it too (the helper). A claim is a record,
    never released, that the other process reads to know where to stop: a lock (filelock's),
    released after the compile, would not keep it;
  * every wait ends after WAIT_LIMIT: the helper is then taken to be stuck and stopped, and this
    process compiles the rest itself;
  * at the end the helper is stopped and the directory removed: only the entry points stay
    cached (kernel/cache.py). What the helper wrote on stderr (a traceback), its exit status
    if it failed, and a wait that timed out are logged (logging.getLogger("fencesweep")).

The helper changes the time only: what this process links is the same LLVM IR (bitcode keeps
it exactly), and without the helper (it fails to start, dies, or FENCESWEEP_COMPILE_HELPER=0)
this process compiles everything itself (tests/test_jit.py compares the results of both).
A process killed outright (SIGKILL) leaves its directory behind (share-* in the cache
directory, a few MB); its helper finishes the plan and exits.
"""
from __future__ import annotations

import contextlib
import hashlib
import importlib
import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Callable, NamedTuple

from fencesweep.kernel.numba_setup import numba  # first: Numba loaded as the kernels load it
from numba import typeof

from fencesweep.kernel import cache
from fencesweep.kernel.internals import REBUILD_PAYLOAD, CompileResultCacheImpl, FunctionCache, NullCache
from fencesweep.kernel.libraries import kernel_libraries
from fencesweep.kernel.locator import KernelLocator
from fencesweep.resources import usable_cores

#: the environment variable that turns the helper off ("0")
HELPER_ENV = "FENCESWEEP_COMPILE_HELPER"
#: how often a process waiting for the other's function looks for it [s]
POLL = 0.005
#: the longest this process waits for the helper, for a plan function or the prelude [s]: each
#: takes seconds, so a helper still at one after this long is stuck (or the machine is swamped)
WAIT_LIMIT = 120.0
#: the most of the helper's stderr that is logged [characters]
LOG_TAIL = 4000

log = logging.getLogger("fencesweep")


class Plan(NamedTuple):
    """A scene's compile plan (module docstring)."""

    #: (entry point, example arguments)
    entry: tuple
    #: [(kernel function, example arguments)]: this process compiles them from the front, the
    #: helper from the back
    kernels: list
    #: prelude(vals): what a run on the parameters vals does before calling the entry point
    prelude: Callable[[dict], object]


class _Session:
    """The compile in progress: its directory, the plan's functions, the helper (None in the helper)."""

    def __init__(self, where: Path, plan: Plan, helper):
        self.where, self.helper = where, helper
        self.roots = {key(d) for d, _ in plan.kernels}
        #: the kernel functions given a KernelCache (turn): given none again at the end
        self.cached: list = []
        self.stopped = False

    def helper_running(self) -> bool:
        return self.helper is not None and self.helper.poll() is None

    def stop_helper(self, why: str | None = None) -> None:
        """Stop the helper (if it still runs) and log what went wrong: `why`, an exit status
        other than 0, or anything it wrote on stderr."""
        if self.helper is None or self.stopped:
            return
        self.stopped = True
        status = self.helper.poll()
        if status is None:
            self.helper.kill()
        self.helper.wait()
        if why is None and status not in (None, 0):
            why = f"exited with status {status}"
        try:
            said = (self.where / "helper.log").read_text(errors="replace").strip()
        except OSError:
            said = ""
        if why is not None or said:
            log.warning("fencesweep: the compile helper %s%s", why or "wrote on stderr",
                        f":\n{said[-LOG_TAIL:]}" if said else "")


_session: _Session | None = None


def key(disp) -> str:
    """A kernel function's name in the directory of a compile (module and qualified name)."""
    return f"{disp.py_func.__module__}.{disp.py_func.__qualname__}"


def load_plan(plan: str) -> Plan:
    """'module:function' -> the Plan that function returns."""
    module, name = plan.split(":")
    return getattr(importlib.import_module(module), name)()


def signature(args: tuple) -> tuple:
    """The Numba types a kernel function is compiled for with these arguments."""
    return tuple(typeof(a) for a in args)


def _exclusive(path: Path) -> bool:
    """Create `path` if no process has: True for the one process that did (False, too, when it
    cannot be made: what it guards is then not done, which only costs time)."""
    try:
        os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except OSError:
        return False
    return True


# ------------------------------------------------------------------ the bitcode cache
class _Locator(KernelLocator):
    """Numba's cache locator for kernel functions during a shared compile: the session's directory."""

    @classmethod
    def root(cls) -> Path:
        return _session.where / "cache"


class _BitcodeImpl(CompileResultCacheImpl):
    """Numba's cache of a compile result with the library as LLVM bitcode (a kernel function's
    library has IR and no machine code: kernel/libraries.py KernelLibrary) and no type annotation
    text; loaded into a KernelLibrary again."""

    _locator_classes = [_Locator]

    def reduce(self, cres):
        fndesc = cres.fndesc
        fndesc.typemap = fndesc.calltypes = None  # as Numba's own reduce: not needed, may not pickle
        parts = dict(libdata=cres.library.serialize_using_bitcode(), fndesc=fndesc, env=cres.environment,
                     signature=cres.signature, objectmode=cres.objectmode, lifted=cres.lifted, typeann=None,
                     reload_init=cres.reload_init, referenced_envs=tuple(cres._find_referenced_environments()))
        return tuple(parts[k] for k in REBUILD_PAYLOAD)  # in the order of CompileResult._rebuild's parameters

    def rebuild(self, target_context, payload):
        with kernel_libraries(target_context.codegen()):
            return super().rebuild(target_context, payload)


class KernelCache(FunctionCache):
    """The cache of one kernel function during a shared compile (module docstring)."""

    _impl_class = _BitcodeImpl

    def __init__(self, py_func):
        super().__init__(py_func)
        code = py_func.__code__
        self._who = f"{py_func.__module__}.{py_func.__qualname__}:{code.co_firstlineno}"

    def save_overload(self, sig, data):
        """Saved by the first process to get here only: both compile the same IR."""
        entry = hashlib.sha256(f"{self._who}{sig}".encode()).hexdigest()[:32]
        if _session is not None and _exclusive(_session.where / "entries" / entry):
            super().save_overload(sig, data)


# ------------------------------------------------------------------ claims
def _claim(k: str) -> bool:
    """Claim plan function k for this process; False if the other process has."""
    path = _session.where / f"{k}.claim"
    try:
        fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return not _claimed_by_other(k)
    with os.fdopen(fd, "w") as fh:
        fh.write(str(os.getpid()))
    return True


def _claimed_by_other(k: str) -> bool:
    """Has the other process claimed plan function k (a claim not yet written counts as its)?"""
    path = _session.where / f"{k}.claim"
    try:
        return path.read_text().strip() != str(os.getpid())
    except OSError:
        return False


def _done(k: str) -> Path:
    """The file that says plan function k (or, for k = PRELUDE, the prelude) is finished."""
    return _session.where / f"{k}.done"


#: the prelude's name among the done files (no kernel function's key: those have a module)
PRELUDE = "prelude"


def _wait_for(k: str) -> None:
    """Wait until the helper has finished k (a plan function, or PRELUDE), while it runs, for at
    most WAIT_LIMIT; then the helper is stopped (module docstring)."""
    deadline = time.monotonic() + WAIT_LIMIT
    while not _done(k).exists() and _session.helper_running():
        if time.monotonic() > deadline:
            _session.stop_helper(f"had not finished {k} after {WAIT_LIMIT:g} s and was stopped")
            return
        time.sleep(POLL)


@contextlib.contextmanager
def turn(disp):
    """Around KernelDispatcher.compile: during a shared compile, the kernel function is loaded
    from the session's cache when there and saved to it when compiled; a plan function the
    helper claimed is waited for (module docstring). Outside one, nothing."""
    if _session is None:
        yield
        return
    if not isinstance(disp._cache, KernelCache):
        with contextlib.suppress(RuntimeError):  # no locator (the directory cannot be made): not shared
            disp._cache = KernelCache(disp.py_func)
            _session.cached.append(disp)
    k = key(disp)
    if k in _session.roots and not _claim(k):
        _wait_for(k)
    try:
        yield
    finally:
        if k in _session.roots:
            with contextlib.suppress(OSError):
                _done(k).touch()


def _helper_enabled() -> bool:
    return os.environ.get(HELPER_ENV, "1") != "0" and usable_cores() > 1 and not numba.config.DISABLE_JIT


def _start(plan: str, steps: Plan, vals: dict | None) -> _Session | None:
    """A session in a new directory, with the helper started on it; None (logged) if it cannot be."""
    where = None
    try:
        cache.DIR.mkdir(parents=True, exist_ok=True)
        where = Path(tempfile.mkdtemp(prefix="share-", dir=cache.DIR))
        (where / "entries").mkdir()
        with contextlib.suppress(TypeError, ValueError):  # parameters JSON cannot hold: no prelude
            (where / "vals.json").write_text(json.dumps(vals))
        with open(where / "helper.log", "wb") as stderr:
            helper = subprocess.Popen([sys.executable, "-m", "fencesweep.kernel.share", str(where), plan],
                                      stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=stderr)
    except OSError as exc:
        log.warning("fencesweep: no compile helper (%s); this process compiles alone", exc)
        if where is not None:
            shutil.rmtree(where, ignore_errors=True)
        return None
    return _Session(where, steps, helper)


@contextlib.contextmanager
def shared_compile(plan: str | None, vals: dict | None = None):
    """Around a cold compile in this process of a run on the parameters `vals`: start the helper
    on `plan` ('module:function', module docstring), compile the plan's entry point sharing the
    kernel functions with the helper; afterwards stop it and remove the directory. Without a
    plan, or with the helper turned off, nothing."""
    global _session
    if plan is None or not _helper_enabled() or _session is not None:
        yield
        return
    steps = load_plan(plan)
    _session = _start(plan, steps, vals)
    try:
        if _session is not None:
            for disp, args in steps.kernels:  # from the front, up to where the helper has come
                if _claimed_by_other(key(disp)):
                    break  # the entry point's compile waits for it only if it gets there first
                disp.compile(signature(args))
            entry, args = steps.entry
            entry.compile(signature(args))
            _wait_for(PRELUDE)  # the run's preparation needs its results: waiting beats doing it again
        yield
    finally:
        session, _session = _session, None
        if session is not None:
            for disp in session.cached:
                disp._cache = NullCache()  # the directory goes: nothing more is kept there
            session.stop_helper()
            shutil.rmtree(session.where, ignore_errors=True)


def helper_main(where: str, plan: str) -> None:
    """The helper: the plan's kernel functions from the back until this process's claims are
    reached, then the plan's prelude. This process needs the prelude's results only for its
    run's preparation, after the entry point's compile (its serial part, during which the
    helper has nothing else to do), while every kernel function the helper compiles first
    shortens the part the two processes share."""
    global _session
    steps = load_plan(plan)
    _session = _Session(Path(where), steps, None)
    for disp, args in reversed(steps.kernels):
        if _claimed_by_other(key(disp)):
            break  # the other process has come this far
        disp.compile(signature(args))
    vals = _session.where / "vals.json"  # absent: parameters JSON cannot hold, no prelude
    try:
        if vals.exists():
            steps.prelude(json.loads(vals.read_text()))
    except Exception:  # the prelude only saves time: the run does it again; the traceback is logged there
        traceback.print_exc()
    finally:
        with contextlib.suppress(OSError):
            _done(PRELUDE).touch()


if __name__ == "__main__":  # run as a script, this file is not the module the kernels use
    from fencesweep.kernel import share

    share.helper_main(*sys.argv[1:3])
