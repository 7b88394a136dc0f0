"""One writer per output (sweeps/README.md, One writer per output): a sweep holds the lock
OUT.lock beside its output from before it makes or removes anything until it is done, so a
second run on the same output refuses at once (or, asked to, waits) instead of mixing its
chunks and tables with the first's.

The lock is an OS file lock (the `filelock` package: flock on POSIX), released by the OS when
the process that holds it dies, however it dies: a stale lock file never blocks anyone. While
it holds the lock, a run records who it is in OUT.lock.json (pid, host, start time, command),
which a refused run names. The lock is reentrant within a process (api.run_grid holds it around
the sweep and the envelope's per-design-point table; run_sweep takes it again).
"""
from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
from pathlib import Path
from typing import Callable

from fencesweep.errors import UsageError
from fencesweep.study.store import table as store

#: the locks this process holds, by path: a nested hold reuses the instance (a FileLock counts
#: its acquisitions), as a second instance on the same file would wait for the first
_HELD: dict = {}


def lock_path(out: Path) -> Path:
    """OUT.lock, beside the output."""
    return out.with_name(out.name + ".lock")


def holder_path(out: Path) -> Path:
    """OUT.lock.json: who holds the lock (pid, host, started, command)."""
    return out.with_name(out.name + ".lock.json")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, but not ours to signal
        return True
    return True


def holder(out: Path) -> str:
    """Who holds the lock of `out`, as a message names it."""
    try:
        info = json.loads(holder_path(out).read_text())
        pid, host, started = int(info["pid"]), str(info["host"]), str(info["started"])
    except (OSError, ValueError, KeyError, TypeError):
        return "holder not known yet: it has just started"
    if host == socket.gethostname() and not _alive(pid):
        return "holder not known yet: it has just started"  # the record of an earlier, dead holder
    return f"pid {pid} on {host}, started {started}"


def _record(out: Path) -> None:
    info = {"pid": os.getpid(), "host": socket.gethostname(),
            "started": time.strftime("%Y-%m-%d %H:%M:%S %z"), "command": " ".join(sys.argv)}
    with store.atomic_path(holder_path(out), fsync=False) as tmp:
        tmp.write_text(json.dumps(info, indent=1) + "\n")


@contextlib.contextmanager
def one_writer(out: Path, wait: bool = False, log: Callable[[str], None] = lambda msg: None):
    """Hold the lock of `out` for a with-block. Held by another process: raise UsageError
    naming the output and the holder, or with `wait` log that and wait for it."""
    from filelock import FileLock, Timeout

    key = str(lock_path(out).resolve())
    lock = _HELD.get(key) or FileLock(key)
    try:
        lock.acquire(timeout=0)
    except Timeout:
        if not wait:
            raise UsageError(f"{out} is being written by another run ({holder(out)}); not touching it: wait for "
                             f"that run to finish, or add --wait (API: wait=True) to wait for it") from None
        log(f"waiting for the run writing {out} ({holder(out)}) to finish")
        lock.acquire()
    first = key not in _HELD
    _HELD[key] = lock
    try:
        if first:
            _record(out)
        yield
    finally:
        if first:
            del _HELD[key]
            with contextlib.suppress(OSError):
                holder_path(out).unlink()
        lock.release()
