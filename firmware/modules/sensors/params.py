"""Parameters of the sensors module: per-device calibration slots, board rotation, filters.

Names, units, ranges and meanings follow PX4's parameter reference so a QGroundControl
calibration written for a real Pixhawk 1 applies here unchanged: a calibration slot ``n`` of a
sensor kind belongs to the device whose ``device_id`` is ``CAL_<KIND>n_ID`` (the id encodes bus,
address and chip type, so a slot follows its chip even when instance numbers change). Defaults
leave the data unchanged: no slot matches a device (ID 0), offsets 0, scales 1.
"""

from __future__ import annotations

from typing import Final

from firmware.modules.sensors.airspeed import AIRSPEED_PARAMS
from firmware.platform.params import ParamDef

__all__ = ["N_ACCEL_CAL", "N_BARO_CAL", "N_GYRO_CAL", "N_MAG_CAL", "PARAMS", "PRIORITY_VALUES"]

N_ACCEL_CAL: Final = 3
N_GYRO_CAL: Final = 3
N_MAG_CAL: Final = 4
N_BARO_CAL: Final = 3

_CAL: Final = "Sensor Calibration"
_SENS: Final = "Sensors"
_IMU: Final = "Sensors"

PRIORITY_VALUES: Final = {-1: "Uninitialized", 0: "Disabled", 1: "Min", 25: "Low", 50: "Medium (Default)",
                   75: "High", 100: "Max"}
_ROT_LONG: Final = ("PX4 rotation enum of the sensor relative to the vehicle (external sensors only); "
             "-1 for an internal sensor, which follows SENS_BOARD_ROT.")


def _slot(kind: str, long_kind: str, n: int, axes_unit: str, scale: bool, odiag: bool,
          rot: bool) -> list[ParamDef]:
    p = f"CAL_{kind}{n}"
    out = [
        ParamDef(f"{p}_ID", "INT32", 0, group=_CAL,
                 short=f"{long_kind} {n} calibration device ID",
                 long=f"Device ID of the {long_kind.lower()} this calibration slot applies to "
                      "(bus, address and chip type); 0: the slot is unused."),
        ParamDef(f"{p}_PRIO", "INT32", -1, min=-1, max=100, group=_CAL,
                 short=f"{long_kind} {n} priority",
                 long="Selection priority among redundant sensors; 0 disables the sensor. -1 "
                      "(uninitialized) is Medium for internal and High for external sensors.",
                 values=PRIORITY_VALUES),
    ]
    if rot:
        out.append(ParamDef(f"{p}_ROT", "INT32", -1, min=-1, max=25, group=_CAL,
                            short=f"{long_kind} {n} rotation relative to airframe",
                            long=_ROT_LONG))
    for ax in "XYZ":
        out.append(ParamDef(f"{p}_{ax}OFF", "FLOAT", 0.0, unit=axes_unit, group=_CAL,
                            short=f"{long_kind} {n} {ax}-axis offset", decimals=4))
    if scale:
        for ax in "XYZ":
            out.append(ParamDef(f"{p}_{ax}SCALE", "FLOAT", 1.0, min=0.1, max=3.0, group=_CAL,
                                short=f"{long_kind} {n} {ax}-axis scaling factor", decimals=4))
    if odiag:
        for ax in "XYZ":
            out.append(ParamDef(f"{p}_{ax}ODIAG", "FLOAT", 0.0, min=-1.0, max=1.0, group=_CAL,
                                short=f"{long_kind} {n} {ax}-axis off diagonal factor",
                                long="Off-diagonal terms of the soft-iron matrix: X is (0,1) "
                                     "and (1,0), Y is (0,2) and (2,0), Z is (1,2) and (2,1).",
                                decimals=4))
    return out


