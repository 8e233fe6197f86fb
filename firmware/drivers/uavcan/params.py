"""The uavcan driver's parameters, PX4's names and meanings (kept apart from the driver so that
declaring them at boot imports nothing of the DroneCAN stack)."""

from __future__ import annotations

from firmware.platform.params import ParamDef

__all__ = ["PARAMS"]

_G = "UAVCAN"

PARAMS: tuple[ParamDef, ...] = (
    ParamDef("UAVCAN_ENABLE", "INT32", 0, min=0, max=3, group=_G, reboot_required=True,
             short="UAVCAN mode",
             long="0: the uavcan driver is not started (no CAN traffic). Any other value starts "
                  "it from the startup script on CAN1. 2 and 3 also run the dynamic node-ID "
                  "allocation server, so nodes without a configured ID get one.",
             values={0: "Disabled", 1: "Sensors Manual Config", 2: "Sensors Automatic Config",
                     3: "Sensors and Actuators (ESCs) Automatic Config"}),
    ParamDef("UAVCAN_NODE_ID", "INT32", 1, min=1, max=125, group=_G, reboot_required=True,
             short="UAVCAN Node ID", long="Read once at startup."),
    ParamDef("UAVCAN_BITRATE", "INT32", 1_000_000, min=20_000, max=1_000_000, group=_G,
             reboot_required=True, unit="bit/s", short="UAVCAN CAN bus bitrate",
             long="The bit rate the FMU's CAN controller is set to. The emulated bus and its "
                  "nodes run at 1 Mbit/s: another value leaves the driver off the bus (a "
                  "controller at the wrong rate sees only errors) and says so."),
    ParamDef("UAVCAN_SUB_GPS", "INT32", 1, min=0, max=1, group=_G, reboot_required=True,
             short="subscription GPS",
             long="1: uavcan.equipment.gnss.Fix2 from CAN GNSS nodes is published as sensor_gps "
                  "(device ID bus type UAVCAN).", values={0: "Disabled", 1: "Enabled"}),
    ParamDef("UAVCAN_SUB_MAG", "INT32", 1, min=0, max=1, group=_G, reboot_required=True,
             short="subscription magnetometer",
             long="1: uavcan.equipment.ahrs.MagneticFieldStrength2 from CAN compass nodes is "
                  "published as sensor_mag (device ID bus type UAVCAN).",
             values={0: "Disabled", 1: "Enabled"}),
    ParamDef("UAVCAN_EC_MIN", "INT32", 1, min=0, max=8191, group=_G, reboot_required=True,
             short="CAN ESC minimum command",
             long="RawCommand value of a mixer output at -1 while armed (UAVCAN_ENABLE 3): the "
                  "CAN counterpart of PWM_MIN (0 stops the motor; 8191 is full throttle)."),
    ParamDef("UAVCAN_EC_MAX", "INT32", 8191, min=1, max=8191, group=_G, reboot_required=True,
             short="CAN ESC maximum command",
             long="RawCommand value of a mixer output at +1 (UAVCAN_ENABLE 3)."),
)
