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
script every error message starts with ``FILE:LINE:``. One guard (:meth:`Shell._contain`) turns
every exception into an error line and a status, whether a command raised it (the rest of the
line runs on) or the interpreter did (the rest of the line is dropped). nsh's fixed limits are
kept (a line of :data:`~firmware.shell.parser.MAX_LINE_CHARS`, ``if`` nested
:data:`MAX_IF_DEPTH` deep, an expanded word of :data:`MAX_WORD_CHARS`, scripts
:data:`MAX_SCRIPT_DEPTH` deep), so nothing recurses in Python past a stated depth: a line from
the console or a link cannot stop the board.
"""

from __future__ import annotations

import errno
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Final

from firmware.shell.parser import (ShellLimitError, ShellSyntaxError, Word, split_statements,
                                   tokenize)

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["MAX_IF_DEPTH", "MAX_SCRIPT_DEPTH", "MAX_WORD_CHARS", "Command", "NotATextFile",
           "Shell"]

#: ``sh`` scripts running inside each other (nsh has no limit but its stack; each level here
#: is about a dozen Python frames).
MAX_SCRIPT_DEPTH: Final = 16
#: ``if`` blocks open at once in one script or at the prompt: CONFIG_NSH_NESTDEPTH of the FMUv2.
MAX_IF_DEPTH: Final = 8
#: The longest word after expansion: ``set A $A$A$A...`` would otherwise grow a variable
#: geometrically, line after line, until the host runs out of memory (the real FMU has 256 KiB).
MAX_WORD_CHARS: Final = 1024
STATUS_NOT_FOUND: Final = 127

#: a command: fn(shell, argv) -> exit status (argv[0] is the command name)
CommandFn = Callable[["Shell", list[str]], int]

_ASSIGN: Final = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)=(.*)$", re.DOTALL)


@dataclass
class Command:
    fn: CommandFn
    summary: str


class NotATextFile(OSError):
    """A file that is not UTF-8 text (a binary on the SD card given to ``sh``, ``cat`` or ``param
    import``): an OSError, so every command's existing ``except OSError`` reports it."""

    def __init__(self, byte_offset: int) -> None:
        super().__init__(errno.EILSEQ, f"not a text file (invalid UTF-8 at byte {byte_offset})")
        self.byte_offset = byte_offset


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

    @property
    def open_ifs(self) -> int:
        """``if`` blocks open at the prompt (the next lines are inside them); at most
        :data:`MAX_IF_DEPTH`."""
        return len(self._frames[0].ifs)

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
                text = self._open_text("sh", str(script), script)
                if text is None:
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
        text = self.open_text("sh", path)
        if text is None:
            return 1
        return self._run_text(text, path, list(args))

    # -- files -------------------------------------------------------------------------------------

    def read_text(self, path: Path) -> str:
        """The text of a file on the board's file system (a host path from
        :meth:`System.resolve_path`), its line ends made LF as ``Path.read_text`` makes them.

        The one way the shell reads a text file: raises ``OSError``, and :class:`NotATextFile`
        (an ``OSError`` too) for bytes that are not UTF-8, so a binary file is an error that
        says so rather than an internal error.
        """
        data = path.read_bytes()
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise NotATextFile(exc.start) from None
        return text.replace("\r\n", "\n").replace("\r", "\n")

    def open_text(self, who: str, path: str) -> str | None:
        """The text of the file at an FMU path, or None after an error line ``who: path:
        reason`` (no such file, not mounted, a directory, not a text file)."""
        from firmware.system import PathError

        try:
            host = self.system.resolve_path(path)
        except PathError as exc:
            self.error(who, str(exc))
            return None
        text = self._open_text(who, path, host)
        if text is not None and host.is_relative_to(self.system.romfs_root):
            from firmware import romfs

            text = romfs.expand(text, self.system.board)  # rc.sensors: the spec's drivers
        return text

    def _open_text(self, who: str, path: str, host: Path) -> str | None:
        try:
            return self.read_text(host)
        except OSError as exc:
            self.error(who, f"{path}: {exc.strerror or exc}")
            return None

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
        """Run one line behind the guard. A syntax error skips the line (the script goes on,
        as nsh's does); any other failure of the interpreter itself (a limit, a bug) leaves
        the ``if`` structure unknown, so the prompt drops its open blocks and a script ends
        with status 1 rather than run commands from a branch it should skip."""
        try:
            for stmt in split_statements(tokenize(line)):
                self._statement(frame, stmt)
        except _ExitScript:
            raise
        except Exception as exc:  # noqa: BLE001 - the shell's one guard (see _contain)
            self.status = self._contain("nsh", exc)
            if isinstance(exc, ShellSyntaxError) and not isinstance(exc, ShellLimitError):
                return  # a plain syntax error: nsh reports it and the if structure stands
            if frame.name is not None:
                raise _ExitScript(1) from None
            frame.ifs.clear()

    def _contain(self, who: str, exc: Exception) -> int:
        """The shell's one guard: an exception from a command or from the interpreter becomes
        an error line and exit status 1, so nothing typed on the console, a link or in a script
        can stop the board. ``who`` is the command (or ``nsh`` for the interpreter)."""
        if isinstance(exc, ShellLimitError):
            self.error("nsh", str(exc))
        elif isinstance(exc, ShellSyntaxError):
            self.error("nsh", f"syntax error: {exc}")
        elif isinstance(exc, RecursionError):
            self.error(who, "nesting too deep (Python recursion limit)")
        else:
            self.error(who, f"internal error: {type(exc).__name__}: {exc}")
        return 1

    def _syntax(self, msg: str) -> None:
        self.error("nsh", f"syntax error: {msg}")
        self.status = 1

    def _statement(self, frame: _Frame, items: list[Word | str]) -> None:
        """One statement; ``then X``, ``else X`` and ``fi X`` go on with ``X`` in a loop (not
        by recursion, so the length of such a chain costs no Python stack)."""
        while True:
            head = items[0]
            kw = head.keyword if isinstance(head, Word) else None
            rest = items[1:]
            top = frame.ifs[-1] if frame.ifs else None
            if kw == "if":
                if not rest:
                    self._syntax("'if' needs a command")
                    return
                if len(frame.ifs) >= MAX_IF_DEPTH:
                    raise ShellLimitError(f"if: nesting too deep (at most {MAX_IF_DEPTH})")
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
                if not rest:
                    return
                if isinstance(rest[0], str):
                    self._syntax(f"unexpected '{rest[0]}' after '{kw}'")
                    return
                items = rest
                continue
            if top is not None and top.state == "cond":
                self._syntax(f"expected 'then' after the 'if' on line {top.lineno}")
                return
            if frame.active:
                self._and_or(frame, items)
            return

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
        for i, arg in enumerate(argv):
            if len(arg) > MAX_WORD_CHARS:
                who = f"{argv[0]}: " if i else ""
                raise ShellLimitError(f"{who}argument too long ({len(arg)} characters, "
                                      f"at most {MAX_WORD_CHARS})")
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
        """Run one expanded command; any exception becomes an error message and status 1.

        The status is 8 bits, as a shell's ``$?`` is: PX4's ``PX4_ERROR`` (-1) reads 255.
        """
        name = argv[0]
        cmd = self.commands.get(name)
        try:
            if cmd is not None:
                return int(cmd.fn(self, argv)) & 0xFF
            if name in self.system.modules:
                return int(self.system.modules.command(name, argv[1:], self.location())) & 0xFF
        except _ExitScript:
            raise
        except Exception as exc:  # noqa: BLE001 - a module bug must not take the shell down
            return self._contain(name, exc)
        self.error("nsh", f"{name}: command not found")
        return STATUS_NOT_FOUND

    def exit_script(self, status: int) -> None:
        """``exit``: end the running script (or the session at the prompt) with ``status``
        taken to 8 bits, as sh does (``exit -1`` is 255)."""
        raise _ExitScript(status & 0xFF)
