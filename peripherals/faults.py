"""Faults a device model can be told to exhibit, the same set for every model.

Faults act where they happen on a real board: the chip answers a wrong ID, its data freezes or
turns to noise, it drops off the bus (an SPI chip that no longer drives MISO reads 0xFF; an I2C
chip stops ACKing), it stops raising data-ready, it saturates, or its output gains a bias step (the FMU board ramps
it for a drift, ``FmuV2Board.ctl_sensor_drift``), or a memory stops taking writes.
The driver must notice what a PX4 driver would notice; the model never tells it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FaultState"]


@dataclass
class FaultState:
    wrong_id: int | None = None     # identity register(s) read this value instead
    frozen: bool = False            # data registers stop updating (stuck sample)
    random_data: bool = False       # data registers read random bytes
    absent: bool = False            # no response on the bus (SPI: MISO high, I2C: NAK)
    drdy_stuck: bool = False        # data-ready line never asserts
    saturate: bool = False          # every axis reads its positive full scale
    bias_step: tuple[float, float, float] = (0.0, 0.0, 0.0)  # added in SI units
    write_fail: bool = False        # a memory's write enable never latches (FRAM: WREN ignored)

    def clear(self) -> None:
        self.__init__()  # type: ignore[misc]

    @property
    def any(self) -> bool:
        return self != FaultState()
