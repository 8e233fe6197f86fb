"""Faults on the orchestrator's wires: cut, mended, or carrying records through a fault.

A mixin of :class:`hil.orchestrator.Orchestrator`, kept apart because a healthy run never
touches it: while no wire has a fault the orchestrator routes a quantum's records with its
plain ``_route_all``; the first fault sets its ``_route_outputs`` to
:meth:`WireFaults._route_all_faulty`, and the last one removed sets it back. The fault catalogue (hil/faults) acts on wires through these
methods, never on a board's state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

from board.wiring import WORLD

if TYPE_CHECKING:
    from board.protocols import BoardHandle

__all__ = ["WireFault", "WireFaults"]


class WireFaults:
    """Cut, mend and fault the wires of an orchestrator (see the module docstring)."""

    # what the orchestrator provides
    _routes: dict[tuple[str, str], list[tuple[str, str]]]
    _wire_faults: dict[tuple[str, str], WireFault]
    _route_outputs: Callable[[str, list], None]
    handles: dict[str, BoardHandle]
    dead: dict[str, str]
    t_ns: int

    def _route(self, board: str, port: str, t_ns: int, payload: Any) -> None:
        raise NotImplementedError

    def _route_all(self, board: str, records: list) -> None:
        raise NotImplementedError

    def call(self, board: str, method: str, *args: Any) -> Any:
        raise NotImplementedError

    def _route_all_faulty(self, board: str, records: list) -> None:
        """:meth:`_route_all` while some wire has a fault (swapped in, so a healthy harness
        pays nothing): records on a faulty wire go through its fault first."""
        faults = self._wire_faults
        clean = []
        for rec in records:
            fault = faults.get((board, rec[0]))
            if fault is None:
                clean.append(rec)
            else:
                clean.extend(fault.carry(rec))
        if clean:
            self._route_all(board, clean)

    def _wire(self, board: str, port: str) -> tuple[str, str]:
        key = (board, port)
        if key not in self._routes:
            wired = sorted(f"{b}.{p}" for b, p in self._routes)
            raise ValueError(f"no wire leaves {board}.{port} (wired outputs: "
                             f"{', '.join(wired)})")
        return key

    def _port_kind(self, board: str, port: str) -> str:
        if board == WORLD:
            return "value" if not port.startswith("rc_") else "uart"
        handle = self.handles.get(board)
        if handle is not None:
            for name, kind, _direction in handle.ports:
                if name == port:
                    return kind
        return "value"

    def set_wire_fault(self, board: str, port: str, fault: WireFault | None) -> None:
        """Put ``fault`` on the wire leaving ``board.port`` (None: a healthy wire again)."""
        key = self._wire(board, port)
        if fault is None:
            self._wire_faults.pop(key, None)
        else:
            self._wire_faults[key] = fault
        self._route_outputs = self._route_all_faulty if self._wire_faults else self._route_all

    def cut_wire(self, board: str, port: str) -> None:
        """The wire leaving ``board.port`` breaks now: it carries nothing more. What the far end
        then sees is what an open wire gives: a UART's RX idles at mark (no bytes), a PWM input
        sees no pulses, a pin input floats to its pull. Bytes already on the wire (sent before
        now) still arrive."""
        key = self._wire(board, port)
        kind = self._port_kind(board, port)
        cut = WireFault(kind)
        self.set_wire_fault(board, port, None)
        if kind == "pwm":
            self._route(board, port, self.t_ns, (0, 0))
        elif kind == "pin":
            self._route(board, port, self.t_ns, -1)
        self.set_wire_fault(*key, cut)

    def mend_wire(self, board: str, port: str) -> None:
        """Reconnect a cut wire: a PWM or pin output's present level reaches the far end again
        (the last one the driver produced while the wire was open)."""
        key = self._wire(board, port)
        fault = self._wire_faults.get(key)
        self.set_wire_fault(board, port, None)
        if fault is None or fault.kind not in ("pwm", "pin"):
            return
        level = fault.last[2] if fault.last is not None else None
        if level is None and board != WORLD and board not in self.dead:
            level = self.call(board, "port_level", port)
        if level is not None:
            self._route(board, port, self.t_ns, level)

    def wire_faults(self) -> list[str]:
        return [f"{b}.{p}" for b, p in self._wire_faults]


class WireFault:
    """What a faulty wire does to each record crossing it. The base is an open wire: nothing
    crosses (the last record is kept so that mending the wire can restore a level)."""

    def __init__(self, kind: str = "value") -> None:
        self.kind = kind
        self.last: tuple | None = None
        self.records_lost = 0

    def carry(self, rec: tuple) -> list:
        self.last = rec
        self.records_lost += 1
        return []
