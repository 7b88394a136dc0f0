"""The private and internal names of Numba, numba-cuda and llvmlite that the compile layer uses
(fencesweep/kernel/internals.py): each one the list holds is where the list says in the installed
versions (numba-cuda's only where numba-cuda is installed), and a failure names the one that moved
and the modules that use it; the layer imports them from the list and uses no private attribute
of Numba's that the list does not hold."""
from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

import pytest

from fencesweep.errors import GpuUnavailable
from fencesweep.kernel import internals
from fencesweep.kernel.internals import ATTRS, NAMES, Attr, Name, moved, resolve

KERNEL = Path(internals.__file__).resolve().parent
#: the compile layer: the modules that use Numba's internals
LAYER = ("jit", "libraries", "locator", "share", "numba_setup", "cuda")
#: the private attributes of the package's own classes in the layer (not Numba's)
OWN = {"_made", "_copy", "_fill", "_translated", "_module", "_who", "_path", "_lineno", "_probe", "_answer"}
#: what the layer may import from Numba directly: its public API
PUBLIC_IMPORTS = {"numba", "numba.njit", "numba.types", "numba.typeof"}
#: the public modules the layer may import by name
PUBLIC_MODULES = {"numba.cuda"}


def _nothing():
    pass


def _cpu():
    return resolve("numba.core.registry:cpu_target")


def _compile_state():
    base, flags = resolve("numba.core.compiler:CompilerBase"), resolve("numba.core.compiler:Flags")
    return base(_cpu().typing_context, _cpu().target_context, None, (), None, flags(), {}).state


def _cuda():
    from fencesweep.kernel import cuda

    return cuda.load()


#: an object of each class whose "instance" attributes are listed (set by its __init__)
SAMPLES = {
    "numba.core.codegen:JITCPUCodegen": lambda: _cpu().target_context.codegen(),
    "numba.core.codegen:JITCodeLibrary": lambda: _cpu().target_context.codegen().create_library("probe"),
    "numba.core.compiler:StateDict": _compile_state,
    "numba.core.registry:CPUDispatcher": lambda: resolve("numba:njit")(_nothing),
    "llvmlite.binding.ffi:_lib_wrapper": lambda: resolve("llvmlite.binding.ffi:lib"),
    "llvmlite.binding.ffi:_LLVMLock": lambda: getattr(resolve("llvmlite.binding.ffi:lib"), ATTRS["llvm_lock"].name),
    "numba.cuda.dispatcher:CUDADispatcher": lambda: _cuda().jit(_nothing),
    "numba.core.caching:InTreeCacheLocator": lambda: resolve("numba.core.caching:InTreeCacheLocator")(_nothing, __file__),
}


def _skip_without_numba_cuda(path: str) -> None:
    if path.startswith("numba.cuda"):
        try:
            _cuda()  # loaded as the package loads it, before its names are looked up
        except GpuUnavailable:
            pytest.skip("numba-cuda is not installed")


def _has(attr: Attr) -> bool:
    """Whether the attribute is there, on its class, on an instance, or among the parameters."""
    owner = resolve(attr.on)
    if attr.kind == "parameter":
        return attr.name in inspect.signature(owner).parameters
    if attr.kind == "instance":
        sample = SAMPLES[attr.on]()
        assert isinstance(sample, owner), f"SAMPLES[{attr.on!r}] is a {type(sample)}"
        return hasattr(sample, attr.name)
    return hasattr(owner, attr.name)


def attr_problem(attr: Attr) -> str | None:
    """None when `attr` is where the list says, else the message naming it and its users."""
    what = f"{attr.on}.{attr.name}"
    try:
        found = _has(attr)
    except (ImportError, AttributeError) as exc:
        return moved(what, attr.users, attr.why, f"{type(exc).__name__}: {exc}")
    return None if found else moved(what, attr.users, attr.why, f"no {attr.kind} attribute {attr.name}")


@pytest.mark.parametrize("key", sorted(NAMES))
def test_each_listed_name_is_there(key):
    _skip_without_numba_cuda(NAMES[key].path)
    try:
        internals.lookup(key)
    except ImportError as exc:
        pytest.fail(str(exc))


@pytest.mark.parametrize("key", sorted(ATTRS))
def test_each_listed_attribute_is_there(key):
    _skip_without_numba_cuda(ATTRS[key].on)
    problem = attr_problem(ATTRS[key])
    assert problem is None, problem


