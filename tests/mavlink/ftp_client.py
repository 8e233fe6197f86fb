"""pymavlink's own MAVLink FTP client (``pymavlink.mavftp.MAVFTP``) on the in-process GCS.

MAVFTP wants a mavutil connection: ``mav.file_transfer_protocol_send``, ``recv_match`` and the
source ids. :class:`GcsMaster` gives it those over :class:`hil.gcs.GcsClient`, and
:class:`VirtualClock` replaces the ``time`` module MAVFTP reads, so that its retry and idle
timers run in the board's virtual time as the GCS's own timeouts do: a slow host never makes
the client retry or give up where a real link would not, and runs are deterministic.
"""

from __future__ import annotations

import struct
from typing import Any

from pymavlink import mavftp
from pymavlink.dialects.v20 import common as mav

__all__ = ["GcsMaster", "VirtualClock", "ftp_call", "ftp_client", "ftp_request", "parse"]

NS_PER_S = 1_000_000_000


class VirtualClock:
    """``time.time``/``time.sleep`` for MAVFTP: the orchestrator's virtual seconds."""

    def __init__(self, orch: Any) -> None:
        self.orch = orch

    def time(self) -> float:
        return self.orch.t_ns / NS_PER_S

    def sleep(self, seconds: float) -> None:
        pass  # recv_match advances the boards; MAVFTP's 0.1 ms naps would only slow it


class GcsMaster:
    """The part of a mavutil connection MAVFTP uses, over the virtual-time GCS."""

    def __init__(self, gcs: Any) -> None:
        self.gcs = gcs
        self.source_system = gcs.mav.srcSystem
        self.source_component = gcs.mav.srcComponent
        self.mav = self
        self._cursor = gcs.mark()

    def file_transfer_protocol_send(self, network: int, target_system: int,
                                    target_component: int, payload: Any) -> None:
        self.gcs.send(mav.MAVLink_file_transfer_protocol_message(
            network, target_system, target_component, list(bytes(payload))))

    def recv_match(self, type: Any = None, blocking: bool = False,  # noqa: A002 - mavutil's
                   timeout: float | None = None) -> Any:
        """The next FILE_TRANSFER_PROTOCOL received, advancing virtual time up to ``timeout``."""
        gcs = self.gcs
        orch = gcs.orch
        end = orch.t_ns + int((timeout or 0.0) * NS_PER_S)
        while True:
            msgs = gcs.messages(None, self._cursor)
            for i, m in enumerate(msgs):
                if m.get_type() == "FILE_TRANSFER_PROTOCOL":
                    self._cursor += i + 1
                    return m
            self._cursor += len(msgs)
            if orch.t_ns >= end:
                return None
            orch.step()


def ftp_client(session: Any, monkeypatch: Any) -> mavftp.MAVFTP:
    """A MAVFTP client on the session's GCS, its clock virtual. Timers shorter than its
    defaults (idle 1 s instead of 3.7 s: remove, mkdir and rename end only when the link has
    been idle that long) keep the tests short; they are virtual seconds, so no less safe."""
    monkeypatch.setattr(mavftp, "time", VirtualClock(session.orch))
    settings = mavftp.MAVFTPSettings([
        ("debug", int, 0), ("pkt_loss_tx", int, 0), ("pkt_loss_rx", int, 0),
        ("max_backlog", int, 5), ("burst_read_size", int, 239), ("write_size", int, 200),
        ("write_qsize", int, 5), ("idle_detection_time", float, 1.0),
        ("read_retry_time", float, 0.5), ("retry_time", float, 0.5),
    ])
    return mavftp.MAVFTP(GcsMaster(session.gcs), session.gcs.target_system,
                         session.gcs.target_component, settings=settings)


_HDR = struct.Struct("<HBBBBBxI")


def ftp_request(gcs: Any, seq: int, opcode: int, data: bytes = b"", *, session: int = 0,
                offset: int = 0, size: int | None = None) -> None:
    """One raw request (``size`` may lie about the data, for bad-input tests)."""
    n = len(data) if size is None else size
    payload = _HDR.pack(seq, session, opcode, n, 0, 0, offset) + data
    payload = payload[:251].ljust(251, b"\x00")
    gcs.send(mav.MAVLink_file_transfer_protocol_message(0, gcs.target_system,
                                                        gcs.target_component, list(payload)))


def parse(m: Any) -> dict[str, Any]:
    raw = bytes(m.payload)
    seq, session, opcode, size, req_opcode, burst_complete, offset = _HDR.unpack_from(raw)
    return {"seq": seq, "session": session, "opcode": opcode, "size": size,
            "req_opcode": req_opcode, "burst_complete": burst_complete, "offset": offset,
            "data": raw[12:12 + size]}


def ftp_call(gcs: Any, seq: int, opcode: int, data: bytes = b"", *, session: int = 0,
             offset: int = 0, size: int | None = None, timeout_s: float = 1.0
             ) -> dict[str, Any]:
    """Send one raw request and return its reply (sequence number + 1), parsed."""
    mark = gcs.mark()
    ftp_request(gcs, seq, opcode, data, session=session, offset=offset, size=size)
    m = gcs.wait_message("FILE_TRANSFER_PROTOCOL",
                         lambda m: parse(m)["seq"] == (seq + 1) & 0xFFFF, timeout_s, since=mark)
    return parse(m)
