"""BehaviorTree.CPP XML as plain elements that keep the line and column where each one starts.

``xml.parsers.expat`` from the standard library reports the position of every start tag, which
``xml.etree`` throws away; the importer needs it to locate its errors (``tree.xml:12:5: error: ...``).
Expat resolves no external entities, and the file is bounded by ``botstage.robots.limits``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from botstage.robots import limits
from botstage.robots.located_yaml import Location, Problem, display_name


@dataclass
class Element:
    tag: str
    attrs: dict[str, str]
    where: Location
    children: list[Element] = field(default_factory=list)
    values_at: dict[str, Location] = field(default_factory=dict)  # where each attribute's value starts
    raw_values: dict[str, str] = field(default_factory=dict)  # each attribute's value as written

    def value_at(self, attr: str, offset: int = 0) -> Location:
        """Where character ``offset`` of an attribute's (parsed) value is written: entities such as
        ``&gt;`` count as the one character they stand for, and a value may span lines. The
        element's start if the attribute is unknown."""
        start = self.values_at.get(attr)
        if start is None:
            return self.where
        line, col = start.line, start.col
        raw = self.raw_values.get(attr, "")
        pos = 0
        for _ in range(offset):
            if pos >= len(raw):
                col += 1
                continue
            end = raw.find(";", pos) + 1 if raw[pos] == "&" and ";" in raw[pos:] else pos + 1
            if raw[pos] == "\n":
                line, col = line + 1, 1
            else:
                col += len(raw[pos:end].encode())
            pos = end
        return Location(start.file, line, col)


# an attribute in a start tag: its name, then its quoted value
_ATTRIBUTE = re.compile(rb"""\s+([^\s=/>]+)\s*=\s*("[^"]*"|'[^']*')""")


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
        values_at, raw_values = _values_at(data, parser.CurrentByteIndex, where)
        element = Element(tag, attrs, where, values_at=values_at, raw_values=raw_values)
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


def _values_at(data: bytes, start: int, where: Location) -> tuple[dict[str, Location], dict[str, str]]:
    """The line and column where each attribute value of the start tag at byte ``start`` begins,
    and the values as written (columns count bytes, as expat's do)."""
    found: dict[str, Location] = {}
    raw: dict[str, str] = {}
    tag = re.match(rb"<[^\s/>]+", data[start : start + 1000])
    if tag is None:
        return found, raw
    pos = start + tag.end()
    line, line_start = where.line, start - (where.col - 1)
    while (match := _ATTRIBUTE.match(data, pos)) is not None:
        value = match.start(2) + 1
        newlines = data.count(b"\n", pos, value)
        if newlines:
            line += newlines
            line_start = data.rfind(b"\n", pos, value) + 1
        name = match.group(1).decode(errors="replace")
        found[name] = Location(where.file, line, value - line_start + 1)
        raw[name] = match.group(2)[1:-1].decode(errors="replace")
        pos = match.end()
        newlines = data.count(b"\n", value, pos)
        if newlines:
            line += newlines
            line_start = data.rfind(b"\n", value, pos) + 1
    return found, raw


def _reason(exc: expat.ExpatError) -> str:
    return expat.ErrorString(exc.code) if exc.code is not None else str(exc)
