"""One vocabulary: the repository cites its own model document, docs/model.md, and speaks of
itself only (no outside specification's file name, no tracker numbers), in the code, the tests,
the benchmarks, the specs, the docs and the results pages."""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
WHERE = ("fencesweep", "tests", "benchmarks", "sweeps", "docs", "results")
TEXT = {".py", ".md", ".yaml", ".yml", ".sh", ".toml", ".txt"}
#: what the repository must not say (built so that this file does not say it itself)
FORBIDDEN = {
    "the outside specification's file": re.compile(r"\b" + "MODEL" + r"\.md\b"),
    "a tracker number": re.compile(r"\b[Ii]ssues?[ -]?#?\d+"),
    "a tracker's bar": re.compile(r"\bthe[ _]" + "issue" + r"('?s)?\b|\bper the " + "issue" + r"\b|the_" + "issue_"),
}


def _files() -> list:
    files = [ROOT / n for n in ("README.md", "CHANGELOG.md", "pyproject.toml")]
    for d in WHERE:
        files += [p for p in (ROOT / d).rglob("*") if p.suffix in TEXT and "__pycache__" not in p.parts
                  and ".fencesweep-revisions" not in p.parts]
    return sorted(files)


def test_files_are_found():  # the test below would pass on no file
    names = {p.relative_to(ROOT).as_posix() for p in _files()}
    assert {"README.md", "docs/model.md", "sweeps/b2k2.yaml", "fencesweep/cli.py"} <= names


@pytest.mark.parametrize("what", sorted(FORBIDDEN))
def test_the_repository_speaks_of_itself_only(what):
    pattern = FORBIDDEN[what]
    hits = [f"{p.relative_to(ROOT)}:{i}: {line.strip()[:100]}" for p in _files()
            for i, line in enumerate(p.read_text(errors="replace").splitlines(), 1) if pattern.search(line)]
    assert not hits, f"{what}:\n" + "\n".join(hits)


def test_the_patterns_find_what_they_should():
    assert FORBIDDEN["a tracker number"].search("as asked in iss" + "ue 30")
    assert FORBIDDEN["a tracker number"].search("README.md#a-heading-iss" + "ue-10")
    assert FORBIDDEN["a tracker's bar"].search("meets the " + "issue's bar")
    assert FORBIDDEN["a tracker's bar"].search("def test_the_" + "issue_overlap():")
    assert not FORBIDDEN["the outside specification's file"].search("docs/model.md §4")
