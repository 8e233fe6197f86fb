"""Sensor calibration routines of the commander (PX4's ``commander/*_calibration``): gyro,
accelerometer on six sides and level horizon, started by MAV_CMD_PREFLIGHT_CALIBRATION,
reporting through the STATUSTEXT protocol QGroundControl's sensor page parses, writing the
``CAL_*`` and ``SENS_BOARD_*`` parameters the sensors module applies. See :mod:`.runner`."""

from firmware.modules.commander.calibration.runner import CalibrationRunner, request

__all__ = ["CalibrationRunner", "request"]
