"""python-can interface ``hil``: the emulated CAN buses as a python-can bus.

Registered through python-can's plug-in entry point (group ``can.interface``, pyproject.toml),
so every python-can tool reaches the virtual board::

    can.Bus(interface="hil", channel="CAN1")                 # CAN1 of the running `hil fly`
    python -m can.logger -i hil -c CAN1 -f can1.log
    python -m can.player -i hil -c CAN1 can1.log
    python -m can.viewer -i hil -c CAN1
    dronecan.make_node("CAN1", bustype="hil", bitrate=1000000, node_id=100)

The tool is one node on the emulated bus (:mod:`fmu.can_port`): its frames are arbitrated,
ACKed and timed as board/can.py models, and it receives every frame of the other nodes.

Where the bus is:

* ``port=N`` (``--port=N`` on python-can's command lines, or ``CAN_CONFIG='{"port": N}'``): the
  TCP endpoint of an emulator on 127.0.0.1;
* otherwise the newest running ``hil fly`` that announced ``channel`` (the runtime folder of
  :mod:`hil.shell_client`, as ``hil shell`` finds the console);
* in-process (tests): ``board=`` a :class:`~hil.can_interface_host.CanHost`, an orchestrator or
  the devices of :func:`hil.system.build_system`; or a host registered with
  :func:`hil.can_interface_host.register` under the channel name. Given an orchestrator, the
  plug-in *drives* it: ``recv(timeout)`` runs the emulation quantum by quantum until a frame
  arrives or ``timeout`` virtual seconds have passed, so a tool written for a real bus runs
  unchanged, deterministically, as fast as the emulator goes.

Timestamps (``Message.timestamp``): the frame's end on the emulated bus; wall-clock epoch
seconds when the emulator is paced (``hil fly``), virtual seconds when it is not.
"""

from __future__ import annotations

import json
import select
import socket
import time
from typing import Any

import can
from can import BusABC, CanOperationError, Message

from hil.can_interface_host import QueueEndpoint, find_host, registered
from hil.can_interface_wire import KIND_ECHO, KIND_FRAME, RECORD, WireFrame, decode, encode

__all__ = ["HilBus", "discover_can"]

NS_PER_S = 1_000_000_000
#: One blocking ``recv(None)`` call drives at most this much virtual time, then returns None
#: (python-can's ``recv`` calls again).
_DRIVE_SLICE_NS = 1_000_000_000


def discover_can() -> dict[str, dict[str, Any]]:
    """CAN channels of the running emulators: ``{channel: {"port", "bitrate", "pid"}}``, the
    newest instance winning."""
    from hil.shell_client import pid_alive, runtime_dir

    found: dict[str, dict[str, Any]] = {}
    infos = []
    for f in runtime_dir().glob("*.json"):
        try:
            info = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(info, dict) and isinstance(info.get("can"), dict) \
                and pid_alive(int(info.get("pid", 0))):
            infos.append(info)
    for info in sorted(infos, key=lambda i: i.get("started", 0)):
        for ch, ep in info["can"].items():
            if isinstance(ep, dict) and isinstance(ep.get("port"), int):
                found[ch] = {**ep, "pid": info["pid"]}
    return found


def _to_message(f: WireFrame, channel: str) -> Message:
    return Message(timestamp=f.timestamp_s, arbitration_id=f.arbitration_id,
                   is_extended_id=f.is_extended, is_remote_frame=f.is_remote, dlc=len(f.data),
                   data=None if f.is_remote else f.data, channel=channel,
                   is_rx=f.kind == KIND_FRAME)


