"""Faults a device model can be told to exhibit, the same set for every model.

Faults act where they happen on a real board: the chip answers a wrong ID, its data freezes or
turns to noise, it drops off the bus (an SPI chip that no longer drives MISO reads 0xFF; an I2C
chip stops ACKing), it stops raising data-ready, it saturates, or its output gains a bias step (the FMU board ramps
it for a drift, ``FmuV2Board.ctl_sensor_drift``), or a memory stops taking writes; its output
gains extra noise (``noise``), its FIFO overflows on every read (``fifo_overflow``), or its
identity goes wrong at its next reset (``wrong_id_after_reset``); its results stop coming
(``stale``), its diagnostics flag a fault (``diag_fault``), or its pressure port is blocked
(``port_blocked``: the pitot tube iced or full of water, a crushed hose).
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
    #: extra white noise on the chip's output: output name ("gyro", "accel", "mag", "pressure")
    #: -> sigma per sample per axis in SI units (rad/s, m/s^2, gauss, Pa); None: off
    noise: dict[str, float] | None = None
    fifo_overflow: bool = False     # the FIFO fills faster than it is read (MPU6000)
    #: the identity register reads this value after the next reset or power-on (a part that
    #: comes back wrong from a reset); None: off
    wrong_id_after_reset: int | None = None
    #: new results never become ready: the chip keeps answering its last data flagged stale
    #: (MS4525DO status 2, a conversion that never completes)
    stale: bool = False
    #: the chip's own diagnostics report a fault (MS4525DO status 3: a broken bridge
    #: connection, a corrupted calibration memory)
    diag_fault: bool = False
    #: a pressure port is blocked (pitot-static plumbing): "stuck" holds the pressure it had
    #: when it blocked, "zero" equalises both sides of a differential sensor; "": clear
    port_blocked: str = ""

    def clear(self) -> None:
        self.__init__()  # type: ignore[misc]

    @property
    def any(self) -> bool:
        return self != FaultState()
