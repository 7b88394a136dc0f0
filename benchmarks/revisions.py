"""An earlier revision's tree, for the benchmarks that run it beside this one.

    from revisions import export
    tree = export("72ef80b")              # .fencesweep-revisions/<commit>/, made once, then reused
    tree = export("72ef80b", tmp / "a")   # a fresh copy in a folder of the caller's

The tree is every file git tracks at that commit (the package, pyproject.toml, sweeps/, ...),
written by `git archive`; a benchmark runs it in a process of its own with PYTHONPATH=tree (its
package has the same name as this one). The default folder is git-ignored (.fencesweep-*) and
keeps one tree per commit: a revision's files never change, so a second benchmark, or a second
run, takes the same tree without exporting it again (what ran in it, __pycache__ and any Numba
cache files there, stays with it; a benchmark that measures a cold start passes a folder of its
own).
"""
from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the exported trees, one folder per commit
CACHE = ROOT / ".fencesweep-revisions"
#: written last into an exported tree: the commit it holds (a folder without it is unfinished)
MARK = ".exported-commit"


def commit_of(rev: str) -> str:
    """The full hash of the commit that `rev` (a hash, tag, branch, HEAD~3, ...) names."""
    r = subprocess.run(["git", "rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}"], cwd=ROOT,
                       capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"{rev!r} is not a commit of {ROOT}")
    return r.stdout.strip()


def _holds(dest: Path, commit: str) -> bool:
    return (dest / MARK).is_file() and (dest / MARK).read_text().strip() == commit


def export(rev: str, dest: Path | None = None) -> Path:
    """The tree of git revision `rev`, exported into `dest` (default: CACHE / its commit); the folder.

    A `dest` that already holds that commit's export is returned as it is; one that holds
    anything else is an error. The files are written into a temporary folder beside `dest` and
    renamed into place, so that an interrupted export leaves nothing that looks finished.
    """
    commit = commit_of(rev)
    dest = Path(dest) if dest is not None else CACHE / commit
    if _holds(dest, commit):
        return dest
    if dest.exists() and any(dest.iterdir()):
        raise SystemExit(f"{dest} holds something other than an export of {rev} ({commit[:12]})")
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}-", dir=dest.parent))
    try:
        archive = subprocess.run(["git", "archive", commit], cwd=ROOT, capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive.stdout, check=True)
        (tmp / MARK).write_text(commit + "\n")
        if dest.exists():
            dest.rmdir()  # empty (checked above)
        try:
            tmp.rename(dest)
        except OSError:  # another process finished the same export first
            if not _holds(dest, commit):
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return dest


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="Export a git revision's tree (as the benchmarks do); print its folder.")
    ap.add_argument("rev")
    ap.add_argument("--dest", type=Path, default=None, help=f"default: {CACHE.relative_to(ROOT)}/<commit>")
    a = ap.parse_args()
    print(export(a.rev, a.dest))
