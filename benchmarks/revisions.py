"""An earlier revision's tree, for tip.py's --before and instructions.py's REV (comparing timings of
revisions is asv's: `asv continuous REV HEAD`, benchmarks/README.md).

    from revisions import export
    tree = export("c3a4204")   # .fencesweep-revisions/<commit>/ (git-ignored), made once, then reused
"""
from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def export(rev: str, dest: Path | None = None) -> Path:
    """The files git tracks at revision `rev`, in `dest` (default .fencesweep-revisions/<commit>)."""
    commit = subprocess.run(["git", "rev-parse", "--verify", f"{rev}^{{commit}}"], cwd=ROOT, capture_output=True,
                            text=True, check=True).stdout.strip()
    dest = Path(dest) if dest is not None else ROOT / ".fencesweep-revisions" / commit
    if (dest / ".exported-commit").is_file():  # written last: the export is whole
        return dest
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}-", dir=dest.parent))
    archive = subprocess.run(["git", "archive", commit], cwd=ROOT, capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True)
    (tmp / ".exported-commit").write_text(commit + "\n")
    tmp.rename(dest)
    return dest
