"""Whole commands, each in a process of its own: the main job, a cold first cycle, and the peak
memory of the envelope study cut to 11 x 11 elements."""
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

import fencesweep

from . import ROOT

B2K2 = ROOT / "sweeps" / "b2k2.yaml"
ENVELOPE = ROOT / "sweeps" / "envelope.yaml"


def grid_command(spec: Path, out: Path, jobs: int) -> None:
    """`fencesweep grid SPEC --out OUT --quiet --jobs N`, as a user types it (its verification on)."""
    cmd = [sys.executable, "-m", "fencesweep", "grid", str(spec), "--out", str(out), "--quiet", "--jobs", str(jobs)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{r.stderr[-3000:]}")


def cut(spec: Path, n: int, where: Path) -> Path:
    """`spec` with its B2 x K2 grid cut to n x n elements (the same ranges), written into `where`."""
    s = yaml.safe_load(spec.read_text())
    for axis in ("B2", "K2"):
        lo, hi, _ = s["grid"][axis]["linspace"]
        s["grid"][axis] = {"linspace": [lo, hi, n]}
    out = where / f"{spec.stem}_{n}x{n}.yaml"
    out.write_text(yaml.safe_dump(s))
    return out


class MainJob:
    """The main job (sweeps/b2k2.yaml, 13,122 cycles) as a whole command on 1 and 2 jobs, wall time:
    start-up, planning, the kernel loaded from the Numba cache (warmed by `setup`'s 3 x 3 cut of the
    same spec), the sweep, its verification, the table written."""
    params = [1, 2]
    param_names = ["jobs"]
    number = 1
    repeat = (1, 3, 120.0)
    warmup_time = 0
    timeout = 900

    def setup(self, jobs):
        self.tmp = Path(tempfile.mkdtemp(prefix="asv-main-job-"))
        self.runs = 0
        grid_command(cut(B2K2, 3, self.tmp), self.tmp / "warm.parquet", jobs)

    def teardown(self, jobs):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def time_grid(self, jobs):
        self.runs += 1
        grid_command(B2K2, self.tmp / f"b2k2-{self.runs}.parquet", jobs)


def timeraw_cold_first_cycle():
    """A new user's first cycle: `import fencesweep; fencesweep.simulate(case="small_far")` in a new
    process with an empty Numba cache (NUMBA_CACHE_DIR a new temporary folder, set before the
    import): the import and the kernel's compile, wall time."""
    setup = ("import atexit, os, shutil, tempfile\n"
             "cache = tempfile.mkdtemp(prefix='asv-numba-')\n"
             "os.environ['NUMBA_CACHE_DIR'] = cache\n"
             "atexit.register(shutil.rmtree, cache, True)\n")
    return "import fencesweep\nfencesweep.simulate('cycle', case='small_far')\n", setup


timeraw_cold_first_cycle.repeat = (1, 3, 120.0)
timeraw_cold_first_cycle.timeout = 600


class EnvelopeCut:
    """Peak resident memory of `fencesweep.grid` on sweeps/envelope.yaml cut to 11 x 11 elements (its 64
    loads: 7,744 cycles; the whole study, 81 x 81, takes ~10 min on 2 cores) on 1 job, which runs the
    sweep in this process: the imports, the kernel, the sweep, its verification, the table and the
    per-element table written."""
    timeout = 900

    def setup(self):
        self.tmp = Path(tempfile.mkdtemp(prefix="asv-envelope-"))
        self.spec = cut(ENVELOPE, 11, self.tmp)

    def teardown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def peakmem_grid(self):
        fencesweep.grid(str(self.spec), out=str(self.tmp / "envelope.parquet"), jobs=1, progress=False)
