"""A whole sweep spec from YAML: the spec itself (spec/spec.py) and its `design:` and `sensitivity:`
sections (spec/design.py, design/sensitivity.py), which build on it (sweeps/README.md). YAML is
read with duplicate keys rejected (PyYAML silently keeps the last one)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from fencesweep.model import params as P
from fencesweep.study.spec import design as D
from fencesweep.study.spec import sensitivity as SA
from fencesweep.study.spec import spec as S


class YamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader with duplicate keys rejected."""


def _construct_mapping(loader, node, deep=False):
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise S.SpecError(f"key {key!r} appears twice in the same mapping "
                              f"(line {key_node.start_mark.line + 1}); give each key once")
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


YamlLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def parse(data: Any, source: str = "", path: str | None = None) -> S.Spec:
    """A spec from its parsed YAML (a dict), with its sections. Raises SpecError on anything wrong."""
    sp = S.parse(data, source=source, path=path)
    try:
        if data.get("design") is not None:
            sp.design = D.parse_section(data["design"], sp)
        if data.get("sensitivity") is not None:
            sp.sensitivity = SA.parse_section(data["sensitivity"], sp)
    except P.ParameterError as exc:
        raise S.SpecError(str(exc)) from None
    return sp


def loads(text: str, path: str | None = None) -> S.Spec:
    """A spec from YAML text."""
    try:
        data = yaml.load(text, Loader=YamlLoader)
    except S.SpecError:
        raise
    except yaml.YAMLError as exc:
        raise S.SpecError(f"{path or 'spec'}: not valid YAML: {exc}") from None
    return parse(data, source=text, path=path)


def load(path: str | Path) -> S.Spec:
    """A spec from a YAML file."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise S.SpecError(f"cannot read spec {str(path)!r}: {exc.strerror}") from None
    return loads(text, path=str(path))