def _build() -> tuple[ParamDef, ...]:
    defs: list[ParamDef] = []
    for n in range(N_ACCEL_CAL):
        defs += _slot("ACC", "Accelerometer", n, "m/s^2", True, False, True)
    for n in range(N_GYRO_CAL):
        defs += _slot("GYRO", "Gyroscope", n, "rad/s", False, False, True)
    for n in range(N_MAG_CAL):
        defs += _slot("MAG", "Magnetometer", n, "gauss", True, True, True)
    for n in range(N_BARO_CAL):
        defs += [
            ParamDef(f"CAL_BARO{n}_ID", "INT32", 0, group=_CAL,
                     short=f"Barometer {n} calibration device ID"),
            ParamDef(f"CAL_BARO{n}_PRIO", "INT32", -1, min=-1, max=100, group=_CAL,
                     short=f"Barometer {n} priority", values=PRIORITY_VALUES),
            ParamDef(f"CAL_BARO{n}_OFF", "FLOAT", 0.0, unit="Pa", group=_CAL,
                     short=f"Barometer {n} offset",
                     long="Subtracted from the measured static pressure.", decimals=1),
        ]
    defs += [
        ParamDef("CAL_MAG_SIDES", "INT32", 63, min=34, max=63, group=_CAL,
                 short="Bitfield selecting mag sides for calibration",
                 long="The sides the magnetometer calibration asks for (bit 0 tail down, 1 "
                      "nose down, 2 left, 3 right, 4 upside down, 5 right side up); "
                      "QGroundControl reads it to show them. 63: all six.",
                 values={34: "Two side calibration", 38: "Three side calibration",
                         63: "Six side calibration"}),
        ParamDef("SENS_BOARD_ROT", "INT32", 0, min=0, max=25, group=_SENS,
                 short="Board rotation",
                 long="How the flight controller is mounted in the vehicle (PX4 rotation enum, "
                      "board to vehicle body); applies to the internal sensors.",
                 reboot_required=False),
        ParamDef("SENS_BOARD_X_OFF", "FLOAT", 0.0, unit="deg", group=_SENS,
                 short="Board rotation X (roll) offset",
                 long="Fine trim of the board mounting, applied after SENS_BOARD_ROT.",
                 decimals=1),
        ParamDef("SENS_BOARD_Y_OFF", "FLOAT", 0.0, unit="deg", group=_SENS,
                 short="Board rotation Y (pitch) offset", decimals=1),
        ParamDef("SENS_BOARD_Z_OFF", "FLOAT", 0.0, unit="deg", group=_SENS,
                 short="Board rotation Z (yaw) offset", decimals=1),
        ParamDef("IMU_GYRO_CUTOFF", "FLOAT", 40.0, min=0.0, max=1000.0, unit="Hz", group=_IMU,
                 short="Low pass filter cutoff frequency for gyro",
                 long="2nd-order Butterworth on vehicle_angular_velocity (what the rate "
                      "controller sees). 0 disables it. Not applied to sensor_combined, which "
                      "the estimator integrates.", decimals=1),
        ParamDef("IMU_GYRO_RATEMAX", "INT32", 400, min=100, max=2000, unit="Hz", group=_IMU,
                 short="Gyro control data maximum publication rate (inner loop rate)",
                 long="The maximum rate the gyro control data (vehicle_angular_velocity) will "
                      "be allowed to publish at. This is the loop rate for the rate controller "
                      "and outputs. Note: sensor data is always read and filtered at the full "
                      "raw rate regardless of this setting.",
                 values={100: "100 Hz", 250: "250 Hz", 400: "400 Hz", 800: "800 Hz",
                         1000: "1000 Hz", 2000: "2000 Hz"},
                 reboot_required=True),
        ParamDef("IMU_DGYRO_CUTOFF", "FLOAT", 30.0, min=0.0, max=1000.0, unit="Hz", group=_IMU,
                 short="Cutoff frequency for angular acceleration (D-term filter)",
                 long="1st-order low-pass on the derivative of the filtered rate "
                      "(vehicle_angular_velocity.xyz_derivative).", decimals=1),
        ParamDef("IMU_ACCEL_CUTOFF", "FLOAT", 30.0, min=0.0, max=1000.0, unit="Hz", group=_IMU,
                 short="Low pass filter cutoff frequency for accel",
                 long="1st-order low-pass on vehicle_acceleration.", decimals=1),
        ParamDef("IMU_INTEG_RATE", "INT32", 250, min=100, max=1000, unit="Hz", group=_IMU,
                 short="IMU integration rate",
                 long="Rate of sensor_combined: gyro and accel are integrated over this "
                      "interval (the estimator's input)."),
        ParamDef("SENS_BARO_QNH", "FLOAT", 1013.25, min=500.0, max=1500.0, unit="hPa",
                 group=_SENS, short="QNH for barometer",
                 long="Sea-level pressure for the ISA altitude of vehicle_air_data.",
                 decimals=2),
        ParamDef("SENS_BARO_RATE", "FLOAT", 20.0, min=1.0, max=200.0, unit="Hz", group=_SENS,
                 short="Baro max rate",
                 long="vehicle_air_data is the average of the samples over this interval.",
                 decimals=1),
        ParamDef("SENS_MAG_RATE", "FLOAT", 15.0, min=1.0, max=200.0, unit="Hz", group=_SENS,
                 short="Magnetometer max rate",
                 long="vehicle_magnetometer is the average of the samples over this interval.",
                 decimals=1),
    ]
    return tuple(defs)


#: Every parameter of the sensors module (the airspeed part's are declared with it).
PARAMS: Final[tuple[ParamDef, ...]] = _build() + AIRSPEED_PARAMS
