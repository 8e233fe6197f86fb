"""EKF2_* parameters: PX4's names, units and defaults for what this estimator implements."""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["PARAMS"]

_G: Final = "EKF2"


def _f(name: str, default: float, unit: str, short: str, long: str = "", lo: float | None = None,
       hi: float | None = None, decimals: int = 3) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=_G, short=short,
                    long=long, decimals=decimals)


PARAMS: Final[tuple[ParamDef, ...]] = (
    ParamDef("EKF2_PREDICT_US", "INT32", 10000, min=1000, max=20000, unit="us", group=_G,
             short="EKF prediction period",
             long="Covariance prediction and measurement fusion run at this period; the "
                  "attitude output follows every sensor_combined sample.",
             reboot_required=True),
    # -- process noise --
    _f("EKF2_GYR_NOISE", 0.015, "rad/s", "Rate gyro noise for covariance prediction",
       lo=0.0001, hi=0.1, decimals=4),
    _f("EKF2_ACC_NOISE", 0.35, "m/s^2", "Accelerometer noise for covariance prediction",
       lo=0.01, hi=1.0, decimals=2),
    _f("EKF2_GYR_B_NOISE", 0.001, "rad/s^2", "Process noise for IMU rate gyro bias prediction",
       lo=0.0, hi=0.01, decimals=4),
    _f("EKF2_ACC_B_NOISE", 0.003, "m/s^3", "Process noise for IMU accelerometer bias prediction",
       lo=0.0, hi=0.01, decimals=4),
    _f("EKF2_GBIAS_INIT", 0.1, "rad/s", "1-sigma IMU gyro switch-on bias", lo=0.0, hi=0.2),
    _f("EKF2_ABIAS_INIT", 0.2, "m/s^2", "1-sigma IMU accelerometer switch-on bias",
       lo=0.0, hi=0.5),
    _f("EKF2_ANGERR_INIT", 0.1, "rad", "1-sigma tilt angle uncertainty after gravity vector "
       "alignment", lo=0.0, hi=0.5),
    # -- observation noise --
    _f("EKF2_GPS_V_NOISE", 0.3, "m/s", "Measurement noise for GNSS velocity",
       "Lower bound; the receiver's speed accuracy is used when larger.", 0.01, 5.0, 2),
    _f("EKF2_GPS_P_NOISE", 0.5, "m", "Measurement noise for GNSS position",
       "Lower bound; the receiver's eph is used when larger.", 0.01, 10.0, 2),
    _f("EKF2_BARO_NOISE", 3.5, "m", "Measurement noise for barometric altitude",
       lo=0.01, hi=15.0, decimals=2),
    _f("EKF2_HEAD_NOISE", 0.3, "rad", "Measurement noise for magnetic heading fusion",
       lo=0.01, hi=1.0, decimals=2),
    # -- innovation gates --
    _f("EKF2_GPS_P_GATE", 5.0, "SD", "Gate size for GNSS position fusion",
       "Innovation consistency gate in standard deviations: a test ratio above 1 rejects.",
       1.0, 10.0, 1),
    _f("EKF2_GPS_V_GATE", 5.0, "SD", "Gate size for GNSS velocity fusion", lo=1.0, hi=10.0,
       decimals=1),
    _f("EKF2_BARO_GATE", 5.0, "SD", "Gate size for barometric and GPS height fusion",
       lo=1.0, hi=10.0, decimals=1),
    _f("EKF2_HDG_GATE", 2.6, "SD", "Gate size for magnetic heading fusion", lo=1.0, hi=10.0,
       decimals=1),
    # -- delays --
    _f("EKF2_GPS_DELAY", 40.0, "ms", "GPS measurement delay relative to IMU measurements",
       "Time from the receiver's epoch to sensor_gps.timestamp_sample. PX4 ships 110 ms for "
       "real receivers; the emulated u-blox (5 Hz, 115200 baud) measures ~40 ms.",
       0.0, 300.0, 1),
    _f("EKF2_BARO_DELAY", 0.0, "ms", "Barometer measurement delay relative to IMU "
       "measurements", lo=0.0, hi=300.0, decimals=1),
    _f("EKF2_MAG_DELAY", 0.0, "ms", "Magnetometer measurement delay relative to IMU "
       "measurements", lo=0.0, hi=300.0, decimals=1),
    # -- GPS use --
    ParamDef("EKF2_GPS_CTRL", "INT32", 7, min=0, max=15, group=_G,
             short="GNSS sensor aiding",
             long="Bitmask: bit 0 horizontal position, bit 1 altitude (not used: baro is the "
                  "height source), bit 2 3D velocity."),
    ParamDef("EKF2_GPS_CHECK", "INT32", 245, min=0, max=511, group=_G,
             short="Integer bitmask controlling GPS checks",
             long="Bits: 0 min sat count (EKF2_REQ_NSATS), 1 max PDOP (EKF2_REQ_PDOP, checked "
                  "on hdop), 2 max horizontal error (EKF2_REQ_EPH), 3 max vertical error "
                  "(EKF2_REQ_EPV), 4 max speed error (EKF2_REQ_SACC). A 3D fix is always "
                  "required."),
    _f("EKF2_REQ_EPH", 3.0, "m", "Required EPH to use GPS", lo=2.0, hi=100.0, decimals=1),
    _f("EKF2_REQ_EPV", 5.0, "m", "Required EPV to use GPS", lo=2.0, hi=100.0, decimals=1),
    _f("EKF2_REQ_SACC", 0.5, "m/s", "Required speed accuracy to use GPS", lo=0.5, hi=5.0,
       decimals=2),
    ParamDef("EKF2_REQ_NSATS", "INT32", 6, min=4, max=12, group=_G,
             short="Required satellite count to use GPS"),
    _f("EKF2_REQ_PDOP", 2.5, "", "Maximum PDOP to use GPS", lo=1.5, hi=5.0, decimals=1),
    _f("EKF2_REQ_GPS_H", 10.0, "s", "Required GPS health time on startup",
       "The checks must pass continuously for this long before GPS is used.", 0.1, 30.0, 1),
    ParamDef("EKF2_NOAID_TOUT", "INT32", 5000000, min=500000, max=10000000, unit="us",
             group=_G, short="Maximum inertial dead-reckoning time",
             long="A GPS position or velocity, or baro height, rejected by its innovation gate "
                  "for longer than this resets the state to the measurement."),
    # -- magnetometer --
    ParamDef("EKF2_MAG_TYPE", "INT32", 0, min=0, max=5, group=_G,
             short="Type of magnetometer fusion",
             long="Automatic and Heading both fuse the magnetic heading; None disables it.",
             values={0: "Automatic", 1: "Magnetic heading", 5: "None"}),
    _f("EKF2_MAG_DECL", 0.0, "deg", "Magnetic declination",
       "East positive; the world's default site (Zurich) has +2.6 deg.", decimals=1),
    ParamDef("EKF2_MAG_CHECK", "INT32", 1, min=0, max=1, group=_G,
             short="Magnetic field strength and inclination check",
             long="1: a field whose strength or inclination differs from the one at alignment "
                  "by more than EKF2_MAG_CHK_STR / EKF2_MAG_CHK_INC is not fused and flagged "
                  "(pre_flt_fail_mag_field_disturbed).",
             values={0: "Disabled", 1: "Enabled"}),
    _f("EKF2_MAG_CHK_STR", 0.2, "gauss", "Magnetic field strength check tolerance",
       lo=0.0, hi=1.0, decimals=2),
    _f("EKF2_MAG_CHK_INC", 20.0, "deg", "Magnetic field inclination check tolerance",
       lo=0.0, hi=90.0, decimals=1),
)
