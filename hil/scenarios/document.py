"""A scenario file as a YAML document: read safely, bounded before it is checked.

The scenario checks in :mod:`hil.scenarios.model` walk the document recursively and print
offending values; this module makes sure that is safe for any file: PyYAML's composer gets a
depth limit, the document's expanded size (aliases counted at every use) and cycles are checked
iteratively, and messages show values cut short.
"""

from __future__ import annotations

import reprlib
from typing import Any

import yaml

__all__ = ["MAX_DEPTH", "MAX_FILE_BYTES", "MAX_NODES", "ScenarioError", "check_shape",
           "parse_yaml", "short_repr"]

#: deepest nesting of a document (the real ones nest 6 levels): PyYAML's composer and the
#: condition parser recurse, so depth is refused before it reaches Python's recursion limit
MAX_DEPTH = 48
#: most values a document may expand to, aliases counted at every use (the library's largest
#: file has a few hundred): an alias bomb ("billion laughs") is refused before it is walked
MAX_NODES = 20_000
#: bytes of a scenario file (the library's largest is a few kB)
MAX_FILE_BYTES = 1 << 20
#: how much of an offending value an error message shows
_REPR = reprlib.Repr()
_REPR.maxstring = _REPR.maxother = 60
_REPR.maxlist = _REPR.maxdict = _REPR.maxtuple = _REPR.maxset = 6
_REPR.maxlevel = 3


class ScenarioError(ValueError):
    """A scenario that cannot be loaded or run as written (the message says where)."""


def short_repr(v: Any) -> str:
    """A value for an error message, cut short: a fuzzed or aliased value may be huge."""
    return _REPR.repr(v)


def check_shape(data: Any) -> None:
    """Refuse a document too deep, too large once its aliases are expanded, or referring to
    itself (YAML anchors can build cycles), before anything walks it recursively.

    Works iteratively with the expanded size of every container memoised by identity, so a
    shared (aliased) sub-tree is measured once however often it is used.
    """
    size: dict[int, int] = {}
    on_path: set[int] = set()
    stack: list[tuple[Any, int, bool]] = [(data, 1, False)]
    while stack:
        node, depth, done = stack.pop()
        if not isinstance(node, (dict, list, tuple)):
            continue
        key = id(node)
        children = list(node.keys()) + list(node.values()) if isinstance(node, dict) \
            else list(node)
        if done:
            on_path.discard(key)
            size[key] = 1 + sum(size.get(id(c), 1) for c in children)
            if size[key] > MAX_NODES:
                raise ScenarioError(f"the document expands to more than {MAX_NODES} values "
                                    f"(YAML aliases used too often?)")
            continue
        if key in size:
            continue
        if key in on_path:
            raise ScenarioError("the document refers to itself (a YAML alias inside its own "
                                "anchor)")
        if depth > MAX_DEPTH:
            raise ScenarioError(f"the document nests deeper than {MAX_DEPTH} levels")
        on_path.add(key)
        stack.append((node, depth, True))
        stack.extend((c, depth + 1, False) for c in children)


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader with a depth limit: its composer recurses once per level, so a
    deeply nested document would otherwise end in RecursionError."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise yaml.composer.ComposerError(
                    None, None, f"nested deeper than {MAX_DEPTH} levels",
                    self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def parse_yaml(text: str, source: str) -> Any:
    """The YAML document in ``text``, or ScenarioError naming ``source`` and the line.

    Besides its own YAMLError, PyYAML's safe constructors let ValueError, TypeError,
    AttributeError and OverflowError out on some malformed scalars (``!!timestamp 1``,
    ``2001-13-45``, ``!!int`` of a huge float); they are the document's fault, so they are
    reported the same way.
    """
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ScenarioError(f"{source}: not valid YAML{at}: "
                            f"{getattr(exc, 'problem', None) or exc}") from None
    except (ValueError, TypeError, AttributeError, OverflowError, RecursionError) as exc:
        raise ScenarioError(f"{source}: not valid YAML: a value PyYAML cannot build "
                            f"({type(exc).__name__}: {short_repr(str(exc))})") from None
