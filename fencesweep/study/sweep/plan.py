"""Planning a sweep (step 1 of sweep/pipeline.py): its scenes mapped to distinct model runs, cut into chunks.

Every scene of the spec is resolved (params.resolve) once, up front, so any bad combination is
reported before work starts, and mapped to its model run by params.model_key: scenes that
differ only in parameters their model does not use (B2, K2 under a rigid drive, ...) share one
run (docs/model.md §8). The runs are numbered in order of first appearance and cut into chunks of
`chunk_size` runs; a chunk's file name carries a digest of the spec hash, the package's source
hash, its chunk size and the model keys of its runs (Plan.chunk_name), so a changed spec or
engine never reuses a stale chunk. The same pass can write the table's parameter columns,
block by block (ASSEMBLY_BLOCK scenes), for sweep/assemble.py.

A spec whose planning would not fit in the memory available is refused before anything is
allocated (plan_size_problem), with its count, the limit and how to split it.
"""
from __future__ import annotations

import hashlib
import io
import math
import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from fencesweep import resources
from fencesweep.errors import UsageError
from fencesweep.model import params as P
from fencesweep.study.spec import spec as S
from fencesweep.study.store import table as store
from fencesweep.study.sweep.progress import bar as progress_bar

ASSEMBLY_BLOCK = 16_384  # rows per Parquet row group of the final table (and per parameter block)
_CHOICES = tuple(p.name for p in P.TABLE if p.kind == "choice")


