"""Tokens of the nsh command language: words, quotes, variables, ``;``, ``&&`` and ``||``.

A line is split into words before anything runs; variables are expanded only when a statement
is executed, so ``$?`` after a command sees that command's status and words in a branch that is
not taken are never expanded. Quoting follows sh: single quotes are literal, double quotes
expand ``$VAR``, a backslash escapes one character, ``#`` at the start of a word begins a
comment.

A line is bounded as nsh bounds it on the FMUv2 (``CONFIG_NSH_LINELEN=128`` in PX4's
``boards/px4/fmu-v2/nuttx-config/nsh/defconfig``: 127 characters and the terminator). nsh's
readline cuts a longer line and runs the pieces as separate commands; here the whole line is
refused with :class:`ShellLimitError`, so half a command never runs. The bound also bounds
everything the interpreter does with one line (words, operators, ``then`` chains).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Final

__all__ = ["MAX_LINE_CHARS", "OPERATORS", "ShellLimitError", "ShellSyntaxError", "Word",
           "split_statements", "tokenize"]

#: The longest line nsh reads (CONFIG_NSH_LINELEN - 1 on the FMUv2).
MAX_LINE_CHARS: Final = 127

OPERATORS: Final[tuple[str, ...]] = (";", "&&", "||")

_VAR: Final = re.compile(r"\$(?:\{([A-Za-z_][A-Za-z0-9_]*|[0-9]+|[?#])\}|([A-Za-z_][A-Za-z0-9_]*)"
                  r"|([0-9?#]))")


class ShellSyntaxError(ValueError):
    """A line that cannot be split into words (an unterminated quote, a dangling operator)."""


class ShellLimitError(ShellSyntaxError):
    """Input beyond one of nsh's fixed limits (line length, ``if`` nesting, the length of an
    expanded word). Its message is nsh's, without the ``syntax error`` prefix."""


class Word:
    """One word as typed: parts of text, each unquoted (``""``), single (``"'"``) or double
    (``'"'``) quoted, so expansion and keyword detection can see what was quoted."""

    __slots__ = ("parts",)

    def __init__(self, parts: list[tuple[str, str]]) -> None:
        self.parts = parts

    @property
    def keyword(self) -> str | None:
        """The text if the word is entirely unquoted (only then can it be ``if``, ``fi``...)."""
        if len(self.parts) == 1 and self.parts[0][0] == "":
            return self.parts[0][1]
        return None

    def expand(self, lookup: Callable[[str], str]) -> str:
        out = []
        for quote, text in self.parts:
            if quote == "'":
                out.append(text)
            else:
                out.append(_VAR.sub(lambda m: lookup(m.group(1) or m.group(2) or m.group(3)),
                                    text))
        return "".join(out)

    def __repr__(self) -> str:
        return f"Word({self.parts!r})"


def tokenize(line: str) -> list[Word | str]:
    """Words and operator strings of one line; comments dropped.

    Raises :class:`ShellSyntaxError` (an unterminated quote) or its subclass
    :class:`ShellLimitError` (a line longer than :data:`MAX_LINE_CHARS`), nothing else.
    """
    if len(line) > MAX_LINE_CHARS:
        raise ShellLimitError(f"line too long ({len(line)} characters, at most {MAX_LINE_CHARS})")
    tokens: list[Word | str] = []
    parts: list[tuple[str, str]] = []
    buf: list[str] = []
    in_word = False
    i, n = 0, len(line)

    def flush_buf(quote: str = "") -> None:
        if buf:
            parts.append((quote, "".join(buf)))
            buf.clear()

    def end_word() -> None:
        nonlocal in_word
        flush_buf()
        if in_word:
            tokens.append(Word(list(parts)))
            parts.clear()
        in_word = False

    while i < n:
        c = line[i]
        if c in " \t\r\n":
            end_word()
            i += 1
        elif c == "#" and not in_word:
            break
        elif c == ";" or line.startswith(("&&", "||"), i):
            end_word()
            op = ";" if c == ";" else line[i:i + 2]
            tokens.append(op)
            i += len(op)
        elif c == "\\":
            in_word = True
            if i + 1 < n:
                flush_buf()
                parts.append(("'", line[i + 1]))
            i += 2
        elif c in "'\"":
            in_word = True
            flush_buf()
            end = i + 1
            text: list[str] = []
            while end < n and line[end] != c:
                ch = line[end]
                if c == '"' and ch == "\\" and end + 1 < n and line[end + 1] in '"\\$':
                    parts.append((c, "".join(text)))   # escaped char stays literal
                    text.clear()
                    parts.append(("'", line[end + 1]))
                    end += 2
                    continue
                text.append(ch)
                end += 1
            if end >= n:
                raise ShellSyntaxError(f"unterminated {c} quote")
            parts.append((c, "".join(text)))
            i = end + 1
        else:
            in_word = True
            buf.append(c)
            i += 1
    end_word()
    return tokens


def split_statements(tokens: list[Word | str]) -> list[list[Word | str]]:
    """Split on ``;``; each statement keeps its ``&&``/``||`` operators. Empty ones dropped."""
    out: list[list[Word | str]] = [[]]
    for t in tokens:
        if t == ";":
            out.append([])
        else:
            out[-1].append(t)
    for stmt in out:
        if stmt and (isinstance(stmt[0], str) or isinstance(stmt[-1], str)):
            raise ShellSyntaxError(f"operator {stmt[0] if isinstance(stmt[0], str) else stmt[-1]}"
                                   " needs a command on both sides")
    return [s for s in out if s]
