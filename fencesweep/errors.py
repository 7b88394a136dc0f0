"""The errors and warnings a user can meet, in one leaf module (it imports nothing of the package, so every
layer raises them without importing another).

Bad input gets one clear message naming the value and what is allowed; the CLI prints it and
exits with code 2. A file that cannot be written (a full disk, a read-only place) is a
WriteError naming the file; the CLI says what was kept and exits with code 1.
"""
from __future__ import annotations

import errno as _errno
import os
from pathlib import Path


class ParameterError(ValueError):
    """Bad user input: names the parameter, the value and what is allowed."""


class UsageError(ValueError):
    """A command-line or API mistake that is not about a parameter value (exit code 2)."""


class SpecError(ParameterError):
    """A bad sweep spec: names the key, the value and what is allowed."""


class EnvelopeError(ParameterError):
    """A bad `envelope:` section of a spec: names the key, the value and what is allowed."""


class DesignError(ParameterError):
    """A bad `design:` section of a spec: names the key, the value and what is allowed."""


class SensitivityError(ParameterError):
    """A bad `sensitivity:` section of a spec: names the key, the value and what is allowed."""


class GpuUnavailable(UsageError):
    """The GPU path cannot run here: numba-cuda is not installed, or no GPU is there (exit code 2)."""


class WriteError(OSError):
    """Writing `filename` failed: `errno` ENOSPC (no space left on device), EACCES, EROFS, ...

    Built like an OSError, WriteError(errno, strerror, filename), so that it crosses process
    boundaries (a worker that writes a chunk) as itself. str() is one line:
    "no space left on device writing PATH"."""

    def __str__(self) -> str:
        return f"{self.reason} writing {self.filename}"

    @property
    def reason(self) -> str:
        """What went wrong, in lower case: os.strerror of the errno when it has one."""
        text = os.strerror(self.errno) if self.errno else (self.strerror or "an error")
        return text[:1].lower() + text[1:]

    @property
    def no_space(self) -> bool:
        """The device is full (ENOSPC, or EDQUOT: the user's quota)."""
        return self.errno in (_errno.ENOSPC, getattr(_errno, "EDQUOT", _errno.ENOSPC))


def write_error(exc: OSError, path: os.PathLike | str) -> WriteError:
    """`exc`, raised while writing `path`, as a WriteError naming `path` (itself if it is one)."""
    if isinstance(exc, WriteError):
        return exc
    return WriteError(exc.errno or 0, exc.strerror or str(exc), str(path))


class SweepWriteError(WriteError):
    """A file of the sweep could not be written (`errno` ENOSPC: the disk is full): names the file
    and the `saved` chunks (of `total`, None: not known) kept in `work` for the next run."""

    def __init__(self, exc: WriteError, work: Path, saved: int, total: int | None):
        super().__init__(exc.errno, exc.strerror, exc.filename)
        self.work, self.saved, self.total = work, saved, total

    def __reduce__(self):
        return (type(self), (WriteError(self.errno, self.strerror, self.filename), self.work, self.saved, self.total))

    def __str__(self) -> str:
        kept = (f"the {self.saved} finished chunk{'s' if self.saved != 1 else ''} are kept in {self.work}"
                if self.saved else "no chunk was finished yet")
        kept = kept.replace("chunk are", "chunk is")
        todo = "free space" if self.no_space else "make it writable"
        return f"{super().__str__()}; {kept} — {todo} and run the same command again"


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: `saved` of `total` chunks (None: not known) are saved in `work`."""

    def __init__(self, work: Path, saved: int, total: int | None):
        self.work, self.saved, self.total = work, saved, total
        self.saved_text = f"interrupted; {saved}{f' of {total}' if total else ''} chunks are saved in {work}"
        super().__init__(f"{self.saved_text}; the same call again (same spec and out) computes only the rest")


class WorkerError(RuntimeError):
    """A Dask worker cannot run the package's tasks: it cannot import fencesweep, or runs another
    version of it (sweep/cluster.py). The message names the worker's address; the CLI prints it and
    exits with code 1, and the chunks finished so far are kept for the next run."""


class VerificationWarning(UserWarning):
    """A sweep's table differs from its re-run at tol / 10 by more than the verification's
    threshold (sweep/verify.py)."""


class MissingInput(FileNotFoundError):
    """A table or trajectory a figure or the report needs is not there; the message names it and
    the command that makes it."""


#: a figure's missing table (the report's figures of a design study)
MissingTable = MissingInput
