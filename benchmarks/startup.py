"""A new user's first run, on this tree (an earlier revision's cold first cycle, and the warm main
job on 1 and 2 jobs: `asv continuous REV HEAD`, benchmarks/README.md; the warm main job's
phases: scaling.py --spec sweeps/b2k2.yaml).

    python benchmarks/startup.py [--rounds 3]   -> prints, writes results/startup.md and its
                                                  measurements, results/startup.json
    python benchmarks/startup.py --page-only    -> the page again from startup.json

Measured:
  * cold first cycle: `fencesweep.simulate(case="small_far")` in a new process with an empty
    Numba cache (a fresh NUMBA_CACHE_DIR): wall time of the process, and whether it said it
    compiles; also without the compile helper (FENCESWEEP_COMPILE_HELPER=0, kernel/share.py);
  * cold main job: `pip install -e .` into a new virtual environment that sees the installed
    dependencies (--system-site-packages: "dependencies present"), then `fencesweep grid
    sweeps/b2k2.yaml` with an empty cache, 2 jobs: the two wall times and their sum;
  * compilations: Numba's compile events of the cold first cycle (numba.core.event), counted per
    function, in the process itself (the helper's are not counted: what it compiled this process
    loaded, counted apart).
Run it alone on the machine: it takes about 3 minutes.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
#: the measurements of the last run, from which --page-only writes the page again
RAW = ROOT / "results" / "startup.json"
FIRST_CYCLE = "import fencesweep; fencesweep.simulate(case='small_far')"
NOTICE = "compiling the"  # the first words of this tree's notice on stderr
COUNT_COMPILES = r"""
import collections, json, time
from numba.core import event as ev
done = []
class Rec(ev.Listener):
    def on_start(self, event):
        pass
    def on_end(self, event):
        d = event.data or {}
        f = getattr(d.get("dispatcher"), "py_func", None)
        done.append(f"{f.__module__}.{f.__qualname__}" if f else "?")
ev.register("numba:compile", Rec())
t = time.perf_counter()
import fencesweep
fencesweep.simulate(case="small_far")
c = collections.Counter(done)
import gc
from numba.core.dispatcher import Dispatcher
loaded = sum(sum(o._cache_hits.values()) for o in gc.get_objects() if isinstance(o, Dispatcher)
             and o.py_func.__module__.startswith("fencesweep") and type(o).__name__ == "KernelDispatcher")
print(json.dumps({"seconds": time.perf_counter() - t, "compilations": len(done), "functions": len(c),
                  "most": c.most_common(8), "loaded": loaded}))
"""


def _env(cache: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH"))}
    return dict(env, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(ROOT))


def _forget(cache: Path) -> None:
    """An empty Numba cache directory."""
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)


def _wall(cmd: list, env: dict, cwd: Path) -> tuple:
    t = time.perf_counter()
    r = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{cmd} failed: {r.stderr[-2000:]}")
    return time.perf_counter() - t, r


def cold_first_cycle(cache: Path, helper: bool = True) -> dict:
    _forget(cache)
    env = _env(cache)
    if not helper:
        env["FENCESWEEP_COMPILE_HELPER"] = "0"
    s, r = _wall([sys.executable, "-c", FIRST_CYCLE], env, ROOT)
    return {"seconds": s, "said": NOTICE in r.stderr}


def install(venv: Path) -> float:
    """`pip install -e .` into a new virtual environment over the installed dependencies."""
    shutil.rmtree(venv, ignore_errors=True)
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH"))}
    s, _ = _wall([str(venv / "bin" / "pip"), "install", "-q", "-e", str(ROOT)], env, ROOT)
    return s


def grid(venv: Path, cache: Path, out: Path, jobs: int) -> tuple:
    """The main job with the venv's `fencesweep` command. PYTHONPATH names this checkout: the venv
    sees the machine's packages, and an editable install there of another checkout would otherwise
    be found before the venv's own editable install."""
    out.unlink(missing_ok=True)
    cmd = [str(venv / "bin" / "fencesweep"), "grid", "sweeps/b2k2.yaml", "--out", str(out), "--jobs", str(jobs),
           "--no-resume", "--quiet"]
    return _wall(cmd, _env(cache), ROOT)


def compilations(cache: Path) -> dict:
    _forget(cache)
    _, r = _wall([sys.executable, "-c", COUNT_COMPILES], _env(cache), ROOT)
    return json.loads(r.stdout.strip().splitlines()[-1])


def _med(xs: list) -> float:
    return statistics.median(xs)


def measure(tmp: Path, rounds: int) -> dict:
    cache, venv, out = tmp / "cache", tmp / "venv", tmp / "b2k2.parquet"
    m = {"first": [], "said": [], "alone": [], "install": [], "grid_cold": []}
    for r in range(rounds):
        c = cold_first_cycle(cache)
        m["first"].append(c["seconds"])
        m["said"].append(c["said"])
        m["alone"].append(cold_first_cycle(cache, helper=False)["seconds"])
        print(f"round {r + 1}: cold first cycle {c['seconds']:.1f} s, without the helper {m['alone'][-1]:.1f} s",
              flush=True)
    for r in range(max(1, rounds - 1)):
        m["install"].append(install(venv))
        _forget(cache)
        m["grid_cold"].append(grid(venv, cache, out, 2)[0])
        print(f"round {r + 1}: install {m['install'][-1]:.1f} s + cold grid {m['grid_cold'][-1]:.1f} s", flush=True)
    m["compiles"] = compilations(cache)
    return m


def _row(name: str, xs: list, bar: str = "", fmt: str = ".1f") -> str:
    return f"| {name} | {_med(xs):{fmt}} ({', '.join(f'{x:{fmt}}' for x in xs)}) | {bar} |"


def page(m: dict, rounds: int) -> str:
    lines = ["# Start fast: a new user's first run", "",
             f"Regenerate: `python benchmarks/startup.py --rounds {rounds}` (what is "
             "measured: its docstring). Wall times on this machine; medians, with each run in brackets.", "",
             "| | this tree | bar |", "|---|---|---|",
             _row("cold first cycle [s]", m["first"], "<= 10"), _row("... without the compile helper [s]", m["alone"]),
             f"| ... said it compiles | {'yes' if all(m['said']) else 'no'} | yes |",
             _row("pip install -e . [s]", m["install"]), _row("cold main job, 2 jobs [s]", m["grid_cold"]),
             f"| install + cold main job [s] | {_med(m['install']) + _med(m['grid_cold']):.1f} | <= 20 |"]
    cc = m["compiles"]
    lines += [f"| compilations (functions) of the cold first cycle | {cc['compilations']} ({cc['functions']}), "
              f"{cc.get('loaded', 0)} more loaded from the helper | one each |", "",
              "Most compiled functions of the cold first cycle (compilations): "
              + ", ".join(f"{f.rsplit('.', 1)[-1]} {c}" for f, c in cc["most"])]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3, help="rounds of the cold measurements (default 3)")
    ap.add_argument("--page-only", action="store_true",
                    help=f"measure nothing: write the page again from the measurements of the last run ({RAW.name})")
    a = ap.parse_args()
    if a.page_only:
        raw = json.loads(RAW.read_text())
        m, rounds = raw["measured"], raw["rounds"]
    else:
        with tempfile.TemporaryDirectory() as tmp:
            m = measure(Path(tmp), a.rounds)
        rounds = a.rounds
        RAW.write_text(json.dumps({"rounds": rounds, "measured": m}, indent=1) + "\n")
    text = page(m, rounds)
    print(text)
    (ROOT / "results" / "startup.md").write_text(text)


if __name__ == "__main__":
    main()
