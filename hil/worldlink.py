"""The world as the orchestrator sees it: named ports, like a board.

Outputs: ``truth`` (every world step, the physical quantities at the FMU's sensors as a plain
tuple in :data:`TRUTH_FIELDS` order) and ``battery`` (voltage, current). Inputs: ``esc1`` ..
``esc8`` (PWM pulse width and period from the IO's MAIN outputs; world channels 0..7) and
``aux1`` .. ``aux6`` (the FMU's AUX outputs; world channels 8..13). What a channel drives (an
ESC and motor, a servo, nothing) is the airframe's data (``hil.world.fdm.Airframe.outputs``).

:class:`WorldPorts` is a :class:`hil.devices.HostDevice`: the orchestrator takes it as its
``world`` alone, or behind a :class:`hil.devices.DeviceHub` beside other host devices.
"""

from __future__ import annotations

from operator import attrgetter
from typing import Any

from board.protocols import Record
from hil.world import World
from hil.world.fdm import N_MAIN
from common.truth import TRUTH_FIELDS, Truth

__all__ = ["WorldPorts", "TRUTH_FIELDS", "truth_record", "truth_from_record"]

#: one C call instead of a generator over 19 getattr calls (truth leaves every world step)
_truth_fields = attrgetter(*TRUTH_FIELDS)


def truth_record(truth: Truth) -> tuple:
    return _truth_fields(truth)


def truth_from_record(record: tuple) -> Truth:
    return Truth(*record)


class WorldPorts:
    """Wraps a :class:`World` with the port interface the orchestrator routes through."""

    ports: tuple[str, ...] = ("truth", "battery", *(f"esc{i}" for i in range(1, 9)),
                              *(f"aux{i}" for i in range(1, 7)))

    def __init__(self, world: World | None = None, truth_every_steps: int = 1, **kwargs: Any
                 ) -> None:
        self.world = world if world is not None else World(**kwargs)
        self.truth_every_steps = truth_every_steps
        self._out: list[Record] = []
        #: Output ports something is wired to (set by the orchestrator); None means all.
        #: Truth costs as much as a JSBSim step, so it is only computed when it goes somewhere.
        self.wired: set[str] | None = None

    @property
    def t_ns(self) -> int:
        return self.world.t_ns

    def run_until(self, t_ns: int) -> None:
        w = self.world
        wired = self.wired
        if wired is not None and "truth" not in wired:
            w.run_until(t_ns)
        else:
            every = self.truth_every_steps
            append = self._out.append
            step, truth, dt_ns = w.step, w.truth, w.dt_ns
            while w.t_ns + dt_ns <= t_ns:
                step()
                if w.steps % every == 0:
                    append(("truth", w.t_ns, _truth_fields(truth())))
        if wired is None or "battery" in wired:
            self._out.append(("battery", w.t_ns, (w.battery.voltage_v, w.battery.current_a)))

    def outputs(self, until_ns: int) -> list[Record]:
        out = self._out
        self._out = []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        if port.startswith("esc"):
            high_ns, period_ns = payload
            self.world.set_pwm(int(port[3:]) - 1, t_ns, high_ns, period_ns)
        elif port.startswith("aux") and port in self.ports:
            high_ns, period_ns = payload
            self.world.set_pwm(N_MAIN + int(port[3:]) - 1, t_ns, high_ns, period_ns)
        else:
            raise ValueError(f"world has no input port {port!r}")
