"""nsh on a serial console: bytes typed on a UART, edited into lines, each run on the shell.

NuttX's console is a UART with readline in front of nsh; the FMU's (UART7) and the companion
computer's (its /dev/ttyS0) are both this. Line editing is the shared
:class:`~firmware.shell.line_editor.LineEditor` (bounded, UTF-8), the echo goes back out of the
UART, and a complete line runs as a thread would: after the receive interrupt, not inside it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from firmware.shell.line_editor import LineEditor

if TYPE_CHECKING:
    from board.uart import Uart
    from firmware.shell import Shell

__all__ = ["SerialConsole"]

#: the shell thread's kernel priority: after interrupts and hardware, like a NuttX task
_SHELL_PRIORITY = 200


class SerialConsole:
    """The console UART's receive side, feeding ``shell`` (set once the board has booted)."""

    def __init__(self, uart: Uart) -> None:
        self.uart = uart
        self.editor = LineEditor()
        self.shell: Shell | None = None

    def attach(self, shell: Shell) -> None:
        """Serve ``shell``: every byte received from now on goes through the line editor."""
        self.shell = shell
        self.uart.on_rx(self._rx)

    def _rx(self, t_ns: int, byte: int, flags: int) -> None:
        echo, line = self.editor.key(byte)
        if echo:
            self.uart.write(echo)
        if line is not None:
            k = self.uart.kernel
            k.call_at(k.now_ns, self._exec, line, priority=_SHELL_PRIORITY)

    def _exec(self, line: str) -> None:
        if self.shell is not None and line.strip():
            self.shell.execute(line)
        self.uart.write(b"nsh> ")
