"""BehaviorTree.CPP v4 XML as a mission format: what the BT.CPP set registers in the entry-point
group ``botstage.formats``, so the mission loader finds ``.xml`` files by suffix without
importing this set. A file is read with the converter that also reads back what
``botstage export`` writes (``botstage.behaviors.btcpp.machines``)."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from botstage.behaviors.btcpp.machines import ExportedConverter
from botstage.behaviors.btcpp.vocabulary import SCOPE
from botstage.behaviors.btcpp.xml_reader import Element, parse, parse_bytes
from botstage.behaviors.kinds import NodeKinds
from botstage.robots.located_yaml import Loaded, Problem, display_name
from botstage.skills.registry import Registry


def load_xml(path: str | Path, registry: Registry | None = None, kinds: NodeKinds | None = None) -> Loaded:
    """A BT.CPP XML file as a loaded mission (data, locations, problems); never raises for bad input."""
    path = Path(path)
    name = display_name(path)
    problems: list[Problem] = []
    root = parse(path, problems)
    return _loaded(root, path, name, problems, registry, kinds)


def loads_xml(
    text: str, name: str = "<xml>", registry: Registry | None = None, kinds: NodeKinds | None = None
) -> Loaded:
    """XML text as a loaded mission (for tests and tools)."""
    problems: list[Problem] = []
    root = parse_bytes(text.encode(), name, problems)
    return _loaded(root, Path(name), name, problems, registry, kinds)


def _loaded(
    root: Element | None,
    path: Path,
    name: str,
    problems: list[Problem],
    registry: Registry | None,
    kinds: NodeKinds | None,
) -> Loaded:
    converter = ExportedConverter(name, registry, kinds)
    data = None
    if root is not None:
        data = converter.document(root, path)
    problems.extend(converter.problems)
    if data is not None:
        # the mission's trees are written in BT.CPP's scope: `botstage import` keeps saying so
        data = {"name": path.stem, "nodes": SCOPE, **data}
    return Loaded(None if problems else data, converter.locations, problems, [path, *converter.files])


class XmlFormat:
    """The ``.xml`` mission format (BT.CPP v4 trees, Nav2's, and what ``botstage export`` writes)."""

    name = "xml"
    suffixes = (".xml",)

    def load(self, path: Path, include_dirs: Iterable[str | Path] = ()) -> Loaded:
        """``<include>`` paths are the file's own (relative to it); ``include_dirs`` are YAML's."""
        return load_xml(path)


XML = XmlFormat()
