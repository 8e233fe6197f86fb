"""A DroneCAN ESC node: ``uavcan.equipment.esc.RawCommand`` in, ``uavcan.equipment.esc.Status``
out at 10 Hz, for one motor (``esc_index`` 0..3 picks its element of the command array).

RawCommand holds one signed 14-bit value per ESC: 0 stops the motor, 1..8191 is the throttle
fraction x 8191 (negative values, reverse, are taken as stop: the F450's ESCs do not reverse).
As on real DroneCAN ESC firmware, a motor whose command stops arriving for 0.5 s
(``COMMAND_TIMEOUT_NS``) is stopped.

The motor is in the world, not on the board: what the node drives is its ``output`` callback,
``output(t_ns, (high_ns, period_ns))``, a pulse train equivalent to the command (1000 us stop, 1000
+ 1000 x throttle us, 400 Hz; line low after the command timeout), so the world's ESC model
(calibrated 1000-2000 us, arming on low pulses, signal loss) turns it into thrust unchanged. The
board exposes it as the output port ``can_escN`` (``FmuV2Board``); wiring it to the world's
``escN`` instead of the IO's PWM output is the system's choice.

esc.Status reports the supply voltage (the board's power input, ``supply_v()``) and, since the
node does not see the motor, current, RPM and temperature estimated from the command
(``current ~ throttle^1.5``, ``rpm ~ throttle``): enough for the FMU to show a live ESC, not a
motor measurement.

``set_error_rate(errors_per_s)`` is a failing ESC (a desyncing motor, a brown-out on its
supply, a bad phase): its firmware counts errors at that rate, which esc.Status carries in
``error_count``, and reports NodeStatus health WARNING while the rate is above 0; it still
drives its motor (fault kind ``bus.can_esc_errors``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar, Final

import numpy as np

from board.can import CanBus
from board.kernel import PRIO_HW, Kernel
from firmware.lib.uavcan.transfer import RxTransfer, types
from peripherals.dronecan.node import (ALLOCATION_DTID, HEALTH_OK, HEALTH_WARNING,
                                       NODE_STATUS_DTID, DronecanNode)

__all__ = ["ESC_STATUS_DTID", "EscNode", "RAW_COMMAND_DTID"]

RAW_COMMAND_DTID: Final = 1030
ESC_STATUS_DTID: Final = 1034
RAW_MAX: Final = 8191
STATUS_PERIOD_NS: Final = 100_000_000       # 10 Hz
COMMAND_TIMEOUT_NS: Final = 500_000_000
PWM_PERIOD_NS: Final = 2_500_000            # the equivalent pulse train: 400 Hz
STOP_HIGH_NS: Final = 1_000_000
FULL_SPAN_NS: Final = 1_000_000
MAX_CURRENT_A: Final = 12.0                 # at full throttle (an F450 motor, 10" prop, 3S)
MAX_RPM: Final = 10_000.0
KELVIN: Final = 273.15

OutputFn = Callable[[int, Any], None]


class EscNode(DronecanNode):
    """ESC number ``esc_index`` on CAN: ``EscNode(kernel, bus, esc_index, node_id=0)``."""

    ACCEPT: ClassVar[frozenset[int]] = frozenset({NODE_STATUS_DTID, ALLOCATION_DTID,
                                                  RAW_COMMAND_DTID})
    HW_NAME = "org.hil.esc"
    SW_VERSION = (2, 1)

    def __init__(self, kernel: Kernel, bus: CanBus, esc_index: int, node_id: int = 0,
                 name: str = "can_esc", seed: int = 0, rng: np.random.Generator | None = None,
                 output: OutputFn | None = None,
                 supply_v: Callable[[], float] | None = None) -> None:
        if type(esc_index) is not int or not 0 <= esc_index <= 19:
            raise ValueError(f"ESC node {name}: esc_index must be 0..19, got {esc_index!r}")
        self.esc_index = esc_index
        self.output = output
        self.supply_v = supply_v
        self.raw = 0
        self.commands_rx = 0
        self.status_tx = 0
        self.error_count = 0
        self.error_rate_per_s = 0.0
        self._error_frac = 0.0
        self.timed_out = True
        self._last_cmd_ns = -COMMAND_TIMEOUT_NS
        self._out: tuple[int, int] = (0, PWM_PERIOD_NS)
        self._status_timer: Any = None
        super().__init__(kernel, bus, node_id, name=name, rng=rng, seed=seed)

    @property
    def throttle(self) -> float:
        """The commanded throttle 0..1 (0 when stopped or timed out)."""
        return 0.0 if self.timed_out or self.raw <= 0 else min(self.raw, RAW_MAX) / RAW_MAX

    def _on_ready(self) -> None:
        self._status_timer = self.kernel.call_every(STATUS_PERIOD_NS, self._status,
                                                    priority=PRIO_HW)

    def _on_transfer(self, tr: RxTransfer) -> None:
        if tr.service or tr.data_type_id != RAW_COMMAND_DTID:
            return
        cmd = tr.payload.cmd
        if len(cmd) <= self.esc_index:
            return  # a command for fewer ESCs: not for this one
        self.commands_rx += 1
        self.raw = int(cmd[self.esc_index])
        self._last_cmd_ns = tr.t_ns
        self.timed_out = False
        self._drive(tr.t_ns)

    def _drive(self, t_ns: int) -> None:
        if self.timed_out:
            out = (0, PWM_PERIOD_NS)
        else:
            out = (STOP_HIGH_NS + round(FULL_SPAN_NS * self.throttle), PWM_PERIOD_NS)
        if out != self._out:
            self._out = out
            if self.output is not None:
                self.output(t_ns, out)

    def _status(self) -> None:
        now = self.kernel.now_ns
        if not self.timed_out and now - self._last_cmd_ns >= COMMAND_TIMEOUT_NS:
            self.timed_out = True
            self._drive(now)
        if self.error_rate_per_s > 0:  # the failing ESC's firmware counts errors meanwhile
            self._error_frac += self.error_rate_per_s * STATUS_PERIOD_NS / 1e9
            whole = int(self._error_frac)
            self._error_frac -= whole
            self.error_count = (self.error_count + whole) & 0xFFFFFFFF
        if self.silent:
            return
        th = self.throttle
        s = types().uavcan.equipment.esc.Status()
        s.error_count = self.error_count
        s.voltage = self.supply_v() if self.supply_v is not None else 0.0
        s.current = MAX_CURRENT_A * th ** 1.5
        s.temperature = KELVIN + 25.0 + 30.0 * th
        s.rpm = round(MAX_RPM * th)
        s.power_rating_pct = round(100 * th)
        s.esc_index = self.esc_index
        self.send(s, ESC_STATUS_DTID, now + STATUS_PERIOD_NS)
        self.status_tx += 1

    def set_error_rate(self, errors_per_s: float) -> None:
        """A failing ESC counts errors at ``errors_per_s`` (0: healthy again; the count stays,
        as an ESC's error counter does until it restarts)."""
        rate = float(errors_per_s)
        if not rate >= 0.0:
            raise ValueError(f"ESC node {self.name}: errors_per_s must be >= 0, got {rate!r}")
        self.error_rate_per_s = rate
        self.health = HEALTH_WARNING if rate > 0 else HEALTH_OK

    def set_silent(self, silent: bool = True) -> None:
        super().set_silent(silent)
        if silent:  # a hung ESC MCU stops driving its motor
            self.timed_out = True
            self._drive(self.kernel.now_ns)

    def stats(self) -> dict[str, Any]:
        return super().stats() | {"esc_index": self.esc_index, "raw": self.raw,
                                  "commands_rx": self.commands_rx, "status_tx": self.status_tx,
                                  "timed_out": self.timed_out, "error_count": self.error_count}
