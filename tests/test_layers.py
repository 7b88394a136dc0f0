"""The package's shape (README, Layout): layers that import only downwards, no import circle
(imports inside functions count), modules and functions short enough to read whole.

Read from the sources with `ast`, so a circle or a layer breach cannot come back unseen."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "fencesweep"
#: each layer may import itself and the layers before it; the leaves import nothing of the package
LAYERS = ("leaf", "kernel", "model", "study", "report", "shell")
LEAVES = {"fencesweep.errors", "fencesweep.resources", "fencesweep.version"}
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 500, 80


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _layer(mod: str) -> str:
    if mod in LEAVES:
        return "leaf"
    parts = mod.split(".")
    if len(parts) > 1 and parts[1] in ("kernel", "model", "study", "report"):
        return parts[1]
    return "shell"  # the package's __init__, __main__, cli


SOURCES = {_module(p): p for p in sorted(ROOT.rglob("*.py"))}
TREES = {m: ast.parse(p.read_text()) for m, p in SOURCES.items()}


def _imports(mod: str) -> set:
    """The package's modules that `mod` imports anywhere in its body (functions included)."""
    is_pkg = SOURCES[mod].name == "__init__.py"
    out = set()
    for node in ast.walk(TREES[mod]):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = mod.split(".") if is_pkg else mod.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                pkg = ".".join(base + ([node.module] if node.module else []))
            else:
                pkg = node.module or ""
            names = [f"{pkg}.{a.name}" if f"{pkg}.{a.name}" in SOURCES else pkg for a in node.names]
        else:
            continue
        out.update(n for n in names if n in SOURCES and n != mod and not mod.startswith(n + "."))
    return out


GRAPH = {m: _imports(m) for m in SOURCES}


def circles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = [stack.pop()]
            while comp[-1] != v:
                comp.append(stack.pop())
            on.difference_update(comp)
            if len(comp) > 1:
                found.append(sorted(comp))

    for m in sorted(graph):
        if m not in index:
            visit(m)
    return found


def test_no_import_circle():
    assert not circles(GRAPH), f"import circles: {circles(GRAPH)}"


def test_a_circle_is_found():  # the check above would pass if circles() found nothing
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_layers_import_only_downwards():
    bad = [f"{m} ({_layer(m)}) imports {t} ({_layer(t)})" for m, ts in GRAPH.items() for t in sorted(ts)
           if LAYERS.index(_layer(t)) > LAYERS.index(_layer(m)) or (_layer(m) == "leaf")]
    assert not bad, "\n".join(bad)


def test_the_graph_is_read():  # the checks above would pass on an empty graph
    assert "fencesweep.model.params" in GRAPH["fencesweep.study.spec.spec"]
    assert _layer("fencesweep.cli") == "shell" and _layer("fencesweep.errors") == "leaf"


@pytest.mark.parametrize("mod", sorted(SOURCES))
def test_module_is_short_enough_to_read(mod):
    n = len(SOURCES[mod].read_text().splitlines())
    assert n <= MAX_MODULE_LINES, f"{SOURCES[mod]} has {n} lines (at most {MAX_MODULE_LINES})"


def test_functions_are_short_enough_to_read():
    long = [f"{SOURCES[m]}:{n.lineno} {n.name}: {n.end_lineno - n.lineno + 1} lines"
            for m, tree in TREES.items() for n in ast.walk(tree)
            if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.end_lineno - n.lineno + 1 > MAX_FUNCTION_LINES]
    assert not long, "\n".join(long)


#: study/'s wings (fencesweep/study/__init__.py): each imports only itself and the wings before it
WINGS = ("store", "spec", "sweep", "design", "adaptive", "risk")


def _wing(mod: str) -> str | None:
    parts = mod.split(".")
    return parts[2] if len(parts) > 3 and parts[1] == "study" else None


def wing_graph(graph: dict) -> dict:
    """The wings of study/ and the wings each imports (a module of one importing a module of another)."""
    out = {w: set() for w in WINGS}
    for m, ts in graph.items():
        for t in ts:
            a, b = _wing(m), _wing(t)
            if a and b and a != b:
                out[a].add(b)
    return out


def test_every_study_module_is_in_a_wing():
    loose = [m for m in SOURCES if m.startswith("fencesweep.study.") and m.count(".") == 2
             and m != "fencesweep.study.api" and SOURCES[m].name != "__init__.py"]
    assert not loose, f"study modules outside a wing: {loose}"
    assert {_wing(m) for m in SOURCES if _wing(m)} == set(WINGS)


def test_wings_import_only_the_wings_before_them():
    graph = wing_graph(GRAPH)
    assert not circles(graph), f"circles between study's wings: {circles(graph)}"
    bad = [f"{a} imports {b}" for a, bs in graph.items() for b in bs if WINGS.index(b) > WINGS.index(a)]
    assert not bad, "\n".join(bad)
    assert "spec" in graph["sweep"]  # the graph is read


@pytest.mark.parametrize("wing", WINGS)
def test_no_circle_inside_a_wing(wing):
    sub = {m: {t for t in ts if _wing(t) == wing} for m, ts in GRAPH.items() if _wing(m) == wing}
    assert len(sub) >= 2 and not circles(sub), circles(sub)


def test_errors_live_in_errors_py():
    """Every exception and warning class of the package is defined in fencesweep/errors.py."""
    elsewhere = [f"{m}.{n.name}" for m, tree in TREES.items() if m != "fencesweep.errors" for n in ast.walk(tree)
                 if isinstance(n, ast.ClassDef) and any(
                     isinstance(b, (ast.Name, ast.Attribute)) and (getattr(b, "id", None) or b.attr).endswith(
                         ("Error", "Warning", "Exception", "Interrupt", "Interrupted")) for b in n.bases)]
    assert not elsewhere, f"exception classes outside errors.py: {elsewhere}"
