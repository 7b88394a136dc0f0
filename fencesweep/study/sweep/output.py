"""Where a sweep writes, and what it may replace: the output table OUT and its work directory
OUT.partial/<id>/ (sweeps/README.md, Resume).

The work directory's id is the start of the plan's salt (a hash of the resolved spec and of the
package's sources); it holds the chunks as they are written and `plan.json` (the spec, its hash and
the chunk size, so that a resumed run cuts the same chunks). A spec swept in pieces writes a
dataset directory OUT instead (sweep/parts.py), each piece's work directory inside it. A sweep never destroys another spec's results: its table at OUT, or the saved
chunks of its unfinished run (check_output).
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Callable

from fencesweep.errors import UsageError
from fencesweep.study.spec import pieces as SP
from fencesweep.study.spec import spec as S
from fencesweep.study.store import table as store
from fencesweep.study.sweep import parts
from fencesweep.study.sweep import plan as PL

PLAN_FILE = "plan.json"


def work_root(out: Path) -> Path:
    """The work directory beside the output: OUT.partial/<salt[:16]>/chunk-*.parquet."""
    return out.with_name(out.name + ".partial")


def default_output(spec: S.Spec) -> Path:
    """The spec's `output`, else SPEC.parquet after the spec's file (sweep.parquet without one)."""
    if spec.output:
        return Path(spec.output)
    stem = Path(spec.path).stem if spec.path else "sweep"
    return Path(f"{stem}.parquet")


def recorded_chunk_size(work: Path) -> int | None:
    """The chunk size an interrupted run of the same spec and engine used (None if none)."""
    try:
        size = json.loads((work / PLAN_FILE).read_text()).get("chunk_size")
    except (OSError, ValueError):
        return None
    return int(size) if isinstance(size, int) and size >= 1 else None


def saved_chunks(spec: S.Spec, out: Path) -> tuple:
    """(work directory, chunks saved in it, chunks in all or None) of an interrupted sweep (of a
    sweep in pieces: the dataset's work directory, the chunks of its unfinished piece)."""
    if SP.n_pieces(spec) > 1:
        work = Path(out) / parts.WORK
        return work, len(list(work.glob("*.partial/*/chunk-*.parquet"))), None
    work = work_root(Path(out)) / PL.plan_salt(spec)[:16]
    saved = len(list(work.glob("chunk-*.parquet"))) if work.exists() else 0
    try:
        total = json.loads((work / PLAN_FILE).read_text()).get("n_chunks")
    except (OSError, ValueError):
        total = None
    return work, saved, total


def chunks_done(plan: PL.Plan, work: Path) -> list:
    """Chunks whose file is in `work` and complete (the others are computed)."""
    if not work.is_dir() or plan.chunk_size is None:
        return []
    return [c for c in range(plan.n_chunks)
            if store.chunk_complete(work / plan.chunk_name(c), len(plan.chunk_models(c)))]


def _spec_label(path: str | None, spec_hash: str) -> str:
    """A spec as messages name it: its file (when known) and the start of its hash."""
    return f"{path} (spec hash {spec_hash[:12]})" if path else f"a spec with hash {spec_hash[:12]}"


def check_output(spec: S.Spec, out: Path, adaptive: bool = False) -> None:
    """Refuse (UsageError, naming both specs) to destroy another spec's results at `out`: the
    table there (or the dataset of parts there, sweep/parts.py), or the saved chunks of its
    unfinished run in OUT.partial/. The same spec's table is replaced by a rerun and its chunks
    are resumed; chunks of the same spec from another engine can never be reused and are
    removed. A full grid and an adaptive map (`adaptive`: the run is one) of the same spec do
    not replace each other either. A piece (spec/pieces.py) is judged as the spec it is part of."""
    whole = spec.whole if spec.whole is not None else spec
    this = _spec_label(whole.path, whole.hash)
    if out.is_dir():  # a dataset of parts: its first part says whose it is
        tables = sorted(out.glob("part-*.parquet"))[:1]
        if not tables and any(p.name != parts.WORK for p in out.iterdir()):
            raise UsageError(f"{out} is a directory that holds no table written by fencesweep grid; not writing "
                             f"the results of {this} into it: choose another --out")
        roots = [work_root(p) for p in sorted((out / parts.WORK).glob("part-*.parquet.partial"))]
    else:
        tables, roots = ([out] if out.exists() else []), [work_root(out)]
    for table in tables:
        _check_table(table, out, whole, this, adaptive)
    for root in roots:
        _check_work(root, whole, this)


def _check_table(table: Path, out: Path, whole: S.Spec, this: str, adaptive: bool) -> None:
    """check_output's judgement of the table at `table` (the output, or a dataset's first part)."""
    try:
        meta = store.read_metadata(table)
    except (OSError, ValueError):  # not Parquet (pyarrow.ArrowInvalid is a ValueError)
        meta = {}
    if not isinstance(meta.get("spec_hash"), str):
        raise UsageError(f"{out} exists and is not a table written by fencesweep grid; not replacing it "
                         f"with the results of {this}: choose another --out, or add --overwrite to "
                         f"replace it")
    if meta["spec_hash"] != whole.hash:
        that = _spec_label(meta.get("spec_path"), meta["spec_hash"])
        raise UsageError(f"{out} holds the results of another spec, {that}; this is {this}. Not replacing "
                         f"it: choose another --out, or add --overwrite to replace it")
    if ("adaptive" in meta) != adaptive:
        kind, other = ("the full grid", "an adaptive map") if adaptive else ("an adaptive map", "the full grid")
        raise UsageError(f"{out} holds {kind} of {this}; not replacing it with {other}: choose another --out "
                         f"(--adaptive writes SPEC-output_adaptive.parquet by default), or add --overwrite")


def _check_work(root: Path, whole: S.Spec, this: str) -> None:
    """check_output's judgement of the unfinished runs saved in the work root `root`."""
    for work in sorted(root.iterdir()) if root.is_dir() else ():
        try:
            state = json.loads((work / PLAN_FILE).read_text())
        except (OSError, ValueError):  # planning never finished there: no chunk was saved
            continue
        saved = len(list(work.glob("chunk-*.parquet")))
        other = state.get("whole_hash", state.get("spec_hash"))
        if saved and isinstance(other, str) and other != whole.hash:
            that = _spec_label(state.get("spec_path"), other)
            raise UsageError(f"{root} holds the unfinished run of another spec, {that} ({saved} of "
                             f"{state.get('n_chunks', '?')} chunks saved); this is {this}. Not discarding it: "
                             f"finish that run first (the same command with its spec), choose another --out, "
                             f"or add --overwrite to discard it")


def check_writable(out: Path) -> None:
    """Make the output's directory if it is missing and check that a file can be written in it,
    before anything is computed; raise UsageError naming the output and why not."""
    where = out.parent
    try:
        where.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):  # a file where a directory should be, here or above
        raise UsageError(f"cannot write {out}: {_not_a_directory(where)} is not a directory") from None
    except OSError as exc:
        raise UsageError(f"cannot write {out}: cannot make the directory {where}: "
                         f"{os.strerror(exc.errno).lower() if exc.errno else exc}") from None
    try:
        with tempfile.TemporaryFile(dir=where, prefix=".fencesweep-probe-"):
            pass
    except OSError as exc:
        reason = os.strerror(exc.errno).lower() if exc.errno else str(exc)
        raise UsageError(f"cannot write {out}: {where} is not writable: {reason}") from None


