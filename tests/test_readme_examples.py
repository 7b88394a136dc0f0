"""Every Python example of the READMEs runs: each file's ```python blocks, in order, in one
namespace, in a scratch directory holding a copy of the sweeps and of the results tables they read
(an example that writes a table writes it there)."""
import re
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
READMES = [p for p in ("README.md", "sweeps/README.md", "benchmarks/README.md") if (ROOT / p).exists()]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.M | re.S)


def blocks(text: str) -> list:
    """(line, source) of each ```python block."""
    return [(text[:m.start()].count("\n") + 2, m.group(1)) for m in BLOCK.finditer(text)]


def test_blocks_are_found():  # the test below would pass on a README without examples
    assert len(blocks((ROOT / "README.md").read_text())) >= 2
    assert blocks("a\n```python\nx = 1\n```\n") == [(3, "x = 1\n")]


@pytest.mark.parametrize("readme", READMES)
def test_examples_run(readme, tmp_path, monkeypatch):
    text = (ROOT / readme).read_text()
    shutil.copytree(ROOT / "sweeps", tmp_path / "sweeps")
    (tmp_path / "results").mkdir()
    for name in sorted(set(re.findall(r"results/(\w+\.parquet)", text))):
        if (ROOT / "results" / name).exists():
            shutil.copy(ROOT / "results" / name, tmp_path / "results" / name)
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__readme__"}
    for line, source in blocks(text):
        try:
            exec(compile(source, f"{readme}:{line}", "exec"), namespace)
        except Exception as exc:
            raise AssertionError(f"the example at {readme} line {line} fails: {exc!r}") from exc
