"""The smaller services of a link: STATUSTEXT, the MAVLink shell, log download, offboard input.

* STATUSTEXT: every ``log_message`` (PX4_INFO and worse) goes to the GCS; texts longer than 50
  characters are split into chunks with a shared id (MAVLink 2 chunking).
* SERIAL_CONTROL (device SHELL): QGroundControl's MAVLink console. Bytes typed go through the
  console's :class:`~firmware.shell.line_editor.LineEditor` (echo, backspace, bounded, UTF-8);
  a complete line runs on a :class:`~firmware.shell.Shell` of its own and its output, then the
  ``nsh> `` prompt, go back in SERIAL_CONTROL replies of up to 70 bytes.
* LOG_REQUEST_LIST / LOG_REQUEST_DATA / LOG_REQUEST_END / LOG_ERASE over the ULog files under
  the SD card's ``log/`` folder (ids 1..n in path order, which is time order).
* MANUAL_CONTROL -> ``manual_control_setpoint`` (data source MAVLink), and the offboard setpoints
  (see :mod:`firmware.modules.mavlink.offboard`).
"""

from __future__ import annotations

import calendar
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.offboard import OffboardService
from firmware.shell.line_editor import LineEditor

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = [
    "REQUESTABLE",
    "LogService",
    "OffboardService",
    "ShellService",
    "StatustextService",
]

STATUSTEXT_LEN: Final = 50
SERIAL_CHUNK: Final = 70
LOG_CHUNK: Final = 90
#: LOG_DATA packets per run at most (the data rate limits them further)
LOG_PACKETS_PER_RUN: Final = 32


class StatustextService:
    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self._sub = inst.module.subscribe("log_message")
        self._sub.copy()  # what was logged before this link existed is in dmesg
        self._chunk_id = 0

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {}

    def send_text(self, severity: int, text: str) -> None:
        raw = text.encode("utf-8", "replace")
        if len(raw) <= STATUSTEXT_LEN:
            self.inst.send(mav.MAVLink_statustext_message(severity, raw))
            return
        self._chunk_id = self._chunk_id % 0xFFFF + 1
        chunks = [raw[i:i + STATUSTEXT_LEN] for i in range(0, len(raw), STATUSTEXT_LEN)]
        for seq, chunk in enumerate(chunks):
            self.inst.send(mav.MAVLink_statustext_message(severity, chunk, self._chunk_id, seq))

    def update(self, now_us: int) -> None:
        while True:
            m = self._sub.update()
            if m is None:
                return
            text = m.text if isinstance(m.text, str) else bytes(m.text).decode("latin-1")
            self.send_text(min(int(m.severity), 7), text.rstrip("\x00"))


class ShellService:
    """QGroundControl's MAVLink console: nsh over SERIAL_CONTROL."""

    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self.shell: Any = None
        self.editor = LineEditor()
        self._out = bytearray()
        self._partner = (0, 0)
        self.lines_run = 0

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_SERIAL_CONTROL: self._on_serial_control}

    def _write(self, text: str) -> None:
        self._out += text.replace("\r\n", "\n").replace("\n", "\r\n").encode("utf-8", "replace")

    def _on_serial_control(self, m: Any) -> None:
        if m.device != mav.SERIAL_CONTROL_DEV_SHELL:
            return  # no serial passthrough to the board's other UARTs
        self._partner = (m.get_srcSystem(), m.get_srcComponent())
        if self.shell is None:
            from firmware.shell import Shell

            self.shell = Shell(self.inst.system, output=self._write)
            self._out += b"\r\nNuttShell (NSH)\r\nnsh> "
        for b in bytes(m.data[: m.count]):
            echo, line = self.editor.key(b)
            self._out += echo
            if line is not None:
                if line.strip():
                    self.shell.execute(line)
                    self.lines_run += 1
                self._out += b"nsh> "

    def update(self, now_us: int) -> None:
        while self._out:
            chunk = bytes(self._out[:SERIAL_CHUNK])
            data = list(chunk) + [0] * (SERIAL_CHUNK - len(chunk))
            msg = mav.MAVLink_serial_control_message(mav.SERIAL_CONTROL_DEV_SHELL,
                                                     mav.SERIAL_CONTROL_FLAG_REPLY, 0, 0,
                                                     len(chunk), data)
            if not self.inst.send(msg, budget=True):
                return
            del self._out[:SERIAL_CHUNK]


