"""The line editor in front of nsh: bytes a terminal types in, echo and complete lines out.

NuttX's readline does this for every console the shell reads from; here the board's console
UART and the MAVLink shell (SERIAL_CONTROL) share this one class, so both treat outside bytes
the same way:

* a line ends at CR, LF or CR LF (one line, not an empty second one: terminals send CR or
  CR LF for Enter, QGroundControl's console LF);
* backspace (BS or DEL) removes the last character, every byte of it if it is UTF-8, and
  echoes ``BS space BS`` so the terminal erases it too;
* the line holds at most :data:`LINE_BYTES` bytes; what a client sends beyond that without a
  line end is dropped (not stored, not echoed), so no client can make the board hold an
  unbounded line, and the cut line is still longer than the shell reads and refused as such;
* the line decodes as UTF-8 (what terminals send), an invalid byte as U+FFFD.
"""

from __future__ import annotations

from typing import Final

from firmware.shell.parser import MAX_LINE_CHARS

__all__ = ["LINE_BYTES", "LineEditor"]

#: Four bytes (UTF-8's widest character) per character of the shell's longest line, plus one,
#: so a cut line still decodes to more characters than the shell takes.
LINE_BYTES: Final = 4 * (MAX_LINE_CHARS + 1)

_CR: Final = 0x0D
_LF: Final = 0x0A
_BS: Final = 0x08
_DEL: Final = 0x7F
_ERASE: Final = b"\x08 \x08"
_NEWLINE: Final = b"\r\n"


class LineEditor:
    """One terminal's line being typed."""

    def __init__(self, max_bytes: int = LINE_BYTES) -> None:
        self.max_bytes = max_bytes
        self.line = bytearray()
        self._after_cr = False

    def key(self, byte: int) -> tuple[bytes, str | None]:
        """Take one typed byte: what to echo, and the completed line (None while typing)."""
        after_cr = self._after_cr
        self._after_cr = byte == _CR
        if byte == _CR or byte == _LF:
            if byte == _LF and after_cr:
                return b"", None  # the LF of CR LF: the line already ended
            text = self.line.decode("utf-8", "replace")
            self.line.clear()
            return _NEWLINE, text
        if byte == _BS or byte == _DEL:
            return (_ERASE, None) if self._erase() else (b"", None)
        if len(self.line) >= self.max_bytes:
            return b"", None
        self.line.append(byte)
        return bytes((byte,)), None

    def _erase(self) -> bool:
        """Drop the last character: a UTF-8 lead byte with its continuation bytes, else one
        byte (an invalid sequence goes a byte at a time); False if the line is empty."""
        line = self.line
        if not line:
            return False
        n = 0
        while n < 3 and n < len(line) - 1 and line[-1 - n] & 0xC0 == 0x80:
            n += 1
        cut = n + 1 if n and 0xC0 <= line[-1 - n] <= 0xF7 else 1
        del line[-cut:]
        return True