def test_a_cached_results_payload_is_in_the_order_numba_rebuilds_it():
    params = list(inspect.signature(resolve("numba.core.compiler:CompileResult._rebuild")).parameters)
    assert tuple(params[1:]) == internals.REBUILD_PAYLOAD, moved(
        "numba.core.compiler:CompileResult._rebuild", ("share",), "the payload of _BitcodeImpl.reduce",
        f"its parameters are {params}, REBUILD_PAYLOAD is {internals.REBUILD_PAYLOAD}")


def test_numbas_llvm_lock_callbacks_are_from_the_listed_module():
    import fencesweep.kernel.jit  # noqa: F401  Numba loaded as the kernels load it

    lock = SAMPLES["llvmlite.binding.ffi:_LLVMLock"]()
    modules = {getattr(pair[0], "__module__", "") for pair in getattr(lock, ATTRS["lock_callbacks"].name)}
    name = NAMES["lock_events_module"]
    assert name.module in modules, moved(name.path, name.users, name.why, f"the callbacks are from {modules}")


def test_a_name_that_moved_is_named_with_the_modules_that_use_it(monkeypatch):
    monkeypatch.setitem(NAMES, "GoneLibrary", Name("numba.core.codegen:GoneLibrary", ("jit", "libraries"), "made up"))
    monkeypatch.setitem(NAMES, "gone_module", Name("numba.core.gone_module", ("share",), "made up"))
    with pytest.raises(ImportError) as info:
        from fencesweep.kernel.internals import GoneLibrary  # noqa: F401
    assert "numba.core.codegen:GoneLibrary is not in the installed numba " in str(info.value)
    assert "fencesweep/kernel/jit.py, fencesweep/kernel/libraries.py uses it (made up)" in str(info.value)
    with pytest.raises(ImportError, match=r"numba\.core\.gone_module .*fencesweep/kernel/share\.py"):
        internals.lookup("gone_module")
    problem = attr_problem(Attr("_gone", "numba.core.codegen:JITCodeLibrary", "class", ("libraries",), "made up"))
    assert "numba.core.codegen:JITCodeLibrary._gone" in problem and "fencesweep/kernel/libraries.py" in problem
    assert attr_problem(ATTRS["library_class"]) is None


def _trees() -> dict:
    return {m: ast.parse((KERNEL / f"{m}.py").read_text()) for m in LAYER}


def _private_names(tree) -> set:
    """The private names (one leading underscore) the code looks up, sets, passes or defines as
    attributes: obj._x, "_x", f(_x=...), a class body's _x."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            found.add(node.attr)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            found.add(node.value)
        elif isinstance(node, ast.keyword) and node.arg:
            found.add(node.arg)
        elif isinstance(node, ast.ClassDef):
            found.update(n.name for n in node.body if isinstance(n, ast.FunctionDef))
            found.update(t.id for n in node.body if isinstance(n, ast.Assign) for t in n.targets
                         if isinstance(t, ast.Name))
    return {n for n in found if re.fullmatch(r"_[A-Za-z]\w*", n)}


def test_the_layer_uses_no_private_attribute_the_list_does_not_hold():
    listed = {a.name for a in ATTRS.values()} | {n.attr for n in NAMES.values() if n.attr}
    missing = {f"kernel/{m}.py: {name}" for m, tree in _trees().items()
               for name in _private_names(tree) - OWN - listed}
    assert not missing, "private names of Numba's not in fencesweep/kernel/internals.py:\n" + "\n".join(sorted(missing))
    assert "_nrt" in _private_names(_trees()["jit"])  # the scan finds what it should


def _numba_imports(tree) -> set:
    """The modules and names of Numba and llvmlite the code imports, by statement or by name."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level:
            found.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and re.fullmatch(r"[\w.]+", node.value):
            found.add(node.value)
    return {n for n in found if n.split(".")[0] in ("numba", "llvmlite")}


def test_the_layer_takes_numbas_internals_from_the_list():
    direct = {f"kernel/{m}.py: {name}" for m, tree in _trees().items()
              for name in _numba_imports(tree) - PUBLIC_IMPORTS - PUBLIC_MODULES}
    assert not direct, "Numba's internals imported directly, not through kernel/internals.py:\n" + "\n".join(
        sorted(direct))


def test_each_listed_user_uses_the_name():
    sources = {m: (KERNEL / f"{m}.py").read_text() for m in LAYER}
    entries = [(k, n.users, {k, n.attr or n.module}) for k, n in NAMES.items()]
    entries += [(k, a.users, {k, a.name}) for k, a in ATTRS.items()]
    unused = [f"{k}: kernel/{u}.py" for k, users, words in entries for u in users
              if u not in sources or not any(w in sources[u] for w in words)]
    assert not unused, "listed users that do not use the name:\n" + "\n".join(unused)
    assert {a.kind for a in ATTRS.values()} <= {"class", "instance", "parameter"}
