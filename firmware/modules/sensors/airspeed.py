"""The sensors module's airspeed part: ``differential_pressure`` in, ``airspeed`` out.

As in PX4 1.x (``Sensors::diff_pres_poll``), the airspeed is computed where the barometer is
voted, because the true airspeed needs the air density:

* indicated airspeed from the filtered differential pressure at sea-level density,
  ``IAS = sqrt(2 dp / 1.225)``, and 0 for a negative pressure (PX4's
  ``calc_IAS_corrected`` for a membrane sensor such as the MS4525DO: no tube-loss
  correction, never a negative airspeed);
* true airspeed ``TAS = IAS * sqrt(1.225 / rho)`` with ``rho = p / (R (T + 273.15))`` from the
  selected barometer's pressure (``vehicle_air_data``) and the air temperature: the airspeed
  sensor's own, or the barometer's less 5 degC (PX4's PCB_TEMP_ESTIMATE_DEG) if it has none;
* ``confidence`` in 0..1, PX4's DataValidator for the airspeed sensor (timeout 300 ms, the
  same raw value 100 times in a row is a stuck sensor, each new driver error raises the error
  density, 1 - density/100), set to 0 while the consistency check below fails.

The consistency check is the airspeed selector's innovation check reduced to what this
stack estimates (no wind estimate): while the vehicle moves over ground faster than
ASPD_STALL, a ground speed that exceeds the true airspeed by more than ASPD_FS_INNOV (a
tailwind larger than that) for ASPD_FS_T_STOP seconds declares the airspeed invalid: a
pitot that reads zero, or stays stuck while the vehicle speeds up. It is valid again after
ASPD_FS_T_START seconds without a failing sample. A reading too *high* for the ground speed
is a headwind and never fails it.

``ASPD_DO_CHECKS`` selects the checks as PX4's bitmask does (bit 1 data stuck, bit 2 the
consistency check above, bit 3 the load factor check; the data-missing timeout always runs;
PX4's default 7 leaves the load factor check off). The load factor check is PX4's
``AirspeedValidator::check_load_factor``: in fixed-wing flight (armed, a fixed-wing vehicle
type, not landed) the measured load factor ``|a_z| / g`` cannot exceed what the wing can lift
at the measured airspeed, ``(CAS / ASPD_STALL)^2``; their ratio, filtered (0.95/0.05 per
20 Hz run, PX4's rate), above 1.1 fails it. A pitot that blocks reads ~0 while the wing still
carries 1 g: the ratio saturates at once. As in PX4's ``update_airspeed_valid_status``, the
consistency and load factor checks failing *together* declare the airspeed invalid at once
(a large fault is then likely), either one alone only after ASPD_FS_T_STOP.

Nothing is advertised until the first ``differential_pressure`` sample arrives, so a board
without an airspeed sensor (the quadrotor) publishes and logs exactly what it did before.
A sensor that falls silent gets one more ``airspeed`` with confidence 0 every 100 ms (the
last values), so its consumers see the loss instead of an old message.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Final

from firmware.platform.params import ParamDef
from firmware.platform.uorb import Publication, Subscription

__all__ = ["AIRSPEED_PARAMS", "Airspeed", "AirspeedValidator", "LoadFactorCheck", "ias_m_s",
           "tas_m_s"]

RHO0: Final = 1.225                   # kg/m^3, ISA sea level 15 degC
R_AIR: Final = 287.1                  # J/(kg K), PX4's CONSTANTS_AIR_GAS_CONST
KELVIN: Final = 273.15
PCB_TEMP_ESTIMATE_DEG: Final = 5.0    # the FMU's baro runs this much warmer than the air
TIMEOUT_US: Final = 300_000           # PX4: _airspeed_validator.set_timeout(300000)
EQUAL_VALUE_COUNT: Final = 100        # PX4: set_equal_value_threshold(100)
ERROR_DENSITY_WINDOW: Final = 100.0   # PX4 DataValidator
SILENT_REPUBLISH_US: Final = 100_000
CHECK_DATA_STUCK: Final = 1 << 1      # ASPD_DO_CHECKS bits (PX4's)
CHECK_INNOVATION: Final = 1 << 2
CHECK_LOAD_FACTOR: Final = 1 << 3
LOAD_FACTOR_PERIOD_S: Final = 0.05    # PX4 airspeed_selector's run period: its filter's unit
G_LOAD: Final = 9.81                  # PX4's figure in check_load_factor
VEHICLE_TYPE_FIXED_WING: Final = 2
ARMING_STATE_ARMED: Final = 2

_GROUP: Final = "Airspeed Validator"

AIRSPEED_PARAMS: Final[tuple[ParamDef, ...]] = (
    ParamDef("SENS_DPRES_OFF", "FLOAT", 0.0, unit="Pa", group="Sensor Calibration",
             short="Differential pressure sensor offset",
             long="The offset (zero-reading) in Pa, subtracted by the airspeed sensor's driver "
                  "from every sample (what an airspeed calibration measures with the pitot "
                  "covered).", decimals=2),
    ParamDef("ASPD_STALL", "FLOAT", 10.0, min=0.0, max=40.0, unit="m/s", group=_GROUP,
             short="Airspeed fault detection stall airspeed",
             long="The consistency check runs only while the ground speed is above this: below "
                  "it the vehicle may be on the ground or hovering.", decimals=1),
    ParamDef("ASPD_FS_INNOV", "FLOAT", 5.0, min=0.5, max=20.0, unit="m/s", group=_GROUP,
             short="Airspeed failsafe consistency threshold",
             long="How far the ground speed may exceed the true airspeed (a tailwind) before "
                  "the airspeed is suspect. This stack has no wind estimate, so this is also "
                  "the largest tailwind the check tolerates.", decimals=1),
    ParamDef("ASPD_FS_T_STOP", "FLOAT", 2.0, min=0.0, max=10.0, unit="s", group=_GROUP,
             short="Airspeed failsafe stop delay",
             long="How long the consistency check must fail before the airspeed is declared "
                  "invalid (confidence 0).", decimals=1),
    ParamDef("ASPD_DO_CHECKS", "INT32", 7, min=0, max=31, group=_GROUP,
             short="Enable checks on airspeed sensors",
             long="Bitmask of the checks that can declare the airspeed invalid: bit 0 data "
                  "missing (always on), bit 1 data stuck, bit 2 consistency with the ground "
                  "speed (ASPD_FS_INNOV), bit 3 load factor (the measured load factor more "
                  "than the wing can lift at the measured airspeed, ASPD_STALL). The "
                  "consistency and load factor checks failing together invalidate the "
                  "airspeed at once."),
    ParamDef("ASPD_FS_T_START", "FLOAT", 10.0, min=0.0, max=1000.0, unit="s", group=_GROUP,
             short="Airspeed failsafe start delay",
             long="How long the consistency check must pass before an airspeed declared "
                  "invalid is used again.", decimals=1),
)


def ias_m_s(diff_pressure_pa: float) -> float:
    """Indicated airspeed of a differential pressure (0 for a negative or NaN one)."""
    if not diff_pressure_pa > 0.0:
        return 0.0
    return math.sqrt(2.0 * diff_pressure_pa / RHO0)


def tas_m_s(ias: float, pressure_pa: float, temperature_c: float) -> float:
    """True airspeed from the indicated one at this static pressure and air temperature."""
    rho = pressure_pa / (R_AIR * (temperature_c + KELVIN))
    if not rho > 0.0:
        return float("nan")
    return ias * math.sqrt(RHO0 / rho)


class AirspeedValidator:
    """PX4's DataValidator as the sensors module sets it up for the airspeed sensor."""

    def __init__(self) -> None:
        self.error_density = 0.0
        self.error_count = 0
        self.equal_count = 0
        self.last_value = float("nan")
        self.last_us = 0
        self.stuck = False

    def put(self, t_us: int, value: float, error_count: int) -> None:
        if error_count > self.error_count:
            self.error_density += error_count - self.error_count
        elif self.error_density > 0.0:
            self.error_density -= 1.0
        self.error_count = error_count
        self.error_density = min(self.error_density, ERROR_DENSITY_WINDOW)
        if value == self.last_value:
            self.equal_count += 1
        else:
            self.equal_count = 0
        self.stuck = self.equal_count > EQUAL_VALUE_COUNT
        self.last_value = value
        self.last_us = t_us

    def timed_out(self, now_us: int) -> bool:
        return self.last_us == 0 or now_us - self.last_us > TIMEOUT_US

    def confidence(self, now_us: int, stuck_check: bool = True) -> float:
        if self.timed_out(now_us) or (self.stuck and stuck_check):
            return 0.0
        return 1.0 - self.error_density / ERROR_DENSITY_WINDOW


