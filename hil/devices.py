"""The host side of the wiring: several devices behind the ``"world"`` end of the wires.

The orchestrator talks to one object for everything outside the boards (``Orchestrator(world=)``):
it calls ``run_until(t_ns)`` once per quantum, collects ``outputs(until_ns)`` (records
``(port, t_ns, payload)``) and delivers ``input(port, t_ns, payload)``. :class:`DeviceHub` lets
several devices share that role: the JSBSim world, RC receivers, a console bridge to a host
terminal, a ground-station link. Each device names the ports it owns; the hub routes inputs to
the owner and concatenates outputs in device order, so routing stays deterministic.

A device is any object with ``ports`` (names it owns), ``run_until(t_ns)``,
``outputs(until_ns) -> list`` and ``input(port, t_ns, payload)``: :class:`HostDevice`, the
protocol the orchestrator's ``world`` follows too (a :class:`DeviceHub`, or one device alone such
as :class:`hil.worldlink.WorldPorts`). Optional members the orchestrator and the hub look for
with ``hasattr``: ``wired`` (the output ports something is wired to, so a device computes only
those), ``set_wired(ports)``, ``lead_ns`` and ``runs_ahead``.

A device whose behaviour is a script fixed before the run (``runs_ahead = True``: an RC
transmitter playing a timeline) is run ``lead_ns`` ahead (the orchestrator sets it to one
quantum). Its records then reach a board before their stamps and are applied at their exact
times instead of at the next quantum start. A device that reacts to the boards must not run
ahead: its outputs would depend on inputs it has not seen.
"""

from __future__ import annotations

from typing import Any, Iterable, Protocol

from board.protocols import Record

__all__ = ["Device", "DeviceHub", "HostDevice"]


class HostDevice(Protocol):
    """Something outside the boards with ports on the wiring: the world, a device, the hub."""

    @property
    def ports(self) -> Iterable[str]:
        """The port names it owns (inputs and outputs)."""
        ...

    def run_until(self, t_ns: int) -> None:
        """Advance to ``t_ns`` (the end of the quantum, or one quantum more if it runs
        ahead)."""
        ...

    def outputs(self, until_ns: int) -> list[Record]:
        """The records ``(port, t_ns, payload)`` produced up to ``until_ns``, once each."""
        ...

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        """A record arriving on one of its input ports (ValueError for a port it lacks)."""
        ...


#: the name this protocol had first
Device = HostDevice


class DeviceHub:
    """Several host devices acting as the orchestrator's world."""

    def __init__(self, *devices: HostDevice) -> None:
        self.devices: list[HostDevice] = []
        self._owner: dict[str, HostDevice] = {}
        self.wired: set[str] | None = None
        #: how far ahead devices with ``runs_ahead`` run (the orchestrator sets one quantum)
        self.lead_ns = 0
        for d in devices:
            self.add(d)

    def add(self, device: HostDevice) -> HostDevice:
        for port in device.ports:
            if port in self._owner:
                raise ValueError(f"host port {port!r} owned by two devices: "
                                 f"{type(self._owner[port]).__name__} and "
                                 f"{type(device).__name__}")
            self._owner[port] = device
        self.devices.append(device)
        self._push_wired()
        return device

    def _push_wired(self) -> None:
        for d in self.devices:
            if hasattr(d, "wired"):
                d.wired = None if self.wired is None else {p for p in self.wired
                                                           if self._owner.get(p) is d}

    def set_wired(self, wired: set[str] | None) -> None:
        self.wired = wired
        self._push_wired()

    @property
    def ports(self) -> list[str]:
        return list(self._owner)

    def __getattr__(self, name: str) -> Any:
        # Let callers reach the JSBSim world's attributes (world.t_ns, .world) through the hub.
        for d in self.__dict__.get("devices", ()):
            if hasattr(d, name):
                return getattr(d, name)
        raise AttributeError(name)

    def run_until(self, t_ns: int) -> None:
        lead = self.lead_ns
        for d in self.devices:
            d.run_until(t_ns + lead if getattr(d, "runs_ahead", False) else t_ns)

    def outputs(self, until_ns: int) -> list[Record]:
        out: list[Record] = []
        lead = self.lead_ns
        for d in self.devices:
            out += d.outputs(until_ns + lead if getattr(d, "runs_ahead", False) else until_ns)
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        owner = self._owner.get(port)
        if owner is None:
            raise ValueError(f"no host device owns port {port!r} (ports: "
                             f"{', '.join(sorted(self._owner))})")
        owner.input(port, t_ns, payload)
