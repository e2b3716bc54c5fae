"""BehaviorTree.CPP XML as plain elements that keep the line and column where each one starts.

``xml.parsers.expat`` from the standard library reports the position of every start tag, which
``xml.etree`` throws away; the importer needs it to locate its errors (``tree.xml:12:5: error: ...``).
Expat resolves no external entities, and the file is bounded by ``robots.limits``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from robots import limits
from robots.located_yaml import Location, Problem, display_name


@dataclass
class Element:
    tag: str
    attrs: dict[str, str]
    where: Location
    children: list[Element] = field(default_factory=list)


def parse(path: Path, problems: list[Problem]) -> Element | None:
    """The root element of ``path``, or None with the reason in ``problems``."""
    name = display_name(path)
    try:
        if path.stat().st_size > limits.MAX_FILE_BYTES:
            problems.append(Problem(Location(name, 1, 1), f"larger than {limits.MAX_FILE_BYTES:,} bytes"))
            return None
        data = path.read_bytes()
    except OSError as exc:
        problems.append(Problem(Location(name, 1, 1), exc.strerror or str(exc)))
        return None
    return parse_bytes(data, name, problems)


def parse_bytes(data: bytes, name: str, problems: list[Problem]) -> Element | None:
    parser = expat.ParserCreate()
    stack: list[Element] = []
    top: list[Element] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        where = Location(name, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        element = Element(tag, attrs, where)
        (stack[-1].children if stack else top).append(element)
        if len(stack) >= limits.MAX_NESTING:
            raise ValueError(f"elements nested more than {limits.MAX_NESTING} deep")
        stack.append(element)

    def end(tag: str) -> None:
        stack.pop()

    def doctype(*_: object) -> None:
        raise ValueError("a DOCTYPE is not allowed in a behaviour tree file")

    parser.StartDoctypeDeclHandler = doctype
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        problems.append(Problem(Location(name, exc.lineno, exc.offset + 1), f"not well-formed XML: {_reason(exc)}"))
        return None
    except ValueError as exc:
        where = Location(name, parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        problems.append(Problem(where, str(exc)))
        return None
    return top[0] if top else None


def _reason(exc: expat.ExpatError) -> str:
    return expat.ErrorString(exc.code) if exc.code is not None else str(exc)