def _not_a_directory(path: Path) -> Path:
    """The first of `path` and its parents that exists and is not a directory (else `path`)."""
    for p in [path, *path.parents]:
        if p.exists():
            return path if p.is_dir() else p
    return path


def check_can_start(spec: S.Spec, out: Path, overwrite: bool = False) -> None:
    """Raise UsageError if a sweep of `spec` into `out` must not start: without `overwrite`,
    another spec's results at `out` (check_output)."""
    if not overwrite:
        check_output(spec, out)


def open_work(root: Path, work: Path, resume: bool, log: Callable[[str], None]) -> bool:
    """Make the sweep's work directory: remove other specs' (or, without resume, all) chunks
    and the temporary files of a worker killed while writing. Returns whether it was new."""
    if root.exists():
        for old in root.iterdir():
            if not resume or old.name != work.name:
                log(f"removing {old} ({'--no-resume' if not resume else 'chunks of another spec or engine'})")
                shutil.rmtree(old) if old.is_dir() else old.unlink()
    made = not work.exists()
    work.mkdir(parents=True, exist_ok=True)
    for tmp in work.glob(".fencesweep-tmp-*"):  # left by a worker killed while writing
        tmp.unlink(missing_ok=True)
    return made


def write_state(work: Path, plan: PL.Plan) -> None:
    """Record the plan in the work directory (PLAN_FILE): the spec, its hash and file, the salt
    and the chunk size, so that a resumed run cuts the same chunks and check_output can name it."""
    spec = plan.spec
    whole = spec.whole if spec.whole is not None else spec
    state = {"spec": spec.normalized(), "spec_hash": spec.hash, "spec_path": whole.path, "salt": plan.salt,
             "whole_hash": whole.hash, "chunk_size": plan.chunk_size, "n_chunks": plan.n_chunks}
    with store.atomic_path(work / PLAN_FILE) as tmp:
        tmp.write_text(json.dumps(state, indent=1))
