"""RC in the world: the pilot's transmitter and the receivers wired to the IO's RC inputs.

:class:`Transmitter` is a timeline of stick, switch and power commands in virtual time.
Receivers sample it frame by frame and put real wire traffic on their world port: S.BUS and
DSM frames as ``uart`` records with their line format, PPM as ``pin`` edge records. Each
receiver is a world device (``run_until``, ``outputs``, ``input``, ``next_event_ns``);
:class:`RcRig` groups a transmitter with its receivers so the world can host them as one.

Receiver models are found by name in :data:`RECEIVERS` (``"sbus"``, ``"dsm"``, ``"ppm"``) and
imported lazily, like the other plug-in tables of the project.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

from hil.rc.receiver import Receiver, Record
from hil.rc.transmitter import ChannelMap, Transmitter

__all__ = ["RECEIVERS", "ChannelMap", "RcRig", "Receiver", "Record", "Transmitter",
           "make_receiver"]

#: Receiver kind → "module:class".
RECEIVERS: dict[str, str] = {
    "sbus": "hil.rc.sbus:SbusReceiver",
    "dsm": "hil.rc.dsm:DsmReceiver",
    "ppm": "hil.rc.ppm:PpmReceiver",
}


def make_receiver(kind: str, tx: Transmitter, **kwargs: Any) -> Receiver:
    """Build a receiver model by kind (see :data:`RECEIVERS`)."""
    try:
        target = RECEIVERS[kind]
    except KeyError:
        raise ValueError(f"no RC receiver kind {kind!r} (known: {', '.join(RECEIVERS)})"
                         ) from None
    module, cls = target.split(":")
    return getattr(import_module(module), cls)(tx, **kwargs)


class RcRig:
    """A transmitter and the receivers bound to it, as one world device.

    ``outputs`` merges the receivers' records in time order (ties keep receiver order), so a
    host sees one stream. ``ports`` lists the world ports the rig drives.
    """

    def __init__(self, tx: Transmitter | None = None, receivers: list[Receiver] | None = None
                 ) -> None:
        self.tx = tx or Transmitter()
        self.receivers: list[Receiver] = list(receivers or [])

    def add(self, kind: str, **kwargs: Any) -> Receiver:
        """Add a receiver of ``kind`` bound to this rig's transmitter."""
        rx = make_receiver(kind, self.tx, **kwargs)
        self.receivers.append(rx)
        return rx

    input_ports: tuple[str, ...] = ()
    #: the rig plays a script written before the run (nothing it does depends on the boards),
    #: so the device hub may run it a quantum ahead: its records then reach the IO before
    #: their stamps and land at exact wire times (PPM edges 400 us apart need that).
    runs_ahead = True

    @property
    def ports(self) -> tuple[str, ...]:
        """World output ports the rig drives (one per receiver)."""
        return tuple(rx.port for rx in self.receivers)

    def run_until(self, t_ns: int) -> None:
        for rx in self.receivers:
            rx.run_until(t_ns)

    def outputs(self, until_ns: int) -> list[Record]:
        out: list[Record] = []
        for rx in self.receivers:
            out += rx.outputs(until_ns)
        if len(self.receivers) > 1:
            out.sort(key=lambda r: r[1])
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        raise ValueError(f"RC rig has no input port {port!r}")

    def next_event_ns(self) -> int | None:
        times = [t for t in (rx.next_event_ns() for rx in self.receivers) if t is not None]
        return min(times) if times else None
