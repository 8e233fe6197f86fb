"""What every calibration routine shares: the state machine's contract, the raw sensor
instances, calibration slots by device id, and writing and saving the ``CAL_*`` parameters.

Routines read the drivers' raw topics (``sensor_gyro``, ``sensor_accel``, ``sensor_mag``: board
frame, no calibration applied), so a calibration never depends on the one it replaces, and they
write the parameters the sensors module applies (``CAL_<KIND>n_*`` matched by device id,
``SENS_BOARD_*``), so the result takes effect through the same path as a calibration loaded
from FRAM at boot.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Final

from firmware.modules.sensors.calibration import Matrix, board_rotation
from firmware.platform.uorb import Subscription

__all__ = ["CANCELLED", "DONE", "FAILED", "RUNNING", "Routine", "SensorSet", "Say",
           "assign_slots", "write_params"]

RUNNING: Final = 0
DONE: Final = 1
FAILED: Final = 2
CANCELLED: Final = 3
#: sensor instances a routine looks at (PX4 calibrates up to 3 gyros/accels, 4 mags)
MAX_INSTANCES: Final = 4

#: ``say(severity, text)``: a STATUSTEXT through the commander's log (6 info, 4 warn, 2 crit)
Say = Callable[[int, str], None]
INFO: Final = 6
WARN: Final = 4
CRITICAL: Final = 2


class SensorSet:
    """The published instances of one raw sensor topic, each with its own subscription."""

    def __init__(self, orb: Any, topic: str, max_instances: int = MAX_INSTANCES) -> None:
        self.subs: list[Subscription] = []
        self.device_ids: list[int] = []
        for i in range(max_instances):
            sub = Subscription(orb, topic, i)
            last = sub.node.last
            if last is None or not int(last.device_id):
                continue
            self.subs.append(sub)
            self.device_ids.append(int(last.device_id))

    def __len__(self) -> int:
        return len(self.subs)

    def drain(self) -> list[list[Any]]:
        """Every unread sample of every instance (queued since the last call)."""
        return [s.update_all() for s in self.subs]

    def skip(self) -> None:
        """Forget what is queued: collection starts with the next samples."""
        for s in self.subs:
            s.copy()


class Routine:
    """One calibration as a state machine in virtual time.

    The runner calls :meth:`step` every few milliseconds until it returns something other than
    RUNNING; a step never waits, so the commander (and everything else on the board) keeps
    running while the vehicle is being turned. :meth:`cancel` ends it at the next step.
    """

    KIND = ""

    def __init__(self, orb: Any, params: Any, say: Say) -> None:
        self.orb = orb
        self.params = params
        self.say = say
        self.cancelled = False
        self.started_us = -1

    def get(self, name: str) -> float:
        return float(self.params[name])

    def board_rotation(self) -> Matrix:
        return board_rotation(self.get)

    def cancel(self) -> None:
        self.cancelled = True

    def step(self, now_us: int) -> int:
        """Advance; RUNNING, DONE, FAILED or CANCELLED."""
        if self.cancelled:
            return CANCELLED
        if self.started_us < 0:
            # after the command's ACCEPTED ack, as PX4 sends it
            self.started_us = now_us
            self.say(INFO, f"[cal] calibration started: 2 {self.KIND}")
        return self._step(now_us)

    def _step(self, now_us: int) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def finish(self, values: dict[str, float]) -> int:
        """Write ``values``, notify, save (PX4 saves right after a calibration); the QGC
        "done" or "failed" text."""
        ok = write_params(self.params, values)
        if not ok:
            self.say(CRITICAL, "[cal] calibration failed: to save parameters")
            return FAILED
        self.say(INFO, "[cal] progress <100>")
        self.say(INFO, f"[cal] calibration done: {self.KIND}")
        return DONE


def assign_slots(params: Any, kind: str, n_slots: int, device_ids: list[int]) -> list[int]:
    """A ``CAL_<kind>n`` slot per device: the one already holding its id, else the first free
    one (id 0) not given to another device here, else -1 (no room)."""
    slots: list[int] = []
    for dev in device_ids:
        slot = -1
        for n in range(n_slots):
            if int(params[f"CAL_{kind}{n}_ID"]) == dev:
                slot = n
                break
        if slot < 0:
            for n in range(n_slots):
                if n not in slots and int(params[f"CAL_{kind}{n}_ID"]) in (0, dev):
                    slot = n
                    break
        slots.append(slot)
    return slots


def write_params(params: Any, values: dict[str, float]) -> bool:
    """Set every value without a notification each, then one ``parameter_update`` (the sensors
    module reloads its calibrations) and a save to FRAM; False if the save failed."""
    for name, value in values.items():
        params.set(name, value, notify=False)
    params.notify()
    if params.storage is None:
        return True
    return bool(params.save())
