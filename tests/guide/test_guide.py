"""docs/driver_guide.md, run: its examples execute, its quotes are the code the tests run, and
the TP100 example device (tests/guide/tp100.py) and driver (tp100_driver.py) do what the guide
says they do.

Three kinds of code block, each announced by an HTML comment on the line before it:

* ``<!-- quote: FILE#REGION -->``: the block is the region of FILE between ``# <guide:REGION>``
  and ``# </guide:REGION>``, line for line (both dedented); FILE is imported and run by these
  tests, so a quote cannot drift from running code;
* ``<!-- example: NAME -->``: the blocks of one NAME run in order, in one namespace, as a
  script (their asserts are the check);
* ``<!-- transcript: VAR -->``: an ``nsh`` block; every ``nsh> `` line is sent to the shell of
  the board ``VAR`` of the example namespace run so far, and the output must match the lines
  after it (``...`` matches any text, as doctest's ELLIPSIS).

A block without a marker fails :func:`test_every_code_block_is_run_or_quoted`.
"""

from __future__ import annotations

import doctest
import re
import textwrap
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from board.specs import FMU_V2, I2cDevice
from hil.turntable import Turntable
from peripherals.regs import check_names
from tests.fuzzing import fuzz
from tests.guide import tp100, tp100_driver
from tests.guide.tp100_driver import decode

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "driver_guide.md"
MS = 1_000_000
TP100 = I2cDevice("tp100", "tests.guide.tp100:Tp100", 0x76, driver="tp100",
                  driver_class="tests.guide.tp100_driver:Tp100Module")
_BLOCK = re.compile(r"(?:<!-- (\w+): ([^ ]+) -->\n)?```(\w*)\n(.*?)^```", re.S | re.M)


def blocks(text: str) -> list[tuple[str | None, str | None, str, str]]:
    """Every fenced block of a Markdown text: (marker kind, marker argument, language, code)."""
    return [(m.group(1), m.group(2), m.group(3), m.group(4)) for m in _BLOCK.finditer(text)]


def region(path: Path, name: str) -> str:
    """The lines between ``# <guide:name>`` and ``# </guide:name>`` in ``path``, dedented."""
    m = re.search(rf"^[ \t]*# <guide:{re.escape(name)}>\n(.*?)^[ \t]*# </guide:{re.escape(name)}>",
                  path.read_text(), re.S | re.M)
    assert m, f"{path.relative_to(ROOT)} has no region {name!r}"
    return textwrap.dedent(m.group(1))


def check_quotes(text: str) -> list[str]:
    """The quotes of ``text`` that are not their region verbatim (empty: all are)."""
    bad = []
    for kind, arg, _lang, code in blocks(text):
        if kind != "quote":
            continue
        file, _, name = (arg or "").partition("#")
        if region(ROOT / file, name) != textwrap.dedent(code):
            bad.append(arg or "")
    return bad


def run_examples(text: str, name: str) -> dict:
    """Run the ``example: name`` blocks and the transcripts between them, in order."""
    ns: dict = {"__name__": f"driver_guide_{name}"}
    for kind, arg, _lang, code in blocks(text):
        if kind == "example" and arg == name:
            exec(compile(code, f"{GUIDE}:{name}", "exec"), ns)  # noqa: S102 - our own doc
        elif kind == "transcript" and arg in ns:
            check_transcript(ns[arg], code)
    return ns


def check_transcript(board: Any, code: str) -> None:
    """Send each command of a transcript to the board's shell; its output must match."""
    checker = doctest.OutputChecker()
    for command, want in transcript(code):
        _status, got = board.ctl_shell(command)
        assert checker.check_output(want, got, doctest.ELLIPSIS), \
            f"nsh> {command}\n--- the guide says:\n{want}--- the board says:\n{got}"


def transcript(code: str) -> list[tuple[str, str]]:
    """``nsh> command`` lines and the expected output after each."""
    steps: list[tuple[str, str]] = []
    for line in code.splitlines(keepends=True):
        if line.startswith("nsh> "):
            steps.append((line[5:].strip(), ""))
        else:
            assert steps, f"transcript output before any command: {line!r}"
            steps[-1] = (steps[-1][0], steps[-1][1] + line)
    return steps


# -- the guide ------------------------------------------------------------------------------

def test_every_code_block_is_run_or_quoted():
    text = GUIDE.read_text()
    found = blocks(text)
    assert len(found) >= 20
    for kind, arg, lang, code in found:
        assert kind in ("quote", "example", "transcript"), \
            f"a {lang or 'plain'} block with no marker in docs/driver_guide.md:\n{code[:200]}"
        assert (lang == "nsh") == (kind == "transcript"), (kind, arg, lang)
    # the examples run here, and "adding-a-device" by tests/board_variants/test_variant.py
    assert {arg for kind, arg, _, _ in found if kind == "example"} == {"adding-a-device",
                                                                       "tp100"}


def test_every_quote_is_the_code_it_quotes():
    assert check_quotes(GUIDE.read_text()) == []


def test_a_changed_quote_or_example_fails():
    """The checks above bite: one character changed in a quote, or a wrong expectation in a
    transcript, is found."""
    text = GUIDE.read_text()
    assert check_quotes(text.replace("CTRL_OSR_4X: Final = 2 << 1", "CTRL_OSR_4X: Final = 3 << 1",
                                     1)) == ["tests/guide/tp100_driver.py#driver-constants"]

    class Echo:
        """A board whose shell prints its command line back."""

        def ctl_shell(self, line: str) -> tuple[int, str]:
            return 0, line.partition(" ")[2] + "\n"

    check_transcript(Echo(), "nsh> echo one two\none ...\n")
    with pytest.raises(AssertionError, match=r"guide says:\s+two\s+--- the board says:\s+one"):
        check_transcript(Echo(), "nsh> echo one\ntwo\n")


def test_the_guides_examples_run_as_written():
    ns = run_examples(GUIDE.read_text(), "tp100")
    assert ns["drv"].perf_not_ready.events >= 10          # the last example ran to its end


# -- the example driver, tested as the guide tells ------------------------------------------

# <guide:check-names>
def test_the_drivers_register_names_are_the_models_table():
    assert check_names(vars(tp100_driver), tp100.REGISTERS, "tp100_driver.") == 6
# </guide:check-names>


# <guide:test-in-process>
def test_tp100_publishes_the_pressure_at_its_altitude():
    board = FmuV2Board(seed=2, spec=FMU_V2.with_device("I2C2", TP100), firmware="sensors")
    Turntable(board.kernel, board.env, alt_m=1500.0)      # the world: a still board at 1500 m
    board.kernel.run(BOOT_TO_SENSORS_NS + 500 * MS)
    baro = board.platform.orb.node("sensor_baro", 1)
    assert 24 <= baro.publish_count <= 26                 # 50 Hz for 0.5 s
    assert board.env.pressure_pa < 86_000                 # thinner air than at sea level
    assert abs(baro.last.pressure - board.env.pressure_pa) < 2.0   # noise 0.4 Pa rms at OSR 4x
    assert baro.last.error_count == 0
# </guide:test-in-process>


# <guide:fuzz-decode>
@fuzz(examples=200)
@given(st.binary(max_size=8))
def test_decode_gives_a_sample_or_a_reason_never_an_exception(data):
    result = decode(data)
    if isinstance(result, str):
        assert len(data) != 6 or not data[0] & 1
    else:
        pressure_pa, temperature_c = result
        assert 0 <= pressure_pa < 2 ** 24 / 64 and -327.68 <= temperature_c < 327.68
# </guide:fuzz-decode>
