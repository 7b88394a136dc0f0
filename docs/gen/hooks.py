"""mkdocs hooks (mkdocs.yml `hooks:`): the pages generated when the site is built, so that they
cannot drift from the code and the repository's Markdown: the command line from the CLI's parser
(cli_ref.py), the spec reference from the spec readers (spec_ref.py), the README, its examples and
sweeps/README.md with their links pointed at the site (repo_pages.py)."""
from __future__ import annotations

import importlib.util
from pathlib import Path

from mkdocs.structure.files import File

HERE = Path(__file__).resolve().parent


def _load(name: str):
    """A module of this directory, by its path (it is not a package, and its names are plain)."""
    spec = importlib.util.spec_from_file_location(f"fencesweep_docs_{name}", HERE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def on_files(files, config):
    repo_pages, cli_ref, spec_ref = _load("repo_pages"), _load("cli_ref"), _load("spec_ref")
    generated = dict(repo_pages.pages(), **{"cli.md": cli_ref.page(), "spec.md": spec_ref.page()})
    for uri, text in generated.items():
        files.append(File.generated(config, uri, content=text))
    for uri, path in repo_pages.assets().items():
        files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files
