"""The errors a user can meet, in one leaf module (it imports nothing of the package, so every
layer raises them without importing another).

Bad input gets one clear message naming the value and what is allowed; the CLI prints it and
exits with code 2. A file that cannot be written (a full disk, a read-only place) is a
WriteError naming the file; the CLI says what was kept and exits with code 1.
"""
from __future__ import annotations

import errno as _errno
import os


class ParameterError(ValueError):
    """Bad user input: names the parameter, the value and what is allowed."""


class UsageError(ValueError):
    """A command-line or API mistake that is not about a parameter value (exit code 2)."""


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
