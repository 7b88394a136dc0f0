"""The oldest Numba the package allows (pyproject.toml's `numba>=A,<B`), tested: a throwaway
virtual environment with nothing but what pip installs into it (no system site packages), the
package installed editable with `numba==A.*`, and the tests of the compile machinery run there.

    python benchmarks/numba_floor.py [--numba 0.62 ...] [--keep]
                                         -> prints, writes results/numba_floor.md

Without --numba the floor A is read from pyproject.toml. For each version: a new virtual
environment in a temporary directory, `pip install -e REPO numba==V.* pytest` (pip resolves
llvmlite, NumPy and the rest for it), then

    python -m pytest tests/test_jit.py tests/test_cycle.py tests/test_compile_isolation.py

in the repository with an empty Numba cache (NUMBA_CACHE_DIR in the temporary directory), its
pass / fail / skip counts read from pytest's JUnit XML. The page gives the versions installed,
the counts, the failures by name and the wall times. A version outside pyproject.toml's range
fails at the install (pip refuses it), which the page says.
"""
from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "results" / "numba_floor.md"
TESTS = ["tests/test_jit.py", "tests/test_cycle.py", "tests/test_compile_isolation.py"]
#: why the floor is where it is (the page says it under the table)
WHY_FLOOR = ("Older than 0.62 is not allowed: Numba 0.61 (llvmlite 0.44) still runs LLVM's legacy pass manager, "
             "whose function pass manager fencesweep/kernel/jit.py's `_optimize_functions_once` cannot use "
             "(`_function_pass_manager()` there takes the module and returns no pass builder): a first compile "
             "fails with a TypeError.")
#: the versions the page reports, read in the new environment
VERSIONS = ("import json, sys, numba, llvmlite, numpy, scipy; print(json.dumps({'python': sys.version.split()[0], "
            "'numba': numba.__version__, 'llvmlite': llvmlite.__version__, 'numpy': numpy.__version__, "
            "'scipy': scipy.__version__}))")


def pinned_range() -> tuple[str, str]:
    """(A, B) of pyproject.toml's `numba>=A,<B`."""
    m = re.search(r'"numba>=([0-9.]+),<([0-9.]+)"', (ROOT / "pyproject.toml").read_text())
    if m is None:
        raise SystemExit("pyproject.toml has no numba>=A,<B dependency")
    return m.group(1), m.group(2)


def _clean_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHONPATH", "VIRTUAL_ENV"))}
    env.update(extra)
    return env


def _timed(cmd: list, **kw) -> tuple[float, subprocess.CompletedProcess]:
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    return time.perf_counter() - t, r


def _counts(junit: Path) -> dict:
    """Tests, failures (with errors), skips and the failing tests' names from pytest's JUnit XML."""
    root = ET.parse(junit).getroot()
    cases = list(root.iter("testcase"))
    failed = [f"{c.get('classname')}::{c.get('name')}" for c in cases
              if c.find("failure") is not None or c.find("error") is not None]
    skipped = sum(c.find("skipped") is not None for c in cases)
    return {"tests": len(cases), "failed": failed, "skipped": skipped,
            "passed": len(cases) - len(failed) - skipped}


def check(version: str, where: Path) -> dict:
    """Install the package with numba==version.* into a new environment under `where` and run TESTS there."""
    venv = where / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    python = str(venv / "bin" / "python")
    env = _clean_env()
    out = {"numba_asked": f"{version}.*"}
    out["install_s"], r = _timed([python, "-m", "pip", "install", "-q", "--disable-pip-version-check", "-e",
                                  str(ROOT), f"numba=={version}.*", "pytest"], env=env)
    if r.returncode != 0:
        out["install_error"] = (r.stderr or r.stdout)[-3000:]
        return out
    out["versions"] = json.loads(subprocess.run([python, "-c", VERSIONS], capture_output=True, text=True,
                                                check=True, env=env).stdout)
    junit = where / "junit.xml"
    env = _clean_env(NUMBA_CACHE_DIR=str(where / "numba_cache"))
    out["tests_s"], r = _timed([python, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={junit}",
                                *TESTS], cwd=ROOT, env=env)
    out["returncode"] = r.returncode
    out["summary"] = (r.stdout.strip().splitlines() or [""])[-1]
    if junit.exists():
        out.update(_counts(junit))
    else:
        out["tail"] = (r.stdout + r.stderr)[-3000:]
    return out


def _row(res: dict) -> str:
    v = res.get("versions", {})
    if "install_error" in res:
        return f"| {res['numba_asked']} | | | | install failed | | {res['install_s']:.0f} | |"
    counts = (f"{res.get('passed', '?')} passed, {len(res.get('failed', []))} failed, "
              f"{res.get('skipped', 0)} skipped")
    verdict = "pass" if res["returncode"] == 0 and not res.get("failed") else "FAIL"
    return (f"| {v['numba']} | {v['llvmlite']} | {v['numpy']} | {v['scipy']} | {verdict} | {counts} | "
            f"{res['install_s']:.0f} | {res['tests_s']:.0f} |")


def page(results: list, floor: str, ceiling: str) -> str:
    lines = [
        "# Numba floor: the oldest Numba the package allows, tested", "",
        f"Regenerate: `python benchmarks/numba_floor.py` (what is run: its docstring). pyproject.toml pins "
        f"`numba>={floor},<{ceiling}`. Each row: a new virtual environment without system site packages, "
        f"`pip install -e . numba==V.* pytest`, then `pytest {' '.join(TESTS)}` with an empty Numba cache. "
        f"Run {dt.date.today().isoformat()} on Python {sys.version.split()[0]}, {os.cpu_count()} cores; wall times.", "",
        "| numba | llvmlite | numpy | scipy | result | tests | install [s] | tests [s] |",
        "|---|---|---|---|---|---|---|---|",
        *(_row(r) for r in results), "", WHY_FLOOR, ""]
    for res in results:
        if res.get("failed"):
            lines += [f"Failed with numba {res['versions']['numba']}: " + ", ".join(res["failed"]) + ".", ""]
        if "install_error" in res:
            lines += [f"numba {res['numba_asked']} did not install:", "", "```", res["install_error"].strip(), "```", ""]
        if "tail" in res:
            lines += [f"numba {res['numba_asked']}: no test report; the run ended with:", "", "```",
                      res["tail"].strip(), "```", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--numba", action="append", help="minor version(s) to test, e.g. 0.62 (default: the floor)")
    ap.add_argument("--keep", action="store_true", help="keep the temporary environments (their paths are printed)")
    ap.add_argument("--page", type=Path, default=PAGE)
    args = ap.parse_args(argv)
    floor, ceiling = pinned_range()
    results = []
    for version in args.numba or [floor]:
        where = Path(tempfile.mkdtemp(prefix=f"numba-{version}-"))
        try:
            res = check(version, where)
        finally:
            if args.keep:
                print(f"kept {where}")
            else:
                shutil.rmtree(where, ignore_errors=True)
        print(_row(res), flush=True)
        results.append(res)
    args.page.write_text(page(results, floor, ceiling) + "\n")
    print(f"wrote {args.page}")
    return 0 if all(r.get("returncode") == 0 and not r.get("failed") for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