@dataclass
class Plan:
    """Scenes of a spec mapped to distinct model runs, cut into chunks."""

    spec: S.Spec
    row_model: np.ndarray  # model run of each scene; -1 for a skipped scene
    first_row: np.ndarray  # the first scene of each model run
    digests: bytes  # 16 bytes per model run: blake2b of its model key
    chunk_size: int | None  # None until measured (run_sweep) unless the spec gives it
    variants: dict  # (scene, drive, contact_law, profile) -> first model run with it
    skipped: int = 0
    skipped_examples: list = field(default_factory=list)
    salt: str = ""

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
        m = self.chunk_models(c)
        h = hashlib.sha256(f"{self.salt}:{self.chunk_size}:{c}:".encode())
        h.update(self.digests[16 * m.start:16 * m.stop])
        return f"chunk-{c:06d}-{h.hexdigest()[:16]}.parquet"

    def chunk_rows(self) -> np.ndarray:
        """Number of scenes each chunk fills."""
        valid = self.row_model[self.row_model >= 0]
        return np.bincount(valid // self.chunk_size, minlength=self.n_chunks)

    def model_vals(self, m: int) -> dict:
        return self.spec.resolve(int(self.first_row[m]))


def plan_salt(spec: S.Spec) -> str:
    """Digest of the spec and the engine: names the work directory and salts the chunk names."""
    v = store.versions()
    return hashlib.sha256(f"{spec.hash}:{v['fencesweep']}:{v['source_hash']}".encode()).hexdigest()


def _key_digester() -> Callable[[tuple], bytes]:
    """model key -> 16-byte blake2b digest of its pickle (binary floats: 4x faster than repr).

    The pickler runs without a memo, so equal keys always give the same bytes."""
    buf = io.BytesIO()
    pickler = pickle.Pickler(buf, protocol=5)
    pickler.fast = True

    def digest(key: tuple) -> bytes:
        buf.seek(0)
        buf.truncate()
        pickler.dump(key)
        return hashlib.blake2b(buf.getvalue(), digest_size=16).digest()

    return digest


def param_columns() -> dict:
    """Empty label and parameter columns of the table, to fill with add_params."""
    return {name: [] for name, _ in store.param_columns()}


def add_params(cols: dict, vals: dict) -> None:
    """Append one scene's row of the table's label and parameter columns (Psi derived)."""
    for name, col in cols.items():
        col.append(S.psi_of(vals) if name == "Psi" else vals[name])


def params_path(work: Path, block: int) -> Path:
    """The file of parameter block `block` (ASSEMBLY_BLOCK scenes) in the work directory."""
    return work / f"params-{ASSEMBLY_BLOCK}-{block:06d}.parquet"


#: memory per scene at the peak of make_plan (model-key digests, their np.unique, the map
#: scene -> run): 132 bytes measured with tracemalloc on 200 000 scenes, with a margin
PLAN_BYTES_PER_SCENE = 160


def _gib(n_bytes: float) -> str:
    return f"{n_bytes / 2**30:,.1f} GiB"


def plan_size_problem(spec: S.Spec) -> str | None:
    """Why `spec` is too large to plan in this machine's memory (its scene count, the limit and
    what to do), or None. Counts only: nothing proportional to the scenes is allocated."""
    n, avail = spec.n_scenes, resources.available_memory()
    if avail is None or n * PLAN_BYTES_PER_SCENE <= avail:
        return None
    most = avail // PLAN_BYTES_PER_SCENE
    pieces, names = 1, []  # split over the outermost dimensions until a piece fits
    for where, size in [("cases", len(spec.cases))] + [(a.where, len(a)) for a in spec.axes]:
        if n // pieces <= most:
            break
        pieces *= size
        names += [where] if size > 1 else []
    hint = (f" (one spec per value of {' x '.join(names)} gives {pieces} specs of {n // pieces} scenes)"
            if n // pieces <= most else "")
    return (f"{spec.path or 'the spec'} expands to {n} scenes ({spec.shape_text()}); planning them needs about "
            f"{_gib(n * PLAN_BYTES_PER_SCENE)} of memory ({PLAN_BYTES_PER_SCENE} bytes per scene), more than the "
            f"{_gib(avail)} available here, which hold at most {most} scenes. Split it into specs of at most "
            f"{most} scenes{hint}, or give its axes fewer values")


def make_plan(spec: S.Spec, progress: bool = False, params_dir: Path | None = None) -> Plan:
    """Resolve every scene (raising SpecError on the first bad one) and deduplicate the runs.

    With `params_dir`, the label and parameter columns of the table are written there too,
    one file per ASSEMBLY_BLOCK scenes, so that assembling the table resolves nothing again.

    Memory: PLAN_BYTES_PER_SCENE at the peak (16 bytes of model-key digest per scene while
    resolving, more at the np.unique), then 8 (its model number) plus 24 per distinct run;
    no Python object per scene is kept. A spec too large for the memory available raises
    UsageError (plan_size_problem) before anything is allocated.
    """
    problem = plan_size_problem(spec)
    if problem:
        raise UsageError(problem)
    n = spec.n_scenes
    keys = bytearray(16 * n)  # blake2b digest of each scene's model key
    valid = np.ones(n, dtype=bool)
    variants_row: dict = {}
    skipped, examples = 0, []
    digest = _key_digester()
    bar = progress_bar(n, "checking", progress and n > 20_000)
    try:
        for block, start in enumerate(range(0, n, ASSEMBLY_BLOCK)):
            stop = min(n, start + ASSEMBLY_BLOCK)
            cols = param_columns() if params_dir is not None else None
            for i in range(start, stop):
                try:
                    vals = spec.resolve(i)
                except P.ParameterError as exc:
                    if spec.invalid == "skip":
                        valid[i] = False
                        skipped += 1
                        if len(examples) < 3:
                            examples.append(f"{spec.describe(i)}: {exc}")
                        continue
                    raise S.SpecError(f"{spec.describe(i)}: {exc}") from None
                keys[16 * i:16 * i + 16] = digest(P.model_key(vals))
                variants_row.setdefault((spec.scene,) + tuple(vals[c] for c in _CHOICES), i)
                if cols is not None:
                    add_params(cols, vals)
            if cols is not None and cols["scene"]:
                store.write_table_atomic(store.param_table(cols), params_path(params_dir, block), fsync=False)
            bar.update(stop - start)
    finally:
        bar.close()
    if skipped == n:
        raise S.SpecError(f"every one of the {n} scenes is invalid (invalid: skip); e.g. {examples[0]}")
    rows = np.nonzero(valid)[0]
    uniq, first, inverse = np.unique(np.frombuffer(keys, dtype="V16")[rows], return_index=True,
                                     return_inverse=True)
    del keys
    order = np.argsort(first, kind="stable")  # model runs numbered in order of first appearance
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    row_model = np.full(n, -1, dtype=np.int64)
    row_model[rows] = rank[inverse.ravel()]
    first_row = rows[first[order]].astype(np.int64)
    digests = uniq[order].tobytes()
    variants = {k: int(row_model[i]) for k, i in variants_row.items()}
    return Plan(spec, row_model, first_row, digests, spec.chunk_size, variants, skipped, examples,
                plan_salt(spec))


def unused_axes(spec: S.Spec) -> list:
    """Axes over parameters that the scene's model never uses (every value gives the same run)."""
    uses = P.SCENE_USES[spec.scene] | {"step_factor", "Psi"}
    return [f"{a.where} ({n})" for a in spec.axes for n in a.names if n not in uses]

