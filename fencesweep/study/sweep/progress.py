"""The progress of planning, of a sweep's chunks and of a design search, on stderr.

  * on a terminal or in a notebook: a tqdm bar;
  * off a terminal (`2>log`, a batch job): a line every LINE_SECONDS ("b2k2: 4,200 of 13,122
    scenes (32 %), 12 s, about 25 s left"), and one when it ends if it printed any (work shorter
    than LINE_SECONDS prints nothing);
  * off (progress=False, or --quiet): nothing, and tqdm is not imported.
The Python API's default, progress=None, is `wanted(None)`: on when a person is watching (a
terminal, a notebook, an interactive interpreter), off otherwise.
"""
from __future__ import annotations

import sys
import time

#: seconds between two progress lines off a terminal: often enough to see a run move, rarely
#: enough that a long run's log stays readable (a 10-minute sweep: 60 lines)
LINE_SECONDS = 10.0


def interactive() -> bool:
    """A person is watching: stderr is a terminal, or this is a notebook or an interactive
    interpreter."""
    return _terminal() or hasattr(sys, "ps1")


def _terminal() -> bool:
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(isatty and isatty()) or "ipykernel" in sys.modules


def wanted(progress: bool | None) -> bool:
    """The API's `progress` argument resolved: None (automatic) is on when interactive()."""
    return interactive() if progress is None else bool(progress)


class _Off:
    """A bar that is off: it takes what the callers give a tqdm bar (total, unit, update, close,
    set_postfix_str) and shows nothing, without importing tqdm (~35 ms)."""

    def __init__(self, total: int = 0):
        self.total, self.unit = total, "scene"

    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, s: str = "") -> None:
        pass

    def close(self) -> None:
        pass


class Lines(_Off):
    """Progress off a terminal: a line on stderr every LINE_SECONDS, and one at the end when it
    printed any."""

    def __init__(self, total: int, desc: str, unit: str = "scene", initial: int = 0, clock=time.monotonic):
        super().__init__(total)
        self.desc, self.unit, self.n, self._initial = desc, unit, initial, initial
        self._clock = clock
        self._start = self._last = clock()
        self._postfix = ""
        self.printed = 0

    def update(self, n: int = 1) -> None:
        self.n += n
        if self._clock() - self._last >= LINE_SECONDS:
            self._print()

    def set_postfix_str(self, s: str = "") -> None:
        self._postfix = s

    def close(self) -> None:
        if self.printed:
            self._print()

    def _print(self) -> None:
        self._last = now = self._clock()
        self.printed += 1
        spent = now - self._start
        of = f" of {self.total:,}" if self.total else ""
        share = f" ({100.0 * self.n / self.total:.0f} %)" if self.total else ""
        done = self.n - self._initial
        left = ""
        if self.total and 0 < done and self.n < self.total:
            left = f", about {human(spent * (self.total - self.n) / done, 0)} left"
        extra = f", {self._postfix}" if self._postfix else ""
        print(f"{self.desc}: {self.n:,}{of} {self.unit}s{share}, {human(spent, 0)}{left}{extra}",
              file=sys.stderr, flush=True)


def human(seconds: float, digits: int = 1) -> str:
    """A duration as s, min or h: `digits` after the point in s and min (the dry run's estimates
    give one, the progress lines none), one in h."""
    if seconds < 90:
        return f"{seconds:.{digits}f} s"
    if seconds < 5400:
        return f"{seconds / 60:.{digits}f} min"
    return f"{seconds / 3600:.1f} h"


def bar(total: int, desc: str, enabled: bool, initial: int = 0, unit: str = "scene", leave: bool = True):
    """Progress of `total` units (module docstring): a tqdm bar on a terminal, lines off it, or
    nothing when not `enabled`."""
    if not enabled:
        return _Off(total)
    if not _terminal():
        return Lines(total, desc, unit, initial)
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit=unit, file=sys.stderr, dynamic_ncols=True,
                smoothing=0.05, leave=leave)