def _log_utc(path: Path, root: Path) -> int:
    """UTC seconds from the logger's ``YYYY-MM-DD/HH_MM_SS.ulg`` naming (0 if not so named)."""
    try:
        day = path.parent.name
        y, mo, d = (int(x) for x in day.split("-"))
        h, mi, s = (int(x) for x in path.stem.split("_"))
        return calendar.timegm((y, mo, d, h, mi, s, 0, 0, 0))
    except ValueError:
        return 0


class LogService:
    """Log list and download from the SD card's ``log/`` folder (PX4's MavlinkLogHandler)."""

    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self._list: list[Path] | None = None
        self._listing: list[int] = []        # ids still to announce
        self._partner = (0, 0)
        self._xfer: dict[str, Any] | None = None
        self.bytes_sent = 0

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_LOG_REQUEST_LIST: self._on_list,
                mav.MAVLINK_MSG_ID_LOG_REQUEST_DATA: self._on_data,
                mav.MAVLINK_MSG_ID_LOG_REQUEST_END: self._on_end,
                mav.MAVLINK_MSG_ID_LOG_ERASE: self._on_erase}

    def _root(self) -> Path | None:
        sd = self.inst.system.sd_root
        return None if sd is None else Path(sd) / "log"

    def _scan(self) -> list[Path]:
        root = self._root()
        if root is None or not root.is_dir():
            return []
        return sorted(p for p in root.rglob("*.ulg") if p.is_file())

    def _entry(self, log_id: int) -> Any:
        files = self._list or []
        p = files[log_id - 1]
        root = self._root()
        return mav.MAVLink_log_entry_message(log_id, len(files), len(files),
                                             _log_utc(p, root) if root else 0, p.stat().st_size)

    def _on_list(self, m: Any) -> None:
        self._list = self._scan()
        self._partner = (m.get_srcSystem(), m.get_srcComponent())
        n = len(self._list)
        if n == 0:
            self.inst.send(mav.MAVLink_log_entry_message(0, 0, 0, 0, 0))
            self._listing = []
            return
        start, end = max(int(m.start), 1), min(int(m.end), n)
        self._listing = list(range(start, end + 1))

    def _on_data(self, m: Any) -> None:
        if self._list is None:
            self._list = self._scan()
        if not 1 <= m.id <= len(self._list):
            return
        path = self._list[m.id - 1]
        try:
            size = path.stat().st_size
            f = open(path, "rb")  # noqa: SIM115 - closed when the transfer ends
        except OSError:
            return
        self._close()
        end = min(size, int(m.ofs) + int(m.count))
        self._xfer = {"id": int(m.id), "file": f, "ofs": int(m.ofs), "end": end, "size": size}
        if m.ofs >= size:  # PX4 answers a request past the end with an empty packet
            self.inst.send(mav.MAVLink_log_data_message(m.id, int(m.ofs), 0, [0] * LOG_CHUNK))
            self._close()

    def _on_end(self, m: Any) -> None:
        self._close()

    def _on_erase(self, m: Any) -> None:
        self._close()
        for p in self._scan():
            try:
                os.remove(p)
            except OSError:
                pass
        self._list = None

    def _close(self) -> None:
        if self._xfer is not None:
            self._xfer["file"].close()
            self._xfer = None

    def update(self, now_us: int) -> None:
        while self._listing:
            if not self.inst.send(self._entry(self._listing[0]), budget=True):
                return
            self._listing.pop(0)
        x = self._xfer
        if x is None:
            return
        for _ in range(LOG_PACKETS_PER_RUN):
            if x["ofs"] >= x["end"]:
                self._close()
                return
            if self.inst.tokens() < LOG_CHUNK + 20:
                return
            f = x["file"]
            f.seek(x["ofs"])
            chunk = f.read(min(LOG_CHUNK, x["end"] - x["ofs"]))
            data = list(chunk) + [0] * (LOG_CHUNK - len(chunk))
            if not self.inst.send(mav.MAVLink_log_data_message(x["id"], x["ofs"], len(chunk),
                                                               data), budget=True):
                return
            x["ofs"] += len(chunk)
            self.bytes_sent += len(chunk)


#: REQUEST_MESSAGE ids answered by something other than a stream builder (hook for more)
REQUESTABLE: Final[dict[int, Callable[[MavlinkInstance], None]]] = {}
