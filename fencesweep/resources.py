"""What this machine has (a leaf module: it imports nothing of the package, so any layer may use it)."""
from __future__ import annotations

import os


def available_memory() -> int | None:
    """Bytes of memory available for planning: Linux's MemAvailable, else the physical memory
    (None if neither is known: no limit is applied then)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, OSError, ValueError):
        return None


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it, else all)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1
