"""AIML files to categories, with every problem located at its file:line:col.

python-aiml's ``Kernel.learn`` prints a broken file's parse error to stderr and goes on, and
prints AIML mistakes (a <pattern> outside a <category>, a bad attribute) the same way. Here each
file is parsed with python-aiml's own SAX handler, but the XML error (expat's, with its line and
column) rejects that file alone with a located ``Problem``, and each AIML mistake becomes a
``Problem`` too while the rest of the file still loads, exactly as python-aiml would load it.
"""

from __future__ import annotations

import re
import xml.sax
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aiml.AimlParser import AimlHandler, AimlParserError

from botstage.robots.located_yaml import Location, Problem, display_name

# (pattern, that, topic) -> template, as python-aiml's handler collects them
Categories = dict[tuple[str, str, str], list[Any]]

_PYAIML_LOCATION = re.compile(r"\s*\(?\(line \d+, column \d+\)\)?\s*$")


class _LocatedHandler(AimlHandler):
    """python-aiml's handler, but its mistakes are collected with their location, not printed."""

    def __init__(self, file: str) -> None:
        super().__init__(None)
        self.file = file
        self.problems: list[Problem] = []

    def _record(self, error: AimlParserError) -> None:
        # what python-aiml's wrappers do after printing: count it and skip the category
        message = " ".join(str(part) for part in error.args)
        message = _PYAIML_LOCATION.sub("", message).strip()
        line, column = self._locator.getLineNumber() or 1, (self._locator.getColumnNumber() or 0) + 1
        self.problems.append(Problem(Location(self.file, line, column), f"AIML: {message}", "category skipped"))
        self._numParseErrors += 1
        if self._state >= self._STATE_InsideCategory:
            self._skipCurrentCategory = True

    def _startElement(self, name: str, attr: Any) -> None:
        try:
            super()._startElement(name, attr)
        except AimlParserError as error:
            self._record(error)

    def _endElement(self, name: str) -> None:
        try:
            super()._endElement(name)
        except AimlParserError as error:
            self._record(error)

    def _characters(self, ch: str) -> None:
        try:
            super()._characters(ch)
        except AimlParserError as error:
            self._record(error)


@dataclass
class Learned:
    """What a set of AIML files taught: their categories, in order, and what was wrong with them."""

    categories: Categories = field(default_factory=dict)
    problems: list[Problem] = field(default_factory=list)
    files: int = 0  # files that loaded (possibly with some categories skipped)


def parse_file(path: Path) -> tuple[Categories, list[Problem]]:
    """One AIML file's categories; a file that is not well-formed XML gives none and one problem."""
    file = display_name(path)
    handler = _LocatedHandler(file)
    parser = xml.sax.make_parser()
    parser.setContentHandler(handler)
    try:
        with path.open("rb") as source:  # a file object: a path string would go through urllib
            parser.parse(source)
    except xml.sax.SAXParseException as error:
        # expat's own position of the first error; the whole file is left out, never half-learnt
        where = Location(file, error.getLineNumber() or 1, (error.getColumnNumber() or 0) + 1)
        return {}, [Problem(where, f"not well-formed XML: {error.getMessage()}", "file skipped")]
    except OSError as error:
        return {}, [Problem(Location(file, 1, 1), f"cannot read: {error.strerror or error}", "file skipped")]
    return handler.categories, handler.problems


def learn_files(paths: Iterable[Path]) -> Learned:
    """Categories of all ``paths`` in order: a later file's category replaces an earlier one's."""
    learned = Learned()
    for path in paths:
        categories, problems = parse_file(path)
        learned.problems += problems
        if categories or not any(p.hint == "file skipped" for p in problems):
            learned.files += 1
        learned.categories.update(categories)
    return learned
