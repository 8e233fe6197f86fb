"""LiPo battery: open-circuit voltage vs state of charge, ohmic sag and a polarisation branch.

Default pack: 3S 5000 mAh LiPo (the usual F450 battery; its mass is inside the airframe's
1.4 kg). Equivalent circuit (one RC Thevenin model, per pack)::

    V = cells * OCV(SOC) - I * r0 - v1,        dv1/dt = (I * r1 - v1) / tau1

* OCV(SOC) is a typical LiPo cell curve (4.20 V full, ~3.84 V at 50 %, 3.27 V empty);
* r0 (ohmic: cells, connectors, wires) gives the instant sag under load and instant partial
  recovery; r1/tau1 give the slower sag and recovery seen after a throttle change;
* SOC = soc0 - used_mah / capacity_mah; used_mah integrates the current (coulomb counting).

The world supplies the current each step (motor electrical power over bus voltage, through the
ESC efficiency, plus the avionics draw); the board's ADC reads ``voltage_v`` and ``current_a``
through its divider and current sensor (that scaling belongs to the board, not here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["BatteryParams", "Battery", "LIPO_OCV_V", "lipo_cell_ocv_v"]

# Typical LiPo cell open-circuit voltage at SOC = 0.00, 0.05, ..., 1.00.
LIPO_OCV_V: tuple[float, ...] = (
    3.27, 3.61, 3.69, 3.71, 3.73, 3.75, 3.77, 3.79, 3.80, 3.82, 3.84,
    3.85, 3.87, 3.91, 3.95, 3.98, 4.02, 4.08, 4.11, 4.15, 4.20,
)  # fmt: skip
_N_SEG = len(LIPO_OCV_V) - 1


def lipo_cell_ocv_v(soc: float) -> float:
    """Open-circuit voltage (V) of one LiPo cell at state of charge soc in [0, 1]."""
    if soc <= 0.0:
        return LIPO_OCV_V[0]
    if soc >= 1.0:
        return LIPO_OCV_V[-1]
    x = soc * _N_SEG
    i = int(x)
    f = x - i
    return LIPO_OCV_V[i] + f * (LIPO_OCV_V[i + 1] - LIPO_OCV_V[i])


@dataclass(frozen=True, slots=True)
class BatteryParams:
    cells: int = 3
    capacity_mah: float = 5000.0
    r0_ohm: float = 0.030  # pack ohmic resistance (3 cells x ~7 mOhm + leads)
    r1_ohm: float = 0.015  # polarisation resistance
    tau1_s: float = 8.0  # polarisation time constant
    soc0: float = 1.0  # state of charge at start
    avionics_a: float = 0.35  # FMU, IO, GPS, telemetry radio, receiver
    esc_efficiency: float = 0.93


class Battery:
    """Pack state. Call ``step(current_a)`` once per world step (dt fixed at construction)."""

    __slots__ = ("params", "voltage_v", "current_a", "used_mah", "soc", "v1_v", "_alpha1",
                 "_alpha_dt", "_cells", "r0_ohm")

    def __init__(self, params: BatteryParams | None = None, dt_s: float = 0.001) -> None:
        p = params or BatteryParams()
        self.params = p
        self._cells = p.cells
        #: ohmic resistance now (a fault raises it: a damaged cell, a loose connector)
        self.r0_ohm = p.r0_ohm
        self.used_mah = 0.0
        self.soc = p.soc0
        self.v1_v = 0.0
        self.current_a = p.avionics_a
        self._alpha_dt = dt_s
        self._alpha1 = 1.0 - math.exp(-dt_s / p.tau1_s) if p.tau1_s > 0 else 1.0
        self.voltage_v = self._cells * lipo_cell_ocv_v(self.soc) - self.current_a * p.r0_ohm

    def force_soc(self, soc: float) -> None:
        """Make the pack hold ``soc`` of its charge now (a pack that was not charged, a cell
        that lost its capacity); it keeps discharging from there. The voltage follows at the
        next step."""
        if not 0.0 <= soc <= 1.0:
            raise ValueError(f"battery state of charge must be in [0, 1], got {soc!r}")
        self.used_mah = (self.params.soc0 - soc) * self.params.capacity_mah
        self.soc = soc

    def set_r0(self, r0_ohm: float) -> None:
        """Ohmic resistance from now on (``params.r0_ohm`` is the healthy pack's)."""
        if not 0.0 <= r0_ohm <= 10.0:
            raise ValueError(f"battery resistance must be in [0, 10] ohm, got {r0_ohm!r}")
        self.r0_ohm = r0_ohm

    @property
    def ocv_v(self) -> float:
        return self._cells * lipo_cell_ocv_v(self.soc)

    def step(self, current_a: float) -> float:
        """Advance one dt with pack current current_a (A, discharge +); returns the voltage."""
        p = self.params
        self.current_a = current_a
        self.used_mah += current_a * self._alpha_dt * (1000.0 / 3600.0)
        soc = p.soc0 - self.used_mah / p.capacity_mah
        self.soc = soc
        v1 = self.v1_v
        v1 += (current_a * p.r1_ohm - v1) * self._alpha1
        self.v1_v = v1
        v = self._cells * lipo_cell_ocv_v(soc) - current_a * self.r0_ohm - v1
        self.voltage_v = v if v > 0.0 else 0.0
        return self.voltage_v