class HilBus(BusABC):
    """A node on an emulated CAN bus (see the module docstring for where the bus is)."""

    def __init__(self, channel: Any = "CAN1", board: Any = None, port: int | None = None,
                 host: str = "127.0.0.1", bitrate: int | None = None,
                 receive_own_messages: bool = False, can_filters: Any = None,
                 **kwargs: Any) -> None:
        channel = str(channel or "CAN1")
        self.channel = channel
        self._receive_own = bool(receive_own_messages)
        self._ep: QueueEndpoint | None = None
        self._host: Any = None
        self._driver: Any = None
        self._sock: socket.socket | None = None
        self._buf = bytearray()
        self._pending: list[WireFrame] = []
        #: records from the emulator that were not valid frames (counted, dropped)
        self.bad_records = 0
        expected = None
        local = None
        if board is not None:
            local = find_host(board, channel)
        elif port is None:
            local = registered(channel)
        if local is not None:
            self._host, self._driver = local
            expected = self._host.bitrate
            self._ep = QueueEndpoint(f"python-can {channel}", receive_own=self._receive_own)
            self._host.attach(self._ep)
            self.channel_info = f"hil {channel} (in-process)"
        else:
            if port is None:
                found = discover_can().get(channel)
                if found is None:
                    raise can.CanInitializationError(
                        f"hil: no running emulator announces CAN channel {channel!r}; start "
                        f"'hil fly' (or pass port=<its CAN TCP port>)")
                port = int(found["port"])
                expected = found.get("bitrate")
            try:
                self._sock = socket.create_connection((host, int(port)), timeout=5.0)
            except OSError as exc:
                raise can.CanInitializationError(
                    f"hil: cannot reach the CAN endpoint {host}:{port} of {channel}: {exc}"
                ) from None
            self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._sock.settimeout(None)
            self.channel_info = f"hil {channel} (tcp {host}:{port})"
        if bitrate is not None and expected is not None and int(bitrate) != int(expected):
            self._close()
            raise can.CanInitializationError(
                f"hil: {channel} runs at {expected} bit/s, not {bitrate} (a node at another "
                f"bit rate would only see error frames)")
        super().__init__(channel, can_filters=can_filters, **kwargs)

    # -- python-can contract ---------------------------------------------------------------------

    def _recv_internal(self, timeout: float | None) -> tuple[Message | None, bool]:
        if timeout is not None and timeout < 0:
            timeout = 0.0  # dronecan's driver passes -1 for "no wait"
        if self._ep is not None:
            f = self._recv_local(timeout)
        else:
            f = self._recv_remote(timeout)
        if f is None:
            return None, False
        return _to_message(f, self.channel), False

    def _recv_local(self, timeout: float | None) -> WireFrame | None:
        ep = self._ep
        assert ep is not None
        if ep.rx:
            return ep.rx.popleft()
        orch = self._driver
        if orch is not None:  # drive the emulation in virtual time until a frame comes
            q = orch.quantum_ns
            budget = _DRIVE_SLICE_NS if timeout is None else int(timeout * NS_PER_S)
            end = orch.t_ns + budget
            while not ep.rx and orch.t_ns < end:
                orch.run(duration_ns=q)
            return ep.rx.popleft() if ep.rx else None
        # someone else runs the emulator (another thread): wait in wall time
        deadline = None if timeout is None else time.monotonic() + timeout
        while not ep.rx:
            if deadline is not None and time.monotonic() >= deadline:
                return None
            time.sleep(0.001)
        return ep.rx.popleft()

    def _recv_remote(self, timeout: float | None) -> WireFrame | None:
        sock = self._sock
        if sock is None:
            raise CanOperationError("hil: bus is shut down")
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            while self._pending:
                f = self._pending.pop(0)
                if f.kind == KIND_ECHO and not self._receive_own:
                    continue
                return f
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready, _, _ = select.select([sock], [], [], left)
            if not ready:
                return None
            try:
                data = sock.recv(RECORD.size * 512)
            except OSError as exc:
                raise CanOperationError(f"hil: connection to the emulator lost: {exc}") from None
            if not data:
                raise CanOperationError("hil: the emulator closed the connection (it stopped)")
            self._buf += data
            frames, bad = decode(self._buf)
            self.bad_records += bad
            self._pending.extend(frames)

    def send(self, msg: Message, timeout: float | None = None) -> None:
        if msg.is_fd or msg.is_error_frame:
            raise CanOperationError("hil: CAN FD and error frames cannot be sent on a classic "
                                    "CAN bus")
        limit = 0x1FFFFFFF if msg.is_extended_id else 0x7FF
        if not 0 <= msg.arbitration_id <= limit or not 0 <= msg.dlc <= 8:
            raise ValueError(f"hil: not a classic CAN frame: {msg}")
        data = bytes(msg.dlc) if msg.is_remote_frame else bytes(msg.data[:msg.dlc])
        f = WireFrame(KIND_FRAME, msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame,
                      data)
        if self._ep is not None:
            self._ep.tx.append(f)
            return
        if self._sock is None:
            raise CanOperationError("hil: bus is shut down")
        try:
            self._sock.sendall(encode(f))
        except OSError as exc:
            raise CanOperationError(f"hil: connection to the emulator lost: {exc}") from None

    def flush_tx_buffer(self) -> None:
        """Nothing to flush: a sent frame is handed to the emulator at once (its adapter node
        queues it for the bus)."""

    def shutdown(self) -> None:
        self._close()
        super().shutdown()

    def _close(self) -> None:
        if self._ep is not None and self._host is not None:
            self._host.detach(self._ep)
            self._ep = None
        if self._sock is not None:
            try:
                self._sock.close()
            except OSError:
                pass
            self._sock = None

    @staticmethod
    def _detect_available_configs() -> list[can.typechecking.AutoDetectedConfig]:
        try:
            found = discover_can()
        except OSError:
            return []
        # "port" goes beyond python-can's TypedDict: Bus(**config) needs it to reach the bus
        return [{"interface": "hil", "channel": ch,  # type: ignore[typeddict-unknown-key]
                 "port": ep["port"]} for ch, ep in sorted(found.items())]
