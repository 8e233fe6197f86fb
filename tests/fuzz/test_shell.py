"""Fuzzing the nsh shell: its tokenizer alone, and whole lines and scripts on a booted FMU.

Anyone on the console (pty or TCP), a MAVLink SERIAL_CONTROL link or the SD card's scripts
feeds the shell text. The inputs are random text, lines built from nsh's own vocabulary
(if/then/else/fi, ``&&``, ``||``, ``;``, quotes, variables, the board's real commands), nested
blocks deeper than nsh allows, lines longer than it reads, and mutations of real lines (the
ROMFS's own scripts and a list of everyday commands: bit flips, truncations, splices).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware.shell import Shell
from firmware.shell.interpreter import MAX_IF_DEPTH
from firmware.shell.parser import (MAX_LINE_CHARS, OPERATORS, ShellSyntaxError, Word,
                                   split_statements, tokenize)
from tests.fuzzing import fuzz

ROMFS = Path(__file__).resolve().parents[2] / "firmware" / "romfs" / "init.d"

#: Everyday console lines; none reboots or reruns the boot (the board is shared).
EVERYDAY = [
    "echo hello world", "help", "help param", "ver all", "ver hwcmp PX4_FMU_V2", "ps", "free",
    "dmesg", "top once", "perf", "work_queue status", "uorb status", "uorb top once",
    "listener sensor_combined -n 2", "listener vehicle_status", "param show SYS_",
    "param show -c", "param get SYS_AUTOSTART", "param set SDLOG_PROFILE 3",
    "param compare SYS_AUTOSTART 4011", "param greater SYS_AUTOSTART 10", "param status",
    "param export f.params", "param import f.params", "commander status", "ekf2 status",
    "mavlink status", "logger status", "px4io status", "sensors status", "mixer",
    "set X 1", "unset X", "X=2", "echo $X ${X}x $? $# $0 $1", "[ $X = 2 ] && echo yes || echo no",
    "test 1 -lt 2 -a ! -z x", "if [ 1 -eq 1 ]; then echo a; else echo b; fi", "! false",
    "ls /etc/init.d", "cat /etc/init.d/rc.autostart", "true; false; echo $?", "exit 3",
    "echo 'single $X' \"double $X\" a\\ b # comment", "if param compare SYS_AUTOSTART 0",
    "then", "else", "fi",
]


def _romfs_lines() -> list[str]:
    """Real nsh lines: the ROMFS scripts, without the lines that start modules or run other
    scripts (the board is shared by the examples: they would rerun the boot)."""
    lines = []
    for path in sorted(ROMFS.rglob("*")):
        if path.is_file():
            for line in path.read_text().splitlines():
                words = line.split()
                if words and not words[0].startswith("#") and "start" not in words \
                        and "sh" not in words:
                    lines.append(line)
    return lines


REAL_LINES = EVERYDAY + _romfs_lines()

VOCABULARY = ["if", "then", "else", "fi", "!", "&&", "||", ";", "[", "]", "=", "!=", "-eq",
              "-lt", "-f", "-z", "-a", "-o", "true", "false", "echo", "set", "unset", "test",
              "param", "get", "set", "compare", "show", "ver", "hwcmp", "help", "exit", "sh",
              "cat", "ls", "listener", "uorb", "top", "once", "status", "commander", "mavlink",
              "$A", "${A}", "$?", "$#", "$1", "$", "${", "'q $A'", "\"d $A\"", "\"", "'", "\\",
              "#", "A=1", "SYS_AUTOSTART", "/etc/init.d", "/fs/microsd/x", "..", "-1", "0x7f"]


@st.composite
def mutated(draw: st.DrawFn, corpus: list[str]) -> str:
    """A real line, bit-flipped, truncated, duplicated or spliced with another."""
    line = draw(st.sampled_from(corpus))
    for _ in range(draw(st.integers(0, 3))):
        how = draw(st.sampled_from(["flip", "cut", "splice", "repeat", "insert"]))
        if how == "flip" and line:
            i = draw(st.integers(0, len(line) - 1))
            bit = 1 << draw(st.integers(0, 7))
            line = line[:i] + chr(ord(line[i]) ^ bit) + line[i + 1:]
        elif how == "cut":
            line = line[:draw(st.integers(0, len(line)))]
        elif how == "splice":
            other = draw(st.sampled_from(corpus))
            line = line[:draw(st.integers(0, len(line)))] + \
                other[draw(st.integers(0, len(other))):]
        elif how == "repeat":
            line = (line + draw(st.sampled_from([" ", ";", " && ", " || "]))) * \
                draw(st.integers(2, 20))
        else:
            i = draw(st.integers(0, len(line)))
            line = line[:i] + draw(st.sampled_from(VOCABULARY)) + line[i:]
    return line


def nested(depth: st.SearchStrategy[int]) -> st.SearchStrategy[str]:
    """``if`` blocks nested around a command, as deep as nsh allows and deeper."""
    return st.builds(lambda n, cond, body, close: "if " + cond + ";then " + ("if true;then " *
                     (n - 1)) + body + ";" + "fi;" * close,
                     depth, st.sampled_from(["true", "false", "[ $A = 1 ]", "! true"]),
                     st.sampled_from(["echo x", "false", "set A 1", "X=1"]), depth)


def from_vocabulary() -> st.SearchStrategy[str]:
    return st.lists(st.sampled_from(VOCABULARY), max_size=40).map(" ".join)


LINES = st.one_of(
    st.text(max_size=MAX_LINE_CHARS + 20),
    from_vocabulary(),
    mutated(REAL_LINES),
    nested(st.integers(1, MAX_IF_DEPTH + 3)),
    st.builds(lambda n, s: s * n, st.integers(1, 2000), st.sampled_from(
        ["if true; ", "then fi ", "x", "$A", "\"", "! ", "&& ", "\\"])),
)


# -- the tokenizer alone -------------------------------------------------------------------------

@fuzz(examples=1200)
@given(st.one_of(st.text(max_size=MAX_LINE_CHARS + 5), from_vocabulary(), mutated(REAL_LINES)))
def test_tokenizer_returns_words_or_a_syntax_error(line: str) -> None:
    """Invariant: ``tokenize`` and ``split_statements`` return words and operators (no empty
    statement, none starting or ending with an operator) or raise ShellSyntaxError (its
    ShellLimitError for a line over MAX_LINE_CHARS), nothing else; every word expands to text."""
    try:
        statements = split_statements(tokenize(line))
    except ShellSyntaxError:
        return
    assert len(line) <= MAX_LINE_CHARS
    for stmt in statements:
        assert stmt and isinstance(stmt[0], Word) and isinstance(stmt[-1], Word)
        for item in stmt:
            assert isinstance(item, Word) or item in OPERATORS
            if isinstance(item, Word):
                assert isinstance(item.expand(lambda name: "v"), str)


# -- the shell on a booted FMU -------------------------------------------------------------------

@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory):
    from fmu.board import FmuV2Board

    board = FmuV2Board(seed=3, sd_root=str(tmp_path_factory.mktemp("sd")))
    board.advance(1_500_000_000, [])
    return board


def _fresh_shell(board) -> tuple[Shell, list[str]]:
    out: list[str] = []
    return Shell(board.system, out.append), out


def _no_internal_failure(text: str) -> None:
    """The shell's guard contained nothing: its "internal error" (a command or the
    interpreter raised) and "recursion" (Python's stack ran out) lines are bugs, however
    politely printed; bad input has nsh's own messages."""
    lowered = text.lower()
    assert "internal error" not in lowered and "recursion" not in lowered, text


def _still_answers(sh: Shell, out: list[str]) -> None:
    """Close what the input left open (as a person would), then ``echo ok`` must work."""
    assert 0 <= sh.open_ifs <= MAX_IF_DEPTH
    for _ in range(MAX_IF_DEPTH):
        if not sh.open_ifs:
            break
        sh.execute("then")
        sh.execute("fi")
    assert sh.open_ifs == 0
    out.clear()
    assert sh.execute("echo ok") == 0 and "".join(out) == "ok\n"


@fuzz(examples=1000)
@given(LINES)
def test_console_lines_never_stop_the_shell(fmu, line: str) -> None:
    """Invariant: every line returns an exit status in 0..255 and raises nothing (errors are
    nsh's lines of output, never "internal error" or "recursion": the guard caught nothing);
    at most MAX_IF_DEPTH blocks stay open; the shell then runs ``echo ok``."""
    sh, out = _fresh_shell(fmu)
    sh.env["A"] = "1"
    status = sh.execute(line)
    assert isinstance(status, int) and 0 <= status <= 255
    assert all(isinstance(chunk, str) for chunk in out)
    _no_internal_failure("".join(out))
    _still_answers(sh, out)


@fuzz(examples=250)
@given(st.lists(LINES, min_size=1, max_size=12), st.booleans())
def test_scripts_never_stop_the_shell(fmu, lines: list[str], as_file: bool) -> None:
    """Invariant: a script (text, or a file on the SD card run by ``sh``) returns a status in
    0..255, raises nothing, prints no "internal error" or "recursion", leaves no block open at
    the prompt; the shell then runs ``echo ok``."""
    sh, out = _fresh_shell(fmu)
    text = "\n".join(lines)
    if as_file:
        (Path(fmu.sd_root) / "fuzz.sh").write_text(text)
        status = sh.execute("sh fuzz.sh a b")
    else:
        status = sh.run_script(text, ["a", "b"], name="fuzz.sh")
    assert isinstance(status, int) and 0 <= status <= 255
    _no_internal_failure("".join(out))
    _still_answers(sh, out)


@fuzz(examples=25)
@given(st.one_of(st.binary(max_size=300),
                 mutated(REAL_LINES).map(lambda s: s.encode("utf-8", "surrogatepass"))),
       st.sampled_from([b"\r", b"\n", b"\r\n", b""]))
def test_console_bytes_never_stop_the_board(fmu, data: bytes, end: bytes) -> None:
    """Invariant: any bytes typed on the console UART (control bytes, invalid UTF-8, lines too
    long, no line end at all) leave the FMU running (its kernel raises nothing) and print no
    internal error; after a line end, ``echo ok`` is answered with ``ok`` and a prompt."""
    from tests.firmware.test_shell import CONSOLE, _type_on_console

    burst = data + end + b"\r"
    t = fmu.kernel.now_ns
    sent = fmu.advance(t + 100_000_000 + len(burst) * 200_000,   # 57600 baud: 174 us a byte
                       [(CONSOLE[0], t, (*CONSOLE[1], burst))])
    _no_internal_failure(b"".join(payload[5] for port, _t, payload in sent
                                  if port == CONSOLE[0] and payload[5]).decode("latin-1"))
    assert 0 <= fmu.shell.open_ifs <= MAX_IF_DEPTH
    for _ in range(MAX_IF_DEPTH):        # close what the junk opened, as a person would
        if not fmu.shell.open_ifs:
            break
        _type_on_console(fmu, "then")
        _type_on_console(fmu, "fi")
    assert _type_on_console(fmu, "echo ok").endswith("echo ok\r\nok\nnsh> ")


#: typed bytes: random, or real lines (mutated) mixed with line ends, erases and cut UTF-8
_TYPED = st.one_of(
    st.binary(max_size=2000),
    st.lists(st.one_of(mutated(REAL_LINES).map(lambda s: s.encode("utf-8", "surrogatepass")),
                       st.sampled_from([b"\r", b"\n", b"\r\n", b"\x08", b"\x7f", b"\xc3",
                                        b"\xe2\x82"])),
             max_size=20).map(b"".join))


@fuzz(examples=300)
@given(_TYPED)
def test_line_editor_takes_any_bytes(data: bytes) -> None:
    """Invariant (the console's and the MAVLink shell's line editor): any bytes give only
    ``str`` lines without CR or LF, the line being typed never holds more than LINE_BYTES,
    the echo is only bytes typed, CR LF and erase sequences, and every line end gives one line
    (CR LF one, not two)."""
    from firmware.shell.line_editor import LINE_BYTES, LineEditor

    ed = LineEditor()
    lines: list[str] = []
    for b in data:
        echo, line = ed.key(b)
        assert len(ed.line) <= LINE_BYTES
        assert echo in (b"", b"\r\n", b"\x08 \x08", bytes((b,)))
        if line is not None:
            assert isinstance(line, str) and "\r" not in line and "\n" not in line
            lines.append(line)
    ends = data.count(b"\r") + data.count(b"\n") - data.count(b"\r\n")
    assert len(lines) == ends
