"""A new user's first run and the warm main job: an earlier revision and this tree side by side,
interleaved in one run on the same machine.

    python benchmarks/startup.py [--before 72ef80b] [--rounds 3] [--warm-rounds 5]
                                                                   -> prints, writes results/startup.md
                                                                      and its measurements, results/startup.json
    python benchmarks/startup.py --page-only                       -> the page again from startup.json

Measured for both trees, alternately (before, this tree, before, ...):
  * cold first cycle: `fencesweep.simulate(case="small_far")` in a new process with an empty
    Numba cache (a fresh NUMBA_CACHE_DIR; the earlier revision's solved values, which it keeps in
    its package folder, removed too): wall time of the process, and whether it said it compiles;
    this tree also without its compile helper (FENCESWEEP_COMPILE_HELPER=0, kernel/share.py);
  * cold main job: `pip install -e TREE` into a new virtual environment that sees the installed
    dependencies (--system-site-packages: "dependencies present"), then `fencesweep grid
    sweeps/b2k2.yaml` with an empty cache, 2 jobs: the two wall times and their sum;
  * warm main job: the same command again with the cache warm, on 1 and on 2 jobs, pairs
    interleaved, --warm-rounds of them (5 by default: on a noisy 2-core machine 3 say too
    little); the ratio of the medians (the target: 2 jobs >= 1.8 x 1 job) and the median
    of the pairs' ratios;
  * what 2 processes get from this machine, in each warm round: a CPU-bound loop (pure Python,
    no I/O, about as long as one worker's share of the main job) alone, then two copies at once;
    2 x alone / the pair's wall time is the most 2 jobs could give over 1 here and now;
  * compilations: Numba's compile events of the cold first cycle (numba.core.event), counted per
    function, in the process itself (the helper's are not counted: what it compiled this process
    loaded, counted apart).
The earlier revision is exported from git (benchmarks/revisions.py) into a temporary folder of
its own (a fresh tree: nothing compiled or cached in it before); this tree is the working tree. Run it alone on the machine: it takes about 15 minutes.
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

from revisions import export  # benchmarks/revisions.py: a revision's tree, exported from git

ROOT = Path(__file__).resolve().parents[1]
BEFORE = "72ef80b"
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


def _env(tree: Path, cache: Path, python_path: bool = True) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH"))}
    env["NUMBA_CACHE_DIR"] = str(cache)
    if python_path:
        env["PYTHONPATH"] = str(tree)
    return env


def _forget(tree: Path, cache: Path) -> None:
    """An empty cache: the Numba cache directory, and the solved values and kernel stamp that the
    earlier revision keeps in its package's __pycache__."""
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)
    for name in ("solved.json", "kernels.sha256"):
        (tree / "fencesweep" / "__pycache__" / name).unlink(missing_ok=True)


def _wall(cmd: list, env: dict, cwd: Path) -> tuple:
    t = time.perf_counter()
    r = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{cmd} failed: {r.stderr[-2000:]}")
    return time.perf_counter() - t, r


def cold_first_cycle(tree: Path, cache: Path, helper: bool = True) -> dict:
    _forget(tree, cache)
    env = _env(tree, cache)
    if not helper:
        env["FENCESWEEP_COMPILE_HELPER"] = "0"
    s, r = _wall([sys.executable, "-c", FIRST_CYCLE], env, tree)
    return {"seconds": s, "said": NOTICE in r.stderr}


def install(tree: Path, venv: Path) -> float:
    """`pip install -e TREE` into a new virtual environment over the installed dependencies."""
    shutil.rmtree(venv, ignore_errors=True)
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH"))}
    s, _ = _wall([str(venv / "bin" / "pip"), "install", "-q", "-e", str(tree)], env, tree)
    r = subprocess.run([str(venv / "bin" / "python"), "-c", "import fencesweep; print(fencesweep.__file__)"],
                       env=dict(env, PYTHONPATH=str(tree)), cwd=tree, capture_output=True, text=True, check=True)
    if not Path(r.stdout.strip()).resolve().is_relative_to(tree.resolve()):  # as grid runs it
        raise RuntimeError(f"the venv of {tree} imports fencesweep from {r.stdout.strip()}")
    return s


