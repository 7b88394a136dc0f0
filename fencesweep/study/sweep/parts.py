"""A sweep too large to plan at once (more than pieces.PIECE_SCENES scenes), written as a Parquet
dataset: OUT is a directory of parts, part-00000.parquet, part-00001.parquet, ..., one per piece
of the spec (spec/pieces.py), in scene order. `pd.read_parquet(OUT)` and `fencesweep.read_table(OUT)`
read it whole (pyarrow reads a directory as one dataset, its files in name order).

sweep/pipeline.py sweeps the pieces one after the other, each as a sweep of its own into
OUT/_work/part-NNNNN.parquet (its lock, its work directory and its chunks there, where a dataset
reader does not look: pyarrow skips names starting with "_" or "."), then moves the finished
part into OUT. A killed run, rerun, keeps the parts finished (part_done) and resumes the piece
it was in from its chunks. Each part's metadata records the whole spec, the piece (its index,
first scene, size and hash) and its own verification.
"""
from __future__ import annotations

import shutil
from pathlib import Path

from fencesweep.errors import UsageError
from fencesweep.study.spec import spec as S
from fencesweep.study.store import table as store

WORK = "_work"


def part_name(k: int) -> str:
    return f"part-{k:05d}.parquet"


def part_done(piece: S.Spec, path: Path) -> bool:
    """Whether `path` is the finished table of `piece`, written by this engine."""
    try:
        meta = store.read_metadata(path)
    except (OSError, ValueError):
        return False
    return (meta.get("piece") or {}).get("hash") == piece.hash and \
        (meta.get("versions") or {}).get("source_hash") == store.source_hash()


def open_dataset(out: Path, overwrite: bool) -> None:
    """Make the dataset directory OUT; a file there (a table of one piece) is replaced only with
    `overwrite` (output.check_output has refused another spec's results before this)."""
    if out.is_file():
        if not overwrite:
            raise UsageError(f"{out} is a single table file; this spec is written as a dataset directory of "
                             f"parts there: choose another --out, or add --overwrite to replace it")
        out.unlink()
    (out / WORK).mkdir(parents=True, exist_ok=True)


def finish_dataset(out: Path, n_parts: int) -> None:
    """Remove the work directory and any part beyond the spec's `n_parts` (of an earlier run)."""
    shutil.rmtree(out / WORK, ignore_errors=True)
    for extra in out.glob("part-*.parquet"):
        if int(extra.name[5:10]) >= n_parts:
            extra.unlink()


def verify_record(records: list) -> dict | None:
    """One record of the parts' verifications: the first that failed (else the first), with
    every part's verdict under "pieces"."""
    records = [r for r in records if r is not None]
    if not records:
        return None
    shown = next((r for r in records if not r.get("ok", True)), records[0])
    return dict(shown, pieces=[{"ok": r.get("ok"), "n": r.get("n"),
                                "share_over_bound": (r.get("random") or {}).get("share_over_bound")}
                               for r in records])
