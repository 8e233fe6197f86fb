"""The nsh-like shell of the emulated FMU: one interpreter for the console, scripts and links.

``Shell.execute(line)`` runs one line and writes everything to an output callback, so the same
shell can sit behind the console UART, a TCP socket or MAVLink SERIAL_CONTROL. Scripts
(``run_script``, ``sh FILE``) use the same interpreter line by line, as NuttX's nsh does; the
subset is what PX4's ROMFS needs:

- ``if CMD`` / ``then`` / ``else`` / ``fi`` on their own statements (``;`` may join them),
  nested; the condition is a command's exit status (``[ ... ]``, ``param compare``, ``ver
  hwcmp``); ``!`` negates;
- ``set VAR value``, ``unset VAR``, ``VAR=value``, ``$VAR``, ``${VAR}``, ``$?``, ``$1``..;
- ``&&`` and ``||``; ``#`` comments; ``sh FILE [args]``; ``exit [n]``.

Errors never leave the shell: a failing command sets its status and the next line runs. In a
script every error message starts with ``FILE:LINE:``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Final

from mypy_extensions import mypyc_attr

from firmware.shell.parser import ShellSyntaxError, Word, split_statements, tokenize

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["MAX_SCRIPT_DEPTH", "Command", "Shell"]

MAX_SCRIPT_DEPTH: Final = 16
STATUS_NOT_FOUND: Final = 127

#: a command: fn(shell, argv) -> exit status (argv[0] is the command name)
CommandFn = Callable[["Shell", list[str]], int]

_ASSIGN: Final = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)=(.*)$", re.DOTALL)


@dataclass
class Command:
    fn: CommandFn
    summary: str


@mypyc_attr(native_class=False)
class _ExitScript(Exception):
    def __init__(self, status: int) -> None:
        self.status = status


@dataclass
class _If:
    lineno: int
    parent_active: bool
    cond: bool
    state: str = "cond"      # "cond" (waiting for then), "then", "else"

    @property
    def active(self) -> bool:
        if not self.parent_active or self.state == "cond":
            return False
        return self.cond if self.state == "then" else not self.cond


@dataclass
class _Frame:
    """One script being run (or the interactive session, ``name=None``)."""

    name: str | None
    args: list[str] = field(default_factory=list)
    lineno: int = 0
    ifs: list[_If] = field(default_factory=list)

    @property
    def active(self) -> bool:
        return not self.ifs or self.ifs[-1].active


class Shell:
    """An nsh session on one :class:`System`; ``output`` receives text (with newlines)."""

    prompt = "nsh> "

    def __init__(self, system: System, output: Callable[[str], None] | None = None) -> None:
        from firmware.shell import commands

        self.system = system
        self.output: Callable[[str], None] = (output if output is not None
                                              else system.write_background)
        self.env: dict[str, str] = {}
        self.status = 0
        self.exited = False
        self._frames: list[_Frame] = [_Frame(None)]
        self.commands: dict[str, Command] = commands.builtin_commands()

    # -- output ------------------------------------------------------------------------------------

    def write(self, text: str) -> None:
        self.output(text)

    def print(self, text: str = "") -> None:
        self.output(text + "\n")

    def location(self) -> str:
        """``FILE:LINE: `` inside a script, empty at the prompt."""
        f = self._frames[-1]
        return f"{f.name}:{f.lineno}: " if f.name is not None else ""

    def error(self, who: str, msg: str) -> None:
        """An error line: ``[FILE:LINE: ]who: msg``."""
        self.print(f"{self.location()}{who}: {msg}")

    def usage(self, lines: Sequence[str]) -> int:
        """Print usage lines and return the status of a bad invocation (1)."""
        for line in lines:
            self.print(line)
        return 1

    # -- entry points ------------------------------------------------------------------------------

    def execute(self, line: str) -> int:
        """Run one line at the prompt; returns its exit status (also in ``$?``)."""
        with self.system.redirect(self.output):
            try:
                self._line(self._frames[0], line)
            except _ExitScript as exc:
                self.status = exc.status
                self.exited = True
        return self.status

    def run_script(self, script: str | Path, args: Sequence[str] = (), *,
                   name: str | None = None) -> int:
        """Run a script: a host :class:`Path`, an FMU path (``/etc/init.d/rcS``, a one-line
        string starting with ``/``) or script text; returns the status of its last command."""
        with self.system.redirect(self.output):
            if isinstance(script, Path):
                try:
                    text = script.read_text()
                except OSError as exc:
                    self.error("sh", f"cannot open {script}: {exc.strerror}")
                    return 1
                return self._run_text(text, name or str(script), list(args))
            if script.startswith("/") and "\n" not in script:
                return self._run_path(script.strip(), args)
            return self._run_text(script, name or "<script>", list(args))

    def run_file(self, path: str, args: Sequence[str] = ()) -> int:
        """Run the script at an FMU path (what ``sh PATH`` does)."""
        with self.system.redirect(self.output):
            return self._run_path(path, args)

    def _run_path(self, path: str, args: Sequence[str]) -> int:
        from firmware.system import PathError

        try:
            text = self.system.resolve_path(path).read_text()
        except PathError as exc:
            self.error("sh", str(exc))
            return 1
        except OSError as exc2:
            self.error("sh", f"cannot open {path}: {exc2.strerror or exc2}")
            return 1
        return self._run_text(text, path, list(args))

    # -- scripts -----------------------------------------------------------------------------------

    def _run_text(self, text: str, name: str, args: list[str]) -> int:
        if len(self._frames) > MAX_SCRIPT_DEPTH:
            self.error("sh", f"{name}: scripts nested more than {MAX_SCRIPT_DEPTH} deep")
            self.status = 1
            return 1
        frame = _Frame(name, [name] + args)
        self._frames.append(frame)
        self.status = 0
        try:
            for lineno, line in enumerate(text.splitlines(), 1):
                frame.lineno = lineno
                self._line(frame, line)
            if frame.ifs:
                frame.lineno = frame.ifs[-1].lineno
                self.error("nsh", "'if' without a matching 'fi'")
                self.status = 1
        except _ExitScript as exc:
            self.status = exc.status
        finally:
            self._frames.pop()
        return self.status

    def _line(self, frame: _Frame, line: str) -> None:
        try:
            statements = split_statements(tokenize(line))
        except ShellSyntaxError as exc:
            self.error("nsh", f"syntax error: {exc}")
            self.status = 1
            return
        for stmt in statements:
            self._statement(frame, stmt)

    def _syntax(self, msg: str) -> None:
        self.error("nsh", f"syntax error: {msg}")
        self.status = 1

    def _statement(self, frame: _Frame, items: list[Word | str]) -> None:
        head = items[0]
        kw = head.keyword if isinstance(head, Word) else None
        rest = items[1:]
        top = frame.ifs[-1] if frame.ifs else None
        if kw == "if":
            if not rest:
                self._syntax("'if' needs a command")
                return
            parent = frame.active
            cond = self._and_or(frame, rest) == 0 if parent else False
            frame.ifs.append(_If(frame.lineno, parent, cond))
            return
        if kw in ("then", "else", "fi"):
            want = {"then": ("cond",), "else": ("then",), "fi": ("then", "else")}[kw]
            if top is None or top.state not in want:
                where = f" (the 'if' is on line {top.lineno})" if top is not None else ""
                self._syntax(f"unexpected '{kw}'{where}")
                return
            if kw == "fi":
                frame.ifs.pop()
            else:
                top.state = kw
            if rest:
                if isinstance(rest[0], str):
                    self._syntax(f"unexpected '{rest[0]}' after '{kw}'")
                    return
                self._statement(frame, rest)
            return
        if top is not None and top.state == "cond":
            self._syntax(f"expected 'then' after the 'if' on line {top.lineno}")
            return
        if frame.active:
            self._and_or(frame, items)

    def _and_or(self, frame: _Frame, items: list[Word | str]) -> int:
        """Run ``a && b || c`` left to right, sh style."""
        status = 0
        run_next = True
        cmd: list[Word] = []
        for item in items + ["&&"]:
            if isinstance(item, Word):
                cmd.append(item)
                continue
            if run_next:
                status = self._simple(frame, cmd)
            cmd = []
            run_next = (status == 0) if item == "&&" else (status != 0)
        return status

    def lookup(self, name: str) -> str:
        """The value of ``$name``: ``?``, ``#``, positional arguments, then variables."""
        if name == "?":
            return str(self.status)
        frame = self._frames[-1]
        if name == "#":
            return str(max(len(frame.args) - 1, 0))
        if name.isdigit():
            i = int(name)
            return frame.args[i] if i < len(frame.args) else ""
        return self.env.get(name, "")

    def _simple(self, frame: _Frame, words: list[Word]) -> int:
        argv = [w.expand(self.lookup) for w in words]
        negate = False
        while argv and argv[0] == "!" and words[0].keyword == "!":
            negate = not negate
            argv, words = argv[1:], words[1:]
        if not argv:
            self.status = 0 if not negate else 1
            return self.status
        m = _ASSIGN.match(argv[0])
        if len(argv) == 1 and m and words[0].parts[0][0] == "":
            self.env[m.group(1)] = m.group(2)
            status = 0
        else:
            status = self.run_command(argv)
        if negate:
            status = 0 if status else 1
        self.status = status
        return status

    def run_command(self, argv: list[str]) -> int:
        """Run one expanded command; any exception becomes an error message and status 1."""
        name = argv[0]
        cmd = self.commands.get(name)
        try:
            if cmd is not None:
                return int(cmd.fn(self, argv))
            if name in self.system.modules:
                return int(self.system.modules.command(name, argv[1:], self.location()))
        except _ExitScript:
            raise
        except Exception as exc:  # noqa: BLE001 - a module bug must not take the shell down
            self.error(name, f"internal error: {type(exc).__name__}: {exc}")
            return 1
        self.error("nsh", f"{name}: command not found")
        return STATUS_NOT_FOUND

    def exit_script(self, status: int) -> None:
        """``exit``: end the running script (or the session at the prompt)."""
        raise _ExitScript(status)
