"""``hil fly --can CAN1=<python-can bus spec>``: an emulated CAN bus joined to a real or
virtual python-can bus, frames both ways.

The spec is ``<interface>:<channel>`` as python-can names them: ``socketcan:vcan0``,
``slcan:/dev/ttyACM0@115200`` (python-can's slcan channel syntax: serial port @ serial baud),
``virtual:chan0``, ``pcan:PCAN_USBBUS1``... The bus is opened at the emulated bus's bit rate
(1 Mbit/s). The other side is one node on the emulated bus (:mod:`fmu.can_port`): what the
real bus carries is sent onto the emulated one when the emulator polls it (between quanta), and
every frame of the emulated nodes is sent to the real bus as it completes; frames relayed from
the real bus are not sent back to it. Meant for paced runs (``hil fly``): a real bus runs in
wall time. Unpaced (tests) it works too, with frames entering at the virtual time of the poll.

A bus that fails (adapter unplugged, interface down, bus shut down) is reported once, the
binding is closed, and the emulator keeps running without it; a frame the real bus cannot take
(its TX buffer full) is counted and dropped.
"""

from __future__ import annotations

from typing import Any, Callable

from board.wiring import WORLD, Wire
from hil.binding_life import DeviceBinding
from hil.can_interface_host import CanHost, Endpoint
from hil.can_interface_wire import KIND_ECHO, KIND_FRAME, WireFrame

__all__ = ["BoundBus", "add_can_hosts", "parse_can_spec"]

#: Frames taken from the real bus per poll at most (the rest wait for the next poll).
_MAX_PER_POLL = 512


def parse_can_spec(spec: str) -> tuple[str, str]:
    """``"socketcan:vcan0"`` -> ("socketcan", "vcan0"), with a clear error otherwise."""
    iface, sep, channel = spec.partition(":")
    if not sep or not iface or not channel:
        raise ValueError(f"--can: expected <interface>:<channel> (e.g. socketcan:vcan0, "
                         f"virtual:chan0, slcan:/dev/ttyACM0@115200), got {spec!r}")
    return iface, channel


class BoundBus(DeviceBinding, Endpoint):
    """A python-can bus attached to a :class:`~hil.can_interface_host.CanHost`."""

    def __init__(self, spec: str, bitrate: int, bus: Any = None,
                 log: Callable[[str], None] | None = None) -> None:
        super().__init__(f"--can {spec}")
        self.log = log or (lambda text: None)
        self.spec = spec
        self.error: str | None = None
        self.send_failures = 0
        if bus is None:
            import can

            iface, channel = parse_can_spec(spec)
            bus = can.Bus(interface=iface, channel=channel, bitrate=bitrate)
        self.bus = bus

    def poll(self, host: CanHost) -> None:
        import can

        try:
            for _ in range(_MAX_PER_POLL):
                msg = self.bus.recv(0)
                if msg is None:
                    break
                if msg.is_error_frame or msg.is_fd or msg.dlc > 8:
                    self.dropped += 1  # not a classic data/remote frame: nothing to relay
                    continue
                data = bytes(msg.dlc) if msg.is_remote_frame else bytes(msg.data[:msg.dlc])
                self.tx.append(WireFrame(KIND_FRAME, msg.arbitration_id, msg.is_extended_id,
                                         msg.is_remote_frame, data))
                self.frames_in += 1
        except (can.CanError, OSError, ValueError) as exc:
            self._fail(exc)

    def deliver(self, frame: WireFrame) -> None:
        if frame.kind == KIND_ECHO or self.closed:
            return  # the real bus already carried it
        import can

        msg = can.Message(arbitration_id=frame.arbitration_id, is_extended_id=frame.is_extended,
                          is_remote_frame=frame.is_remote, dlc=len(frame.data),
                          data=None if frame.is_remote else frame.data)
        try:
            self.bus.send(msg, timeout=0)
            self.frames_out += 1
        except can.CanOperationError as exc:
            if "closed" in str(exc) or "shut" in str(exc):
                self._fail(exc)
            else:
                self.send_failures += 1  # TX buffer full, bus-off, no ACK: drop, go on
        except (can.CanError, OSError, ValueError) as exc:
            self._fail(exc)

    def describe(self) -> str:
        return f"CAN binding {self.spec}"

    def _close_device(self) -> None:
        self.bus.shutdown()


def add_can_hosts(cfg: Any, hub: Any, devices: dict[str, Any], buses: tuple[str, ...]
                  ) -> list[Wire]:
    """Host devices for the FMU's ``buses`` (SystemConfig.can_hosts/can_bind) and their wires."""
    wires: list[Wire] = []
    for bus in buses:
        host = CanHost(bus, speed=cfg.speed, tcp_port=0 if cfg.can_tcp else None)
        hub.add(host)
        devices[host.port] = host
        spec = cfg.can_bind.get(bus)
        if spec is not None:
            ep = BoundBus(spec, host.bitrate, log=host.log)
            host.attach(ep)
            devices[f"{host.port}_bind"] = ep
        p = host.port
        wires += [Wire(("fmu", p), (WORLD, p), f"FMU {bus} -> host tools"),
                  Wire((WORLD, p), ("fmu", p), f"host tools -> FMU {bus}"),
                  Wire((WORLD, f"{p}_host"), ("fmu", f"{p}_host"),
                       f"a host tool attached to {bus}")]
    return wires
