"""The progress bar of planning and of a sweep's chunks: tqdm on stderr, off unless asked."""
from __future__ import annotations

import sys


def bar(total: int, desc: str, enabled: bool, initial: int = 0):
    """A bar of `total` scenes (a no-op bar when not `enabled`)."""
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit="scene", disable=(None if enabled else True),
                file=sys.stderr, dynamic_ncols=True, smoothing=0.05)
