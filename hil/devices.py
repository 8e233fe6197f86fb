"""The host side of the wiring: several devices behind the ``"world"`` end of the wires.

The orchestrator talks to one object for everything outside the boards (``Orchestrator(world=)``):
it calls ``run_until(t_ns)`` once per quantum, collects ``outputs(until_ns)`` (records
``(port, t_ns, payload)``) and delivers ``input(port, t_ns, payload)``. :class:`DeviceHub` lets
several devices share that role: the JSBSim world, RC receivers, a console bridge to a host
terminal, a ground-station link. Each device names the ports it owns; the hub routes inputs to
the owner and concatenates outputs in device order, so routing stays deterministic.

A device is any object with ``ports`` (names it owns), ``run_until(t_ns)``,
``outputs(until_ns) -> list`` and ``input(port, t_ns, payload)``.

A device whose behaviour is a script fixed before the run (``runs_ahead = True``: an RC
transmitter playing a timeline) is run ``lead_ns`` ahead (the orchestrator sets it to one
quantum). Its records then reach a board before their stamps and are applied at their exact
times instead of at the next quantum start. A device that reacts to the boards must not run
ahead: its outputs would depend on inputs it has not seen.
"""

from __future__ import annotations

from typing import Any, Iterable, Protocol

__all__ = ["Device", "DeviceHub"]


class Device(Protocol):
    ports: Iterable[str]

    def run_until(self, t_ns: int) -> None: ...

    def outputs(self, until_ns: int) -> list: ...

    def input(self, port: str, t_ns: int, payload: Any) -> None: ...


class DeviceHub:
    """Several host devices acting as the orchestrator's world."""

    def __init__(self, *devices: Device) -> None:
        self.devices: list[Device] = []
        self._owner: dict[str, Device] = {}
        self.wired: set[str] | None = None
        #: how far ahead devices with ``runs_ahead`` run (the orchestrator sets one quantum)
        self.lead_ns = 0
        for d in devices:
            self.add(d)

    def add(self, device: Device) -> Device:
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

    def set_wired(self, wired: set[str]) -> None:
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

    def outputs(self, until_ns: int) -> list:
        out: list = []
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
