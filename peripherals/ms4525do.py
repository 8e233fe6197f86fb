"""TE (MEAS) MS4525DO digital differential pressure sensor on I2C (address 0x28): the airspeed
sensor of the Pixhawk kits, modelled at its I2C bytes.

The part PX4's ``ms4525_airspeed`` driver expects is the +-1 psi differential one with output
type A (MS4525DO-DS5AI001DP: I2C interface "I" at 0x28, output 10 % to 90 % of 2^14 counts).
The chip has no registers and no commands; what a driver sees (datasheet sections 1.5-1.6):

* **Measurement request** (Read_MR / Write_MR): a transaction that addresses the chip for
  writing (an address-only quick write, or PX4's one-byte write; the bytes are ACKed and
  ignored) starts a conversion, which lands ``CONVERSION_NS`` later. A request while one runs
  is ignored (the running one lands).
* **Data fetch** (Read_DF2/3/4): a read returns status (bits 15:14) and the 14-bit bridge
  count in two bytes, then the temperature: byte 3 holds its 8 high bits, byte 4's top three
  bits complete the 11-bit count and its five low bits are undetermined (this model sets them).
  Bytes beyond the fourth read 0xFF (nobody drives SDA).
* **Status**: 0 "normal operation, good data packet" for the first fetch of a new result;
  2 "stale data that has been already fetched" for any later fetch, and for a fetch before the
  first conversion (data 0); 3 "fault detected" from the chip's diagnostics; 1 is reserved.

Transfer functions (datasheet figure "pressure transfer function", type A):

    counts = 0.8 * 16383 * (P - Pmin) / (Pmax - Pmin) + 0.1 * 16383,  P in psi, Pmin/Pmax = -1/+1
    T_degC = counts_T * 200 / 2047 - 50

P is the datasheet's port 1 minus port 2. On the Pixhawk kit the pitot's total pressure goes to
the port that makes P negative (PX4's driver negates the result so that airspeed comes out
positive), so the model's bridge sees ``-diff_pressure_pa``. Counts clip at 0 and 16383 (2047
for the temperature), as the 14-bit output does beyond its range.

Inputs: ``env.diff_pressure_pa`` (pitot minus static, the world's dynamic pressure) and
``env.temperature_c`` (the air at the probe), plus white noise from the board's per-device
random stream (``PRESSURE_NOISE_PA``, ``TEMPERATURE_NOISE_C``: the datasheet gives a total
error band, not a noise figure; these are about one count, which is what a still sensor on a
real Pixhawk shows) and an optional zero offset (what SENS_DPRES_OFF calibrates away).

Faults (:class:`peripherals.faults.FaultState`): ``absent`` NAKs; ``frozen`` lands every new
result with the counts of the last one; ``random_data`` reads random bytes (status bits
included); ``saturate`` reads full-scale counts; ``bias_step`` adds Pa (x) and degC (y);
``noise`` {"pressure": sigma Pa}; ``stale`` never lands a conversion (every fetch is status 2);
``diag_fault`` reads status 3; ``port_blocked`` "stuck" holds the differential pressure of the
moment the pitot blocked, "zero" reads no differential (both ports at static pressure).
"""

from __future__ import annotations

import logging
from typing import Final

import numpy as np

from board.gpio import Pin
from board.i2c import I2cTarget
from board.kernel import PRIO_HW, Event, Kernel
from peripherals.faults import FaultState
from peripherals.physics import Environment

__all__ = [
    "CONVERSION_NS",
    "I2C_ADDRESS",
    "PSI_PA",
    "STATUS_FAULT",
    "STATUS_NORMAL",
    "STATUS_STALE",
    "Ms4525do",
    "counts_from_pressure_pa",
    "counts_from_temperature_c",
    "pressure_pa_from_counts",
    "temperature_c_from_counts",
]

log = logging.getLogger(__name__)

I2C_ADDRESS: Final = 0x28
PSI_PA: Final = 6894.757            # pascal per psi
P_MIN_PSI: Final = -1.0             # 001PD: +-1 psi differential
P_MAX_PSI: Final = 1.0
FULL_COUNTS: Final = 16383          # 14-bit output
OUT_MIN: Final = 0.1 * FULL_COUNTS  # output type A: 10 % ...
OUT_SPAN: Final = 0.8 * FULL_COUNTS  # ... to 90 %
TEMP_FULL_COUNTS: Final = 2047      # 11-bit temperature
#: response time of one measurement (the datasheet's 0.5 ms): a fetch sooner reads stale
CONVERSION_NS: Final = 500_000
STATUS_NORMAL: Final = 0
STATUS_STALE: Final = 2
STATUS_FAULT: Final = 3
PRESSURE_NOISE_PA: Final = 1.0      # ~1 count (1.05 Pa per count)
TEMPERATURE_NOISE_C: Final = 0.05   # half a count (0.098 degC per count)
_UNDETERMINED: Final = 0x1F         # the low five bits of byte 4


def counts_from_pressure_pa(p_pa: float) -> int:
    """The 14-bit bridge count of a pressure (datasheet's P, port 1 minus port 2), clipped."""
    c = round(OUT_SPAN * (p_pa / PSI_PA - P_MIN_PSI) / (P_MAX_PSI - P_MIN_PSI) + OUT_MIN)
    return min(max(c, 0), FULL_COUNTS)


