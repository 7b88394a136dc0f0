"""docs/model.md, the model document, against itself and against the code (read with `ast`,
nothing imported).

(a) every numbered equation has a row in the implementation index, and every row an equation;
(b) every function the index names exists;
(c) each indexed function is small (<= MAX_LINES) and its docstring names its equation label
    "(n.k)" or its section ("model.md §n"). Rows marked "(inline)" (a formula inside a larger function) are exempt from both;
    PENDING lists the functions, in files that belong to others, whose docstrings do not cite
    docs/model.md yet (their docstring check is a strict xfail);
(d) every "model.md §n" under fencesweep/ names a section or subsection heading
    of docs/model.md ("## §n Title", "### §n.k Title"), and every "model.md (n.k)" an equation.

An equation is a line inside a fenced block of docs/model.md that ends with its label (n.k);
its block (since the previous label) states its units in brackets.
"""
from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "model.md"
PACKAGE = ROOT / "fencesweep"
MAX_LINES = 40
#: the sections the code and the specs cite, kept under their numbers (§1-§14 the model, §13.3 a paper's figure)
SPEC_SECTIONS = {str(n) for n in range(1, 15)} | {"5.1", "5.2", "5.3", "13.3"}
INDEX_HEADING = "## Implementation index"

HEADING = re.compile(r"^(##|###) §(\d+(?:\.\d+)?) \S")
LABEL_AT_END = re.compile(r"\((\d+\.\d+)\)\s*$")
LABEL = re.compile(r"\((\d+\.\d+)\)")
UNITS = re.compile(r"\[[^\]]+\]")
ROW = re.compile(r"^\|\s*\((\d+\.\d+)\)\s*\|[^|]*\|\s*`([\w/.]+)::(\w+)`\s*(\(inline\))?\s*\|\s*$")
SECTION_CITATION = re.compile(r"model\.md\s+(§\d+(?:\.\d+)?(?:\s*(?:,|-|–|and|or)\s*§\d+(?:\.\d+)?)*)")
SECTION_TOKEN = re.compile(r"§(\d+(?:\.\d+)?)|([-–])")
EQUATION_CITATION = re.compile(r"model\.md\s+(\(\d+\.\d+\)(?:\s*(?:,|-|–|and|or)\s*\(\d+\.\d+\))*)")
#: a docstring citing this document
DOC_SECTION_CITATION = re.compile(r"(?<![A-Za-z])model\.md §(\d+)")

#: indexed functions whose docstrings do not cite docs/model.md yet, in files that others own or
#: are rewriting. Strict xfail: once such a docstring cites its equation "(n.k)", its check
#: passes, which fails the run as XPASS until the entry is removed here.
PENDING: set[str] = set()


@dataclass(frozen=True)
class Equation:
    label: str  # "4.1"
    section: str | None  # the "## §n" it stands under
    block: str  # its lines in the fenced block, since the previous label
    line: int


@dataclass(frozen=True)
class Row:
    label: str
    path: str
    function: str
    inline: bool

    @property
    def key(self) -> str:
        return f"{self.path}::{self.function}"


LINES = DOC.read_text(encoding="utf-8").splitlines()


def _headings() -> list[tuple[str, str]]:
    """(level "##" or "###", number) of the §-headings, in order, outside fenced blocks."""
    out, fenced = [], False
    for line in LINES:
        if line.strip().startswith("```"):
            fenced = not fenced
        elif not fenced and HEADING.match(line):
            m = HEADING.match(line)
            out.append((m.group(1), m.group(2)))
    return out


def _section_of(line: str, current: str | None) -> str | None:
    m = HEADING.match(line)
    if m and m.group(1) == "##":
        return m.group(2)
    if line.startswith("## "):
        return None  # an unnumbered section (Symbols, Implementation index)
    return current


def _equations() -> list[Equation]:
    """The numbered equations, in the order of the document (module docstring)."""
    out: list[Equation] = []
    section, block = None, None  # block: the lines since the last label while inside a fence
    for no, line in enumerate(LINES, 1):
        if line.strip().startswith("```"):
            block = [] if block is None else None
            continue
        if block is None:
            section = _section_of(line, section)
            continue
        block.append(line)
        m = LABEL_AT_END.search(line)
        if m:
            out.append(Equation(m.group(1), section, "\n".join(block), no))
            block = []
    return out


def _rows() -> list[Row]:
    """The rows of the implementation index."""
    start = LINES.index(INDEX_HEADING)
    rows = []
    for line in LINES[start + 1:]:
        if line.startswith("## "):
            break
        m = ROW.match(line)
        if m:
            rows.append(Row(m.group(1), m.group(2), m.group(3), m.group(4) is not None))
        elif line.startswith("| (") or line.startswith("|("):
            raise AssertionError(f"an index row that does not read as (n.k) | what | `path::function`: {line}")
    return rows


EQUATIONS = _equations()
ROWS = _rows()
SECTIONS = {number for _, number in _headings()}
LABELS = {eq.label for eq in EQUATIONS}


def _function(row: Row) -> ast.FunctionDef:
    path = ROOT / row.path
    assert path.is_file(), f"{row.path} (equation ({row.label})) does not exist"
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = [n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.name == row.function]
    assert found, f"{row.key} (equation ({row.label})) is not a module-level function"
    return found[0]


# ---------------------------------------------------------------- the document itself