#: the control of the warm rounds: CPU-bound work of ~2-3 s, the same in every process
SPIN = "s = 0\nfor i in range(30_000_000):\n    s += i"


def two_processes() -> dict:
    """SPIN alone, then two copies at once: their wall times and 2 x alone / pair."""
    t = time.perf_counter()
    subprocess.run([sys.executable, "-c", SPIN], check=True)
    alone = time.perf_counter() - t
    t = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(2)]
    if any(p.wait() for p in procs):
        raise RuntimeError("the control loop failed")
    pair = time.perf_counter() - t
    return {"alone": alone, "pair": pair, "ratio": 2 * alone / pair}


def grid(tree: Path, venv: Path, cache: Path, out: Path, jobs: int) -> tuple:
    """The main job with the venv's `fencesweep` command. PYTHONPATH names the tree: the venv sees
    the machine's packages, and an editable install there of another checkout (a path entry in
    a .pth file) would otherwise be found before the venv's own editable install (a finder that
    Python asks after the path entries); install checks it once."""
    out.unlink(missing_ok=True)
    env = _env(tree, cache)
    cmd = [str(venv / "bin" / "fencesweep"), "grid", "sweeps/b2k2.yaml", "--out", str(out), "--jobs", str(jobs),
           "--no-resume", "--quiet"]
    return _wall(cmd, env, tree)


def compilations(tree: Path, cache: Path) -> dict:
    _forget(tree, cache)
    _, r = _wall([sys.executable, "-c", COUNT_COMPILES], _env(tree, cache), tree)
    return json.loads(r.stdout.strip().splitlines()[-1])


def _med(xs: list) -> float:
    return statistics.median(xs)


def _runs(xs: list) -> str:
    return ", ".join(f"{x:.1f}" for x in xs)


def measure(trees: dict, tmp: Path, rounds: int, warm_rounds: int) -> dict:
    cache = {k: tmp / f"cache-{i}" for i, k in enumerate(trees)}
    venv = {k: tmp / f"venv-{i}" for i, k in enumerate(trees)}
    out = {k: tmp / f"b2k2-{i}.parquet" for i, k in enumerate(trees)}
    m = {k: {"first": [], "said": [], "install": [], "grid_cold": [], "warm1": [], "warm2": [], "alone": []}
         for k in trees}
    m["control"] = []
    for r in range(rounds):
        for k, tree in trees.items():
            c = cold_first_cycle(tree, cache[k])
            m[k]["first"].append(c["seconds"])
            m[k]["said"].append(c["said"])
            print(f"round {r + 1}: {k} cold first cycle {c['seconds']:.1f} s", flush=True)
        k = list(trees)[-1]
        m[k]["alone"].append(cold_first_cycle(trees[k], cache[k], helper=False)["seconds"])
        print(f"round {r + 1}: {k} cold first cycle without the helper {m[k]['alone'][-1]:.1f} s", flush=True)
    for r in range(max(1, rounds - 1)):
        for k, tree in trees.items():
            m[k]["install"].append(install(tree, venv[k]))
            _forget(tree, cache[k])
            s, _ = grid(tree, venv[k], cache[k], out[k], 2)
            m[k]["grid_cold"].append(s)
            print(f"round {r + 1}: {k} install {m[k]['install'][-1]:.1f} s + cold grid {s:.1f} s", flush=True)
    for r in range(warm_rounds):
        for jobs in (1, 2):
            for k, tree in trees.items():
                s, _ = grid(tree, venv[k], cache[k], out[k], jobs)
                m[k][f"warm{jobs}"].append(s)
        m["control"].append(two_processes())
        print(f"round {r + 1}: warm " + "; ".join(f"{k} {m[k]['warm1'][-1]:.2f} / {m[k]['warm2'][-1]:.2f} s"
                                                 for k in trees)
              + f"; control: 2 processes / 1 {m['control'][-1]['ratio']:.2f}", flush=True)
    for k, tree in trees.items():
        m[k]["compiles"] = compilations(tree, cache[k])
    import pandas as pd

    tables = [pd.read_parquet(out[k]) for k in trees]
    m["same_table"] = tables[0].equals(tables[1])
    m["rows"] = len(tables[0])
    m["differences"] = differences(*tables)
    return m