def pressure_pa_from_counts(counts: int) -> float:
    """The datasheet's transfer function read backwards: count -> P in Pa (port 1 - port 2)."""
    return ((counts - OUT_MIN) * (P_MAX_PSI - P_MIN_PSI) / OUT_SPAN + P_MIN_PSI) * PSI_PA


def counts_from_temperature_c(t_c: float) -> int:
    """The 11-bit temperature count, clipped (-50..150 degC)."""
    return min(max(round((t_c + 50.0) * TEMP_FULL_COUNTS / 200.0), 0), TEMP_FULL_COUNTS)


def temperature_c_from_counts(counts: int) -> float:
    return counts * 200.0 / TEMP_FULL_COUNTS - 50.0


class Ms4525do(I2cTarget):
    """The MS4525DO; attach with ``bus.attach(0x28, Ms4525do(...))``."""

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "ms4525do", drdy_pin: Pin | None = None,
                 zero_offset_pa: float = 0.0) -> None:
        self.kernel = kernel
        self.env = env
        self.rng = rng
        self.name = name
        self.faults = FaultState()
        self.zero_offset_pa = zero_offset_pa
        #: the last result: (bridge count, temperature count); None before the first
        self.result: tuple[int, int] | None = None
        self.fetched = True          # the result has been read once already
        self.conversions = 0
        self.requests_ignored = 0    # measurement requests while a conversion ran
        self._event: Event | None = None
        self._held_pa: float | None = None   # a "stuck" blocked pitot's trapped pressure
        self._warned_bytes = False

    # -- I2C hooks -------------------------------------------------------------------------

    def _start(self, t_ns: int, is_read: bool) -> bool:
        if self.faults.absent:
            return False
        if not is_read:
            self._request(t_ns)
        return True

    def _write(self, t_ns: int, data: bytes) -> int:
        if any(data) and not self._warned_bytes:
            self._warned_bytes = True
            log.info("%s: bytes %s after a measurement request ignored (no command set)",
                     self.name, data.hex(" "))
        return len(data)

    def _read(self, t_ns: int, n: int) -> bytes:
        f = self.faults
        if f.random_data:
            return bytes(int(b) for b in self.rng.integers(0, 256, min(n, 4)))
        if self.result is None:
            p_counts, t_counts = 0, 0
        else:
            p_counts, t_counts = self.result
        status = STATUS_FAULT if f.diag_fault else STATUS_STALE if self.fetched else STATUS_NORMAL
        if n:
            self.fetched = True
        t11 = t_counts << 5 | _UNDETERMINED
        packet = bytes((status << 6 | p_counts >> 8, p_counts & 0xFF, t11 >> 8, t11 & 0xFF))
        return packet[:n]

    # -- conversions -----------------------------------------------------------------------

    def _request(self, t_ns: int) -> None:
        if self._event is not None:
            self.requests_ignored += 1
            return
        if self.faults.stale:
            return   # the conversion never completes
        self._event = self.kernel.call_at(max(t_ns, self.kernel.now_ns) + CONVERSION_NS,
                                          self._land, priority=PRIO_HW)

    def _land(self) -> None:
        self._event = None
        if self.faults.stale:
            return
        self.conversions += 1
        if self.faults.frozen and self.result is not None:
            self.fetched = False
            return
        self.result = self._measure()
        self.fetched = False

    def differential_input_pa(self) -> float:
        """What reaches the sensor's ports (pitot minus static), blocked plumbing included."""
        f = self.faults
        dp = self.env.diff_pressure_pa
        if f.port_blocked == "zero":
            dp = 0.0
        elif f.port_blocked == "stuck":
            if self._held_pa is None:
                self._held_pa = dp
            dp = self._held_pa
        if f.port_blocked != "stuck":
            self._held_pa = None
        return dp

    def _measure(self) -> tuple[int, int]:
        f = self.faults
        if f.saturate:
            return FULL_COUNTS, counts_from_temperature_c(self.env.temperature_c)
        sigma_p = PRESSURE_NOISE_PA
        nz = f.noise
        if nz:
            extra = nz.get("pressure", 0.0)
            sigma_p = (sigma_p * sigma_p + extra * extra) ** 0.5
        noise_p, noise_t = self.rng.normal(0.0, 1.0, 2)
        dp = self.differential_input_pa() + self.zero_offset_pa + f.bias_step[0] \
            + sigma_p * float(noise_p)
        temp = self.env.temperature_c + f.bias_step[1] + TEMPERATURE_NOISE_C * float(noise_t)
        # port 1 - port 2 is minus the pitot's differential pressure as plumbed (module doc)
        return counts_from_pressure_pa(-dp), counts_from_temperature_c(temp)

    def power_cycle(self) -> None:
        """Supply off and on: no result, nothing running."""
        if self._event is not None:
            self.kernel.cancel(self._event)
            self._event = None
        self.result = None
        self.fetched = True
        self._held_pa = None

    def __repr__(self) -> str:
        return f"<Ms4525do {self.name}>"
