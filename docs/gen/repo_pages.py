"""The repository's own Markdown as pages of the site, written when it is built (hooks.py): README.md
whole (readme.md) and its examples (examples.md), sweeps/README.md (sweeps.md). Their text is taken
as it is; only their links are pointed at the site's pages (TARGETS), as GitHub's are at the files.
"""
from __future__ import annotations

import posixpath
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: a file the repository's Markdown links to -> where it is on the site (None: not on the site; the
#: link becomes its text). A link to a file not named here is left as it is, and a strict build names it.
TARGETS = {
    "README.md": "readme.md",
    "docs/index.md": "index.md",
    "docs/model.md": "model.md",
    "docs/dask.md": "dask.md",
    "sweeps/README.md": "sweeps.md",
    "results/figures/cycle_small_far.gif": "assets/cycle_small_far.gif",
    "benchmarks/README.md": None,
}
#: anchors that name no heading of their page (on GitHub either) -> the heading meant (none today)
ANCHORS: dict = {}
#: the README's sections that are its examples, in the order of the examples page
EXAMPLES = ("One cycle", "Python API", "Python API for sweeps")
LINK = re.compile(r"\[([^\]]*)\]\(([^)\s]+)\)")


def site_links(text: str, source: str) -> str:
    """`text`, the Markdown of the repository's file `source`, with its links to TARGETS pointed at the site."""
    def one(m: re.Match) -> str:
        label, url = m.group(1), m.group(2)
        if "://" in url or url.startswith(("#", "mailto:")):
            return m.group(0)
        path, _, anchor = url.partition("#")
        repo_path = posixpath.normpath(posixpath.join(posixpath.dirname(source), path))
        if repo_path not in TARGETS:
            return m.group(0)
        if TARGETS[repo_path] is None:
            return label
        anchor = ANCHORS.get(anchor, anchor)
        return f"[{label}]({TARGETS[repo_path]}{'#' + anchor if anchor else ''})"

    return LINK.sub(one, text)


def sections(text: str) -> dict:
    """The `## ` sections of a Markdown text by title, each with its heading."""
    found, title = {}, None
    for line in text.splitlines(keepends=True):
        if line.startswith("## "):
            title = line[3:].strip()
            found[title] = ""
        if title is not None:
            found[title] += line
    return found


def examples(readme: str) -> str:
    have = sections(readme)
    missing = [t for t in EXAMPLES if t not in have]
    if missing:
        raise ValueError(f"README.md has no section {missing[0]!r}: docs/gen/repo_pages.py EXAMPLES names the "
                         f"README's sections that are its examples")
    head = ("# Examples\n\nThe README's examples ([README](readme.md): " + ", ".join(EXAMPLES) + "), taken from it "
            "when this site is built.\n\n")
    return head + "\n".join(have[t] for t in EXAMPLES)


def pages() -> dict:
    """{page: Markdown} of the repository's Markdown on the site."""
    readme = site_links((ROOT / "README.md").read_text(encoding="utf-8"), "README.md")
    sweeps = site_links((ROOT / "sweeps" / "README.md").read_text(encoding="utf-8"), "sweeps/README.md")
    return {"readme.md": readme, "examples.md": examples(readme), "sweeps.md": sweeps}


def assets() -> dict:
    """{site path: the repository's file} of the files the pages show."""
    return {site: ROOT / repo for repo, site in TARGETS.items() if site and not site.endswith(".md")}