class LoadFactorCheck:
    """PX4's load factor check (module doc): :attr:`failed` while the filtered ratio of the
    measured load factor to the most the wing lifts at the measured airspeed exceeds 1.1."""

    def __init__(self) -> None:
        self.ratio = 0.5
        self.failed = False

    def update(self, dt_s: float, cas_m_s: float, accel_z_m_s2: float, stall_m_s: float,
               in_fixed_wing_flight: bool) -> None:
        if not in_fixed_wing_flight or not math.isfinite(accel_z_m_s2):
            self.ratio, self.failed = 0.5, False
            return
        max_lift_ratio = (max(cas_m_s, 0.7) / max(stall_m_s, 1.0)) ** 2
        # PX4 filters 0.95/0.05 per 50 ms run; the same time constant at this sample rate
        a = min(0.05 * max(dt_s, 0.0) / LOAD_FACTOR_PERIOD_S, 1.0)
        ratio = (1.0 - a) * self.ratio + a * (abs(accel_z_m_s2) / G_LOAD) / max_lift_ratio
        self.ratio = min(max(ratio, 0.25), 2.0)
        self.failed = self.ratio > 1.1


class Airspeed:
    """Fed by the sensors module each run; publishes ``airspeed`` (see the module doc)."""

    def __init__(self, subscribe: Callable[[str], Subscription],
                 advertise: Callable[[str], Publication], msg: Any) -> None:
        self._dp = subscribe("differential_pressure")
        self._air = subscribe("vehicle_air_data")
        self._lpos = subscribe("vehicle_local_position")
        self._accel = subscribe("vehicle_acceleration")
        self._status = subscribe("vehicle_status")
        self._land = subscribe("vehicle_land_detected")
        self._advertise = advertise
        self._pub: Publication | None = None
        self._msg = msg
        self.validator = AirspeedValidator()
        self.stall_m_s = 10.0
        self.innov_m_s = 5.0
        self.t_stop_us = 2_000_000
        self.t_start_us = 10_000_000
        self.checks = CHECK_DATA_STUCK | CHECK_INNOVATION
        self.load_factor = LoadFactorCheck()
        self._last_sample_us = 0
        self.consistent = True          # the consistency check's verdict
        self._fail_since = 0            # first failing sample of the current run of them
        self._pass_since = 0
        self._last_pub_us = 0
        self.ias = self.tas = float("nan")
        self.air_temperature_c = float("nan")
        self.confidence = 0.0
        self.published = 0

    def set_params(self, get: Callable[[str], float]) -> None:
        self.stall_m_s = float(get("ASPD_STALL"))
        self.innov_m_s = float(get("ASPD_FS_INNOV"))
        self.t_stop_us = int(float(get("ASPD_FS_T_STOP")) * 1e6)
        self.t_start_us = int(float(get("ASPD_FS_T_START")) * 1e6)
        self.checks = int(get("ASPD_DO_CHECKS"))

    def update(self, now: int) -> bool:
        """A new differential pressure sample, if any, into ``airspeed``: True if published."""
        if not self._dp.updated():
            if self._pub is not None and self.validator.timed_out(now) \
                    and now - self._last_pub_us >= SILENT_REPUBLISH_US:
                self.confidence = 0.0
                self._publish(now)
                return True
            return False
        dp = self._dp.copy()
        self.validator.put(now, dp.differential_pressure_raw_pa, dp.error_count)
        air = self._air.copy()
        pressure_pa = air.baro_pressure_pa if air is not None else 101325.0
        if dp.temperature > -300.0:
            temp_c = dp.temperature
        elif air is not None:
            temp_c = air.baro_temp_celcius - PCB_TEMP_ESTIMATE_DEG
        else:
            temp_c = 15.0
        ias = ias_m_s(dp.differential_pressure_filtered_pa)
        tas = tas_m_s(ias, pressure_pa, temp_c)
        if not (math.isfinite(ias) and math.isfinite(tas)):
            return False
        self.ias, self.tas, self.air_temperature_c = ias, tas, temp_c
        dt_s = (now - self._last_sample_us) * 1e-6 if self._last_sample_us else 0.0
        self._last_sample_us = now
        self._check_load_factor(min(dt_s, 0.2), ias)
        self._check_consistency(now, tas)
        conf = self.validator.confidence(now, bool(self.checks & CHECK_DATA_STUCK))
        self.confidence = conf if self.consistent else 0.0
        self._publish(now)
        return True

    def _check_load_factor(self, dt_s: float, cas_m_s: float) -> None:
        if not self.checks & CHECK_LOAD_FACTOR:
            self.load_factor.update(dt_s, cas_m_s, 0.0, self.stall_m_s, False)
            return
        st, land, acc = self._status.copy(), self._land.copy(), self._accel.copy()
        in_fw = (st is not None and int(st.arming_state) == ARMING_STATE_ARMED
                 and int(st.vehicle_type) == VEHICLE_TYPE_FIXED_WING
                 and land is not None and not land.landed)
        az = float(acc.xyz[2]) if acc is not None else math.nan
        self.load_factor.update(dt_s, cas_m_s, az, self.stall_m_s, in_fw)

    def _check_consistency(self, now: int, tas: float) -> None:
        lpos = self._lpos.copy()
        innovation = False
        if self.checks & CHECK_INNOVATION and lpos is not None and lpos.v_xy_valid:
            ground = math.hypot(lpos.vx, lpos.vy)
            innovation = ground > self.stall_m_s and ground - tas > self.innov_m_s
        load = self.load_factor.failed
        if innovation or load:
            self._pass_since = 0
            if not self._fail_since:
                self._fail_since = now
            # both at once: a large fault, invalid at once (PX4); one alone after T_STOP
            if self.consistent and ((innovation and load)
                                    or now - self._fail_since >= self.t_stop_us):
                self.consistent = False
        else:
            self._fail_since = 0
            if not self._pass_since:
                self._pass_since = now
            if not self.consistent and now - self._pass_since >= self.t_start_us:
                self.consistent = True

    def _publish(self, now: int) -> None:
        if self._pub is None:
            self._pub = self._advertise("airspeed")
        m = self._msg
        m.timestamp = now
        m.indicated_airspeed_m_s = self.ias
        m.true_airspeed_m_s = self.tas
        m.air_temperature_celsius = self.air_temperature_c
        m.confidence = self.confidence
        self._pub.publish(m)
        self._last_pub_us = now
        self.published += 1

    def status_line(self) -> str:
        v = self.validator
        return (f"airspeed: IAS {self.ias:.2f} TAS {self.tas:.2f} m/s, "
                f"{self.air_temperature_c:.1f} degC, confidence {self.confidence:.2f}, "
                f"{'consistent' if self.consistent else 'INCONSISTENT with ground speed'}"
                f"{', STUCK' if v.stuck else ''}, error density {v.error_density:.0f}, "
                f"load factor ratio {self.load_factor.ratio:.2f}")
