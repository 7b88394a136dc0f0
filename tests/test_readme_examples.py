"""Every Python example of the READMEs runs: each file's ```python blocks, in order, in one
namespace, in a scratch directory holding a copy of the sweeps and of the results tables they read
(an example that writes a table writes it there).

And the values an example's comments state are the values it gives. A comment that states them
starts with "->" and follows an expression statement:

    s["n_scraped"], s["throughput"]        # -> 20, 2400 (per h)

lists the expression's values (its elements, for several), each one
  * a number, true to the digits written: 0.68 is a value that rounds to 0.68, 2400 one that
    rounds to 2400; with "..." after it a number that starts so: 0.6... is 0.6 <= x < 0.7;
  * a string, quoted: exactly that string ('scraped'); with "..." after it, one that starts so;
  * True, False, None, or a literal list, tuple or dict: equal to it;
each optionally followed by a unit in parentheses, which is not checked; after the values, a
":" or ";" begins a remark. A comment of an example that starts with a value (a number, a quote,
a bracket, True/False/None) must be such a comment, so that no stated value goes unchecked."""
from __future__ import annotations

import ast
import io
import re
import shutil
import tokenize
from decimal import ROUND_DOWN, ROUND_HALF_UP, Decimal
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
READMES = [p for p in ("README.md", "sweeps/README.md", "benchmarks/README.md") if (ROOT / p).exists()]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.M | re.S)
#: a comment that states values (module docstring), and one that looks as if it did
STATED = re.compile(r"#\s*->\s*(.*)$")
VALUE_LIKE = re.compile(r"#\s*(~?[-+]?\.?\d|['\"\[({]|(True|False|None)\b)")
NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
UNIT = re.compile(r"\s*\([^()]*\)$")


def blocks(text: str) -> list:
    """(line, source) of each ```python block."""
    return [(text[:m.start()].count("\n") + 2, m.group(1)) for m in BLOCK.finditer(text)]


def comments(source: str) -> dict:
    """{line in the block: the comment's text} of a block's comments."""
    tokens = tokenize.generate_tokens(io.StringIO(source).readline)
    return {t.start[0]: t.string for t in tokens if t.type == tokenize.COMMENT}


def _split(text: str) -> list:
    """The values of a stated comment's text, split at the commas outside quotes and brackets,
    up to a ":" or ";" there (a remark follows)."""
    parts, depth, quote, start = [], 0, None, 0
    for i, c in enumerate(text):
        if quote:
            quote = None if c == quote else quote
        elif c in "'\"":
            quote = c
        elif c in "([{":
            depth += 1
        elif c in ")]}":
            depth -= 1
        elif depth == 0 and c in ",:;":
            parts.append(text[start:i])
            if c != ",":
                return parts
            start = i + 1
    return parts + [text[start:]]


def stated(text: str) -> list:
    """The values a comment states (module docstring), each as it is written, without its unit."""
    values = []
    for part in _split(text):
        part = part.strip()
        unit = UNIT.search(part)
        if unit and part[:unit.start()].strip():
            part = part[:unit.start()].strip()
        values.append(part)
    return values


def _number(actual, written: str) -> bool:
    """Is `actual` the number `written` to its digits (or, with "...", does it start so)?"""
    prefix = written.endswith("...")
    want = Decimal(written.removesuffix("..."))
    if isinstance(actual, (str, bytes)):
        return False
    try:
        have = Decimal(repr(float(actual)))
    except (TypeError, ValueError):
        return False
    digits = Decimal(1).scaleb(want.as_tuple().exponent)
    return have.quantize(digits, rounding=ROUND_DOWN if prefix else ROUND_HALF_UP) == want


def agrees(actual, written: str) -> bool:
    """Does `actual` agree with one value as a comment writes it (module docstring)?"""
    if NUMBER.fullmatch(written.removesuffix("...")):
        return _number(actual, written)
    if written.endswith("...") and written[:1] in "'\"":
        return isinstance(actual, str) and actual.startswith(ast.literal_eval(written.removesuffix("...")))
    expected = ast.literal_eval(written)
    if expected is None:
        return actual is None
    if isinstance(expected, (list, tuple)) and not isinstance(actual, str):
        return len(expected) == len(actual) and all(bool(a == e) for a, e in zip(actual, expected))
    return bool(actual == expected)