def differences(a, b) -> dict:
    """How two tables of the main job differ: whether the outcomes agree row by row, and per
    numeric column that differs its largest relative difference |b - a| / |a|, largest first."""
    import numpy as np

    out = {"same_columns": list(a.columns) == list(b.columns), "outcomes_agree": bool((a["outcome"] == b["outcome"]).all()),
           "columns": {}}
    for c in a.columns.intersection(b.columns):
        x, y = a[c], b[c]
        if x.equals(y) or not (np.issubdtype(x.dtype, np.number) and np.issubdtype(y.dtype, np.number)):
            continue
        x, y = x.to_numpy(float), y.to_numpy(float)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.abs(y - x) / np.abs(x)
        rel = np.where((x == y) | (np.isnan(x) & np.isnan(y)), 0.0, rel)
        out["columns"][c] = {"rows": int((rel > 0).sum()), "max_rel": float(np.nanmax(rel))}
    out["columns"] = dict(sorted(out["columns"].items(), key=lambda kv: -kv[1]["max_rel"]))
    return out


def page(m: dict, trees: dict, rounds: int, warm_rounds: int) -> str:
    b, n = list(trees)
    lines = ["# Start fast: a first run and the warm main job, before and after, in one run", "",
             f"Regenerate: `python benchmarks/startup.py --before {b} --rounds {rounds} --warm-rounds {warm_rounds}` "
             f"(what is measured: its "
             f"docstring). Wall times on this machine (2 cores), the two trees alternating; medians, with each "
             f"run in brackets.", "",
             f"| | {b} | this tree | bar |", "|---|---|---|---|"]
    first = {k: _med(m[k]["first"]) for k in trees}
    lines.append(f"| cold first cycle [s] | {first[b]:.1f} ({_runs(m[b]['first'])}) | "
                 f"{first[n]:.1f} ({_runs(m[n]['first'])}) | <= 10 |")
    lines.append(f"| ... this tree without its compile helper [s] | | {_med(m[n]['alone']):.1f} "
                 f"({_runs(m[n]['alone'])}) | |")
    lines.append(f"| ... said it compiles | {'yes' if all(m[b]['said']) else 'no'} | "
                 f"{'yes' if all(m[n]['said']) else 'no'} | yes |")
    inst = {k: _med(m[k]["install"]) for k in trees}
    cold = {k: _med(m[k]["grid_cold"]) for k in trees}
    lines.append(f"| pip install -e . [s] | {inst[b]:.1f} | {inst[n]:.1f} | |")
    lines.append(f"| cold main job, 2 jobs [s] | {cold[b]:.1f} ({_runs(m[b]['grid_cold'])}) | "
                 f"{cold[n]:.1f} ({_runs(m[n]['grid_cold'])}) | |")
    lines.append(f"| install + cold main job [s] | {inst[b] + cold[b]:.1f} | {inst[n] + cold[n]:.1f} | <= 20 |")
    for jobs in (1, 2):
        w = {k: _med(m[k][f"warm{jobs}"]) for k in trees}
        lines.append(f"| warm main job, {jobs} job{'s' if jobs > 1 else ''} [s] | {w[b]:.2f} "
                     f"({', '.join(f'{x:.2f}' for x in m[b][f'warm{jobs}'])}) | {w[n]:.2f} "
                     f"({', '.join(f'{x:.2f}' for x in m[n][f'warm{jobs}'])}) | |")
    ratio = {k: _med(m[k]["warm1"]) / _med(m[k]["warm2"]) for k in trees}
    pr = {k: [a / c for a, c in zip(m[k]["warm1"], m[k]["warm2"])] for k in trees}
    pairs = {k: ", ".join(f"{x:.2f}" for x in pr[k]) for k in trees}
    lines.append(f"| 2 jobs / 1 job, warm: ratio of the medians (of each pair) | {ratio[b]:.2f} ({pairs[b]}) | "
                 f"{ratio[n]:.2f} ({pairs[n]}) | >= 1.8 |")
    lines.append(f"| 2 jobs / 1 job, warm: median of the pairs' ratios | {_med(pr[b]):.2f} | {_med(pr[n]):.2f} | |")
    cc = {k: m[k]["compiles"] for k in trees}
    lines.append(f"| compilations (functions) of the cold first cycle | {cc[b]['compilations']} "
                 f"({cc[b]['functions']}) | {cc[n]['compilations']} ({cc[n]['functions']}), "
                 f"{cc[n].get('loaded', 0)} more loaded from the helper | one each |")
    ctl = m["control"]

    def each(key: str) -> str:
        return ", ".join(f"{c[key]:.2f}" for c in ctl)

    lines += ["", f"What 2 processes get from this machine (the control, in each warm round): a CPU-bound loop "
              f"alone took {each('alone')} s, two copies at once {each('pair')} s: 2 x alone / pair = "
              f"{each('ratio')} (median {_med([c['ratio'] for c in ctl]):.2f}). That is the most 2 jobs could give "
              f"over 1 here and then, with no serial work at all; above 2, the lone run was the one the machine "
              f"slowed.", "",
              f"The main job's table ({m['rows']} rows) is the same from both trees: {m['same_table']}."]
    d = m["differences"]
    if not m["same_table"]:
        cols = list(d["columns"].items())
        lines += ["", f"How they differ: the same columns in the same order: {d['same_columns']}; outcomes agree in every "
                  f"row: {d['outcomes_agree']}; {len(cols)} numeric columns differ, the largest relative differences "
                  "(rows that differ): " + ", ".join(f"{c} {v['max_rel']:.2g} ({v['rows']})" for c, v in cols[:8])
                  + (", ..." if len(cols) > 8 else "") + f". What changed on purpose since {b} is in CHANGELOG.md."]
    lines += ["",
              "Most compiled functions of the cold first cycle (compilations):", ""]
    for k in trees:
        lines.append(f"* {k}: " + ", ".join(f"{f.rsplit('.', 1)[-1]} {c}" for f, c in cc[k]["most"]))
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default=BEFORE, help=f"the earlier revision (default {BEFORE})")
    ap.add_argument("--rounds", type=int, default=3, help="rounds of the cold measurements (default 3)")
    ap.add_argument("--warm-rounds", type=int, default=5, help="interleaved warm pairs per tree (default 5)")
    ap.add_argument("--page-only", action="store_true",
                    help=f"measure nothing: write the page again from the measurements of the last run ({RAW.name})")
    a = ap.parse_args()
    if a.page_only:
        raw = json.loads(RAW.read_text())
        m, trees, rounds, warm_rounds = raw["measured"], dict.fromkeys(raw["trees"]), raw["rounds"], raw["warm_rounds"]
    else:
        with tempfile.TemporaryDirectory() as tmp:
            trees = {a.before: export(a.before, Path(tmp) / "before"), "this tree": ROOT}  # a fresh tree
            m = measure(trees, Path(tmp), a.rounds, a.warm_rounds)
        rounds, warm_rounds = a.rounds, a.warm_rounds
        RAW.write_text(json.dumps({"trees": list(trees), "rounds": rounds, "warm_rounds": warm_rounds, "measured": m},
                                  indent=1) + "\n")
    text = page(m, trees, rounds, warm_rounds)
    print(text)
    (ROOT / "results" / "startup.md").write_text(text)


if __name__ == "__main__":
    main()