def test_the_sections_of_the_specification_keep_their_numbers():
    heads = _headings()
    tops = [int(n) for level, n in heads if level == "##"]
    assert tops == list(range(1, len(tops) + 1)) and len(tops) >= 14, tops
    assert SPEC_SECTIONS <= SECTIONS, sorted(SPEC_SECTIONS - SECTIONS)
    current = None
    for level, n in heads:  # a subsection stands under its section, in order
        if level == "##":
            current, last = n, 0
            continue
        top, sub = n.split(".")
        assert top == current and int(sub) == last + 1, f"§{n} under §{current}"
        last = int(sub)


def test_equations_are_numbered_in_order_within_their_section_and_state_units():
    assert len(EQUATIONS) > 50
    expected: dict[str, int] = {}
    for eq in EQUATIONS:
        top, k = eq.label.split(".")
        assert eq.section == top, f"({eq.label}) at line {eq.line} stands in §{eq.section}"
        expected[top] = expected.get(top, 0) + 1
        assert int(k) == expected[top], f"({eq.label}) at line {eq.line}: expected ({top}.{expected[top]})"
        assert UNITS.search(eq.block), f"({eq.label}) at line {eq.line} gives no units in brackets"


def test_every_equation_the_document_refers_to_exists():
    missing = [(no, m.group(1)) for no, line in enumerate(LINES, 1) for m in LABEL.finditer(line)
               if m.group(1) not in LABELS]
    assert not missing, f"(line, label) referred to but not numbered: {missing}"


# ---------------------------------------------------------------- (a) equations <-> index

def test_every_equation_is_in_the_index_and_every_row_is_an_equation():
    labels = [eq.label for eq in EQUATIONS]
    rows = [row.label for row in ROWS]
    assert len(set(rows)) == len(rows), "an equation with two rows"
    assert set(labels) - set(rows) == set(), "equations without a row"
    assert set(rows) - set(labels) == set(), "rows without an equation"
    assert rows == labels, "the index is not in the order of the equations"


# ---------------------------------------------------------------- (b), (c) the indexed functions

@pytest.mark.parametrize("row", ROWS, ids=lambda r: f"({r.label}) {r.function}")
def test_the_indexed_function_exists(row):
    _function(row)


def _cites(doc: str, label: str) -> bool:
    """Does a docstring name equation `label` or its section of docs/model.md?"""
    if f"({label})" in doc:
        return True
    top = label.split(".")[0]
    return any(m.group(1) == top for m in DOC_SECTION_CITATION.finditer(doc))


#: the rows whose function is its formula's own (not "(inline)")
OWN_ROWS = [row for row in ROWS if not row.inline]


@pytest.mark.parametrize("row", OWN_ROWS, ids=lambda r: f"({r.label}) {r.function}")
def test_the_indexed_function_is_small(row):
    fn = _function(row)
    size = fn.end_lineno - fn.lineno + 1
    assert size <= MAX_LINES, f"{row.key} has {size} lines (> {MAX_LINES}): mark the row (inline) or split it"


def _docstring_rows():
    for row in OWN_ROWS:
        marks = [pytest.mark.xfail(strict=True, reason="its docstring does not cite docs/model.md yet (PENDING)")] \
            if row.key in PENDING else []
        yield pytest.param(row, id=f"({row.label}) {row.function}", marks=marks)


@pytest.mark.parametrize("row", list(_docstring_rows()))
def test_the_indexed_function_cites_its_equation(row):
    doc = ast.get_docstring(_function(row)) or ""
    assert _cites(doc, row.label), f"{row.key}: its docstring names neither ({row.label}) nor model.md §{row.label}"


def test_pending_lists_only_indexed_functions():
    keys = {row.key for row in OWN_ROWS}
    assert PENDING <= keys, sorted(PENDING - keys)


# ---------------------------------------------------------------- (d) the code's citations

def _sections_cited(text: str) -> list[str]:
    """The §-numbers of one citation's list, ranges (§1-§6) expanded."""
    out: list[str] = []
    pending_range = False
    for m in SECTION_TOKEN.finditer(text):
        if m.group(2):
            pending_range = True
            continue
        n = m.group(1)
        if pending_range and out and "." not in n and "." not in out[-1]:
            out.extend(str(k) for k in range(int(out[-1]) + 1, int(n)))
        out.append(n)
        pending_range = False
    return out


def _citations():
    """(file:line, kind, number) of every citation of the model document under fencesweep/."""
    for path in sorted(PACKAGE.rglob("*.py")):
        for no, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            where = f"{path.relative_to(ROOT)}:{no}"
            for m in SECTION_CITATION.finditer(line):
                yield from ((where, "§", n) for n in _sections_cited(m.group(1)))
            for m in EQUATION_CITATION.finditer(line):
                yield from ((where, "eq", n) for n in LABEL.findall(m.group(1)))


def test_every_section_and_equation_the_code_cites_exists():
    cited = list(_citations())
    assert sum(kind == "§" for _, kind, _ in cited) > 100  # the citations are found at all
    bad = [(where, f"§{n}") for where, kind, n in cited if kind == "§" and n not in SECTIONS]
    bad += [(where, f"({n})") for where, kind, n in cited if kind == "eq" and n not in LABELS]
    assert not bad, f"cited but not in docs/model.md: {bad}"


def test_the_citation_parser_reads_lists_and_ranges():
    assert _sections_cited("§1-§6, §9-§11") == ["1", "2", "3", "4", "5", "6", "9", "10", "11"]
    assert _sections_cited("§5.2") == ["5.2"]
    line = "(docs/model.md §4, §5, §6) and docs/model.md (4.1), (4.2); model.md §12."
    assert [m.group(1) for m in SECTION_CITATION.finditer(line)] == ["§4, §5, §6", "§12"]
    assert [LABEL.findall(m.group(1)) for m in EQUATION_CITATION.finditer(line)] == [["4.1", "4.2"]]
