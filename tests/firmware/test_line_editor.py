"""The line editor the board's console and the MAVLink shell share (bytes in, lines out)."""

from firmware.shell.line_editor import LINE_BYTES, LineEditor


def _type(editor: LineEditor, data: bytes) -> tuple[bytes, list[str]]:
    echo, lines = bytearray(), []
    for b in data:
        out, line = editor.key(b)
        echo += out
        if line is not None:
            lines.append(line)
    return bytes(echo), lines


def test_cr_lf_and_cr_lf_each_end_one_line():
    ed = LineEditor()
    assert _type(ed, b"a\rb\nc\r\nd\r\r") == (b"a\r\nb\r\nc\r\nd\r\n\r\n", ["a", "b", "c", "d", ""])


def test_backspace_erases_a_character_and_says_so():
    ed = LineEditor()
    echo, lines = _type(ed, "x\u00e9\u20ac".encode() + b"\x7f\x08y\x08\x08\x08\n")
    assert lines == [""]  # everything typed was erased again
    # two characters of 2 and 3 bytes, then y and x: one erase each; the last BS erases nothing
    assert echo.endswith(b"\x08 \x08" * 2 + b"y" + b"\x08 \x08" * 2 + b"\r\n")
    assert _type(ed, b"\xff\x80\x08z\n")[1] == ["\ufffdz"]  # invalid bytes: one at a time


def test_the_line_is_bounded_and_decodes_utf8():
    ed = LineEditor()
    echo, lines = _type(ed, b"y" * (2 * LINE_BYTES))
    assert lines == [] and len(ed.line) == LINE_BYTES and len(echo) == LINE_BYTES
    assert _type(ed, b"\n")[1] == ["y" * LINE_BYTES]
    assert _type(ed, "h\u00e9 \u2603".encode() + b"\xc3\n")[1] == ["h\u00e9 \u2603\ufffd"]
