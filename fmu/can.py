"""The FMU's CAN side: its bxCAN controllers, the buses, the DroneCAN nodes plugged into CAN1,
and the controls the fault catalogue and the tests use on them (a part of
:class:`~fmu.board.FmuV2Board`, kept apart so the board file stays one idea).

The buses are built on first use (a board that never touches CAN pays nothing); the nodes are
the board's ``uavcan_nodes`` entries: a node ID alone is a bare NodeStatus node, ``"gnss"``,
``"mag"`` or ``"escN"`` (with an optional ``@ID``) a DroneCAN peripheral (peripherals/dronecan).
"""

from __future__ import annotations

from typing import Any

__all__ = ["FmuCanSide"]


class FmuCanSide:
    """Mixin of :class:`~fmu.board.FmuV2Board`: uses its kernel, spec, seed, environment,
    ``_rng``, ``expose_output``, ``_bus`` and the CAN attributes its ``__init__`` sets
    (``_can``, ``can_ctrl``, ``can_nodes``, ``can_host``, ``_uavcan_nodes``)."""

    kernel: Any
    spec: Any
    seed: int
    env: Any
    name: str
    _can: dict[str, Any] | None
    can_ctrl: dict[str, Any]
    can_nodes: list[Any]
    can_host: dict[str, Any]
    _uavcan_nodes: Any
    _power_v: float
    # the board's methods (annotations only: nothing here shadows them)
    _rng: Any
    expose_output: Any
    _bus: Any

    #: CAN bit rate of the FMU's buses (PX4's UAVCAN_BITRATE default)
    CAN_BITRATE = 1_000_000

    @property
    def can(self) -> dict[str, Any]:
        """The CAN buses by name (``CAN1``, ``CAN2``), built on first use."""
        if self._can is None:
            self._build_can()
        return self._can  # type: ignore[return-value]

    def _build_can(self) -> None:
        from board.can import CanBus, CanController

        self._can = {}
        for c in self.spec.can:
            bus = CanBus(self.kernel, c.name, self.CAN_BITRATE)
            self._can[c.name] = bus
            # bxCAN after reset: sleep mode, off the bus until the driver initialises it;
            # automatic bus-off management (ABOM) as libuavcan's STM32 driver sets it
            self.can_ctrl[c.name] = CanController(bus, f"{self.name}.{c.name}", enabled=False,
                                                  auto_recovery=True)
        for spec in self._uavcan_nodes:
            self.can_nodes.append(self._can_node(spec))

    def _can_node(self, spec: int | str) -> Any:
        """One DroneCAN node on CAN1 from its ``uavcan_nodes`` entry (see the module doc)."""
        bus = self._can["CAN1"]  # type: ignore[index]
        if isinstance(spec, int):
            from peripherals.uavcan_node import UavcanNode

            return UavcanNode(self.kernel, bus, spec, name=f"uavcan_node{spec}", seed=self.seed)
        from peripherals.dronecan.spec import parse_node_spec

        try:
            kind, node_id = parse_node_spec(spec)
        except ValueError as exc:
            raise ValueError(f"uavcan_nodes: {exc}") from None
        nid = str(spec).partition("@")[2]
        esc = kind[3:] if kind.startswith("esc") else ""
        name = f"can_{kind}{nid and '@' + nid}"
        if esc:
            from peripherals.dronecan.esc import EscNode

            # the motor is in the world: a pulse train equivalent to the command, on can_escN
            return EscNode(self.kernel, bus, int(esc) - 1, node_id, name=name, seed=self.seed,
                           rng=self._rng(name), output=self.expose_output(f"can_{kind}", "pwm"),
                           supply_v=lambda: self._power_v)
        if kind == "gnss":
            from peripherals.dronecan.gnss import GnssNode

            return GnssNode(self.kernel, bus, self.env, self._rng(name), node_id, name=name,
                            seed=self.seed)
        from peripherals.dronecan.mag import MagNode

        return MagNode(self.kernel, bus, self.env, self._rng(name), node_id, name=name,
                       seed=self.seed)

    def ctl_can_fault(self, bus: str, short: bool = False, bit_error_rate: float = 0.0) -> None:
        """Make a CAN bus's wire faulty: CAN_H shorted to CAN_L (``short``) and/or a bit-error
        rate (seeded by the board seed); both off heals it (:meth:`CanBus.set_wire_fault`)."""
        self._bus("can", bus).set_wire_fault(bool(short), float(bit_error_rate),
                                             seed=f"{self.seed}")

    def ctl_can_node_silent(self, node: str, silent: bool = True) -> None:
        """A DroneCAN node on CAN1 (by name, ``can_gnss``, or node ID as text) stops talking
        (off the bus: no frames, no ACKs) or comes back: a hung node MCU or a cut stub."""
        for n in self.can_nodes:
            if node in (n.name, str(n.node_id)):
                n.set_silent(bool(silent))
                return
        raise ValueError(f"no CAN node {node!r} (have {[n.name for n in self.can_nodes]})")

    def ctl_can_esc_errors(self, node: str, errors_per_s: float) -> None:
        """A DroneCAN ESC node on CAN1 (by name or node ID as text) counts errors at this rate
        in its esc.Status (0: healthy again): :meth:`EscNode.set_error_rate`."""
        for n in self.can_nodes:
            if node in (n.name, str(n.node_id)) and hasattr(n, "set_error_rate"):
                n.set_error_rate(float(errors_per_s))
                return
        raise ValueError(f"no CAN ESC node {node!r} (have "
                         f"{[n.name for n in self.can_nodes if hasattr(n, 'set_error_rate')]})")

    def ctl_can_stats(self, bus: str) -> dict[str, Any]:
        """The FMU controller's error state and counters on ``bus``, the bus's, and every
        UAVCAN node plugged into it."""
        b = self._bus("can", bus)
        c = self.can_ctrl[bus]
        return {"state": c.state, "tec": c.tec, "rec": c.rec, "enabled": c.enabled,
                "bus_off_count": c.bus_off_count, "tx_errors": c.tx_errors,
                "tx_frames": c.tx_frames, "rx_frames": c.rx_frames, "frames": b.frames,
                "error_frames": b.error_frames, "wire_fault": b.wire_fault,
                "nodes": {(n.node_id or n.name): n.stats() for n in self.can_nodes
                          if n.ctrl.bus is b},
                "host": self.can_host[bus].stats() if bus in self.can_host else None}
