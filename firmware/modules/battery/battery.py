"""Battery estimation from the power module: volts and amps through the FMU's ADC.

The estimate follows PX4's analog battery (behaviour, not code):

* volts = counts * vref / full scale * BAT_V_DIV, amps = (counts * vref / full scale -
  BAT_V_OFFS_CURR) * BAT_A_PER_V; a negative BAT_V_DIV / BAT_A_PER_V means "the board's divider"
  (FMUv2 power module: 10.177939394 V/V and 15.391030303 A/V, from the board spec);
* both filtered with first-order low passes (voltage tau 1 s, current 0.5 s) so that motor
  transients do not trip warnings;
* discharged mAh integrates the unfiltered current (it is the one quantity that must not lag);
* remaining: the voltage-based state of charge uses the per-cell voltage compensated for the
  load (BAT_R_INTERNAL x current), linear between BAT_V_EMPTY and BAT_V_CHARGED. With a known
  BAT_CAPACITY it seeds a coulomb-counting estimate which the voltage estimate then corrects
  slowly (weighted more as the pack empties, where the voltage curve is steep and informative);
* warning levels from remaining against BAT_LOW_THR / BAT_CRIT_THR / BAT_EMERGEN_THR; they only
  ever increase while the battery stays connected (a voltage bounce under lower load must not
  clear a critical warning in flight).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from firmware.platform.module import ModuleError, WorkItemModule
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["FMUV2_A_PER_V", "FMUV2_V_DIV", "PARAMS", "BatteryStatusModule"]

FMUV2_V_DIV = 10.177939394
FMUV2_A_PER_V = 15.391030303
FMUV2_V_CHANNEL, FMUV2_A_CHANNEL = 2, 3
CONNECTED_V = 2.1           # below this the ADC sees an open input: no battery
V_TAU_S, A_TAU_S = 1.0, 0.5
INTERVAL_US = 100_000       # 10 Hz, as PX4's battery_status module
_G = "Battery Calibration"

PARAMS: tuple[ParamDef, ...] = (
    ParamDef("BAT_V_DIV", "FLOAT", -1.0, group=_G, decimals=8,
             short="Battery voltage divider (V divider)",
             long="Multiplier from ADC volts to battery volts; -1 uses the board's divider."),
    ParamDef("BAT_A_PER_V", "FLOAT", -1.0, group=_G, decimals=8,
             short="Battery current per volt (A/V)",
             long="Multiplier from ADC volts to battery amps; -1 uses the board's value."),
    ParamDef("BAT_V_OFFS_CURR", "FLOAT", 0.0, group=_G, unit="V", decimals=8,
             short="Offset in volt as seen by the ADC input of the current sensor"),
    ParamDef("BAT_N_CELLS", "INT32", 3, min=1, max=14, group=_G, short="Number of cells"),
    ParamDef("BAT_CAPACITY", "FLOAT", -1.0, min=-1.0, max=100000.0, unit="mAh", group=_G,
             short="Battery capacity", long="-1: unknown, remaining is voltage based only.",
             decimals=0),
    ParamDef("BAT_V_CHARGED", "FLOAT", 4.05, min=0.0, unit="V", group=_G, decimals=2,
             short="Full cell voltage (5C load)"),
    ParamDef("BAT_V_EMPTY", "FLOAT", 3.5, min=0.0, unit="V", group=_G, decimals=2,
             short="Empty cell voltage (5C load)"),
    ParamDef("BAT_R_INTERNAL", "FLOAT", 0.005, min=-1.0, max=0.2, unit="Ohm", group=_G,
             decimals=4, short="Explicitly defines the per cell internal resistance",
             long="Used to compensate the cell voltage for the drop under load; -1 disables."),
    ParamDef("BAT_LOW_THR", "FLOAT", 0.15, min=0.12, max=0.5, unit="norm", group=_G,
             decimals=2, short="Low threshold (warning)"),
    ParamDef("BAT_CRIT_THR", "FLOAT", 0.07, min=0.05, max=0.25, unit="norm", group=_G,
             decimals=2, short="Critical threshold"),
    ParamDef("BAT_EMERGEN_THR", "FLOAT", 0.05, min=0.03, max=0.1, unit="norm", group=_G,
             decimals=2, short="Emergency threshold"),
    ParamDef("BAT_SOURCE", "INT32", 0, min=-1, max=2, group=_G,
             short="Battery monitoring source", values={-1: "Disabled", 0: "Power Module",
                                                        1: "External", 2: "ESCs"}),
)


class BatteryStatusModule(WorkItemModule):
    """Samples the power-module ADC channels at 10 Hz and publishes ``battery_status``.

    The ADC comes from the ``adc`` argument, else ``system.adc``; the channels and dividers
    from the board spec (``system.board.adc`` entries ``battery_voltage``/``battery_current``),
    else FMUv2's channels 2 and 3.
    """

    NAME = "battery_status"
    DESCRIPTION = "battery voltage, current, consumption and remaining from the ADC"
    WQ = "wq:lp_default"
    INTERVAL_US = INTERVAL_US
    CPU_COST_NS = 40_000
    PARAMS = PARAMS

    def __init__(self, system: System, args: Sequence[str] = (), adc: Any = None) -> None:
        super().__init__(system, args)
        self.adc = adc if adc is not None else getattr(system, "adc", None)
        self.v_channel, self.a_channel = FMUV2_V_CHANNEL, FMUV2_A_CHANNEL
        self.board_v_div, self.board_a_per_v = FMUV2_V_DIV, FMUV2_A_PER_V
        spec = getattr(system, "board", None)
        for ch in getattr(spec, "adc", ()) or ():
            if ch.signal == "battery_voltage":
                self.v_channel, self.board_v_div = ch.channel, ch.scale
            elif ch.signal == "battery_current":
                self.a_channel, self.board_a_per_v = ch.channel, ch.scale

    def _start(self) -> None:
        if self.adc is None:
            raise ModuleError(f"{self.name}: no ADC on this system (System.adc is not set)")
        self._pub = self.advertise("battery_status")
        self._msg = self.platform.orb.new("battery_status")
        self._sub_param = self.subscribe("parameter_update")
        self._lsb_v = self.adc.vref_v / self.adc.full_scale
        self._load_params()
        self.reset()

    def reset(self) -> None:
        """Forget the filters and the consumption (a new pack was connected)."""
        self.v_filt: float | None = None
        self.a_filt = 0.0
        self.discharged_mah = 0.0
        self.soc: float | None = None
        self.warning = 0
        self._last_us: int | None = None

    def _load_params(self) -> None:
        p = self.param
        v_div, a_per_v = float(p("BAT_V_DIV")), float(p("BAT_A_PER_V"))
        self.v_div = v_div if v_div > 0 else self.board_v_div
        self.a_per_v = a_per_v if a_per_v > 0 else self.board_a_per_v
        self.v_offs_curr = float(p("BAT_V_OFFS_CURR"))
        self.n_cells = int(p("BAT_N_CELLS"))
        self.capacity = float(p("BAT_CAPACITY"))
        self.v_charged, self.v_empty = float(p("BAT_V_CHARGED")), float(p("BAT_V_EMPTY"))
        self.r_internal = float(p("BAT_R_INTERNAL"))
        self.low_thr, self.crit_thr = float(p("BAT_LOW_THR")), float(p("BAT_CRIT_THR"))
        self.emergen_thr = float(p("BAT_EMERGEN_THR"))
        self.enabled = int(p("BAT_SOURCE")) == 0

    # -- estimation (plain floats: it runs at 10 Hz for the whole flight) ---------------------

    def volts_amps(self) -> tuple[float, float]:
        """Read both ADC channels: (battery volts, battery amps)."""
        lsb = self._lsb_v
        volts = self.adc.read(self.v_channel) * lsb * self.v_div
        amps = (self.adc.read(self.a_channel) * lsb - self.v_offs_curr) * self.a_per_v
        return volts, amps

    def soc_from_voltage(self, volts: float, amps: float) -> float:
        """State of charge 0..1 from the load-compensated cell voltage."""
        cell = volts / self.n_cells
        if self.r_internal > 0:
            cell += self.r_internal * amps
        span = self.v_charged - self.v_empty
        soc = (cell - self.v_empty) / span if span > 0 else 0.0
        return 0.0 if soc < 0 else 1.0 if soc > 1 else soc

    def update(self, now_us: int, volts: float, amps: float) -> Any:
        """One estimation step; returns the battery_status message (not yet published)."""
        m = self._msg
        dt = 0.0 if self._last_us is None else (now_us - self._last_us) * 1e-6
        self._last_us = now_us
        connected = volts > CONNECTED_V
        if not connected:
            if self.v_filt is not None:
                self.reset()
                self._last_us = now_us
        else:
            if self.v_filt is None:
                self.v_filt, self.a_filt = volts, max(amps, 0.0)
            elif dt > 0:
                kv, ka = dt / (V_TAU_S + dt), dt / (A_TAU_S + dt)
                self.v_filt += kv * (volts - self.v_filt)
                self.a_filt += ka * (amps - self.a_filt)
            if amps > 0 and dt > 0:
                self.discharged_mah += amps * dt * (1000.0 / 3600.0)
            self._update_soc(dt)
        soc = self.soc if self.soc is not None else 0.0
        if connected:
            level = (3 if soc < self.emergen_thr else 2 if soc < self.crit_thr
                     else 1 if soc < self.low_thr else 0)
            self.warning = max(self.warning, level)
        m.timestamp = now_us
        m.connected = connected
        m.voltage_v = volts
        m.voltage_filtered_v = self.v_filt if self.v_filt is not None else volts
        m.current_a = amps
        m.current_filtered_a = self.a_filt
        m.current_average_a = self.a_filt
        m.discharged_mah = self.discharged_mah
        m.remaining = soc
        m.scale = 1.0
        m.temperature = float("nan")
        m.cell_count = self.n_cells
        m.source = 0
        m.capacity = int(self.capacity) if self.capacity > 0 else 0
        m.warning = self.warning
        return m

    def _update_soc(self, dt: float) -> None:
        soc_v = self.soc_from_voltage(self.v_filt or 0.0, self.a_filt)
        if self.capacity <= 0:
            self.soc = soc_v
            return
        if self.soc is None:  # a fresh pack: the voltage is the only information
            self.soc = soc_v
            self._mah_at_soc = self.discharged_mah
            return
        used = self.discharged_mah - self._mah_at_soc
        self._mah_at_soc = self.discharged_mah
        soc = self.soc - used / self.capacity
        w = 3e-4 * dt * 10.0 * (1.0 - soc_v)  # per 10 Hz step, as PX4's weighting
        soc = (1.0 - w) * soc + w * soc_v
        self.soc = 0.0 if soc < 0 else 1.0 if soc > 1 else soc

    # -- the loop ---------------------------------------------------------------------------

    def run(self) -> None:
        if self._sub_param.updated():
            self._sub_param.copy()
            self._load_params()
        if not self.enabled:
            return
        volts, amps = self.volts_amps()
        self._pub.publish(self.update(self.platform.time_us(), volts, amps))

    def status_lines(self) -> list[str]:
        m = self._msg
        return [(f"{m.voltage_filtered_v:.2f} V, {m.current_filtered_a:.2f} A, "
                 f"{m.discharged_mah:.0f} mAh used, remaining {m.remaining * 100:.0f} %, "
                 f"warning {m.warning}")]
