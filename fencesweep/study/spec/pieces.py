"""A spec too large to plan at once, cut into pieces that are specs themselves (sweep/pipeline.py runs
them one after the other, each into one part of a Parquet dataset).

A spec's scenes are a product (its cases, then its axes, the last varying fastest: spec.Spec.decode),
so a run of consecutive scenes that fixes the leading dimensions and takes a range of one is the
same spec with those dimensions cut down: a *piece*. Its scenes, in order, are the whole spec's
scenes `offset` ... `offset + n_scenes - 1`, so the pieces' tables, one after the other, are the
whole table. A piece remembers the spec it comes from (`whole`), which its table records as its
spec (store.table's provenance), and names its scenes by their number in the whole spec.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from fencesweep import resources
from fencesweep.study.spec import spec as S
from fencesweep.study.spec.axes import Axis

#: memory per scene at the peak of planning (sweep/plan.py make_plan: its key digest, free
#: values and validity, then np.unique's sorts of them and the map scene -> run), with a margin
#: over what results/scale_memory.md measured
PLAN_BYTES_PER_SCENE = 160

#: The most scenes one piece of a sweep holds: planning it takes ~0.8 GB at the peak, and its
#: assembly one block of rows and a bounded cache of chunks, so a sweep's process stays under
#: 2 GB whatever the spec's size (results/scale_memory.md measured it). A spec of up to this
#: many scenes is one piece, one table file (the envelope study, 10x over, is 4.2 million). On a
#: machine with less memory available (half of it for planning), pieces are smaller (piece_limit).
PIECE_SCENES = 5_000_000


def piece_limit() -> int:
    """The most scenes of a piece here: PIECE_SCENES, or what half the memory available plans."""
    avail = resources.available_memory()
    return PIECE_SCENES if avail is None else max(1, min(PIECE_SCENES, avail // (2 * PLAN_BYTES_PER_SCENE)))


def n_pieces(spec: S.Spec, most: int | None = None) -> int:
    """How many pieces `spec` is cut into (1: it is planned whole), without making them; pieces
    of at most `most` scenes (default piece_limit())."""
    shape, d, step = _cut(spec, most)
    return 1 if d < 0 else math.prod(shape[:d]) * math.ceil(shape[d] / step)


def _cut(spec: S.Spec, most: int | None) -> tuple:
    """(the spec's shape, the dimension d a piece takes a range of (-1: none, the spec fits),
    the values of d a piece takes): the last dimensions whole, as many as fit in `most`."""
    most = piece_limit() if most is None else most
    shape = (len(spec.cases),) + tuple(len(a) for a in spec.axes)
    if math.prod(shape) <= most:
        return shape, -1, 0
    d, inner = len(shape) - 1, 1
    while inner * shape[d] <= most:
        inner *= shape[d]
        d -= 1
    return shape, d, most // inner


def pieces(spec: S.Spec, most: int | None = None):
    """The pieces of `spec`, in scene order (the spec itself when it fits in `most` scenes,
    default piece_limit())."""
    shape, d, step = _cut(spec, most)
    if d < 0:
        yield spec
        return
    for prefix in np.ndindex(*shape[:d]):
        for lo in range(0, shape[d], step):
            yield _piece(spec, shape, prefix, d, lo, min(shape[d], lo + step))


def _piece(spec: S.Spec, shape: tuple, prefix: tuple, d: int, lo: int, hi: int) -> S.Spec:
    """The piece that fixes dimensions 0 .. d-1 at `prefix` and takes values lo .. hi-1 of dimension d."""
    def cut(k: int, values):
        return values[prefix[k]:prefix[k] + 1] if k < d else values[lo:hi] if k == d else values

    cases = list(cut(0, spec.cases))
    axes = [Axis(a.names, tuple(cut(k, a.values)), a.where) for k, a in enumerate(spec.axes, 1)]
    first = tuple(prefix) + (lo,) + (0,) * (len(shape) - d - 1)
    return dataclasses.replace(spec, cases=cases, axes=axes, whole=spec,
                               offset=int(np.ravel_multi_index(first, shape)))
