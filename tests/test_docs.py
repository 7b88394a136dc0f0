"""The documentation site (mkdocs.yml, docs/index.md): built strict into a temporary directory (a
warning, e.g. a broken link or an anchor that names no heading, fails), with the API from the
docstrings, the command line from the CLI's parser and the spec reference from the spec readers.
The docs toolchain comes with the test extra (pip install -e ".[test]"; alone: ".[docs]")."""
import html
import importlib.util
import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOOLCHAIN = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")


def _generator(name: str):
    """A module of docs/gen/ (the build's generators), loaded by its path."""
    spec = importlib.util.spec_from_file_location(f"docs_gen_{name}", ROOT / "docs" / "gen" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _toolchain_missing() -> list:
    return [m for m in TOOLCHAIN if importlib.util.find_spec(m.split(".")[0]) is None
            or importlib.util.find_spec(m) is None]


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    missing = _toolchain_missing()
    if missing:
        why = f"the docs toolchain is not installed ({', '.join(missing)}): pip install -e '.[docs]'"
        if os.environ.get("CI"):
            pytest.fail(why + "; CI installs it with the test extra")
        pytest.skip(why)
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
                        "--site-dir", str(out)], capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return out


def _text(site: Path, page: str) -> str:
    """A page's article as plain text, whitespace collapsed."""
    doc = (site / page / "index.html").read_text(encoding="utf-8")
    body = doc[doc.find("<article"):doc.find("</article>")]
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", body)).split())


def _signature(name: str, func) -> str:
    """A pattern of `name(...)` with the function's parameters in their order, as the page writes them."""
    kinds = {inspect.Parameter.VAR_POSITIONAL: r"\*", inspect.Parameter.VAR_KEYWORD: r"\*\*"}
    params = [kinds.get(p.kind, "") + r"\s*" + re.escape(p.name) + r"\s*[:=,)]"
              for p in inspect.signature(func).parameters.values()]
    return re.escape(name) + r"\s*\(\s*" + r"[^()]*?".join(params)


def test_the_pages_are_built(site):
    for page in ("", "readme", "examples", "api", "cli", "spec", "sweeps", "model", "dask"):
        assert (site / page / "index.html").is_file(), page
    assert (site / "assets" / "cycle_small_far.gif").is_file()
    assert "Implementation index" in _text(site, "model")
    assert "SLURM" in _text(site, "dask")
    assert "fencesweep grid sweeps/b2k2.yaml" in _text(site, "readme")
    examples = _text(site, "examples")
    assert "One cycle" in examples and re.search(r"fencesweep\s*\.\s*grid\s*\(", examples)


def test_the_api_page_has_the_signatures(site):
    import fencesweep

    text = _text(site, "api")
    for name in ("simulate", "grid", "estimate", "design", "sensitivity", "risk", "animate", "read_table",
                 "to_xarray", "points"):
        assert f"fencesweep.{name}" in text, name
        assert re.search(_signature(name, getattr(fencesweep, name)), text), f"{name}'s signature"
    for name in ("ParameterError", "SpecError", "UsageError", "WriteError", "SweepWriteError", "SweepInterrupted",
                 "VerificationWarning", "WorkerError"):
        assert name in text, name


def test_the_cli_page_has_every_command_and_flag(site):
    from fencesweep.cli import build_parser

    text = _text(site, "cli")
    assert "--animate FILE.gif" in text and "--jobs N" in text
    commands = [a for a in build_parser()._actions if a.dest == "command"][0].choices
    for name, parser in commands.items():
        assert f"fencesweep {name}" in text, name
        for flag in (o for a in parser._actions for o in a.option_strings):
            assert flag in text, (name, flag)


def test_the_spec_page_has_every_key_with_its_default(site):
    from fencesweep.study.spec import risk as R

    text = _text(site, "spec")
    p_max = R.RiskSpec.__dataclass_fields__["p_max"].default
    assert f"p_max number in (0, 1) {p_max:g}" in text
    for name in ("chunk_size", "envelope", "corners", "popsize", "too_large", "dalpha_perm", "Psi"):
        assert f"{name}" in text, name


def test_a_spec_key_without_a_row_stops_the_build():
    spec_ref = _generator("spec_ref")
    spec_ref.check(spec_ref._sections())  # the reference covers every key the readers accept today
    with pytest.raises(ValueError, match=r"keys without a row here: \['new_key'\]"):
        spec_ref.check([("`risk:`", "", ("p_max", "new_key"), [("p_max", "number", 0.001, "...")])])


def test_the_repository_links_point_at_the_site():
    pages = _generator("repo_pages")
    assert pages.site_links("[d](../docs/dask.md)", "sweeps/README.md") == "[d](dask.md)"
    assert pages.site_links("[s](sweeps/README.md#a-full-disk)", "README.md") == "[s](sweeps.md#a-full-disk)"
    assert pages.site_links("[`b`](benchmarks/README.md)", "README.md") == "`b`"
    assert pages.site_links("[x](https://example.org/a.md)", "README.md") == "[x](https://example.org/a.md)"
