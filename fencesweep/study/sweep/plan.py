"""Planning a sweep (step 1 of sweep/pipeline.py): its scenes mapped to distinct model runs, cut into chunks.

Every scene of the spec is resolved up front, so any bad combination is reported before work
starts, and mapped to its model run by params.model_key: scenes that differ only in parameters
their model does not use (B2, K2 under a rigid drive, ...) share one run (docs/model.md §8). Both
are done on whole columns (spec/scenes.py): params.resolve runs once per combination of the values
it reads together, not once per scene. The runs are numbered in order of first appearance and
cut into chunks of `chunk_size` runs; a chunk's file name carries a digest of the spec hash, the
package's source hash, its chunk size and the first scene of each of its runs (Plan.chunk_name),
so a changed spec or engine never reuses a stale chunk.

Planning holds about pieces.PLAN_BYTES_PER_SCENE a scene at its peak; a spec larger than a piece
(spec/pieces.py, sized to the memory available) is planned piece by piece (sweep/pipeline.py).
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from fencesweep.model import params as P
from fencesweep.study.spec import spec as S
from fencesweep.study.spec.scenes import Scenes
from fencesweep.study.store import table as store

ASSEMBLY_BLOCK = 16_384  # rows per Parquet row group of the final table


@dataclass
class Plan:
    """Scenes of a spec mapped to distinct model runs, cut into chunks."""

    spec: S.Spec
    row_model: np.ndarray  # model run of each scene; -1 for a skipped scene
    first_row: np.ndarray  # the first scene of each model run
    chunk_size: int | None  # None until measured (run_sweep) unless the spec gives it
    variants: dict  # (scene, drive, contact_law, profile) -> first model run with it
    skipped: int = 0
    skipped_examples: list = field(default_factory=list)
    salt: str = ""
    scenes: Scenes | None = None  # the spec's scenes as columns (made when first needed)

    @property
    def n_scenes(self) -> int:
        return len(self.row_model)

    @property
    def n_models(self) -> int:
        return len(self.first_row)

    @property
    def n_chunks(self) -> int:
        return math.ceil(self.n_models / self.chunk_size)

    def chunk_models(self, c: int) -> range:
        return range(c * self.chunk_size, min(self.n_models, (c + 1) * self.chunk_size))

    def chunk_name(self, c: int) -> str:
        """The file of chunk `c`: its number and a digest of the salt (the spec and the engine),
        the chunk size and the first scene of each of its runs, which together fix its runs."""
        m = self.chunk_models(c)
        h = hashlib.sha256(f"{self.salt}:{self.chunk_size}:{c}:".encode())
        h.update(np.ascontiguousarray(self.first_row[m.start:m.stop], dtype="<i8").tobytes())
        return f"chunk-{c:06d}-{h.hexdigest()[:16]}.parquet"

    def chunk_rows(self) -> np.ndarray:
        """Number of scenes each chunk fills."""
        valid = self.row_model[self.row_model >= 0]
        return np.bincount(valid // self.chunk_size, minlength=self.n_chunks)

    def model_vals(self, m: int) -> dict:
        return self.spec.resolve(int(self.first_row[m]))

    def columns(self) -> Scenes:
        """The spec's scenes as columns (spec/scenes.py), kept for the plan's life."""
        if self.scenes is None:
            self.scenes = Scenes(self.spec)
        return self.scenes


def plan_salt(spec: S.Spec) -> str:
    """Digest of the spec and the engine: names the work directory and salts the chunk names."""
    v = store.versions()
    return hashlib.sha256(f"{spec.hash}:{v['fencesweep']}:{v['source_hash']}".encode()).hexdigest()


#: scenes keyed at once while planning (Scenes.keys): the slots of a block are held resolved
PLAN_BLOCK = 65_536


def make_plan(spec: S.Spec) -> Plan:
    """Resolve every scene (raising SpecError on the first bad one) and deduplicate the runs, on
    whole columns (spec/scenes.py), block by block: params.resolve runs once per combination of
    the values it reads together, and a scene's model run is found from its slot's key digest and
    the free axes' values that key uses.

    Memory: about pieces.PLAN_BYTES_PER_SCENE at the peak (16 bytes of key digest, 8 of free
    values and a validity byte per scene, then np.unique's sorts of them), then 8 bytes (its
    model number) plus 8 per distinct run; no Python object per scene.
    """
    n = spec.n_scenes
    scenes = Scenes(spec)
    valid = np.empty(n, dtype=bool)
    digest = np.empty(n, dtype="V16")
    free = np.empty(n, dtype=np.int64)
    firsts: dict = {}  # (scene, drive, contact_law, profile) -> its first scene
    for start in range(0, n, PLAN_BLOCK):
        stop = min(n, start + PLAN_BLOCK)
        valid[start:stop], digest[start:stop], free[start:stop], met = scenes.keys(np.arange(start, stop))
        for key, row in met.items():
            firsts.setdefault(key, row)
    rows = np.flatnonzero(valid)
    skipped, examples = n - len(rows), _examples(spec, valid)
    if skipped and spec.invalid != "skip":
        raise S.SpecError(examples[0])
    if skipped == n:
        raise S.SpecError(f"every one of the {n} scenes is invalid (invalid: skip); e.g. {examples[0]}")
    _, key_id = np.unique(digest[rows] if skipped else digest, return_inverse=True)
    del digest
    code = key_id.ravel().astype(np.int64) * scenes.free_size + (free[rows] if skipped else free)
    del key_id, free
    _, first, inverse = np.unique(code, return_index=True, return_inverse=True)
    del code
    order = np.argsort(first, kind="stable")  # model runs numbered in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    row_model = np.full(n, -1, dtype=np.int64)
    row_model[rows] = rank[inverse.ravel()]
    first_row = rows[first[order]].astype(np.int64)
    variants = {key: int(row_model[row]) for key, row in firsts.items()}
    return Plan(spec, row_model, first_row, spec.chunk_size, variants, int(skipped), examples, plan_salt(spec),
                scenes)


def _examples(spec: S.Spec, valid: np.ndarray) -> list:
    """The first three invalid scenes, each with why (resolved again: an invalid one raises)."""
    out = []
    for i in np.flatnonzero(~valid)[:3].tolist():
        try:
            spec.resolve(i)
        except P.ParameterError as exc:
            out.append(f"{spec.describe(i)}: {exc}")
    return out


def unused_axes(spec: S.Spec) -> list:
    """Axes over parameters that the scene's model never uses (every value gives the same run)."""
    uses = P.SCENE_USES[spec.scene] | {"step_factor", "Psi"}
    return [f"{a.where} ({n})" for a in spec.axes for n in a.names if n not in uses]