def check(actual, text: str, where: str) -> None:
    """AssertionError unless the expression's value `actual` is what the comment's `text` states."""
    values = stated(text)
    items = [actual] if len(values) == 1 else list(actual) if isinstance(actual, tuple) else None
    if items is None or len(items) != len(values):
        raise AssertionError(f"{where}: the comment states {len(values)} values, the expression gives {actual!r}")
    for have, written in zip(items, values):
        try:
            ok = agrees(have, written)
        except (ValueError, SyntaxError, TypeError) as exc:
            raise AssertionError(f"{where}: the comment's value {written!r} cannot be read ({exc})") from None
        if not ok:
            raise AssertionError(f"{where}: the comment says {written}, the example gives {have!r}")


def run_block(source: str, name: str, line: int, namespace: dict) -> int:
    """Run a block's statements in `namespace`, checking each stated comment; the number checked."""
    notes = comments(source)
    tree = ast.parse(source)
    checked = set()
    for stmt in tree.body:
        end = stmt.end_lineno
        claim = STATED.search(notes.get(end, ""))
        ast.increment_lineno(stmt, line - 1)  # a traceback names the README's line
        if claim and isinstance(stmt, ast.Expr):
            value = eval(compile(ast.Expression(stmt.value), name, "eval"), namespace)
            check(value, claim.group(1), f"{name} line {line + end - 1}")
            checked.add(end)
        else:
            exec(compile(ast.Module([stmt], []), name, "exec"), namespace)
    loose = sorted(n for n, c in notes.items() if STATED.search(c) and n not in checked)
    if loose:
        raise AssertionError(f"{name} line {line + loose[0] - 1}: a '# ->' comment that follows no expression")
    return len(checked)


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
            run_block(source, readme, line, namespace)
        except AssertionError:
            raise
        except Exception as exc:
            raise AssertionError(f"the example at {readme} line {line} fails: {exc!r}") from exc


@pytest.mark.parametrize("readme", READMES)
def test_every_value_an_example_states_is_checked(readme):
    loose = [f"{readme} line {line + n - 1}: {c}" for line, source in blocks((ROOT / readme).read_text())
             for n, c in comments(source).items() if VALUE_LIKE.match(c) and not STATED.search(c)]
    assert not loose, "comments that state values without '->' (tests/test_readme_examples.py):\n" + "\n".join(loose)


def test_a_wrong_stated_value_fails():
    ok = ("r = {'outcome': 'scraped', 'overload': 0.6234, 'n': 20}\n"
          "r['outcome'], r['overload'], r['n']      # -> 'scraped', 0.6..., 20 (per h): a remark, 1\n"
          "r['overload']  # -> 0.62\n"
          "[1, 2], None, 'scrap' 'ed'  # -> [1, 2], None, 'scr'...\n")
    assert run_block(ok, "ok.md", 10, {}) == 3
    for wrong, says in (("r['overload']  # -> 0.63", "line 11: the comment says 0.63, the example gives 0.6234"),
                        ("r['overload']  # -> 0.7...", "says 0.7..."),
                        ("r['outcome'], r['n']  # -> 'scraped', 21", "says 21, the example gives 20"),
                        ("r['outcome']  # -> 'scrap'", "says 'scrap', the example gives 'scraped'"),
                        ("r['n']  # -> '20'", "says '20'"),
                        ("r['outcome'], r['n']  # -> 'scraped'", "says 'scraped', the example gives ('scraped', 20)"),
                        ("r['outcome']  # -> 'scraped', 20", "states 2 values, the expression gives 'scraped'"),
                        ("x = r['n']  # -> 20", "follows no expression")):
        with pytest.raises(AssertionError, match=re.escape(says)):
            run_block("r = {'outcome': 'scraped', 'overload': 0.6234, 'n': 20}\n" + wrong + "\n", "bad.md", 10, {})


def test_the_stated_values_are_read_as_written():
    assert stated(" 'scraped', 0.6..., 0.2... (rad)") == ["'scraped'", "0.6...", "0.2..."]
    assert stated(" 20, -1, 0.68, 2400 (per h)") == ["20", "-1", "0.68", "2400"]
    assert stated(" True: a re-run agrees to 1e-3") == ["True"]
    assert stated(" (512, 448), 'a, b; c'") == ["(512, 448)", "'a, b; c'"]
    assert agrees(2399.6, "2400") and not agrees(2399.4, "2400") and agrees(0.675, "0.68")
    assert agrees(-0.61, "-0.6...") and not agrees(0.7, "0.6...") and agrees(1.0e-3, "1e-3")
    assert agrees(True, "True") and not agrees("True", "True") and not agrees(0, "None")
