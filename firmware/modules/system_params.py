"""Core system parameters: airframe selection, IO use, SD logging (PX4's SYS_* and SDLOG_*).

They belong to no single module: the startup script (ROMFS rcS) reads them to choose the
airframe, whether to start the IO coprocessor driver and how to log. Metadata follows PX4's
parameter reference so QGroundControl shows the same names, ranges and meanings.
"""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["PARAMS"]

PARAMS: Final[tuple[ParamDef, ...]] = (
    ParamDef("SYS_AUTOSTART", "INT32", 0, min=0, max=9999999, group="System",
             short="Auto-start script index",
             long="The airframe the startup script configures: the number of a file in "
                  "/etc/init.d/airframes (4001 generic quadcopter X, 4011 DJI F450). "
                  "0 starts no vehicle.",
             reboot_required=True),
    ParamDef("SYS_AUTOCONFIG", "INT32", 0, min=0, max=2, group="System",
             short="Automatically configure default values",
             long="Set to 1 to load the airframe's default parameters at the next boot; the "
                  "startup script sets it back to 0 afterwards.",
             values={0: "Keep parameters", 1: "Reset parameters to airframe defaults",
                     2: "Reload airframe parameters"}),
    ParamDef("SYS_USE_IO", "INT32", 1, min=0, max=1, group="System",
             short="Use the IO coprocessor for outputs",
             long="If 0, the px4io driver is not started and the FMU drives the outputs.",
             values={0: "FMU outputs", 1: "IO coprocessor"}, reboot_required=True),
    ParamDef("SYS_HITL", "INT32", 0, min=0, max=1, group="System",
             short="Enable HITL mode",
             long="Sensors are replaced by HIL_* messages from the simulator (PX4 meaning). In "
                  "fmu-hil the emulated sensors are real drivers, so this normally stays 0.",
             values={0: "HITL disabled", 1: "HITL enabled"}, reboot_required=True),
    ParamDef("SYS_PARAM_VER", "INT32", 1, min=0, group="System",
             short="Parameter version",
             long="Compared with the airframe's version to decide whether to reset parameters."),
    ParamDef("SYS_FAILURE_EN", "INT32", 0, min=0, max=1, group="System",
             short="Enable failure injection",
             long="If enabled, MAV_CMD_INJECT_FAILURE is passed to the failure_injector module, "
                  "which has the orchestrator apply a fault of its catalogue (docs/faults.md). "
                  "If disabled, the command is denied. Only for testing: never enable it on a "
                  "vehicle that flies (PX4 meaning).",
             values={0: "Disabled", 1: "Enabled"}),
    ParamDef("SDLOG_MODE", "INT32", 0, min=-1, max=3, group="SD Logging",
             short="Logging mode",
             long="When the logger writes a file.",
             values={-1: "disabled", 0: "when armed until disarm", 1: "from boot until disarm",
                     2: "from boot until shutdown", 3: "depending on AUX1 RC channel"},
             reboot_required=True),
    ParamDef("SDLOG_PROFILE", "INT32", 1, min=0, max=4095, group="SD Logging",
             short="Logging topic profile (bitmask)",
             long="Bit 0 default set, bit 1 estimator replay, bit 2 thermal calibration, "
                  "bit 3 system identification, bit 4 high rate, bit 5 debug, bit 6 sensor "
                  "comparison.",
             reboot_required=True),
    ParamDef("SDLOG_DIRS_MAX", "INT32", 0, min=0, max=1000, group="SD Logging",
             short="Maximum number of log directories to keep (0: keep all)",
             reboot_required=True),
    ParamDef("SDLOG_UTC_OFFSET", "INT32", 0, min=-1000, max=1000, unit="min",
             group="SD Logging", short="UTC offset of log file names"),
)
