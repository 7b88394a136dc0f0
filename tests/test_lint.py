"""The lint configured in pyproject.toml ([tool.ruff]: pyflakes, bugbear, McCabe complexity) over
the whole repository, run by the README's test command like every other check."""
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _ruff() -> str:
    try:
        from ruff.__main__ import find_ruff_bin
    except ImportError:
        found = shutil.which("ruff")
    else:
        found = find_ruff_bin()
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("ruff is not installed, but CI installs it with the test extra (pip install -e '.[test]')")
        pytest.skip("ruff is not installed: pip install -e '.[test]' brings the version pyproject.toml pins")
    return str(found)


def _check(*args, cwd=ROOT):
    return subprocess.run([_ruff(), "check", "--no-cache", "--output-format", "concise", *args],
                          capture_output=True, text=True, cwd=cwd)


def test_ruff_finds_nothing_in_the_repository():
    r = _check(str(ROOT))
    assert r.returncode == 0, r.stdout + r.stderr


def test_the_lint_configuration_catches_what_it_should(tmp_path):
    bad = tmp_path / "new_code.py"
    branches = "\n".join(f"    if x == {k}:\n        return {k}" for k in range(11))
    bad.write_text(f"import os\n\n\ndef f(x, seen=[]):\n{branches}\n    return -1\n")
    r = _check("--config", str(ROOT / "pyproject.toml"), str(bad), cwd=tmp_path)
    assert r.returncode == 1
    for code in ("F401", "B006", "C901"):  # pyflakes, bugbear, complexity 12 > 10
        assert code in r.stdout, r.stdout


def test_ci_runs_exactly_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    command = re.search(r"Install and run the tests:\n\n {4}(.+)\n", readme).group(1)
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines() if line and not line.startswith("#")]
    assert ci[-1] == command
