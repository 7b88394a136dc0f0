"""What the benchmark scripts share: the repository's root, a fresh process's JSON answer, a Markdown
table, a figure written, an earlier revision's tree (`git archive` of a commit, for tip.py's --before
and instructions.py's REV; comparing timings of revisions is asv's: `asv continuous REV HEAD`)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def sample_runs(step_factor: float = 1.0) -> str:
    """Python code for a fresh process: the main job's fixed 60-scene sample (the seed of asv_bench
    main_job_sample) set up for the kernel's entry point, from the tree on its PYTHONPATH: `args`,
    one argument tuple of `run_cycles` a scene, on parameter vectors that tree's `prepare` made at
    `step_factor`, and one call made (instructions.py and time_profile.py run it, then their own
    loop)."""
    return _SAMPLE_RUNS.replace("STEP_FACTOR", repr(float(step_factor)))


_SAMPLE_RUNS = r"""
import os, sys
import numpy as np
from fencesweep.model import layout as Lp
from fencesweep.model import params as P
from fencesweep.model.prepare import prepare
from fencesweep.model.scenes.stream import run_cycles
b2, k2 = np.linspace(0, 200, 81), np.linspace(100, 2100, 81)
idx = np.random.default_rng(20261123).choice(81 * 81 * 2, 60, replace=False)
args = []
for i in idx:
    p = prepare(P.resolve("cycle", ("small_far", "long_near")[i // 6561], B2=float(b2[i % 6561 // 81]),
                          K2=float(k2[i % 81]), step_factor=STEP_FACTOR))
    loads = np.ascontiguousarray(p[list(Lp.LOAD_SLOTS)][None, :])
    args.append((p, loads, float(p[Lp.TC]), np.empty((1, 40)), np.empty((0, 19)), np.zeros(2, np.int64)))
run_cycles(*args[0])
"""


def run_json(code: str, *args, env: dict | None = None, cwd: Path = ROOT):
    """`python -c code args` in a fresh process (env added to this one's): the JSON of its last line."""
    r = subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                       env={**os.environ, **(env or {})})
    if r.returncode:
        raise SystemExit(f"a benchmark's process failed:\n{r.stderr[-4000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def md_row(cells) -> str:
    return "| " + " | ".join(map(str, cells)) + " |"


def md_table(head: list[str], rows=()) -> list[str]:
    """A Markdown table's lines; a column named with a trailing ">" is right-aligned."""
    return [md_row(c.rstrip(">") for c in head), "|" + "".join("---:|" if c[-1] == ">" else "---|" for c in head),
            *map(md_row, rows)]


def pyplot():
    """matplotlib's pyplot, drawing to files only."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    pyplot().close(fig)


def export(rev: str, dest: Path | None = None) -> Path:
    """The files git tracks at revision `rev`, in `dest` (default .fencesweep-revisions/<commit>, git-ignored:
    made once, then reused)."""
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
